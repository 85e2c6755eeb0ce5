"""Progress bars and warnings on stderr for long work (evaluations, sweeps, training).

Warnings of a command's work are printed once each (:func:`warnings_said_once`).

On a terminal a bar redraws up to ten times a second. Where stderr is a file or a pipe (``nohup``,
a batch job, CI), every redraw would be appended to the log, a line of it per tenth of a second over a
run of hours: there a bar redraws at most once a minute (and at its end). A notebook keeps tqdm's
own widget.
"""

from __future__ import annotations

import contextlib
import sys
import warnings
from collections.abc import Iterator
from typing import Any

#: Seconds between redraws where stderr is not a terminal.
LOG_INTERVAL = 60.0


def _writes_to_log() -> bool:
    if "ipykernel" in sys.modules:  # tqdm.auto draws a widget there, not text
        return False
    isatty = getattr(sys.stderr, "isatty", None)
    return not (isatty and isatty())


def progress_bar(total: int, initial: int = 0, *, desc: str | None = None, unit: str = "it",
                 enabled: bool = True, leave: bool = True) -> Any:
    """A ``tqdm`` bar on stderr.

    Args:
        total: The count at completion.
        initial: The count already done (a resumed run).
        desc: Its label.
        unit: What it counts.
        enabled: False: a disabled bar (same calls, no output).
        leave: Keep the finished bar on screen.

    Returns:
        The bar.
    """
    from tqdm.auto import tqdm

    log = _writes_to_log()
    return tqdm(
        total=total,
        initial=initial,
        desc=desc,
        unit=unit,
        file=sys.stderr,
        disable=not enabled,
        dynamic_ncols=not log,
        leave=leave,
        mininterval=LOG_INTERVAL if log else 0.1,
        # tqdm lowers the interval again where updates come slowly; in a log that would undo the above
        maxinterval=max(LOG_INTERVAL, 10.0) if log else 10.0,
        smoothing=0.0 if log else 0.3,
    )


def say_line(line: str) -> None:
    """Prints ``line`` on stderr on a line of its own, above a progress bar that is being drawn.

    A plain ``print`` would land after the bar's text on the bar's own line.
    """
    try:
        from tqdm import tqdm
    except ImportError:  # no bar can be drawn either
        print(line, file=sys.stderr, flush=True)
        return
    tqdm.write(line, file=sys.stderr)
    sys.stderr.flush()


@contextlib.contextmanager
def warnings_said_as_they_come() -> Iterator[None]:
    """Prints each distinct warning once, as ``warning: …`` above any progress bar, when it is raised.

    For long work (training) whose warnings matter before it ends; Python's own format would add the
    source line that raised it.
    """
    said: set[str] = set()

    def show(message: Warning | str, *_: Any, **__: Any) -> None:
        if str(message) not in said:
            said.add(str(message))
            say_line(f"warning: {message}")

    with warnings.catch_warnings():
        warnings.simplefilter("always")
        warnings.showwarning = show
        yield


@contextlib.contextmanager
def warnings_said_once(sort: bool = True) -> Iterator[None]:
    """Collects the warnings of a command's work and prints each distinct one once, as ``warning: …``.

    A warning raised per episode or per task would otherwise fill the terminal (Python's own filter
    shows it once per code location, hiding different messages from the same line).

    Args:
        sort: Print in sorted order (True) or in the order first raised.
    """
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        yield  # a failure propagates without them: its one-line error is what the user needs then
    messages = dict.fromkeys(str(w.message) for w in caught)
    for note in sorted(messages) if sort else messages:
        print(f"warning: {note}", file=sys.stderr)

"""Progress bars: redrawn often on a terminal, rarely in a log file (socialnav._progress)."""

from __future__ import annotations

import io
import sys

import pytest

from socialnav import _progress
from socialnav._progress import LOG_INTERVAL, progress_bar


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def _run_bar(monkeypatch: pytest.MonkeyPatch, stream: io.StringIO, updates: int) -> str:
    monkeypatch.setattr(sys, "stderr", stream)
    monkeypatch.delitem(sys.modules, "ipykernel", raising=False)
    clock = iter(range(10_000))  # tqdm's clock: one second per call, so a terminal bar redraws each time
    monkeypatch.setattr("tqdm.std.time", lambda: float(next(clock)))
    bar = progress_bar(updates, desc="demo", unit="ep")
    for _ in range(updates):
        bar.update(1)
    bar.close()
    return stream.getvalue()


def test_a_log_file_gets_a_redraw_per_minute_not_per_update(monkeypatch: pytest.MonkeyPatch) -> None:
    # 100 updates, one second apart: 100 s of work -> at most two timed redraws, plus the first and last.
    text = _run_bar(monkeypatch, io.StringIO(), 100)
    assert LOG_INTERVAL == 60.0
    assert 2 <= text.count("\r") <= 4, text
    assert "100/100" in text


def test_a_terminal_gets_a_redraw_per_update(monkeypatch: pytest.MonkeyPatch) -> None:
    text = _run_bar(monkeypatch, _Terminal(), 100)
    assert text.count("\r") >= 100


def test_a_notebook_keeps_tqdms_own_bar(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sys, "stderr", io.StringIO())
    monkeypatch.setitem(sys.modules, "ipykernel", object())
    assert not _progress._writes_to_log()
    monkeypatch.delitem(sys.modules, "ipykernel")
    assert _progress._writes_to_log()


def test_a_disabled_bar_writes_nothing(monkeypatch: pytest.MonkeyPatch) -> None:
    stream = io.StringIO()
    monkeypatch.setattr(sys, "stderr", stream)
    bar = progress_bar(10, enabled=False)
    bar.update(10)
    bar.close()
    assert stream.getvalue() == ""


def test_warnings_said_once_prints_each_distinct_warning_once_and_nothing_on_failure(capsys):
    import warnings

    from socialnav._progress import warnings_said_once

    with warnings_said_once():
        for _ in range(3):
            warnings.warn("b: per episode", stacklevel=1)
        warnings.warn("a: once", stacklevel=1)
    assert capsys.readouterr().err == "warning: a: once\nwarning: b: per episode\n"
    with warnings_said_once(sort=False):
        warnings.warn("z", stacklevel=1)
        warnings.warn("a", stacklevel=1)
    assert capsys.readouterr().err == "warning: z\nwarning: a\n"
    with pytest.raises(ValueError), warnings_said_once():
        warnings.warn("before the failure", stacklevel=1)
        raise ValueError("bad input")
    assert capsys.readouterr().err == ""  # the error alone reaches the user


def test_say_line_puts_a_line_above_an_active_bar_not_after_its_text(monkeypatch):
    from socialnav._progress import say_line

    monkeypatch.setattr(sys, "stderr", io.StringIO())
    bar = progress_bar(10, desc="work")
    bar.update(3)
    say_line("episode 32: validation success 0.500")
    bar.close()
    text = sys.stderr.getvalue()
    # the bar's line is cleared first (\r, blanks, \r), so the line starts a line of its own
    assert "\repisode 32: validation success 0.500\n" in text
    assert "]episode 32" not in text and "s]episode" not in text  # not glued onto the bar's text


def test_warnings_said_as_they_come_print_at_once_without_the_source_line(monkeypatch):
    import warnings

    from socialnav._progress import warnings_said_as_they_come

    monkeypatch.setattr(sys, "stderr", io.StringIO())
    with warnings_said_as_they_come():
        warnings.warn("8 slots for 9 scenarios", UserWarning, stacklevel=1)
        assert sys.stderr.getvalue() == "warning: 8 slots for 9 scenarios\n"  # at once, not at the end
        warnings.warn("8 slots for 9 scenarios", UserWarning, stacklevel=1)
    assert sys.stderr.getvalue() == "warning: 8 slots for 9 scenarios\n"  # once

"""Can worker processes be started from here without re-running the user's script?

Worker processes started by ``forkserver`` or ``spawn`` re-import the ``__main__`` module (as
``__mp_main__``). A script that calls :func:`~socialnav.evaluate.runner.run_protocol` at its top level,
outside ``if __name__ == "__main__":``, would therefore run the protocol again in every worker, which
multiprocessing refuses (``BrokenProcessPool``). The runner asks :func:`main_module_reruns_call`
and scores in its own process in that case.
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path


def main_module_reruns_call(depth: int = 1) -> bool:
    """True when the current call comes from top-level code of the ``__main__`` module (a script or
    ``python -m`` module) that is not inside an ``if __name__ == "__main__":`` block.

    Args:
        depth: Frames to skip (the caller of the function asking).
    """
    main = sys.modules.get("__main__")
    path = getattr(main, "__file__", None)
    if main is None or not path:
        return False  # interactive, `python -c`, notebooks: workers import no __main__ file
    frame = sys._getframe(depth)
    while frame is not None and not (
        frame.f_code.co_name == "<module>" and frame.f_globals is vars(main)
    ):
        frame = frame.f_back
    if frame is None:
        return False  # not reached from the script's top-level code (e.g. from a thread)
    try:
        tree = ast.parse(Path(path).read_text(encoding="utf-8"))
    except (OSError, SyntaxError, ValueError, UnicodeDecodeError):
        return True  # cannot tell: assume the worst
    line = frame.f_lineno
    return not any(
        isinstance(node, ast.If) and _is_main_test(node.test) and node.lineno <= line <= node.end_lineno
        for node in tree.body
    )


def _is_main_test(test: ast.expr) -> bool:
    """``__name__ == "__main__"`` (either order)."""
    if not (isinstance(test, ast.Compare) and len(test.ops) == 1 and isinstance(test.ops[0], ast.Eq)):
        return False
    sides = [test.left, test.comparators[0]]
    names = [s.id for s in sides if isinstance(s, ast.Name)]
    consts = [s.value for s in sides if isinstance(s, ast.Constant)]
    return names == ["__name__"] and consts == ["__main__"]

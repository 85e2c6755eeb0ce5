"""How socialnav's processes run: BLAS threads, worker processes tied to their run, the main guard.

The layer below every package (docs/internals.md, "Layers"), beside :mod:`socialnav._io`.

**One BLAS thread where processes already give the parallelism.** NumPy's OpenBLAS starts a thread
per core and, after each call, keeps them spinning for a while. In an evaluation or a sweep, where
worker processes already use every core, those threads only take CPU from the workers: measured on
a 2-core machine (`benchmarks/bench_sweep.py`'s sweep), the driver's OpenBLAS threads burnt 0.7 s of
CPU in a 3 s run, for the bootstrap's small matrix products; with one BLAS thread the driver's CPU
halved and the 2-worker sweep got 8 % faster. The number of BLAS threads does not change a result
here (OpenBLAS splits a product's output, not its sums).

**Workers die with the run that started them, however it dies (SIGKILL included).** Pools run in a
``forkserver``: the forkserver is a child of the run, the workers are children of the forkserver.
On Linux each link gets ``PR_SET_PDEATHSIG``: the kernel sends SIGKILL to the forkserver when the
run dies and to a worker when the forkserver dies, so nothing of the run's tree is left holding
memory or the caller's stdout. The resource tracker then sees end-of-file on its pipe and exits by
itself. Elsewhere (no ``prctl``) this does nothing. The forkserver imports this module
(``set_forkserver_preload``); it acts only in a process whose parent is the pid recorded in
``SOCIALNAV_LIFELINE_PARENT`` by the run, so importing it anywhere else is harmless.

**Can workers be started without re-running the user's script?** Processes started by
``forkserver`` or ``spawn`` re-import the ``__main__`` module (as ``__mp_main__``). A script that
calls :func:`socialnav.evaluate.run_protocol` at its top level, outside ``if __name__ ==
"__main__":``, would run the protocol again in every worker, which multiprocessing refuses
(``BrokenProcessPool``). The runner asks :func:`main_module_reruns_call` and works in its own
process in that case.
"""

from __future__ import annotations

import ast
import contextlib
import importlib
import os
import signal
import sys
from collections.abc import Callable
from pathlib import Path
from types import FrameType
from typing import Any

__all__ = [
    "one_blas_thread",
    "one_blas_thread_for_good",
    "die_with_parent",
    "worker_init",
    "start_forkserver",
    "forkserver_pool",
    "main_module_reruns_call",
    "lazy_exports",
]

_LIMITED_FOR_GOOD = False


def one_blas_thread() -> Any:
    """A context manager limiting BLAS to one thread inside it (a no-op without threadpoolctl)."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - a declared dependency
        return contextlib.nullcontext()
    return threadpool_limits(limits=1, user_api="blas")


def one_blas_thread_for_good() -> None:
    """Limits BLAS to one thread for the rest of this process (worker processes), once."""
    global _LIMITED_FOR_GOOD
    if not _LIMITED_FOR_GOOD:
        one_blas_thread()
        _LIMITED_FOR_GOOD = True


# ------------------------------------------------------------------------------------ lifeline
ENV = "SOCIALNAV_LIFELINE_PARENT"
_PR_SET_PDEATHSIG = 1

#: What every worker imports, imported once by the forkserver instead (its workers are forked with
#: them loaded, so a new pool's workers start in milliseconds instead of each importing for ~0.4 s).
#: Named, not imported, here: they sit above this layer. Not torch: a learned policy's worker
#: imports it when it unpickles the policy.
WORKER_MODULES = ("socialnav.evaluate.runner", "socialnav.sweep.tasks", "pyarrow.parquet")

#: pid of the forkserver when this module was imported there (inherited by the forked workers).
FORKSERVER_PID: int | None = None


def die_with_parent(parent: int) -> bool:
    """Asks the kernel to SIGKILL this process when ``parent`` (its parent now) exits.

    Returns False where unsupported. Exits at once if ``parent`` is already gone (the race between
    fork and this call).
    """
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        if libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0) != 0:
            return False
    except (OSError, AttributeError):
        return False
    if os.getppid() != parent:
        os._exit(1)
    return True


def worker_init() -> None:
    """Initializer of a pool worker: tied to the forkserver; Ctrl-C is the run's to handle."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if FORKSERVER_PID is not None:
        die_with_parent(FORKSERVER_PID)
    one_blas_thread_for_good()  # the workers are the parallelism


def start_forkserver() -> None:
    """Starts the forkserver (if not yet running) with this module preloaded, tied to this process."""
    import multiprocessing
    from multiprocessing import forkserver

    multiprocessing.get_context("forkserver").set_forkserver_preload([__name__, *WORKER_MODULES])
    previous = os.environ.get(ENV)
    os.environ[ENV] = str(os.getpid())  # only the forkserver started now sees it
    try:
        forkserver.ensure_running()
    finally:
        if previous is None:
            os.environ.pop(ENV, None)
        else:
            os.environ[ENV] = previous


def forkserver_pool(
    workers: int, initializer: Callable[..., None] = worker_init, initargs: tuple[Any, ...] = ()
) -> Any:
    """A ``ProcessPoolExecutor`` of ``workers`` forkserver processes that die with this process.

    ``initializer`` must call :func:`worker_init` first (the default is :func:`worker_init` itself).
    """
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    start_forkserver()
    return ProcessPoolExecutor(
        max_workers=workers,
        mp_context=multiprocessing.get_context("forkserver"),
        initializer=initializer,
        initargs=initargs,
    )


def _on_import_in_forkserver() -> None:
    global FORKSERVER_PID
    parent = os.environ.get(ENV)
    in_forkserver = sys.argv[:1] == ["-c"] and "multiprocessing.forkserver" in sys.modules
    if in_forkserver and parent and parent.isdigit() and os.getppid() == int(parent):
        FORKSERVER_PID = os.getpid()
        die_with_parent(int(parent))


_on_import_in_forkserver()


# ---------------------------------------------------------------------------------- main guard
def main_module_reruns_call(depth: int = 1) -> bool:
    """Whether the current call comes from unguarded top-level code of ``__main__``.

    True when the caller is top-level code of the ``__main__`` module (a script or ``python -m`` module) that
    is not inside an ``if __name__ == "__main__":`` block.

    Args:
        depth: Frames to skip (the caller of the function asking).
    """
    main = sys.modules.get("__main__")
    path = getattr(main, "__file__", None)
    if main is None or not path:
        return False  # interactive, `python -c`, notebooks: workers import no __main__ file
    frame: FrameType | None = sys._getframe(depth)
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
        isinstance(node, ast.If)
        and _is_main_test(node.test)
        and node.lineno <= line <= (node.end_lineno or node.lineno)
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


# --------------------------------------------------------------------------- package public APIs
def lazy_exports(
    package: str, exports: dict[str, str]
) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """``__getattr__`` and ``__dir__`` for a package whose public names live in its submodules.

    ``exports`` maps each public name to the submodule defining it. A name's submodule is imported on
    first access, so ``import socialnav.sim`` costs no more than before and a package's API never
    pulls in what its user does not touch (``import socialnav.metrics`` stays NumPy-only, the
    simulator torch-free).
    """
    namespace = sys.modules[package].__dict__

    def __getattr__(name: str) -> Any:
        module = exports.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module), name)
        namespace[name] = value  # later look-ups skip this function
        return value

    def __dir__() -> list[str]:
        return sorted({*namespace, *exports})

    return __getattr__, __dir__

"""Scoring workers die with the run that started them, however it dies (SIGKILL included).

The runner scores in a ``forkserver`` pool: the forkserver is a child of the run, the workers are
children of the forkserver. On Linux each link gets ``PR_SET_PDEATHSIG``: the kernel sends SIGKILL
to the forkserver when the run dies and to a worker when the forkserver dies, so nothing of the run's
tree is left holding memory or the caller's stdout. The resource tracker then sees end-of-file on its
pipe and exits by itself. Elsewhere (no ``prctl``) this module does nothing.

The forkserver imports this module (``set_forkserver_preload``); it acts only in a process whose
parent is the pid recorded in ``SOCIALNAV_LIFELINE_PARENT`` by the run, so importing it anywhere
else is harmless.
"""

from __future__ import annotations

import os
import signal
import sys

ENV = "SOCIALNAV_LIFELINE_PARENT"
_PR_SET_PDEATHSIG = 1

#: What every worker imports, imported once by the forkserver instead (its workers are forked with
#: them loaded, so a new pool's workers start in milliseconds instead of each importing for ~0.4 s).
#: Not torch: a learned policy's worker imports it when it unpickles the policy.
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
    """Initializer of a scoring worker: tied to the forkserver; Ctrl-C is the run's to handle."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if FORKSERVER_PID is not None:
        die_with_parent(FORKSERVER_PID)
    from socialnav.evaluate.blas import one_blas_thread_for_good

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


def _on_import_in_forkserver() -> None:
    global FORKSERVER_PID
    parent = os.environ.get(ENV)
    in_forkserver = sys.argv[:1] == ["-c"] and "multiprocessing.forkserver" in sys.modules
    if in_forkserver and parent and parent.isdigit() and os.getppid() == int(parent):
        FORKSERVER_PID = os.getpid()
        die_with_parent(int(parent))


_on_import_in_forkserver()

"""One BLAS thread where processes already give the parallelism.

NumPy's OpenBLAS starts a thread per core and, after each call, keeps them spinning for a while. In an
evaluation or a sweep, where worker processes already use every core, those threads only take CPU
from the workers: measured on a 2-core machine (`benchmarks/bench_sweep.py`'s sweep), the driver's
OpenBLAS threads burnt 0.7 s of CPU in a 3 s run, for the bootstrap's small matrix products; with one
BLAS thread the driver's CPU halved and the 2-worker sweep got 8 % faster. The number of BLAS
threads does not change a result here (OpenBLAS splits a product's output, not its sums).
"""

from __future__ import annotations

import contextlib
from typing import Any

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

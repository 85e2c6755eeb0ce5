"""The native worker pools: one per thread count, shared by every World and native policy of a process.

A batched step runs several parallel jobs (the world's step and refill, a native policy's actions).
On one pool, a worker that has just finished a job spins briefly for the next one instead of going
to sleep (cpp/thread_pool.cpp), so consecutive jobs find it awake; on a virtual machine that halts
idle CPUs, waking a sleeping worker costs tens to hundreds of microseconds per job. Two pools would
have their idle workers spin against each other's busy ones.
"""

from __future__ import annotations

import ctypes
import os
from typing import Any

from socialnav import _core

_POOLS: dict[int, Any] = {}


def shared_pool(threads: int) -> Any:
    """The process's native worker pool of ``threads`` threads (created on first use)."""
    if threads < 1:
        raise ValueError(f"threads must be >= 1, got {threads}")
    if threads not in _POOLS:
        _POOLS[threads] = _core.ThreadPool(threads)
    return _POOLS[threads]


def _forget_pools_in_child() -> None:
    # A forked child has none of the parent's threads: a pool inherited from it would wait forever,
    # and destroying it would join threads that do not exist. The child starts pools of its own and
    # leaks the inherited ones (one extra reference each: never destroyed, not even at exit).
    for pool in _POOLS.values():
        ctypes.pythonapi.Py_IncRef(ctypes.py_object(pool))
    if _POOLS:
        _core._silence_leak_warnings()  # the leak is deliberate; nanobind would report it at exit
    _POOLS.clear()


os.register_at_fork(after_in_child=_forget_pools_in_child)

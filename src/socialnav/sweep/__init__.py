"""Sweeps: grids of evaluation and training jobs on this machine or a Ray cluster (docs/sweeps.md).

Example::

    from socialnav.sweep import load_sweep, make_executor, run_sweep

    result = run_sweep(load_sweep("sweep.yaml"), "runs/sweep", make_executor("local", workers=2))

Each name below loads its module on first use.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from socialnav._runtime import lazy_exports

#: Public name → the module that defines it (imported on first use: see ``lazy_exports``).
_EXPORTS = {
    "load_sweep": "socialnav.sweep.spec",
    "parse_sweep": "socialnav.sweep.spec",
    "SweepSpec": "socialnav.sweep.spec",
    "Job": "socialnav.sweep.spec",
    "run_sweep": "socialnav.sweep.driver",
    "SweepResult": "socialnav.sweep.driver",
    "make_executor": "socialnav.sweep.executors",
    "LocalExecutor": "socialnav.sweep.executors",
    "RayExecutor": "socialnav.sweep.executors",
}
__all__ = [
    "load_sweep",
    "parse_sweep",
    "SweepSpec",
    "Job",
    "run_sweep",
    "SweepResult",
    "make_executor",
    "LocalExecutor",
    "RayExecutor",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

if TYPE_CHECKING:  # what type checkers and IDEs see; at run time the names load lazily
    from socialnav.sweep.driver import SweepResult, run_sweep
    from socialnav.sweep.executors import LocalExecutor, RayExecutor, make_executor
    from socialnav.sweep.spec import Job, SweepSpec, load_sweep, parse_sweep

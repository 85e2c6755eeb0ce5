"""Parquet/CSV IO for :class:`socialnav.trajectory.Trajectory` (long format).

One row per (episode, sample, agent); the schema is documented in ``docs/trajectory_format.md``.
Reading validates strictly and names the file, column and row (1-based data row, header excluded;
a CSV's line number is row + 1) of the first problem. ``pyarrow`` is imported lazily so that
``import socialnav.metrics`` stays NumPy-only.

The package's modules: :mod:`~socialnav.trajectory_io.schema` (columns and constants),
:mod:`~socialnav.trajectory_io.writer`, :mod:`~socialnav.trajectory_io.reader` (with
:mod:`~socialnav.trajectory_io.table`, the checked columns) and :mod:`~socialnav.trajectory_io.resample`
(time grids).
"""

from __future__ import annotations

from socialnav.trajectory_io.reader import read_trajectories
from socialnav.trajectory_io.schema import MAX_RESAMPLED_STEPS, OPTIONAL_COLUMNS, REQUIRED_COLUMNS
from socialnav.trajectory_io.writer import write_trajectories

__all__ = [
    "REQUIRED_COLUMNS", "OPTIONAL_COLUMNS", "MAX_RESAMPLED_STEPS", "read_trajectories", "write_trajectories",
]

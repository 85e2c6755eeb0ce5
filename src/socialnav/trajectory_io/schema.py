"""The long trajectory format's columns and constants, shared by the writer and the reader.

One row per (episode, sample, agent); the schema is documented in ``docs/trajectory_format.md``.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from socialnav.trajectory import TrajectoryFormatError

#: Columns every trajectory file has.
REQUIRED_COLUMNS: tuple[str, ...] = ("episode", "t", "agent", "x", "y", "radius", "gx", "gy", "v_pref")
#: Columns a file may have (any other column is ignored).
OPTIONAL_COLUMNS: tuple[str, ...] = (
    "role", "vx", "vy", "outcome", "continuation", "min_clearance", "human_overlaps", "settings",
    "arrival_t", "static_map",
)
#: Columns read as float64 (an empty cell is NaN).
FLOAT_COLUMNS = ("t", "x", "y", "vx", "vy", "radius", "gx", "gy", "v_pref", "min_clearance", "arrival_t")
#: The order the writer gives the columns.
WRITE_ORDER = (
    "episode", "t", "agent", "role", "x", "y", "vx", "vy", "radius", "gx", "gy", "v_pref", "outcome",
    "continuation", "min_clearance", "human_overlaps", "settings", "arrival_t", "static_map",
)
#: Parquet metadata key of the format version, the episodes' settings and their maps.
METADATA_KEY = b"socialnav"
#: Rows per Parquet row group: small enough that a reader of some episodes skips the rest.
ROW_GROUP = 1 << 16
#: Version of the Parquet metadata layout.
FORMAT_VERSION = 1
# Relative tolerance on sample spacing: CSV text round-trips k·dt exactly, but logs written by other
# tools carry float noise of order 1e-12 s; real jitter (ms) is far above this.
DT_RTOL = 1e-6


def time_tolerance(dt: float, times: np.ndarray) -> float:
    """The largest difference of two sample times still read as the same time [s].

    ``DT_RTOL`` of the step, widened to what float64 resolves at the times' magnitude: a log stamped
    with epoch seconds (1.7e9 s) resolves 2.4e-7 s, more than 1e-6 of a 0.1 s step, so its regular 10 Hz
    samples would otherwise read as irregular.
    """
    return DT_RTOL * dt + 16.0 * _resolution(times)


def step_from_span(span: float, steps: int, times: np.ndarray) -> float:
    """A regular grid's step from its span over its step count, rounded to what the times resolve.

    The span over the count is the least noisy estimate; rounding off the digits below the times'
    resolution recovers the step as written (k·0.1 written as text is not exact, and epoch stamps lose
    more digits), at most 12 significant digits.
    """
    raw = span / steps
    error = _resolution(times) / steps  # the most the two rounded end times can move the estimate
    if not (raw > 0 and np.isfinite(raw)) or error <= 0:
        return float(f"{raw:.12g}")
    digits = int(np.floor(np.log10(raw))) - int(np.ceil(np.log10(2 * error))) + 1
    return float(f"{raw:.{int(np.clip(digits, 1, 12))}g}")


def _resolution(times: np.ndarray) -> float:
    scale = float(np.max(np.abs(times))) if np.size(times) else 0.0
    return float(np.spacing(scale)) if np.isfinite(scale) else 0.0


#: Samples of one resampled episode at most (a dt far below the log's own step is a typo).
MAX_RESAMPLED_STEPS = 1_000_000


def episode_keys(episodes: Iterable[Any], kind: Any) -> list[Any]:
    """Episode keys as the file stores them, so that "1" and 1 name the same episode.

    Args:
        episodes: The keys a caller asked for.
        kind: The Arrow type of the file's ``episode`` column.

    Returns:
        Integers for an integer column (keys that are not integers cannot match and are dropped),
        strings otherwise.
    """
    import pyarrow as pa

    if not pa.types.is_integer(kind):
        return [str(e) for e in episodes]
    out = []
    for e in episodes:
        try:
            out.append(int(str(e).strip()))
        except ValueError:
            continue
    return out


def file_suffix(path: Path) -> str:
    """The format a path's suffix selects.

    Args:
        path: A trajectory file's path.

    Returns:
        ``.parquet`` or ``.csv`` (lower case).

    Raises:
        TrajectoryFormatError: Any other suffix.
    """
    suffix = path.suffix.lower()
    if suffix not in (".parquet", ".csv"):
        raise TrajectoryFormatError(f"{path}: unsupported suffix {path.suffix!r}; use .parquet or .csv")
    return suffix

"""Columns of an Arrow table read from a log (CSV or Parquet): numbers, times, ids, per-agent constants.

What :func:`socialnav.logs.readers.read_table` reads a table with; every problem is a
:class:`~socialnav.trajectory.TrajectoryFormatError` naming the file, the column and the row (``Fail``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from socialnav.trajectory import TrajectoryFormatError

__all__ = ["Fail", "agent_ids", "check_text", "group_codes", "load_table", "numeric_column",
           "per_agent_value", "read_times", "require_finite", "scene_constant", "string_column"]


class Fail:
    """Makes the error of a bad value: ``fail(column, row, message)`` names the file, column and row."""

    def __init__(self, path: Path, unit: str = "row") -> None:
        self.path, self.unit = path, unit

    def __call__(self, column: str, row: int | None, message: str) -> TrajectoryFormatError:
        """The error naming ``column`` and ``row`` (0-based; said 1-based, or not at all where None)."""
        where = f"column '{column}'" + ("" if row is None else f", {self.unit} {row + 1}")
        return TrajectoryFormatError(f"{self.path}: {where}: {message}")


def check_text(path: Path) -> None:
    """Refuses a file whose first 4 KiB are not UTF-8 text (a binary file given as a CSV)."""
    head = path.read_bytes()[:4096]
    if b"\x00" in head:
        raise TrajectoryFormatError(f"{path}: binary data (NUL bytes), not a text file")
    try:
        head.decode("utf-8")
    except UnicodeDecodeError as exc:
        if exc.start < len(head) - 4:  # not just a multi-byte character cut at 4096
            raise TrajectoryFormatError(f"{path}: not UTF-8 text (byte {exc.start}); is it binary?") from None


def load_table(path: Path) -> Any:
    """The file as an Arrow table (``.parquet``, or ``.csv``/``.txt``/``.tsv``), refused by name otherwise."""
    import pyarrow as pa

    suffix = path.suffix.lower()
    try:
        if suffix == ".parquet":
            import pyarrow.parquet as pq

            return pq.read_table(path)
        if suffix in (".csv", ".txt", ".tsv"):
            import pyarrow.csv as pcsv

            check_text(path)
            delimiter = "\t" if suffix == ".tsv" else ","
            return pcsv.read_csv(path, parse_options=pcsv.ParseOptions(delimiter=delimiter))
    except (pa.ArrowInvalid, pa.ArrowNotImplementedError, OSError) as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise TrajectoryFormatError(f"{path}: cannot be read as {suffix[1:]} ({first})") from None
    raise TrajectoryFormatError(f"{path}: unsupported suffix {path.suffix!r}; use .csv or .parquet")


def read_times(table: Any, column: str, fail: Fail, scale: float) -> tuple[np.ndarray, float]:
    """The time column as seconds after its earliest stamp, and that stamp [s].

    Integer clocks (ROS nanoseconds since 1970 exceed float64's 2^53 exact integers) and Parquet
    timestamps (their own unit, whatever ``scale`` says) are differenced as integers first.
    """
    import pyarrow as pa

    col = table.column(column)
    kind = col.type
    if pa.types.is_timestamp(kind) or pa.types.is_integer(kind):
        if col.null_count:
            row = int(np.flatnonzero(np.asarray(col.is_null().to_numpy(zero_copy_only=False)))[0])
            raise fail(column, row, "missing value")
        if pa.types.is_timestamp(kind):
            scale = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}[kind.unit]
            ints = col.cast(pa.int64()).to_numpy(zero_copy_only=False)
        else:
            ints = col.to_numpy(zero_copy_only=False).astype(np.int64)
        first = int(ints.min())
        return (ints - first).astype(np.float64) * scale, float(first) * scale
    values = numeric_column(table, column, fail, "time")
    require_finite(values, fail, column)
    first = float(values.min())
    return (values - first) * scale, first * scale


def numeric_column(table: Any, column: str, fail: Fail, field: str) -> np.ndarray:
    """The column as float64; the first value that is not a number is named."""
    import pyarrow as pa

    col = table.column(column)
    try:
        return col.cast(pa.float64()).to_numpy(zero_copy_only=False).astype(np.float64)
    except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
        for i, v in enumerate(col.to_pylist()):
            try:
                float(v) if v is not None else None
            except (TypeError, ValueError):
                raise fail(column, i, f"not a number: {v!r} ({field})") from None
        raise fail(column, None, f"not numeric ({field})") from None


def require_finite(values: np.ndarray, fail: Fail, column: str) -> None:
    """Refuses the first missing or infinite value, named."""
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        v = values[bad[0]]
        raise fail(column, int(bad[0]), "missing value" if np.isnan(v) else f"value is {v} (not finite)")


def string_column(table: Any, column: str) -> np.ndarray:
    """The column as text ("" for a missing value)."""
    return np.array(["" if v is None else str(v) for v in table.column(column).to_pylist()], dtype=object)


def agent_ids(table: Any, column: str, fail: Fail) -> np.ndarray:
    """The ids: integers where every id is one (also written as 7.0), else text; a missing id is named."""
    values = table.column(column).to_pylist()
    for i, v in enumerate(values):
        if v is None or (isinstance(v, float) and not np.isfinite(v)) or v == "":
            raise fail(column, i, "missing agent id")
    if all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in values):
        return np.asarray(values, dtype=np.int64)
    if all(isinstance(v, float) and v == int(v) for v in values):
        return np.asarray(values, dtype=np.int64)
    return np.array([str(v) for v in values], dtype=object)


def group_codes(scene: np.ndarray, agent: np.ndarray) -> np.ndarray:
    """One integer per (scene, agent) pair, row by row."""
    pairs = np.array([f"{s}\x1f{a}" for s, a in zip(scene, agent, strict=True)], dtype=object)
    return np.unique(pairs, return_inverse=True)[1]


def per_agent_value(values: np.ndarray, rows: np.ndarray, a_of_row: np.ndarray, n: int, fail: Fail,
               column: str) -> np.ndarray:
    """One value per agent; a column that varies within an agent's rows is an error."""
    out = np.full(n, np.nan)
    v = values[rows]
    for a in range(n):
        sel = np.flatnonzero(a_of_row == a)
        vals = v[sel]
        finite = np.isfinite(vals)
        if not finite.any():
            continue
        ref = vals[finite][0]
        diff = np.flatnonzero(finite & (vals != ref))
        if diff.size:
            raise fail(column, int(rows[sel[diff[0]]]), f"value {vals[diff[0]]:g} differs from {ref:g}; it "
                       "must be constant per agent")
        out[a] = ref
    return out


def scene_constant(values: np.ndarray, rows: np.ndarray, fail: Fail, column: str) -> str | None:
    """The scene's one value of a text column (None where all are empty); a second value is named."""
    nonempty = [i for i, v in enumerate(values) if v not in ("", "nan", "None")]
    if not nonempty:
        return None
    ref = values[nonempty[0]]
    for i in nonempty:
        if values[i] != ref:
            raise fail(column, int(rows[i]), f"value {values[i]!r} differs from {ref!r}; it must be constant "
                       "per scene")
    return str(ref)

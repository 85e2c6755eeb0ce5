"""A trajectory file's columns as NumPy arrays, checked, with errors naming the file, column and row.

Rows are numbered 1-based over the data (header excluded; a CSV's line number is row + 1). A subset
of a file (some episodes, or a block of rows) keeps the file's row numbers in messages.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from socialnav.trajectory import TrajectoryFormatError
from socialnav.trajectory_io.schema import (
    FLOAT_COLUMNS,
    METADATA_KEY,
    OPTIONAL_COLUMNS,
    REQUIRED_COLUMNS,
    episode_keys,
    file_suffix,
)


class TrajectoryTable:
    """Columns of the file as NumPy arrays, plus helpers that raise errors naming file/column/row."""

    def __init__(self, path: Path, episodes: list[Any] | None = None,
                 rows: tuple[int, int] | None = None) -> None:
        """Reads the file (Parquet page checksums verified) and converts its known columns.

        Args:
            path: ``.parquet`` or ``.csv`` file.
            episodes: Read only these episode keys.
            rows: Read only the file's rows [start, stop) (0-based).

        Raises:
            FileNotFoundError: No such file.
            TrajectoryFormatError: Not a readable file, a required column missing, a numeric column
                that is not.
            ValueError: ``rows`` outside the file.
        """
        import pyarrow as pa

        self.path = path
        suffix = file_suffix(path)
        if not path.exists():
            raise FileNotFoundError(f"{path}: no such file")
        if path.is_dir():
            raise TrajectoryFormatError(f"{path}: is a directory, not a trajectory file")
        meta_settings: dict[str, str] = {}
        meta: dict[str, Any] = {}
        if suffix == ".parquet":

            from socialnav._io import CorruptFileError, read_parquet_verified

            try:  # page checksums verified, where the writer stored them
                if rows is not None:  # a block of rows (parallel scoring of a file with contiguous episodes)
                    table = read_parquet_verified(path)
                elif episodes is not None:  # read only the row groups that can hold them (statistics)
                    import pyarrow.parquet as pq

                    schema = pq.read_schema(path)
                    kind = schema.field("episode").type if "episode" in schema.names else pa.string()
                    keys = episode_keys(episodes, kind)
                    table = read_parquet_verified(path, filters=[("episode", "in", keys)] if keys else None)
                else:
                    table = read_parquet_verified(path)
            except CorruptFileError as err:
                raise TrajectoryFormatError(str(err)) from None
            raw = (table.schema.metadata or {}).get(METADATA_KEY)
            if raw is not None:
                meta = _file_metadata(path, raw)
                meta_settings = meta.get("settings", {})
        else:
            import pyarrow.csv as pcsv

            strings = {c: pa.string() for c in ("role", "outcome", "settings", "static_map")}
            try:
                table = pcsv.read_csv(path, convert_options=pcsv.ConvertOptions(column_types=strings))
            except pa.ArrowInvalid as err:
                text = " ".join(str(err).split())
                raise TrajectoryFormatError(f"{path}: not a readable CSV file ({text[:200]})") from None
        self.meta_settings = meta_settings
        self.meta_maps: list[Any] = meta.get("maps", [])
        self.meta_episode_maps: dict[str, int] = meta.get("episode_maps", {})
        self.maps: dict[Any, Any] = {}  # parsed maps, shared by the episodes that reference one
        self.row_map = None
        if rows is not None:
            start, stop = rows
            if not 0 <= start <= stop <= table.num_rows:
                raise ValueError(f"{path}: rows {rows} outside the file's {table.num_rows} rows")
            self.row_map = np.arange(start, stop)  # messages keep the file's row numbers
            table = table.slice(start, stop - start)
        elif episodes is not None and "episode" in table.column_names:
            # a subset of episodes (parallel scoring); messages keep the file's row numbers
            import pyarrow.compute as pc

            col = table.column("episode")
            integer = pa.types.is_integer(col.type)
            keys = pa.array(episode_keys(episodes, col.type), type=col.type if integer else pa.string())
            mask = pc.is_in(col if integer else col.cast(pa.string()), value_set=keys)
            self.row_map = np.flatnonzero(mask.to_numpy(zero_copy_only=False))
            table = table.filter(mask)
        self.n_rows = table.num_rows
        missing = [c for c in REQUIRED_COLUMNS if c not in table.column_names]
        if missing:
            raise TrajectoryFormatError(
                f"{path}: missing required column(s) {missing}; columns present: {table.column_names}"
            )
        self.cols: dict[str, np.ndarray] = {}
        self._codes: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        for name in table.column_names:
            if name not in REQUIRED_COLUMNS + OPTIONAL_COLUMNS:
                continue  # extra columns are allowed and ignored
            col = table.column(name)
            if name in FLOAT_COLUMNS:
                try:
                    arr = col.cast(pa.float64()).to_numpy()
                except (pa.ArrowInvalid, pa.ArrowNotImplementedError) as exc:
                    raise self.fail(name, _first_not_numeric(col), f"not numeric ({exc})") from exc
            elif name in ("agent", "episode") and pa.types.is_integer(col.type) and col.null_count == 0:
                arr = col.to_numpy()
            elif (pa.types.is_string(col.type) or pa.types.is_large_string(col.type)
                  or pa.types.is_boolean(col.type) or pa.types.is_integer(col.type)):
                # through a dictionary: a few distinct values repeated over many rows; the codes
                # serve the per-episode equality checks (equal codes are equal values, nulls None)
                enc = col.combine_chunks().dictionary_encode()
                values = np.empty(len(enc.dictionary) + 1, dtype=object)
                values[:] = enc.dictionary.to_pylist() + [None]
                idx = enc.indices.fill_null(len(values) - 1).to_numpy().astype(np.int64)
                arr = values[idx]
                self._codes[name] = (idx, values)
            else:
                arr = np.asarray(col.to_pylist(), dtype=object)
            self.cols[name] = arr

    def codes(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """An object column as (integer code per row, distinct values): equal codes are equal values.

        Per-episode checks compare codes instead of Python objects, for every episode of the file.
        Each distinct value gets one code (a NaN object only equals itself, as with ``==``).
        """
        if name not in self._codes:
            lookup: dict[Any, int] = {}
            values: list[Any] = []
            codes = np.empty(len(self.cols[name]), dtype=np.int64)
            for i, v in enumerate(self.cols[name]):
                code = lookup.get(v)
                if code is None:
                    code = lookup[v] = len(values)
                    values.append(v)
                codes[i] = code
            distinct = np.empty(len(values), dtype=object)
            distinct[:] = values
            self._codes[name] = (codes, distinct)
        return self._codes[name]

    def continuation_state(self) -> np.ndarray:
        """Per row: 1 continuation, 0 main sample, -1 neither (not a boolean or 'true'/'false')."""
        if "_continuation" not in self._codes:
            codes, values = self.codes("continuation")
            state = np.array([1 if (v == True or v == "true") else 0 if (v == False or v == "false")  # noqa: E712
                              else -1 for v in values], dtype=np.int8)
            self._codes["_continuation"] = (state[codes], values)
        return self._codes["_continuation"][0]

    def fail(self, column: str, row_index: int | None, message: str) -> TrajectoryFormatError:
        """The error to raise about a cell, naming the file, the column and the file's row.

        Args:
            column: The column's name.
            row_index: The row in this table (0-based), or None for the whole column.
            message: What is wrong.

        Returns:
            The error.
        """
        if row_index is not None and self.row_map is not None:
            row_index = int(self.row_map[row_index])
        where = f"column '{column}'" + ("" if row_index is None else f", row {row_index + 1}")
        return TrajectoryFormatError(f"{self.path}: {where}: {message}")

    def file_row(self, row_index: int) -> int:
        """The 1-based row number in the file of this table's row ``row_index`` (as :meth:`fail` names it)."""
        if self.row_map is not None:
            row_index = int(self.row_map[row_index])
        return row_index + 1

    def int_column(self, name: str) -> np.ndarray:
        """A column as int64, every value checked.

        Args:
            name: The column's name.

        Returns:
            Its values.

        Raises:
            TrajectoryFormatError: A value that is not an integer in the int64 range.
        """
        values = self.cols[name]
        if values.dtype.kind in "iu":
            return values.astype(np.int64)
        out = np.empty(len(values), dtype=np.int64)
        for i, v in enumerate(values):
            try:
                iv = int(v)
                if iv != float(v):
                    raise ValueError
                out[i] = iv
            except (TypeError, ValueError, OverflowError):
                raise self.fail(name, i, f"expected an integer in the int64 range, got {v!r}") from None
        return out

    def require_finite(self, name: str) -> None:
        """Refuses a float column with a missing or non-finite value.

        Args:
            name: The column's name.

        Raises:
            TrajectoryFormatError: Naming the first such row.
        """
        arr = self.cols[name]
        bad = np.flatnonzero(~np.isfinite(arr))
        if bad.size:
            raise self.fail(name, int(bad[0]), f"value is {arr[bad[0]]} (missing or not finite)")


def _file_metadata(path: Path, raw: bytes) -> dict[str, Any]:
    """The Parquet file metadata under :data:`METADATA_KEY`, checked.

    It is a JSON object whose ``settings`` and ``episode_maps`` are objects and whose ``maps`` is a list.

    Raises:
        TrajectoryFormatError: Naming the file and saying its metadata is damaged (cut, or not JSON).
    """
    key = METADATA_KEY.decode()

    def damaged(why: str) -> TrajectoryFormatError:
        return TrajectoryFormatError(f"{path}: the file's metadata (Parquet key {key!r}: the episodes' "
                                     f"settings and maps) is damaged: {why}")

    try:
        meta = json.loads(raw.decode())
    except UnicodeDecodeError as exc:
        raise damaged(f"not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except json.JSONDecodeError as exc:
        cut = " (cut short?)" if exc.pos >= len(exc.doc.rstrip()) else ""
        raise damaged(f"not valid JSON{cut}: {exc.msg} at character {exc.pos} of {len(exc.doc)}") from None
    if not isinstance(meta, dict):
        raise damaged(f"expected a JSON object, got {type(meta).__name__}")
    for field, kind in (("settings", dict), ("maps", list), ("episode_maps", dict)):
        if field in meta and not isinstance(meta[field], kind):
            raise damaged(f"field {field!r}: expected a JSON {'object' if kind is dict else 'array'}, got "
                          f"{type(meta[field]).__name__}")
    return meta


def _first_not_numeric(col: Any) -> int | None:
    """The row (0-based) of a column's first cell that is not a number, or None if none is found."""
    for i, value in enumerate(col.to_pylist()):
        if value is None or isinstance(value, int | float) and not isinstance(value, bool):
            continue
        try:
            float(value)
        except (TypeError, ValueError):
            return i
    return None

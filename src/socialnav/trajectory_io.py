"""Parquet/CSV IO for :class:`socialnav.trajectory.Trajectory` (long format).

One row per (episode, sample, agent); the schema is documented in ``docs/trajectory_format.md``.
Reading validates strictly and names the file, column and row (1-based data row, header excluded;
a CSV's line number is row + 1) of the first problem. ``pyarrow`` is imported lazily so that
``import socialnav.metrics`` stays NumPy-only.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from socialnav._io import atomic_write
from socialnav.trajectory import OUTCOMES, ROLES, Trajectory, TrajectoryFormatError

__all__ = ["REQUIRED_COLUMNS", "OPTIONAL_COLUMNS", "read_trajectories", "write_trajectories"]

REQUIRED_COLUMNS: tuple[str, ...] = ("episode", "t", "agent", "x", "y", "radius", "gx", "gy", "v_pref")
OPTIONAL_COLUMNS: tuple[str, ...] = (
    "role", "vx", "vy", "outcome", "continuation", "min_clearance", "human_overlaps", "settings",
    "arrival_t", "static_map",
)
_FLOAT_COLUMNS = ("t", "x", "y", "vx", "vy", "radius", "gx", "gy", "v_pref", "min_clearance", "arrival_t")
_WRITE_ORDER = (
    "episode", "t", "agent", "role", "x", "y", "vx", "vy", "radius", "gx", "gy", "v_pref", "outcome",
    "continuation", "min_clearance", "human_overlaps", "settings", "arrival_t", "static_map",
)
_METADATA_KEY = b"socialnav"
_ROW_GROUP = 1 << 16
_FORMAT_VERSION = 1
# Relative tolerance on sample spacing: CSV text round-trips k·dt exactly, but logs written by other
# tools carry float noise of order 1e-12 s; real jitter (ms) is far above this.
_DT_RTOL = 1e-6
#: Samples of one resampled episode at most (a dt far below the log's own step is a typo).
MAX_RESAMPLED_STEPS = 1_000_000


def _episode_keys(episodes: Iterable[Any], kind: Any) -> list[Any]:
    """Episode keys as the file stores them: integers for an integer column (keys that are not
    integers cannot match and are dropped), strings otherwise; "1" and 1 name the same episode."""
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


def _suffix(path: Path) -> str:
    suffix = path.suffix.lower()
    if suffix not in (".parquet", ".csv"):
        raise TrajectoryFormatError(f"{path}: unsupported suffix {path.suffix!r}; use .parquet or .csv")
    return suffix


# ---------------------------------------------------------------------------------------- writing
def write_trajectories(path: str | os.PathLike[str], trajs: Iterable[Trajectory]) -> None:
    """Write trajectories to one Parquet or CSV file, atomically.

    The table is written to a temporary file in the same directory and moved over ``path`` with
    ``os.replace``, so readers never see a half-written file. Each episode is keyed by
    ``settings["episode"]`` when present, else by its position in ``trajs``.

    Args:
        path: Destination; the suffix (``.parquet`` or ``.csv``) selects the format.
        trajs: Trajectories to write.

    Raises:
        TrajectoryFormatError: Unsupported suffix, duplicated episode keys or settings that are not
            JSON-serialisable.
    """
    import pyarrow as pa

    path = Path(path)
    suffix = _suffix(path)
    trajs = list(trajs)
    keys = [tr.settings.get("episode", i) for i, tr in enumerate(trajs)]
    if len({str(k) for k in keys}) != len(keys):
        raise TrajectoryFormatError(f"{path}: duplicated episode keys {keys}")
    settings_json: dict[str, str] = {}
    map_json = _map_texts(trajs)
    for key, tr in zip(keys, trajs, strict=True):
        try:
            settings_json[str(key)] = json.dumps(tr.settings, sort_keys=True)
        except TypeError as exc:
            raise TrajectoryFormatError(
                f"{path}: episode {key!r}: settings not JSON-serialisable: {exc}"
            ) from exc
    arrays = _columns(
        trajs, keys, [settings_json[str(k)] for k in keys], map_json, with_text_columns=suffix == ".csv"
    )
    table = pa.table(arrays)
    if suffix == ".parquet":
        meta: dict[str, Any] = {"format_version": _FORMAT_VERSION, "settings": settings_json}
        if any(map_json):
            # each distinct map once (the episodes of one scene share theirs), referenced per episode
            distinct = list(dict.fromkeys(m for m in map_json if m))
            index = {m: i for i, m in enumerate(distinct)}
            meta["maps"] = [json.loads(m) for m in distinct]
            meta["episode_maps"] = {str(k): index[m] for k, m in zip(keys, map_json, strict=True) if m}
        table = table.replace_schema_metadata({_METADATA_KEY: json.dumps(meta).encode()})
    _atomic_write(path, table, suffix)


def _columns(
    trajs: list[Trajectory], keys: list[Any], settings_json: list[str], map_json: list[str],
    with_text_columns: bool,
) -> dict[str, Any]:
    """The long table's columns (Arrow arrays, in ``_WRITE_ORDER``), one row per (episode, sample,
    agent), built for all episodes at once: per-row values come from gathers over per-episode and
    per-agent arrays, so the cost per episode is a few array views, not a dozen allocations (the
    ``wang2022`` protocol writes 4060 episodes; issue #32)."""
    import pyarrow as pa

    n_ep = len(trajs)
    n_main = np.array([tr.positions.shape[0] for tr in trajs], dtype=np.int64)
    n_agents = np.array([tr.positions.shape[1] for tr in trajs], dtype=np.int64)
    conts = [tr.continuation for tr in trajs]
    n_cont = np.array([0 if c is None else c.shape[0] for c in conts], dtype=np.int64)
    rows = (n_main + n_cont) * n_agents
    total = int(rows.sum())
    row0 = np.concatenate([[0], np.cumsum(rows)[:-1]]).astype(np.int64)
    ep = np.repeat(np.arange(n_ep, dtype=np.int64), rows)  # episode of each row
    local = np.arange(total, dtype=np.int64) - row0[ep]
    agent = local % n_agents[ep]
    sample = local // n_agents[ep]
    gagent = np.concatenate([[0], np.cumsum(n_agents)[:-1]]).astype(np.int64)[ep] + agent  # into per-agent

    def stacked(parts: list[np.ndarray], width: int) -> np.ndarray:
        return np.concatenate(parts) if parts else np.zeros((0, width))

    pos_parts, vel_parts = [], []
    for tr, cont in zip(trajs, conts, strict=True):
        pos_parts.append(tr.positions.reshape(-1, 2))
        vel_parts.append(tr.velocities.reshape(-1, 2))
        if cont is not None and cont.shape[0]:
            pos_parts.append(cont.reshape(-1, 2))
            vel_parts.append(np.full((cont.shape[0] * cont.shape[1], 2), np.nan))
    pos, vel = stacked(pos_parts, 2), stacked(vel_parts, 2)
    radius = stacked([tr.radii for tr in trajs], 1).reshape(-1)[gagent]
    goals = stacked([tr.goals for tr in trajs], 2)[gagent]
    v_pref = stacked([tr.v_pref for tr in trajs], 1).reshape(-1)[gagent]
    arrival = stacked(
        [np.full(tr.positions.shape[1], np.nan) if tr.arrival_times is None else tr.arrival_times
         for tr in trajs], 1,
    ).reshape(-1)[gagent]
    dt = np.array([tr.dt for tr in trajs], dtype=np.float64)
    mc = np.full(total, np.nan)
    for e, tr in enumerate(trajs):
        if tr.min_clearance is not None:  # robot rows of samples k >= 1
            a = int(n_agents[e])
            mc[row0[e] + a : row0[e] + int(n_main[e]) * a : a] = tr.min_clearance
    overlaps = np.array([-1 if tr.human_overlaps is None else tr.human_overlaps for tr in trajs],
                        dtype=np.int64)[ep]
    keep = None
    if any(tr.present is not None for tr in trajs):  # absent agents have no row (nothing invented)
        keep = np.ones(total, dtype=bool)
        for e, tr in enumerate(trajs):
            if tr.present is not None:
                k = tr.present.reshape(-1).copy()
                k[0] = True  # the settings cell lives on the first row (the robot's, always present)
                keep[row0[e] : row0[e] + k.size] = k
    take = None if keep is None else pa.array(np.flatnonzero(keep))

    def kept(values: np.ndarray) -> np.ndarray:
        return values if keep is None else values[keep]

    def gathered(per_item: Any, index: np.ndarray) -> Any:
        arr = per_item.take(pa.array(index))
        return arr if take is None else arr.take(take)

    def floats(values: np.ndarray) -> Any:
        values = kept(values)
        return pa.array(values, mask=np.isnan(values))  # NaN is written as an empty cell

    arrays: dict[str, Any] = {}
    if all(isinstance(k, (int, np.integer)) and not isinstance(k, bool) for k in keys):
        arrays["episode"] = pa.array(kept(np.asarray(keys, dtype=np.int64)[ep]))
    else:
        arrays["episode"] = gathered(_string_array(np.array(keys + [None], dtype=object)[:-1]), ep)
    arrays["t"] = floats(sample * dt[ep])
    arrays["agent"] = pa.array(kept(agent))
    roles = np.array([r for tr in trajs for r in tr.roles] + [None], dtype=object)[:-1]
    arrays["role"] = gathered(_string_array(roles), gagent)
    arrays["x"], arrays["y"] = floats(pos[:, 0]), floats(pos[:, 1])
    arrays["vx"], arrays["vy"] = floats(vel[:, 0]), floats(vel[:, 1])
    arrays["radius"] = floats(radius)
    arrays["gx"], arrays["gy"] = floats(goals[:, 0]), floats(goals[:, 1])
    arrays["v_pref"] = floats(v_pref)
    outcomes = np.array([tr.outcome for tr in trajs] + [None], dtype=object)[:-1]
    arrays["outcome"] = gathered(_string_array(outcomes), ep)
    arrays["continuation"] = pa.array(kept(sample >= n_main[ep]))
    if not np.all(np.isnan(mc)):
        arrays["min_clearance"] = floats(mc)
    if np.any(overlaps >= 0):
        vals = kept(overlaps)
        arrays["human_overlaps"] = pa.array(vals, mask=vals < 0)
    def first_rows(texts: list[str]) -> Any:  # one text per episode, on its first row (CSV)
        col = np.full(total, "", dtype=object)
        col[row0[rows > 0]] = np.array(texts + [None], dtype=object)[:-1][rows > 0]
        return _string_array(kept(col))

    if with_text_columns:  # Parquet keeps settings and maps in the file metadata instead
        arrays["settings"] = first_rows(settings_json)
    if not np.all(np.isnan(arrival)):
        arrays["arrival_t"] = floats(arrival)
    if with_text_columns and any(map_json):  # open floor everywhere: files stay as before maps
        arrays["static_map"] = first_rows(map_json)
    return arrays


def _map_texts(trajs: list[Trajectory]) -> list[str]:
    """Each episode's static map as compact JSON ("" for an open floor); one text per distinct
    map object, since the episodes of a scene usually share one."""
    texts: dict[int, str] = {}
    out = []
    for tr in trajs:
        smap = tr.static_map
        if smap is None:
            out.append("")
            continue
        if id(smap) not in texts:
            texts[id(smap)] = json.dumps(smap.to_dict(), separators=(",", ":"))
        out.append(texts[id(smap)])
    return out


def _string_array(values: np.ndarray) -> Any:
    """A string column: Arrow converts an object array of str in C; other objects go through str()."""
    import pyarrow as pa

    try:
        arr = pa.array(values, type=pa.string())
        if arr.null_count == 0:  # None is written as the text "None", as str() does
            return arr
    except (pa.ArrowTypeError, pa.ArrowInvalid):
        pass
    return pa.array([str(v) for v in values], type=pa.string())


def _atomic_write(path: Path, table: Any, suffix: str) -> None:
    atomic_write(path, lambda tmp: _write_table(table, tmp, suffix))


def _write_table(table: Any, tmp: str, suffix: str) -> None:
    if suffix == ".parquet":
        import pyarrow as pa
        import pyarrow.parquet as pq

        # Episodes are contiguous: small row groups let a reader of some episodes skip the rest.
        # zstd on byte-split floats: about 25 % smaller than the default snappy, and as fast;
        # values stay float64 so that a stored episode compares bit for bit with its replay.
        floats = [f.name for f in table.schema if pa.types.is_floating(f.type)]
        pq.write_table(
            table,
            tmp,
            row_group_size=_ROW_GROUP,
            compression="zstd",
            use_byte_stream_split=floats,
            use_dictionary=[c for c in table.column_names if c not in floats],
            write_page_checksum=True,
        )
    else:
        import pyarrow.csv as pcsv

        pcsv.write_csv(table, tmp)


# ---------------------------------------------------------------------------------------- reading
class _Table:
    """Columns of the file as NumPy arrays, plus helpers that raise errors naming file/column/row."""

    def __init__(self, path: Path, episodes: list[Any] | None = None,
                 rows: tuple[int, int] | None = None) -> None:
        import pyarrow as pa

        self.path = path
        suffix = _suffix(path)
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
                    keys = _episode_keys(episodes, kind)
                    table = read_parquet_verified(path, filters=[("episode", "in", keys)] if keys else None)
                else:
                    table = read_parquet_verified(path)
            except CorruptFileError as err:
                raise TrajectoryFormatError(str(err)) from None
            raw = (table.schema.metadata or {}).get(_METADATA_KEY)
            if raw is not None:
                meta = json.loads(raw.decode())
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
        self._maps: dict[Any, Any] = {}  # parsed maps, shared by the episodes that reference one
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
            keys = pa.array(_episode_keys(episodes, col.type), type=col.type if integer else pa.string())
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
            if name in _FLOAT_COLUMNS:
                try:
                    arr = col.cast(pa.float64()).to_numpy()
                except (pa.ArrowInvalid, pa.ArrowNotImplementedError) as exc:
                    raise TrajectoryFormatError(f"{path}: column '{name}': not numeric ({exc})") from exc
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
        if row_index is not None and self.row_map is not None:
            row_index = int(self.row_map[row_index])
        where = f"column '{column}'" + ("" if row_index is None else f", row {row_index + 1}")
        return TrajectoryFormatError(f"{self.path}: {where}: {message}")

    def int_column(self, name: str) -> np.ndarray:
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
        arr = self.cols[name]
        bad = np.flatnonzero(~np.isfinite(arr))
        if bad.size:
            raise self.fail(name, int(bad[0]), f"value is {arr[bad[0]]} (missing or not finite)")


def read_trajectories(
    path: str | os.PathLike[str], *, resample: bool = False, dt: float | None = None,
    episodes: list[Any] | None = None, rows: tuple[int, int] | None = None,
) -> list[Trajectory]:
    """Read trajectories from a Parquet or CSV file in the long format.

    Episodes are returned in order of first appearance; ``settings["episode"]`` holds each key.
    Agents are ordered robot first, then humans by increasing ``agent`` id; when the ids are not
    0..A−1 the original ids are kept in ``settings["agent_ids"]``. A time origin t_0 ≠ 0 is kept in
    ``settings["t0"]``.

    Args:
        path: ``.parquet`` or ``.csv`` file.
        resample: If True, episodes with irregular or per-agent timestamps are resampled by linear
            interpolation to a fixed step on [latest agent start, earliest agent end]; ``min_clearance``
            (a per-step swept value) is then dropped and ``settings["resampled"]`` is set. If False,
            such episodes raise an error.
        dt: Step [s] to resample to, or to assume for one-sample episodes. Default: (t_K − t_0)/K
            on a regular grid, the median of the robot's steps when resampling (both rounded to 12
            significant digits, which recovers a dt written as text exactly).
        episodes: Read only these episode keys (rows keep their file numbers in messages).
        rows: Read only the file's rows [start, stop) (0-based; whole episodes, as parallel scoring
            splits a file whose episodes are contiguous); messages keep the file's row numbers.

    Returns:
        One Trajectory per episode.

    Raises:
        TrajectoryFormatError: The file breaks the schema; the message names file, column and row.
    """
    tab = _Table(Path(path), episodes, rows)
    for name in ("t", "x", "y", "radius", "gx", "gy"):
        tab.require_finite(name)
    vp = tab.cols["v_pref"]
    if np.any(np.isinf(vp)):  # empty v_pref means unknown (logs); inf is an error
        raise tab.fail("v_pref", int(np.flatnonzero(np.isinf(vp))[0]), "value is inf (not finite)")
    agents = tab.int_column("agent")
    episode_raw = tab.cols["episode"]
    episode_keys = episode_raw if episode_raw.dtype.kind in "iu" else np.array(
        [str(v) for v in episode_raw], dtype=object)
    _, first, inverse = np.unique(episode_keys, return_index=True, return_inverse=True)
    by_group = np.argsort(inverse, kind="stable")  # rows of each episode, in file order
    bounds = np.concatenate([[0], np.cumsum(np.bincount(inverse.reshape(-1), minlength=len(first)))])
    trajs = []
    for group in np.argsort(first, kind="stable"):
        rows = by_group[bounds[group] : bounds[group + 1]]
        key = episode_raw[rows[0]]
        key = key.item() if isinstance(key, np.generic) else key
        traj = None if resample else _fast_episode(tab, rows, agents, key, dt)
        trajs.append(traj if traj is not None else _read_episode(tab, rows, agents, key, resample, dt))
    return trajs


def _fast_episode(tab: _Table, rows: np.ndarray, agents: np.ndarray, key: Any, dt_arg: float | None
                  ) -> Trajectory | None:
    """The common case in a few array operations: every agent on one regular grid, written
    sample-major (as :func:`write_trajectories` does). None means "not that case": the general
    reader then handles it and reports any error precisely."""
    cols = tab.cols
    # an episode's rows are usually one block of the file: views instead of copies
    sel = slice(int(rows[0]), int(rows[-1]) + 1) if rows[-1] - rows[0] + 1 == len(rows) else rows
    ep_agents = agents[sel]
    n_agents = int(np.count_nonzero(ep_agents == ep_agents[0]))
    n_agents = len(rows) // max(n_agents, 1)
    if n_agents < 1 or len(rows) % n_agents or ep_agents[0] != 0:
        return None
    n_samples = len(rows) // n_agents
    grid_agents = ep_agents.reshape(n_samples, n_agents)
    ids = grid_agents[0]
    if not ((grid_agents == ids).all() and (ids[1:] > ids[:-1]).all()):
        return None
    t = cols["t"][sel].reshape(n_samples, n_agents)
    if not (t == t[:, :1]).all():
        return None
    cont = np.zeros(n_samples, dtype=bool)
    if "continuation" in cols:
        state = tab.continuation_state()[sel].reshape(n_samples, n_agents)
        if (state < 0).any() or not (state == state[:, :1]).all():
            return None
        cont = state[:, 0] == 1
    n_main = int(np.count_nonzero(~cont))
    if n_main < 2 or cont[:n_main].any():
        return None
    t_main = t[:n_main, 0]
    steps = np.diff(t_main)
    dt = float(dt_arg) if dt_arg is not None else float(f"{(t_main[-1] - t_main[0]) / steps.size:.12g}")
    if not (dt > 0 and (np.abs(steps - dt) <= _DT_RTOL * dt).all()):
        return None
    if n_main < n_samples:
        expected = t_main[-1] + dt * np.arange(1, n_samples - n_main + 1)
        if (np.abs(t[n_main:, 0] - expected) > _DT_RTOL * dt * np.arange(1, n_samples - n_main + 1)).any():
            return None
    per_agent = {}
    for name in ("radius", "gx", "gy", "v_pref", "arrival_t"):
        if name not in cols:
            continue
        v = cols[name][sel].reshape(n_samples, n_agents)
        first = v[:1]
        if not ((v == first) | (np.isnan(v) & np.isnan(first))).all():
            return None
        per_agent[name] = v[0]
    for name in ("role", "outcome", "human_overlaps"):
        if name in cols:
            c = tab.codes(name)[0][sel].reshape(n_samples, n_agents)
            if not (c == c[:1]).all():
                return None
    if "role" in cols:
        want = np.array(["robot"] + ["human"] * (n_agents - 1), dtype=object)
        first_roles = cols["role"][rows[:n_agents]]
        if not ((first_roles == want) | (first_roles == None)).all():  # noqa: E711
            return None
    outcome = "unknown"
    if "outcome" in cols:
        outcome = cols["outcome"][rows[0]] or "unknown"
        if outcome not in OUTCOMES:
            return None
    pos = np.stack([cols["x"][sel], cols["y"][sel]], axis=1).reshape(n_samples, n_agents, 2)
    if "vx" in cols and "vy" in cols:
        vel = np.stack([cols["vx"][sel], cols["vy"][sel]], axis=1).reshape(n_samples, n_agents, 2)[:n_main]
        if not np.isfinite(vel).all():
            return None
    else:
        vel = _velocities([{"vel": None}], pos[:n_main], dt)
    min_clearance = None
    if "min_clearance" in cols:
        mc = cols["min_clearance"][sel].reshape(n_samples, n_agents)[1:n_main, 0]
        missing = np.isnan(mc)
        if missing.any() and not missing.all():
            return None
        min_clearance = None if missing.all() else mc
    overlaps = None
    if "human_overlaps" in cols:
        ho = cols["human_overlaps"][rows[0]]
        overlaps = None if ho is None or (isinstance(ho, float) and np.isnan(ho)) else int(ho)
    settings = _episode_settings(tab, rows, key)
    if t_main[0] != 0.0:
        settings["t0"] = float(t_main[0])
    if not np.array_equal(ids, np.arange(n_agents)):
        settings["agent_ids"] = [int(i) for i in ids]
    arrival = per_agent.get("arrival_t")
    return Trajectory(
        dt=dt, positions=pos[:n_main], velocities=vel, radii=per_agent["radius"], v_pref=per_agent["v_pref"],
        goals=np.stack([per_agent["gx"], per_agent["gy"]], axis=1),
        roles=("robot",) + ("human",) * (n_agents - 1), outcome=outcome, min_clearance=min_clearance,
        continuation=pos[n_main:] if n_main < n_samples else None, human_overlaps=overlaps,
        settings=settings, arrival_times=None if arrival is None or np.all(np.isnan(arrival)) else arrival,
        static_map=_episode_map(tab, rows, key),
    )


def _constant(tab: _Table, name: str, rows: np.ndarray, *, allow_empty: bool = True) -> Any:
    """The single value of a per-agent or per-episode column over ``rows`` (None when all empty)."""
    values = tab.cols[name][rows]
    empty = np.array([v is None or v == "" or (isinstance(v, float) and np.isnan(v)) for v in values])
    if np.all(empty):
        return None
    ref_i = int(np.flatnonzero(~empty)[0])
    for i in np.flatnonzero(~empty):
        if values[i] != values[ref_i]:
            raise tab.fail(name, int(rows[i]), f"value {values[i]!r} differs from {values[ref_i]!r} "
                           f"(row {rows[ref_i] + 1}); it must be constant per episode/agent")
    if not allow_empty and np.any(empty):
        raise tab.fail(name, int(rows[np.flatnonzero(empty)[0]]), "value missing")
    return values[ref_i]


def _read_episode(
    tab: _Table, rows: np.ndarray, agents: np.ndarray, key: Any, resample: bool, dt_arg: float | None
) -> Trajectory:
    cols = tab.cols
    ep_agents = agents[rows]
    ids = np.unique(ep_agents)
    if 0 not in ids:
        raise tab.fail("agent", int(rows[0]), f"episode {key!r} has no robot (agent 0)")
    if np.any(ids < 0):
        raise tab.fail("agent", int(rows[np.flatnonzero(ep_agents < 0)[0]]), "agent ids must be >= 0")
    cont_flag = np.zeros(len(rows), dtype=bool)
    if "continuation" in cols:
        for j, v in enumerate(cols["continuation"][rows]):
            if v in (True, 1, "true", "True"):
                cont_flag[j] = True
            elif v not in (False, 0, None, "", "false", "False"):
                raise tab.fail("continuation", int(rows[j]), f"expected true/false, got {v!r}")
    per_agent: list[dict[str, Any]] = []
    for a in ids:
        sel = np.flatnonzero(ep_agents == a)
        arows = rows[sel]
        t = cols["t"][arows]
        steps = np.diff(t)
        if np.any(steps <= 0):
            i = int(np.flatnonzero(steps <= 0)[0])
            raise tab.fail("t", int(arows[i + 1]), f"time not increasing for episode {key!r}, agent {a}: "
                           f"{t[i]} -> {t[i + 1]} (dt = {steps[i]:g} s <= 0)")
        is_cont = cont_flag[sel]
        if np.any(np.diff(is_cont.astype(int)) < 0):
            i = int(np.flatnonzero(np.diff(is_cont.astype(int)) < 0)[0])
            raise tab.fail("continuation", int(arows[i + 1]), "main sample after a continuation sample")
        if not np.any(~is_cont):
            raise tab.fail("continuation", int(arows[0]), f"agent {a} has only continuation samples")
        role = _constant(tab, "role", arows) if "role" in cols else None
        want = "robot" if a == 0 else "human"
        if role is not None and role != want:
            bad = "role must be one of " + str(ROLES) if role not in ROLES else f"agent {a} must be {want!r}"
            raise tab.fail("role", int(arows[0]), f"{bad}, got {role!r}")
        vel = None
        if "vx" in cols and "vy" in cols:
            vel = np.stack([cols["vx"][arows], cols["vy"][arows]], axis=1)
            main_bad = np.flatnonzero(~np.all(np.isfinite(vel), axis=1) & ~is_cont)
            if main_bad.size:
                c = "vx" if not np.isfinite(vel[main_bad[0], 0]) else "vy"
                raise tab.fail(c, int(arows[main_bad[0]]), "missing or not finite (drop the vx/vy columns "
                               "to derive velocities from positions)")
        per_agent.append({
            "rows": arows, "t": t, "cont": is_cont,
            "pos": np.stack([cols["x"][arows], cols["y"][arows]], axis=1), "vel": vel,
            "radius": _constant(tab, "radius", arows), "v_pref": _constant(tab, "v_pref", arows),
            "arrival": _constant(tab, "arrival_t", arows) if "arrival_t" in cols else None,
            "goal": (_constant(tab, "gx", arows), _constant(tab, "gy", arows)),
        })
    robot = per_agent[0]
    settings = _episode_settings(tab, rows, key)
    outcome = "unknown"
    if "outcome" in cols:
        outcome = _constant(tab, "outcome", rows) or "unknown"
        if outcome not in OUTCOMES:
            raise tab.fail("outcome", int(rows[0]), f"must be one of {OUTCOMES}, got {outcome!r}")
    overlaps = None
    if "human_overlaps" in cols:
        ho = _constant(tab, "human_overlaps", rows)
        overlaps = None if ho is None else int(ho)
    grid_t = robot["t"][~robot["cont"]]
    regular, dt = _check_grid(tab, per_agent, dt_arg, key)
    masked = None if regular else _masked_grid(per_agent, dt)
    if not regular and masked is None and not resample:
        raise _regular_error(tab, per_agent, dt, key)
    if not regular and masked is None and dt_arg is None:
        dt = float(f"{np.median(np.diff(grid_t)):.12g}")
    min_clearance = None
    present = None
    if masked is not None:
        pos, vel, present = masked
        cont = None
        if "min_clearance" in cols:
            min_clearance = _min_clearance(tab, robot)
    elif regular:
        pos = np.stack([p["pos"][~p["cont"]] for p in per_agent], axis=1)
        vel = _velocities(per_agent, pos, dt)
        cont = _regular_continuation(tab, per_agent, grid_t[-1], dt, key)
        if "min_clearance" in cols:
            min_clearance = _min_clearance(tab, robot)
    else:
        pos, vel, cont, grid_t = _resample(per_agent, dt)
        settings["resampled"] = True
    if grid_t[0] != 0.0:
        settings["t0"] = float(grid_t[0])
    if not np.array_equal(ids, np.arange(len(ids))):
        settings["agent_ids"] = [int(i) for i in ids]
    arrival = np.array([np.nan if p["arrival"] is None else p["arrival"] for p in per_agent], dtype=float)
    return Trajectory(
        dt=dt, positions=pos, velocities=vel, present=present,
        arrival_times=None if np.all(np.isnan(arrival)) else arrival,
        radii=np.array([p["radius"] for p in per_agent], dtype=float),
        v_pref=np.array([p["v_pref"] for p in per_agent], dtype=float),
        goals=np.array([p["goal"] for p in per_agent], dtype=float),
        roles=("robot",) + ("human",) * (len(ids) - 1), outcome=outcome,
        min_clearance=min_clearance, continuation=cont, human_overlaps=overlaps, settings=settings,
        static_map=_episode_map(tab, rows, key),
    )


def _episode_settings(tab: _Table, rows: np.ndarray, key: Any) -> dict[str, Any]:
    text = tab.meta_settings.get(str(key))
    row = int(rows[0])
    if text is None and "settings" in tab.cols:
        text = _constant(tab, "settings", rows)
        nonempty = [r for r in rows if tab.cols["settings"][r] not in (None, "")]
        row = int(nonempty[0]) if nonempty else row
    settings: dict[str, Any] = {}
    if text:
        try:
            settings = json.loads(text)
        except json.JSONDecodeError as exc:
            raise tab.fail("settings", row, f"invalid JSON ({exc})") from None
        if not isinstance(settings, dict):
            raise tab.fail("settings", row, "settings JSON must be an object")
    settings["episode"] = key.item() if isinstance(key, np.generic) else key
    return settings


def _episode_map(tab: _Table, rows: np.ndarray, key: Any) -> Any:
    """The episode's static map: from the Parquet metadata, else the ``static_map`` column (JSON on
    one row of the episode); None for an open floor."""
    from socialnav.static_map import MapError, StaticMap

    ref = tab.meta_episode_maps.get(str(key))
    if ref is not None:
        if not isinstance(ref, int) or not 0 <= ref < len(tab.meta_maps):
            raise TrajectoryFormatError(f"{tab.path}: metadata 'episode_maps' of episode {key!r}: map index "
                                        f"{ref!r} outside the {len(tab.meta_maps)} stored maps")
        source: Any = ("meta", ref)
        data = tab.meta_maps[ref]

        def fail(message: str) -> TrajectoryFormatError:
            return TrajectoryFormatError(f"{tab.path}: metadata 'maps'[{ref}] (episode {key!r}): {message}")
    elif "static_map" in tab.cols:
        text = _constant(tab, "static_map", rows)
        if not text:
            return None
        source = ("text", text)
        row = int(next(r for r in rows if tab.cols["static_map"][r] not in (None, "")))
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise tab.fail("static_map", row, f"invalid JSON ({exc})") from None

        def fail(message: str) -> TrajectoryFormatError:
            return tab.fail("static_map", row, message)
    else:
        return None
    if source not in tab._maps:
        try:
            tab._maps[source] = StaticMap.from_dict(data)
        except MapError as exc:
            raise fail(str(exc)) from None
    smap = tab._maps[source]
    return smap if smap else None


def _check_grid(
    tab: _Table, per_agent: list[dict[str, Any]], dt_arg: float | None, key: Any
) -> tuple[bool, float]:
    """Whether all agents share one regular main time grid, and the step to use [s]."""
    robot_t = per_agent[0]["t"][~per_agent[0]["cont"]]
    steps = np.diff(robot_t)
    if dt_arg is not None:
        dt = float(dt_arg)
        if not np.isfinite(dt) or dt <= 0:
            raise TrajectoryFormatError(f"{tab.path}: dt argument must be > 0, got {dt_arg!r}")
    elif steps.size:
        # the span over the step count is the least noisy estimate on a regular grid; rounding to 12
        # significant digits recovers the written dt exactly (k·0.1 written as text is not exact)
        dt = float(f"{(robot_t[-1] - robot_t[0]) / steps.size:.12g}")
    else:
        raise tab.fail("t", int(per_agent[0]["rows"][0]), f"episode {key!r} has one sample: pass dt=")
    tol = _DT_RTOL * dt
    regular = bool(np.all(np.abs(steps - dt) <= tol))
    for p in per_agent[1:]:
        t = p["t"][~p["cont"]]
        regular &= t.shape == robot_t.shape and bool(np.all(np.abs(t - robot_t) <= tol))
    return regular, dt


def _masked_grid(
    per_agent: list[dict[str, Any]], dt: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Agents entering or leaving: every sample on the robot's regular grid, some agents absent at some
    samples (no row). Returns (positions, velocities, present) or None when that is not the case."""
    if any(np.any(p["cont"]) for p in per_agent):
        return None  # continuation samples need every agent at every sample
    robot_t = per_agent[0]["t"]
    if robot_t.size < 2 or not np.all(np.abs(np.diff(robot_t) - dt) <= _DT_RTOL * dt):
        return None
    n = robot_t.size
    pos = np.full((n, len(per_agent), 2), np.nan)
    present = np.zeros((n, len(per_agent)), dtype=bool)
    given = per_agent[0]["vel"] is not None
    vel = np.full_like(pos, np.nan)
    for a, p in enumerate(per_agent):
        k = (p["t"] - robot_t[0]) / dt
        ki = np.rint(k)
        if np.any(np.abs(k - ki) > _DT_RTOL * np.maximum(1.0, np.abs(k))) or ki.min() < 0 or ki.max() > n - 1:
            return None
        ki = ki.astype(np.int64)
        pos[ki, a], present[ki, a] = p["pos"], True
        if given:
            vel[ki, a] = p["vel"]
    if not given:
        from socialnav.trajectory import derive_velocities

        vel = derive_velocities(pos, present, dt)
    return np.nan_to_num(pos), np.nan_to_num(vel), present


def _regular_error(
    tab: _Table, per_agent: list[dict[str, Any]], dt: float, key: Any
) -> TrajectoryFormatError:
    """Describe the first sample that breaks a shared regular grid."""
    robot = per_agent[0]
    robot_t = robot["t"][~robot["cont"]]
    tol = _DT_RTOL * dt
    hint = " (pass resample=True to interpolate to a fixed dt)"
    steps = np.diff(robot_t)
    ref = float(np.median(steps)) if steps.size else dt  # the typical step, to point at the odd one
    if steps.size and np.all(np.abs(steps - ref) <= tol) and abs(ref - dt) > tol:
        return tab.fail("t", int(robot["rows"][1]), f"episode {key!r} is sampled every {ref:g} s but "
                        f"dt={dt:g} was passed{hint}")
    for i, step in enumerate(steps):
        if abs(step - ref) > tol:
            return tab.fail("t", int(robot["rows"][i + 1]), f"irregular sampling in episode {key!r}: step "
                            f"{step:g} s, typical step {ref:g} s{hint}")
    for a, p in enumerate(per_agent[1:], start=1):
        t = p["t"][~p["cont"]]
        n = min(len(t), len(robot_t))
        off = np.flatnonzero(np.abs(t[:n] - robot_t[:n]) > tol)
        if off.size:
            i = int(off[0])
            return tab.fail("t", int(p["rows"][i]), f"episode {key!r}: agent row {a} at t = {t[i]:g} s, "
                            f"the robot at t = {robot_t[i]:g} s{hint}")
        if len(t) != len(robot_t):
            return tab.fail("t", int(p["rows"][n - 1]), f"episode {key!r}: agent row {a} has {len(t)} "
                            f"samples, the robot {len(robot_t)}{hint}")
    return tab.fail("t", int(robot["rows"][0]), f"irregular sampling in episode {key!r}{hint}")


def _velocities(per_agent: list[dict[str, Any]], pos: np.ndarray, dt: float) -> np.ndarray:
    if per_agent[0]["vel"] is not None:
        return np.stack([p["vel"][~p["cont"]] for p in per_agent], axis=1)
    vel = np.zeros_like(pos)
    if pos.shape[0] > 1:
        vel[1:] = np.diff(pos, axis=0) / dt
        vel[0] = vel[1]  # the velocity before the first logged sample is unknown
    return vel


def _regular_continuation(
    tab: _Table, per_agent: list[dict[str, Any]], t_end: float, dt: float, key: Any
) -> np.ndarray | None:
    robot = per_agent[0]
    n = int(np.sum(robot["cont"]))
    if n == 0 and not any(np.any(p["cont"]) for p in per_agent):
        return None
    expected = t_end + dt * np.arange(1, n + 1)
    for a, p in enumerate(per_agent):
        t = p["t"][p["cont"]]
        rows = p["rows"][p["cont"]]
        if len(t) != n:
            raise tab.fail("continuation", int(rows[0] if len(rows) else p["rows"][-1]),
                           f"episode {key!r}: agent row {a} has {len(t)} continuation samples, robot {n}")
        off = np.flatnonzero(np.abs(t - expected) > _DT_RTOL * dt * np.arange(1, n + 1))
        if off.size:
            raise tab.fail("t", int(rows[off[0]]), f"continuation sample at t = {t[off[0]]:g} s, expected "
                           f"{expected[off[0]]:g} s (continuation must continue the grid)")
    return np.stack([p["pos"][p["cont"]] for p in per_agent], axis=1)


def _min_clearance(tab: _Table, robot: dict[str, Any]) -> np.ndarray | None:
    rows = robot["rows"][~robot["cont"]][1:]
    values = tab.cols["min_clearance"][rows]
    if np.all(np.isnan(values)):
        return None
    if np.any(np.isnan(values)):
        raise tab.fail("min_clearance", int(rows[np.flatnonzero(np.isnan(values))[0]]),
                       "missing on a robot row; give it on every robot row after the first or on none")
    return values


def _resample(
    per_agent: list[dict[str, Any]], dt: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray]:
    """Linear interpolation of every agent onto t_0 + k·dt over the common time span."""
    main = [(p["t"][~p["cont"]], p["pos"][~p["cont"]]) for p in per_agent]
    t0 = max(t[0] for t, _ in main)
    t1 = min(t[-1] for t, _ in main)
    if t1 < t0:
        raise TrajectoryFormatError("agents' time spans do not overlap; cannot resample")
    k = int(np.floor((t1 - t0) / dt + 1e-9))
    if k >= MAX_RESAMPLED_STEPS:
        raise TrajectoryFormatError(f"resampling {t1 - t0:.6g} s at dt {dt:.6g} s makes {k + 1} samples per "
                                    f"agent, more than the {MAX_RESAMPLED_STEPS} allowed: raise --dt")
    grid = t0 + dt * np.arange(k + 1)
    pos = np.stack([np.stack([np.interp(grid, t, x[:, d]) for d in (0, 1)], -1) for t, x in main], 1)
    if per_agent[0]["vel"] is not None:
        vel = np.stack([np.stack([np.interp(grid, p["t"][~p["cont"]], p["vel"][~p["cont"], d])
                                  for d in (0, 1)], -1) for p in per_agent], 1)
    else:
        vel = _velocities([{"vel": None}], pos, dt)
    cont = None
    if all(np.any(p["cont"]) for p in per_agent):
        c_end = min(p["t"][-1] for p in per_agent)
        m = int(np.floor((c_end - grid[-1]) / dt + 1e-9))
        if m > 0:
            c_grid = grid[-1] + dt * np.arange(1, m + 1)
            cont = np.stack([np.stack([np.interp(c_grid, p["t"], p["pos"][:, d]) for d in (0, 1)], -1)
                             for p in per_agent], 1)
    return pos, vel, cont, grid

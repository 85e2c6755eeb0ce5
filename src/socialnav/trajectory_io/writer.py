"""Writing trajectories to Parquet or CSV in the long format, atomically.

The columns are built for all episodes at once (gathers over per-episode and per-agent arrays), and
the file is written through :func:`socialnav._io.atomic_write`: readers never see a half-written file.
``pyarrow`` is imported lazily so that ``import socialnav.metrics`` stays NumPy-only.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from socialnav._io import atomic_write
from socialnav.trajectory import Trajectory, TrajectoryFormatError
from socialnav.trajectory_io.schema import FORMAT_VERSION, METADATA_KEY, ROW_GROUP, file_suffix


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
    suffix = file_suffix(path)
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
        meta: dict[str, Any] = {"format_version": FORMAT_VERSION, "settings": settings_json}
        if any(map_json):
            # each distinct map once (the episodes of one scene share theirs), referenced per episode
            distinct = list(dict.fromkeys(m for m in map_json if m))
            index = {m: i for i, m in enumerate(distinct)}
            meta["maps"] = [json.loads(m) for m in distinct]
            meta["episode_maps"] = {str(k): index[m] for k, m in zip(keys, map_json, strict=True) if m}
        table = table.replace_schema_metadata({METADATA_KEY: json.dumps(meta).encode()})
    atomic_write(path, lambda tmp: _write_table(table, tmp, suffix))


def _columns(
    trajs: list[Trajectory], keys: list[Any], settings_json: list[str], map_json: list[str],
    with_text_columns: bool,
) -> dict[str, Any]:
    """The long table's columns (Arrow arrays, in ``WRITE_ORDER``), one row per (episode, sample, agent).

    They are built for all episodes at once: per-row values come from gathers over per-episode and
    per-agent arrays, so the cost per episode is a few array views, not a dozen allocations (the
    ``wang2022`` protocol writes 4060 episodes per run).
    """
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
    if with_text_columns and any(map_json):  # open floor everywhere: no map column (readers without maps)
        arrays["static_map"] = first_rows(map_json)
    return arrays


def _map_texts(trajs: list[Trajectory]) -> list[str]:
    """Each episode's static map as compact JSON ("" for an open floor).

    One text per distinct map object, since the episodes of a scene usually share one.
    """
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
            row_group_size=ROW_GROUP,
            compression="zstd",
            use_byte_stream_split=floats,
            use_dictionary=[c for c in table.column_names if c not in floats],
            write_page_checksum=True,
        )
    else:
        import pyarrow.csv as pcsv

        pcsv.write_csv(table, tmp)

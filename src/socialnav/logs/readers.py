"""Importers: ETH/UCY pedestrian files and generic CSV/Parquet logs into :class:`Scene` objects.

Every problem raises :class:`~socialnav.trajectory.TrajectoryFormatError` naming the file, the column
and the row (1-based data row, header excluded; for ETH/UCY text files the line number). Values the
data do not give are assumed only with an :class:`~socialnav.trajectory.AssumedValueWarning` naming
them. See ``docs/real_world_logs.md``.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from socialnav.logs.columns import (
    Fail,
    agent_ids,
    check_text,
    group_codes,
    load_table,
    numeric_column,
    per_agent_value,
    read_times,
    require_finite,
    scene_constant,
    string_column,
)
from socialnav.logs.scene import Scene, clock, id_matches, scene_from_tracks
from socialnav.trajectory import OUTCOMES, AssumedValueWarning, TrajectoryFormatError

__all__ = [
    "DEFAULT_RADIUS",
    "ETH_UCY_FPS",
    "FIELDS",
    "MAX_SPEED",
    "parse_columns",
    "read_eth_ucy",
    "read_table",
]

FIELDS: dict[str, str] = {
    "time": "sample time (required)",
    "id": "agent id (required)",
    "x": "position x (required)",
    "y": "position y (required)",
    "scene": "scene/episode key (default: the whole file is one scene)",
    "vx": "velocity x", "vy": "velocity y",
    "radius": "agent radius [m]",
    "gx": "goal x", "gy": "goal y",
    "v_pref": "preferred speed [m/s]",
    "role": "robot/human (marks the robot)",
    "outcome": "success/collision/timeout/unknown, per scene",
}
"""Fields of the column mapping (``--columns field=column,...``)."""
_ALIASES = {"t": "time", "agent": "id", "episode": "scene"}
_REQUIRED = ("time", "id", "x", "y")
_LENGTH = {"m": 1.0, "cm": 0.01, "mm": 0.001}
_TIME = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
DEFAULT_RADIUS = 0.3
"""Body radius [m] assumed when the data have none (CrowdNav's human radius), with a warning."""
MAX_SPEED = 10.0
"""Speeds above this [m/s] between consecutive samples are rejected as implausible (wrong units?)."""
ETH_UCY_FPS = 25.0
"""Frame numbers per second in ETH/UCY files: frames step by 10 between annotations, 0.4 s (2.5 Hz)."""


def parse_columns(spec: str | Mapping[str, str] | None) -> dict[str, str]:
    """``"time=t,id=agent,x=px"`` (or a dict) -> {field: column}; unknown fields raise ValueError."""
    if spec is None:
        return {}
    items = spec.items() if isinstance(spec, Mapping) else []
    if isinstance(spec, str):
        parsed = []
        for part in filter(None, (p.strip() for p in spec.split(","))):
            field, sep, column = part.partition("=")
            if not sep or not field.strip() or not column.strip():
                raise ValueError(f"--columns: expected field=column, got {part!r} "
                                 "(e.g. time=t,id=agent,x=px)")
            parsed.append((field.strip(), column.strip()))
        items = parsed
    out: dict[str, str] = {}
    for field, column in items:
        name = _ALIASES.get(field, field)
        if name not in FIELDS:
            raise ValueError(f"--columns: unknown field {field!r}; valid fields: {', '.join(FIELDS)}")
        if name in out:
            raise ValueError(f"--columns: field {name!r} given twice")
        out[name] = column
    return out


def _check_path(path: Path) -> None:
    if path.is_dir():
        raise TrajectoryFormatError(f"{path}: is a directory, not a trajectory file")
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file")
    if path.stat().st_size == 0:
        raise TrajectoryFormatError(f"{path}: empty file")


# ------------------------------------------------------------------------------------ ETH/UCY
def read_eth_ucy(
    path: str | Path,
    *,
    fps: float = ETH_UCY_FPS,
    radius: float | None = None,
    dt: float | None = None,
    max_gap: float | None = None,
    max_speed: float = MAX_SPEED,
) -> list[Scene]:
    """Read an ETH/UCY-style text file: ``frame id x y`` per line (whitespace or tab separated).

    This is the layout used by the trajectory-prediction community (e.g. the Social-GAN / Trajnet
    copies of ETH, HOTEL, UNIV, ZARA1/2): positions in metres, frames stepping by 10 at 25 fps, i.e.
    0.4 s (2.5 Hz). The file holds one scene without a robot: score it with ``ego``.

    Args:
        path: Text file.
        fps: Frame numbers per second (t = frame/fps).
        radius: Radius of every agent [m]; default :data:`DEFAULT_RADIUS` with a warning.
        dt: Grid step [s], see :func:`scene_from_tracks`.
        max_gap: Longest bridged gap [s], see :func:`scene_from_tracks`.
        max_speed: Implausible-speed limit [m/s] (``inf`` disables the check).

    Returns:
        One :class:`Scene` named after the file.
    """
    path = Path(path)
    _check_path(path)
    check_text(path)
    fail = Fail(path, "line")
    if not np.isfinite(fps) or fps <= 0:
        raise ValueError(f"fps must be > 0, got {fps!r}")
    names = ("frame", "id", "x", "y")
    values: list[list[float]] = []
    rows: list[int] = []
    with path.open(encoding="utf-8") as handle:
        for line_no, line in enumerate(handle):
            parts = line.split()
            if not parts or parts[0].startswith("#"):
                continue
            if len(parts) != 4:
                raise fail("frame", line_no, f"expected 4 fields (frame id x y), got {len(parts)}: "
                           f"{line.strip()[:60]!r}")
            rec = []
            for name, text in zip(names, parts, strict=True):
                try:
                    value = float(text)
                except ValueError:
                    raise fail(name, line_no, f"not a number: {text!r}") from None
                if not np.isfinite(value):
                    raise fail(name, line_no, f"value is {text} (not finite)")
                rec.append(value)
            values.append(rec)
            rows.append(line_no)
    if not values:
        raise TrajectoryFormatError(f"{path}: no data lines (expected 'frame id x y' per line)")
    data = np.array(values)
    ids = data[:, 1]
    if np.any(ids != np.round(ids)):
        i = int(np.flatnonzero(ids != np.round(ids))[0])
        raise fail("id", rows[i], f"agent id must be an integer, got {ids[i]:g}")
    t = data[:, 0] / fps
    xy = data[:, 2:4]
    row_arr = np.array(rows)
    agent = ids.astype(np.int64)
    _check_speeds(fail, t, agent, xy, row_arr, max_speed, "x")
    radius = _assumed_radius(path, radius, "ETH/UCY files have no radii")
    scene_ids, grid = scene_from_tracks(name=path.stem, source=str(path), t=t, agent=agent, xy=xy,
                                        rows=row_arr, dt=dt, max_gap=max_gap, time_column="frame", fail=fail)
    n = len(scene_ids)
    scene = _make_scene(path, path.stem, scene_ids, grid, np.full(n, radius), np.full(n, np.nan),
                        np.full((n, 2), np.nan), None, "unknown", {"format": "eth-ucy"})
    return [dataclasses.replace(scene, row_word="line")]


def _assumed_radius(path: Path, radius: float | None, why: str) -> float:
    if radius is None:
        warnings.warn(f"{path}: {why}; assumed radius {DEFAULT_RADIUS} m for every agent (set --radius)",
                      AssumedValueWarning, stacklevel=3)
        return DEFAULT_RADIUS
    if not np.isfinite(radius) or radius < 0:
        raise ValueError(f"radius must be >= 0, got {radius!r}")
    return float(radius)


def _check_speeds(fail: Fail, t: np.ndarray, agent: np.ndarray, xy: np.ndarray, rows: np.ndarray,
                  max_speed: float, column: str) -> None:
    """Reject steps faster than ``max_speed`` (metres vs millimetres, or ms vs s, usually)."""
    order = np.lexsort((t, agent))
    same = agent[order][1:] == agent[order][:-1]
    dt = np.diff(t[order])
    dist = np.linalg.norm(np.diff(xy[order], axis=0), axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        speed = np.where(same & (dt > 0), dist / dt, 0.0)
    bad = np.flatnonzero(speed > max_speed)
    if bad.size:
        i = int(bad[0])
        raise fail(column, int(rows[order[i + 1]]), f"implausible speed {speed[i]:.4g} m/s for agent "
                   f"{agent[order][i + 1]} (limit {max_speed:g} m/s): positions must be in metres and times "
                   "in seconds (see --length-unit, --time-unit, --fps; --max-speed to change the limit)")


def _make_scene(path: Path, name: str, ids: np.ndarray, grid: dict[str, Any], radii: np.ndarray,
                v_pref: np.ndarray, goals: np.ndarray, robot: int | None, outcome: str,
                settings: dict[str, Any]) -> Scene:
    return Scene(
        name=name, dt=grid["dt"], t0=grid["t0"], ids=ids, positions=grid["positions"],
        present=grid["present"], velocities=grid["velocities"], radii=radii, v_pref=v_pref, goals=goals,
        robot=robot, outcome=outcome, rows=grid["first_rows"], source=str(path), resampled=grid["resampled"],
        settings=settings,
    )


# ------------------------------------------------------------------------------------ CSV / Parquet
def read_table(
    path: str | Path,
    columns: str | Mapping[str, str] | None = None,
    *,
    robot: Any = None,
    radius: float | None = None,
    dt: float | None = None,
    max_gap: float | None = None,
    max_speed: float = MAX_SPEED,
    length_unit: str = "m",
    time_unit: str = "s",
) -> list[Scene]:
    """Read a CSV or Parquet log with any column names, one row per (time, agent).

    Args:
        path: ``.csv`` or ``.parquet`` file.
        columns: Mapping from the fields of :data:`FIELDS` to the file's columns, as
            ``"time=t,id=agent,x=px,y=py"`` or a dict. Fields not mapped are looked up under their own
            name (``time``/``t``, ``id``/``agent``, ``x``, ...).
        robot: Id of the robot in every scene; default the agent whose ``role`` is ``robot`` when a
            role column exists, else none (pedestrian data: score with ``ego``).
        radius: Radius of every agent [m] when there is no radius column; default
            :data:`DEFAULT_RADIUS` with a warning.
        dt: Grid step [s] (see :func:`scene_from_tracks`).
        max_gap: Longest bridged gap [s] (see :func:`scene_from_tracks`).
        max_speed: Implausible-speed limit [m/s].
        length_unit: ``m``, ``cm`` or ``mm``: of positions, radii and goals, and of speeds (``vx``,
            ``vy``, ``v_pref``), which are read as this unit per second whatever ``time_unit`` is.
        time_unit: ``s``, ``ms``, ``us`` or ``ns``: of the time column only (loggers stamp with
            millisecond or nanosecond clocks but report speeds per second).

    Returns:
        One :class:`Scene` per scene key, in order of first appearance.
    """
    path = Path(path)
    _check_path(path)
    if length_unit not in _LENGTH or time_unit not in _TIME:
        raise ValueError(f"units: length one of {list(_LENGTH)}, time one of {list(_TIME)}; "
                         f"got {length_unit!r}, {time_unit!r}")
    mapping = parse_columns(columns)
    table = load_table(path)
    fail = Fail(path)
    names = table.column_names
    for field in FIELDS:
        if field not in mapping:
            for candidate in [field] + [a for a, f in _ALIASES.items() if f == field]:
                if candidate in names:
                    mapping[field] = candidate
                    break
    for field, column in mapping.items():
        if column not in names:
            raise TrajectoryFormatError(f"{path}: column {column!r} (mapped to {field}) not found; "
                                        f"columns present: {names}")
    missing = [f for f in _REQUIRED if f not in mapping]
    if missing:
        raise TrajectoryFormatError(f"{path}: no column for {missing}; columns present: {names}; map them "
                                    "with --columns, e.g. --columns time=stamp,id=track,x=px,y=py")
    for pair in (("gx", "gy"), ("vx", "vy")):
        alone = [f for f in pair if f in mapping]
        if len(alone) == 1:
            other = pair[1 - pair.index(alone[0])]
            raise TrajectoryFormatError(f"{path}: column {mapping[alone[0]]!r} ({alone[0]}) has no {other} "
                                        f"beside it; map both {pair[0]} and {pair[1]} or neither (columns "
                                        f"present: {names})")
    doubled = [c for c in dict.fromkeys(mapping.values()) if list(mapping.values()).count(c) > 1]
    if doubled:
        fields = [f for f, c in mapping.items() if c == doubled[0]]
        raise TrajectoryFormatError(f"{path}: column {doubled[0]!r} is mapped to {' and '.join(fields)}; "
                                    "each field needs its own column")
    if table.num_rows == 0:
        raise TrajectoryFormatError(f"{path}: no data rows")
    lscale, tscale = _LENGTH[length_unit], _TIME[time_unit]
    col = {f: numeric_column(table, c, fail, f) for f, c in mapping.items()
           if f in ("x", "y", "vx", "vy", "radius", "gx", "gy", "v_pref")}
    # seconds after the file's first stamp (exact for integer clocks), and that stamp: epoch stamps keep
    # their sub-millisecond differences, which float seconds since 1970 would round away
    t, origin = read_times(table, mapping["time"], fail, tscale)
    agent = agent_ids(table, mapping["id"], fail)
    for f in ("x", "y"):
        lost = np.flatnonzero(np.isnan(col[f]))
        if lost.size:  # a tracker's lost person, usually: said with whom and when
            row = int(lost[0])
            raise fail(mapping[f], row, f"missing value (agent {agent[row]} at t = {clock(origin + t[row])} "
                       "s): leave out the rows of samples where an agent was not seen (it is absent there)")
        require_finite(col[f], fail, mapping[f])
    xy = np.stack([col["x"], col["y"]], axis=1) * lscale
    scene_key = (string_column(table, mapping["scene"]) if "scene" in mapping
                 else np.full(table.num_rows, path.stem, dtype=object))
    vel = None
    if "vx" in col and "vy" in col:
        vel = np.stack([col["vx"], col["vy"]], axis=1) * lscale
        require_finite(vel[:, 0], fail, mapping["vx"])
        require_finite(vel[:, 1], fail, mapping["vy"])
    roles = string_column(table, mapping["role"]) if "role" in mapping else None
    outcomes = string_column(table, mapping["outcome"]) if "outcome" in mapping else None
    if "radius" not in col:
        radius = _assumed_radius(path, radius, "no radius column")
    all_rows = np.arange(table.num_rows)
    _check_speeds(fail, t, group_codes(scene_key, agent), xy, all_rows, max_speed, mapping["x"])
    scenes = []
    keys, first = np.unique(scene_key.astype(str), return_index=True)
    inverse = np.searchsorted(keys, scene_key.astype(str))
    for s in np.argsort(first, kind="stable"):
        rows = np.flatnonzero(inverse == s)
        name = str(scene_key[rows[0]])
        robot_id = _robot_id(path, name, agent, roles, rows, robot, fail, mapping)
        ids, grid = scene_from_tracks(name=name, source=str(path), t=t[rows], agent=agent[rows], xy=xy[rows],
                                      rows=rows, velocity=None if vel is None else vel[rows], dt=dt,
                                      max_gap=max_gap, anchor=robot_id, time_column=mapping["time"],
                                      fail=fail, time_origin=origin)
        grid["t0"] = origin + grid["t0"]  # the file's clock again
        a_of_row = np.searchsorted(ids, agent[rows])
        per_agent = {}
        for f in ("radius", "gx", "gy", "v_pref"):
            if f in col:
                per_agent[f] = per_agent_value(col[f] * lscale, rows,
                                          a_of_row, len(ids), fail, mapping[f])
        radii = per_agent.get("radius", np.full(len(ids), radius))
        if np.any(~np.isfinite(radii)) or np.any(radii < 0):
            a = int(np.flatnonzero(~(radii >= 0))[0])
            raise fail(mapping["radius"], int(grid["first_rows"][a]), f"radius must be >= 0, got {radii[a]}")
        goals = np.stack([per_agent.get("gx", np.full(len(ids), np.nan)),
                          per_agent.get("gy", np.full(len(ids), np.nan))], axis=1)
        v_pref = per_agent.get("v_pref", np.full(len(ids), np.nan))
        robot_index = None if robot_id is None else int(np.flatnonzero(ids.astype(str) == str(robot_id))[0])
        outcome = "unknown"
        if outcomes is not None:
            outcome = scene_constant(outcomes[rows], rows, fail, mapping["outcome"]) or "unknown"
            if outcome not in OUTCOMES:
                raise fail(mapping["outcome"], int(rows[0]), f"must be one of {OUTCOMES}, got {outcome!r}")
        scenes.append(_make_scene(path, name, ids, grid, radii, v_pref, goals, robot_index, outcome,
                                  {"format": "table"}))
    return scenes


def _robot_id(path: Path, name: str, agent: np.ndarray, roles: np.ndarray | None, rows: np.ndarray,
              robot: Any, fail: Fail, mapping: dict[str, str]) -> Any:
    """The id of the scene's robot: ``robot`` when given, else the agent whose role is ``robot``, else None.

    A role column must give each agent one role; ``robot`` overriding it is said in a note.
    """
    ids_here = agent[rows]
    logged = None
    if roles is not None:
        r = roles[rows]
        bad = [i for i, v in enumerate(r) if v not in ("robot", "human", "")]
        if bad:
            raise fail(mapping["role"], int(rows[bad[0]]),
                       f"role must be 'robot' or 'human', got {r[bad[0]]!r}")
        first_role: dict[str, tuple[str, int]] = {}
        for i, (a, v) in enumerate(zip(ids_here, r, strict=True)):
            if v == "":
                continue
            seen = first_role.setdefault(str(a), (v, i))
            if seen[0] != v:
                raise fail(mapping["role"], int(rows[i]), f"agent {a} is {v!r} here but {seen[0]!r} at row "
                           f"{int(rows[seen[1]]) + 1}; the role must be constant per agent")
        robots = list(dict.fromkeys(str(a) for a, v in zip(ids_here, r, strict=True) if v == "robot"))
        if len(robots) > 1:
            i = next(i for i, (a, v) in enumerate(zip(ids_here, r, strict=True))
                     if v == "robot" and str(a) == robots[1])
            raise fail(mapping["role"], int(rows[i]), f"scene {name!r} has more than one robot "
                       f"({robots[0]}, {robots[1]})")
        if robots:
            logged = ids_here[next(i for i, v in enumerate(r) if v == "robot")]
    if robot is None:
        return logged
    # The same matching as --ego: as text, else as numbers (--robot 104 names an id logged as 104.0).
    unique = np.array(list(dict.fromkeys(ids_here.tolist())), dtype=object)
    match = unique[id_matches(unique, robot)].tolist()
    if not match:
        known = list(dict.fromkeys(str(a) for a in ids_here))
        raise KeyError(f"{path}: scene {name!r} has no agent with robot id {robot!r}; its ids: "
                       f"{', '.join(known[:10])}{' ...' if len(known) > 10 else ''}")
    if logged is not None and str(logged) != str(match[0]):
        warnings.warn(f"{path}: scene {name!r}: --robot {robot} overrides the role column, which names agent "
                      f"{logged} as the robot", AssumedValueWarning, stacklevel=4)
    return match[0]

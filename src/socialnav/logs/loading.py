"""Trajectory files of any supported format read into the trajectories to score.

:func:`load_trajectories` turns a file (the project's long format, a generic CSV/Parquet table, or an
ETH/UCY text file; :func:`detect_format` tells them apart) into
:class:`~socialnav.trajectory.Trajectory` objects: the logged robot's, or one per ego pedestrian
("human as robot"). Scoring them is :mod:`socialnav.logs.scoring`.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from socialnav.logs.readers import _ALIASES, ETH_UCY_FPS, FIELDS, MAX_SPEED, read_eth_ucy, read_table
from socialnav.logs.scene import Scene, SceneError, id_matches
from socialnav.trajectory import AssumedValueWarning, Trajectory, TrajectoryFormatError
from socialnav.trajectory_io.schema import OPTIONAL_COLUMNS, REQUIRED_COLUMNS

__all__ = ["FORMATS", "DataWarning", "check_speeds", "detect_format", "load_trajectories"]

FORMATS = ("auto", "long", "csv", "parquet", "eth-ucy")
"""``long``: the project's schema (docs/trajectory_format.md); ``csv``/``parquet``: any columns, mapped
with ``columns``; ``eth-ucy``: ``frame id x y`` text files."""


class DataWarning(UserWarning):
    """The data are suspicious but can still be scored (inconsistent outcome label, skipped agents)."""


def detect_format(path: str | Path, columns: Any = None) -> str:
    """The format of ``path`` for ``format="auto"``: by suffix, and for tables by their header."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix in (".txt", ".dat"):
        return "eth-ucy"
    if suffix not in (".csv", ".parquet", ".tsv"):
        raise TrajectoryFormatError(f"{path}: cannot tell the format from suffix {path.suffix!r}; pass "
                                    f"--format ({', '.join(FORMATS[1:])})")
    if columns:
        return "parquet" if suffix == ".parquet" else "csv"
    names = _header(path)
    if names is not None and all(c in names for c in REQUIRED_COLUMNS):
        return "long"
    return "parquet" if suffix == ".parquet" else "csv"


#: Columns of the long format that a generic table's fields (readers.FIELDS) do not include: a file
#: with some of them but not every required column is read as a table, with a note naming them.
LONG_ONLY = tuple(c for c in (*REQUIRED_COLUMNS, *OPTIONAL_COLUMNS) if c not in FIELDS and c not in _ALIASES)


def _header(path: Path) -> list[str] | None:
    if path.is_dir() or not path.exists() or path.stat().st_size == 0:
        return None  # the reader gives the precise error
    if path.suffix.lower() == ".parquet":
        try:
            import pyarrow.parquet as pq

            return list(pq.read_schema(path).names)
        except Exception:  # noqa: BLE001 - unreadable: let the reader report it
            return None
    with path.open("rb") as handle:
        line = handle.readline(65536)
    try:
        return [c.strip().strip('"') for c in line.decode("utf-8").strip().split(",")]
    except UnicodeDecodeError:
        return None


def load_trajectories(
    path: str | Path,
    *,
    format: str = "auto",
    ego: Any = None,
    columns: Any = None,
    robot: Any = None,
    radius: float | None = None,
    dt: float | None = None,
    resample: bool = False,
    max_gap: float | None = None,
    fps: float = ETH_UCY_FPS,
    max_speed: float = MAX_SPEED,
    length_unit: str = "m",
    time_unit: str = "s",
) -> list[Trajectory]:
    """Read ``path`` and return the trajectories to score.

    Without ``ego`` the logged robot of each scene is scored (long format: agent 0; tables: the
    ``robot`` id or the agent whose role is ``robot``). With ``ego=ID`` that agent, and with
    ``ego="all"`` every agent except the logged robot in turn, is scored as the robot against
    everyone else ("human as robot": start and goal are its observed first and last positions).

    Args:
        path: The file.
        format: One of :data:`FORMATS`.
        ego: None, an agent id, or ``"all"``.
        columns: Column mapping for ``csv``/``parquet`` (see :func:`socialnav.logs.read_table`).
        robot: Robot id for ``csv``/``parquet`` logs without a role column.
        radius: Radius for files without radii [m] (default 0.3 m with a warning).
        dt: Grid step [s] (default: the data's median step).
        resample: Long format only: interpolate irregular timestamps (other formats always do, with a
            note, since their clocks are rarely regular).
        max_gap: Longest gap in a track bridged by interpolation [s] (default: twice each agent's own
            median step when resampling, none on a regular clock). Tables and ETH/UCY only.
        fps: ETH/UCY frame numbers per second.
        max_speed: Reject faster steps as implausible [m/s].
        length_unit: Length unit of tables (``m``, ``cm`` or ``mm``).
        time_unit: Time unit of tables (``s``, ``ms``, ``us`` or ``ns``).

    Raises:
        TrajectoryFormatError: The file is unreadable or breaks its format (file, column, row named).
        KeyError: ``ego`` or ``robot`` names no agent.
        SceneError: An explicitly named ego cannot be scored (too short, or gaps).
    """
    if format not in FORMATS:
        raise ValueError(f"unknown format {format!r}; valid: {', '.join(FORMATS)}")
    path = Path(path)
    fmt = detect_format(path, columns) if format == "auto" else format
    if fmt != "long" and format == "auto" and path.is_dir():
        raise TrajectoryFormatError(f"{path}: is a directory, not a trajectory file")
    if max_gap is not None and not (np.isfinite(max_gap) and max_gap > 0):
        raise ValueError(f"--max-gap must be a finite number of seconds > 0, got {max_gap}")
    if not max_speed > 0:  # NaN included
        raise ValueError(f"--max-speed must be > 0 (inf disables the check), got {max_speed}")
    if fmt == "long":
        refuse_table_options(path, columns=columns, robot=robot, radius=radius, max_gap=max_gap,
                              length_unit=length_unit, time_unit=time_unit)
        from socialnav.trajectory_io import read_trajectories

        trajs = read_trajectories(path, resample=resample, dt=dt)
        check_speeds(path, trajs, max_speed)
        resampled = [tr for tr in trajs if tr.settings.get("resampled")]
        if resampled:
            steps = sorted({f"{tr.dt:g}" for tr in resampled})
            warnings.warn(f"{path}: {len(resampled)} of {len(trajs)} episode(s) linearly interpolated onto a "
                          f"{' / '.join(steps)} s grid (--resample)", AssumedValueWarning, stacklevel=2)
        for tr in trajs:
            tr.settings.setdefault("source", str(path))
        if ego is None:
            for tr in trajs:
                tr.settings.setdefault("scene", path.stem)  # a file is one scene, as for tables
            return trajs
        scene_of = {str(tr.settings.get("episode")): tr.settings.get("scene", path.stem) for tr in trajs}
        out = _select(path, [Scene.from_trajectory(tr, str(path)) for tr in trajs], ego)
        for tr in out:  # each episode is a recording to take egos from; the file is the summary's scene
            episode = tr.settings["scene"]
            tr.settings["episode"] = episode
            tr.settings["scene"] = scene_of.get(str(episode), path.stem)
        return out
    elif fmt == "eth-ucy":
        if columns or robot is not None:
            raise ValueError("ETH/UCY files have fixed columns (frame id x y) and no robot; use --ego")
        scenes = read_eth_ucy(path, fps=fps, radius=radius, dt=dt, max_gap=max_gap, max_speed=max_speed)
    else:
        expected = ".parquet" if fmt == "parquet" else ".csv"
        if path.suffix.lower() not in (expected, ".tsv" if fmt == "csv" else expected) and not path.is_dir():
            raise TrajectoryFormatError(f"{path}: --format {fmt} expects a {expected} file")
        if format == "auto" and not columns:
            _note_partial_long_format(path)
        scenes = read_table(path, columns, robot=robot, radius=radius, dt=dt, max_gap=max_gap,
                            max_speed=max_speed, length_unit=length_unit, time_unit=time_unit)
    for scene in scenes:
        if scene.resampled:
            why = (f"the requested step --dt {dt:g} s" if dt is not None else
                   "timestamps not on one clock shared by all agents (jitter, or agents logged at other "
                   "rates or times)")
            warnings.warn(f"{path}: scene {scene.name!r}: {why}, linearly interpolated onto a {scene.dt:g} s "
                          "grid", AssumedValueWarning, stacklevel=2)
    return _select(path, scenes, ego)


def _note_partial_long_format(path: Path) -> None:
    """Say so when a file with long-format columns lacks some required ones and is read as a table."""
    names = _header(path) or []
    kept = [c for c in LONG_ONLY if c in names]
    if kept:
        missing = [c for c in REQUIRED_COLUMNS if c not in names]
        warnings.warn(f"{path}: has columns of the long format but not its required {', '.join(missing)}: "
                      f"read as a generic table, whose fields do not include {', '.join(kept)} (not read)",
                      AssumedValueWarning, stacklevel=3)


def refuse_table_options(path: Path, **given: Any) -> None:
    """Options of generic tables that a long-format file would silently ignore: refused, named."""
    defaults = {"columns": None, "robot": None, "radius": None, "max_gap": None, "length_unit": "m",
                "time_unit": "s"}
    ignored = [f"--{k.replace('_', '-')}" for k, v in given.items() if v not in (defaults[k], "")]
    if ignored:
        raise ValueError(
            f"{path}: a file in the long format (docs/trajectory_format.md) is in metres and seconds and has "
            f"its own role and radius columns, so {', '.join(ignored)} would be ignored; to read it as a "
            "generic table instead, pass --format csv (or parquet) with them")


def check_speeds(path: Path, trajs: Iterable[Trajectory], max_speed: float) -> None:
    """Refuse a trajectory whose agent moves faster than ``max_speed`` between two present samples.

    Args:
        path: The file, for the message.
        trajs: Its trajectories.
        max_speed: The limit [m/s] (``inf`` disables the check).

    Raises:
        TrajectoryFormatError: The first such step, with the episode, agent, time and speed.
    """
    if not np.isfinite(max_speed):
        return
    for tr in trajs:
        step = np.linalg.norm(np.diff(tr.positions, axis=0), axis=-1) / tr.dt
        if tr.present is not None:
            step = np.where(tr.present[1:] & tr.present[:-1], step, 0.0)
        if step.size and float(step.max()) > max_speed:
            k, a = np.unravel_index(int(np.argmax(step > max_speed)), step.shape)
            ids = tr.settings.get("agent_ids")
            t0 = float(tr.settings.get("t0", 0.0))
            raise TrajectoryFormatError(
                f"{path}: episode {tr.settings.get('episode')!r}: agent {ids[a] if ids else a} moves at "
                f"{step[k, a]:.4g} m/s between t = {t0 + k * tr.dt:g} and {t0 + (k + 1) * tr.dt:g} s (limit "
                f"{max_speed:g} m/s): the long format is in metres and seconds (--max-speed to change the "
                "limit; --format csv with --length-unit/--time-unit for a file in other units)")


def _select(path: Path, scenes: list[Scene], ego: Any) -> list[Trajectory]:
    if ego is None:
        missing = [s.name for s in scenes if s.robot is None]
        if missing:
            raise ValueError(f"{path}: no robot in scene(s) {missing[:5]}: map a role column (--columns "
                             "role=...), pass --robot ID, or score pedestrians with --ego ID|all")
        return [s.robot_trajectory() for s in scenes]
    if str(ego) != "all":
        found = [s for s in scenes if id_matches(s.ids, ego).any()]
        if not found:
            ids = list(dict.fromkeys(str(i) for s in scenes for i in s.ids))
            raise KeyError(f"{path}: no agent with id {ego!r} in any scene; ids: {', '.join(ids[:20])}"
                           + (" ..." if len(ids) > 20 else ""))
        out = []
        for s in found:
            if s.robot is not None and s.index_of(ego) == s.robot:
                # the logged robot keeps its logged outcome and goal: scored as the robot
                warnings.warn(f"{path}: scene {s.name!r}: agent {ego} is the logged robot; scored as the "
                              f"robot (logged outcome {s.outcome!r}), not as a pedestrian",
                              AssumedValueWarning, stacklevel=3)
                out.append(s.robot_trajectory())
            else:
                out.append(s.ego_trajectory(ego))
        return out
    trajs = []
    for scene in scenes:
        skipped = []
        for a in range(scene.n_agents):
            if a == scene.robot:
                continue
            try:
                trajs.append(scene.trajectory(a, human_as_robot=True))
            except SceneError as err:
                skipped.append(str(err).split(": ", 1)[1])
        if skipped:
            warnings.warn(f"{path}: {len(skipped)} agent(s) not scored as ego: {skipped[0]}"
                          + (f" (and {len(skipped) - 1} more)" if len(skipped) > 1 else ""),
                          DataWarning, stacklevel=2)
    if not trajs:
        raise SceneError(f"{path}: no agent can be scored as ego (each needs >= 2 samples without gaps)")
    return trajs

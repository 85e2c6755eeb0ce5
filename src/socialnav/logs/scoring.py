"""Score trajectory files of any supported format: robot logs and "human as robot" pedestrian data.

:func:`load_trajectories` turns a file into :class:`~socialnav.trajectory.Trajectory` objects (the
logged robot's, or one per ego pedestrian); :func:`score_trajectories` scores them, checks logged
outcomes against the geometry, and summarises per scene and over the whole dataset. The
``socialnav metrics`` command is a thin layer over :func:`score_file`.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from socialnav.logs.readers import _ALIASES, ETH_UCY_FPS, FIELDS, MAX_SPEED, read_eth_ucy, read_table
from socialnav.logs.scene import Scene, SceneError, id_matches
from socialnav.metrics.obstacles import obstacle_clearance
from socialnav.trajectory import AssumedValueWarning, Trajectory, TrajectoryFormatError
from socialnav.trajectory_io.schema import OPTIONAL_COLUMNS, REQUIRED_COLUMNS

__all__ = [
    "FORMATS",
    "DataWarning",
    "LogScores",
    "detect_format",
    "load_trajectories",
    "outcome_problems",
    "score_file",
    "score_trajectories",
]

FORMATS = ("auto", "long", "csv", "parquet", "eth-ucy")
"""``long``: the project's schema (docs/trajectory_format.md); ``csv``/``parquet``: any columns, mapped
with ``columns``; ``eth-ucy``: ``frame id x y`` text files."""
ID_KEYS = ("source", "scene", "episode", "ego", "mode", "outcome")


class DataWarning(UserWarning):
    """The data are suspicious but can still be scored (inconsistent outcome label, skipped agents)."""


@dataclass
class LogScores:
    """Result of scoring a file: per-trajectory rows, summaries, and what was assumed or suspicious.

    Attributes:
        rows: One dict per trajectory: ``source``, ``scene``, ``episode``, ``ego``, ``mode``
            (``robot`` or ``human_as_robot``), ``outcome`` and every metric key of ``score_episode``.
        summaries: One dict per scene (``scope: "scene"``) and, with several scenes, one over the
            whole input (``scope: "dataset"``): ``episodes`` and per metric key ``<key>.mean``,
            ``.std``, ``.ci_low``, ``.ci_high``, ``.n``, as in the protocol's summary.
        notes: Values assumed or caveats (radius defaults, resampling, M_V), once each.
        warnings: Data problems found (scoring went on); ``socialnav metrics`` exits with 1 if any.
    """

    rows: list[dict[str, Any]]
    summaries: list[dict[str, Any]]
    notes: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)


# ------------------------------------------------------------------------------------ loading
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
        _refuse_table_options(path, columns=columns, robot=robot, radius=radius, max_gap=max_gap,
                              length_unit=length_unit, time_unit=time_unit)
        from socialnav.trajectory_io import read_trajectories

        trajs = read_trajectories(path, resample=resample, dt=dt)
        check_speeds(path, trajs, max_speed)
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
            warnings.warn(f"{path}: scene {scene.name!r}: timestamps not on one clock shared by all agents "
                          "(jitter, or agents logged at other rates or times), linearly interpolated onto "
                          f"a {scene.dt:g} s grid", AssumedValueWarning, stacklevel=2)
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


def _refuse_table_options(path: Path, **given: Any) -> None:
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


# ------------------------------------------------------------------------------------ checks
def outcome_problems(traj: Trajectory, goal_tolerance: float | None = None) -> list[str]:
    """Contradictions between a logged ``success`` and the geometry (empty when none).

    A successful robot neither overlaps a human at any sample (centre distance < r_r + r_h) nor, where
    the trajectory has a map, an obstacle, nor ends farther than ``goal_tolerance`` (default its radius,
    the simulator's success test) from its goal.
    """
    if traj.outcome != "success":
        return []
    where = _where(traj)
    out = []
    if traj.n_humans:
        pos = traj.positions
        d = np.linalg.norm(pos[:, 1:] - pos[:, :1], axis=-1) - traj.radii[1:] - traj.radii[0]
        d = np.where(traj.presence[:, 1:], d, np.inf)
        k, h = np.unravel_index(int(np.argmin(d)), d.shape)
        if d[k, h] < -1e-9:
            ids = traj.settings.get("agent_ids")
            who = ids[h + 1] if ids else h + 1
            out.append(f"{where}: labelled 'success' but the robot overlaps agent {who} at "
                       f"t = {k * traj.dt:g} s (clearance {d[k, h]:.3g} m)")
    clearance = obstacle_clearance(traj)  # None without a map
    if clearance is not None and clearance.size:
        k = int(np.argmin(clearance))
        if clearance[k] < -1e-9:  # samples 1..K
            out.append(f"{where}: labelled 'success' but the robot overlaps an obstacle at "
                       f"t = {(k + 1) * traj.dt:g} s (clearance {clearance[k]:.3g} m)")
    tol = float(traj.radii[0]) if goal_tolerance is None else float(goal_tolerance)
    miss = float(np.linalg.norm(traj.positions[-1, 0] - traj.goals[0]))
    if miss > tol + 1e-9:
        out.append(f"{where}: labelled 'success' but the robot ends {miss:.3g} m from its goal "
                   f"(tolerance {tol:g} m)")
    return out


def _where(traj: Trajectory) -> str:
    s = traj.settings
    parts = [str(s.get("source", "")), f"episode {s.get('episode', s.get('scene', '?'))!r}"]
    if s.get("mode") == "human_as_robot":
        parts.append(f"ego {s.get('ego')}")
    return ": ".join(p for p in parts if p)


# ------------------------------------------------------------------------------------ scoring
def score_trajectories(
    trajs: Iterable[Trajectory],
    *,
    require_success: bool = True,
    goal_tolerance: float | None = None,
    params: Any = None,
    label: str | None = None,
    summarize: bool = True,
) -> LogScores:
    """Score trajectories, check logged outcomes, summarise per scene and over all of them.

    Args:
        trajs: From :func:`load_trajectories` (or anywhere).
        require_success: Social metrics on successful episodes only (the paper's protocol). Episodes of
            unknown outcome then have NaN social metrics, which is reported once in ``warnings``.
        goal_tolerance: See :func:`outcome_problems`.
        params: Metric parameter overrides, as for ``score_episode``.
        label: Name of the scored agents in summaries (default ``human-as-robot`` or ``robot``).
        summarize: False leaves ``summaries`` empty (a worker scoring part of a file: the caller
            summarises all rows once).
    """
    from socialnav.metrics import score_episode, walking_speed_note
    from socialnav.metrics.score import UnknownOutcomeWarning

    if goal_tolerance is not None and not (np.isfinite(goal_tolerance) and goal_tolerance >= 0):
        raise ValueError(f"--goal-tolerance must be a finite distance >= 0 [m], got {goal_tolerance}")
    trajs = list(trajs)
    rows: list[dict[str, Any]] = []
    problems: list[str] = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnknownOutcomeWarning)  # reported once below, not per episode
        for i, tr in enumerate(trajs):
            s = tr.settings
            mode = s.get("mode", "robot")
            if mode != "human_as_robot":
                problems += outcome_problems(tr, goal_tolerance)
            rows.append({
                "source": str(s.get("source", "")), "scene": str(s.get("scene", s.get("episode", i))),
                "episode": str(s.get("episode", s.get("scene", i))), "ego": str(s.get("ego", "robot")),
                "mode": mode, "outcome": tr.outcome,
                **score_episode(tr, params, require_success=require_success),
            })
    notes = []
    unknown = sum(tr.outcome == "unknown" for tr in trajs)
    if unknown and require_success:
        problems.append(f"{unknown} episode(s) have outcome 'unknown': their social metrics (M_I-M_VI) are "
                        "NaN; score them with --all-episodes (require_success=False) or log the outcome")
    v_prefs = {float(tr.v_pref[0]) for tr in trajs if np.isfinite(tr.v_pref[0])}
    notes += sorted(filter(None, (walking_speed_note(v) for v in v_prefs)))
    for note in notes:
        warnings.warn(note, AssumedValueWarning if "v_pref" not in note else UserWarning, stacklevel=2)
    for problem in problems:
        warnings.warn(problem, DataWarning, stacklevel=2)
    label = label or _rows_label(rows)
    summaries = summarize_scores(rows, label) if summarize else []
    return LogScores(rows=rows, summaries=summaries, notes=notes, warnings=problems)


def summarize_scores(rows: Sequence[dict[str, Any]], label: str,
                     scene_summaries: dict[str, dict[str, Any]] | None = None) -> list[dict[str, Any]]:
    """Per-scene summaries, plus one over the dataset when there are several scenes.

    ``scene_summaries`` holds scenes already summarised (by a worker that had all their rows, with
    this label); the others are summarised here.
    """
    from socialnav.evaluate.summary import summarize_group

    by_scene = _metric_rows_by_scene(rows, label)
    done = scene_summaries or {}
    out = [done.get(scene) or {"scope": "scene", **summarize_group((label, scene, "-"), members)}
           for scene, members in by_scene.items()]
    if len(by_scene) > 1:
        everything = [m for members in by_scene.values() for m in members]
        out.append({"scope": "dataset", **summarize_group((label, "dataset", "-"), everything,
                                                          pooled_over=sorted(by_scene))})
    return out


def _metric_rows_by_scene(rows: Sequence[dict[str, Any]], label: str) -> dict[str, list[dict[str, Any]]]:
    sources: dict[str, set[str]] = {}
    for row in rows:
        sources.setdefault(row["scene"], set()).add(row["source"])
    by_scene: dict[str, list[dict[str, Any]]] = {}
    for i, row in enumerate(rows):
        # two files with the same scene name (d1/run.csv, d2/run.csv) are two scenes
        scene = row["scene"] if len(sources[row["scene"]]) == 1 else f"{row['scene']} ({row['source']})"
        metric_row = {"policy": label, "scenario": scene, "visibility": "-", "index": i,
                      "outcome": row["outcome"], **{k: v for k, v in row.items() if k not in ID_KEYS}}
        by_scene.setdefault(scene, []).append(metric_row)
    return by_scene


def _rows_label(rows: Sequence[dict[str, Any]]) -> str:
    return "human-as-robot" if {r["mode"] for r in rows} == {"human_as_robot"} else "robot"


def score_file(
    path: str | Path,
    *,
    require_success: bool = True,
    goal_tolerance: float | None = None,
    params: Any = None,
    workers: int = 0,
    **load_kwargs: Any,
) -> LogScores:
    """:func:`load_trajectories` then :func:`score_trajectories`; the Python twin of ``socialnav metrics``.

    Notes and warnings raised while loading (assumed radii, resampling, skipped egos) are collected
    into the result as well as re-issued.

    Args:
        path: The trajectory file (CSV or Parquet; see docs/real_world_logs.md).
        require_success: Social metrics only over successful episodes.
        goal_tolerance: Distance to the goal [m] that counts as arrival (None: the agent's radius, as the
            simulator's success test; see :func:`outcome_problems`).
        params: Metric parameter overrides (None: the registered defaults).
        workers: Processes that read and score disjoint sets of episodes of a long-format file
            (0: in this process). Rows come back in file order, so the result does not depend on it.
        **load_kwargs: Passed to :func:`load_trajectories` (format, columns, ego, ...).

    Returns:
        The per-episode metric rows with their notes and warnings.
    """
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if workers > 1 and load_kwargs.get("ego") is None and detect_format(
                path, load_kwargs.get("columns")) == "long" and load_kwargs.get("format", "auto") in (
                "auto", "long"):
            _refuse_table_options(Path(path), columns=None, robot=load_kwargs.get("robot"),
                                  radius=load_kwargs.get("radius"), max_gap=load_kwargs.get("max_gap"),
                                  length_unit=load_kwargs.get("length_unit", "m"),
                                  time_unit=load_kwargs.get("time_unit", "s"))
            scores = _score_parallel(Path(path), workers, require_success, goal_tolerance, params,
                                     load_kwargs)
        else:
            trajs = load_trajectories(path, **load_kwargs)
            scores = score_trajectories(trajs, require_success=require_success,
                                        goal_tolerance=goal_tolerance, params=params)
    for w in caught:
        text = str(w.message)
        if issubclass(w.category, DataWarning):
            if text not in scores.warnings:
                scores.warnings.append(text)
        elif text not in scores.notes:
            scores.notes.append(text)
    for w in caught:
        warnings.warn(w.message, w.category, stacklevel=2)
    return scores


def _episode_keys(path: Path) -> tuple[list[Any], np.ndarray | None]:
    """The file's episode keys in order of first appearance, and where each one's rows start.

    ``starts`` is given when every episode is one block of rows (then it has one more entry, the row count).
    """
    import pyarrow as pa

    if path.suffix.lower() == ".parquet":
        import pyarrow.parquet as pq

        col = pq.read_table(path, columns=["episode"]).column("episode")
    else:
        import pyarrow.csv as pcsv

        col = pcsv.read_csv(path, convert_options=pcsv.ConvertOptions(include_columns=["episode"])).column(
            "episode")
    if not pa.types.is_integer(col.type):
        col = col.cast(pa.string())
    values = col.to_numpy(zero_copy_only=False)
    _, first = np.unique(values, return_index=True)
    first = np.sort(first)
    keys = [v.item() if hasattr(v, "item") else v for v in values[first]]
    changes = np.flatnonzero(values[1:] != values[:-1]) + 1 if len(values) else np.zeros(0, dtype=int)
    contiguous = len(changes) + 1 == len(first) if len(values) else False
    starts = np.concatenate([[0], changes, [len(values)]]) if contiguous else None
    return keys, starts


def _score_chunk(path: str, keys: list[Any], rows: tuple[int, int] | None, require_success: bool,
                 goal_tolerance: float | None, params: Any, load_kwargs: dict[str, Any]
                 ) -> tuple[list[dict], list[str], list[str], str, dict[str, dict[str, Any]]]:
    """Score one share of a file and summarise its scenes.

    Scenes are summarised under the label their own rows give; the caller keeps the summary of every scene
    that lies wholly in this share.
    """
    from socialnav.evaluate.summary import summarize_group
    from socialnav.trajectory_io import read_trajectories

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        # a block of rows when the file's episodes are contiguous (a slice), else the keys (a mask)
        trajs = read_trajectories(path, resample=load_kwargs.get("resample", False), dt=load_kwargs.get("dt"),
                                  episodes=None if rows is not None else keys, rows=rows)
        check_speeds(Path(path), trajs, load_kwargs.get("max_speed", MAX_SPEED))
        for tr in trajs:
            tr.settings.setdefault("source", path)
            tr.settings.setdefault("scene", Path(path).stem)
        scores = score_trajectories(trajs, require_success=require_success, goal_tolerance=goal_tolerance,
                                    params=params, summarize=False)
    notes = [str(w.message) for w in caught if not issubclass(w.category, DataWarning)]
    label = _rows_label(scores.rows) if scores.rows else "robot"
    summaries = {scene: {"scope": "scene", **summarize_group((label, scene, "-"), members)}
                 for scene, members in _metric_rows_by_scene(scores.rows, label).items()}
    return scores.rows, notes, scores.warnings, label, summaries


def _score_parallel(path: Path, workers: int, require_success: bool, goal_tolerance: float | None,
                    params: Any, load_kwargs: dict[str, Any]) -> LogScores:
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    keys, starts = _episode_keys(path)
    if not keys:  # nothing to share out: the reader in this process reports the empty file
        return score_trajectories(load_trajectories(path, **load_kwargs), require_success=require_success,
                                  goal_tolerance=goal_tolerance, params=params)
    bounds = [int(b[0]) for b in np.array_split(np.arange(len(keys)), workers) if len(b)] + [len(keys)]
    chunks = [(keys[a:b], None if starts is None else (int(starts[a]), int(starts[b])))
              for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
    ctx = multiprocessing.get_context("forkserver")  # pyarrow's threads make a plain fork unsafe
    with ProcessPoolExecutor(max_workers=len(chunks), mp_context=ctx) as pool:
        futures = [pool.submit(_score_chunk, str(path), c, rows, require_success, goal_tolerance, params,
                               load_kwargs) for c, rows in chunks]
        try:
            results = [f.result() for f in futures]
        except (ValueError, KeyError):
            results = None
    if results is None:  # read again in this process for the error message with the file's row numbers
        load_trajectories(path, **load_kwargs)
        raise TrajectoryFormatError(f"{path}: invalid (see the worker's error)")
    rows = [r for res in results for r in res[0]]
    notes = list(dict.fromkeys(n for res in results for n in res[1]))
    problems = list(dict.fromkeys(p for res in results for p in res[2]))
    for note in notes:
        warnings.warn(note, UserWarning, stacklevel=3)
    for problem in problems:
        warnings.warn(problem, DataWarning, stacklevel=3)
    label = _rows_label(rows)
    # a scene's summary from a worker holds when the worker had all its rows and the same label
    shares: dict[str, int] = {}
    for res in results:
        for scene in res[4]:
            shares[scene] = shares.get(scene, 0) + 1
    done = {scene: summary for res in results if res[3] == label
            for scene, summary in res[4].items() if shares[scene] == 1}
    return LogScores(rows=rows, summaries=summarize_scores(rows, label, done), notes=notes, warnings=problems)

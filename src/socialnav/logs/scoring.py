"""Scoring trajectories of robot logs and "human as robot" pedestrian data.

:func:`score_trajectories` scores trajectories (from :func:`~socialnav.logs.loading.load_trajectories`
or anywhere), checks logged outcomes against the geometry, and summarises per scene and over the whole
dataset; :func:`score_file` loads and scores a file, sharing a long-format file's episodes out to
worker processes. The ``socialnav metrics`` command is a thin layer over :func:`score_file`.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from socialnav.logs.loading import (
    DataWarning,
    check_speeds,
    detect_format,
    load_trajectories,
    refuse_table_options,
)
from socialnav.logs.readers import MAX_SPEED
from socialnav.metrics.obstacles import obstacle_clearance
from socialnav.trajectory import AssumedValueWarning, Trajectory, TrajectoryFormatError

__all__ = ["LogScores", "outcome_problems", "score_file", "score_trajectories"]

ID_KEYS = ("source", "scene", "episode", "ego", "mode", "outcome")


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
            refuse_table_options(Path(path), columns=None, robot=load_kwargs.get("robot"),
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

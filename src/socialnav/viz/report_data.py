"""The report's data: result runs read back, and the episode viewer's embedded data.

Layout of the viewer's data (``<script id="episode-data" type="application/json">`` in the page)::

    {"scale": 1000, "eps": 0.2, "tau": 1.0,
     "metrics": [{"key", "label", "direction"}],        # ranking metrics of the viewer
     "metric_labels": {key: label},
     "cells": [{"policy", "scenario", "visibility", "episodes": [episode indices],
                "picks": {metric key: {"best"|"median"|"worst": episode index}}}],
     "episodes": [{"id", "policy", "outcome", "dt", "n_main", "radii", "goals",
                   "pos": [x, y per (sample, agent), integers in 1/scale m],
                   "m1"|"m2"|"collision": "0101…" per sample, "side": [sample, label] | null,
                   "values": {metric key: value},
                   "walls": [[x, y, x, y, ...] per polygon, integers in 1/scale m],
                   "routes": {agent index: [x, y, x, y, ...], integers in 1/scale m}}]}
                                                    # walls: only with a static map; 2 vertices = a segment
                                                    # routes: only where an agent's route bends
                                                    # (socialnav/viz/routes.py): start, points, goal
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from socialnav.trajectory import Trajectory
from socialnav.viz.routes import Routes, episode_routes, resolve_routes

# (key prefix, label, direction) — what the viewer can rank a cell's episodes by
RANKING_METRICS = (
    ("navigation_time", "navigation time (s)", "lower"),
    ("min_clearance", "minimum clearance (m)", "higher"),
    ("m1_personal_space.duration_s@eps=0.2,", "M_I ε=0.2 m (s)", "lower"),
    ("m2_projected_path.duration_s@tau=1,", "M_II τ=1 s (s)", "lower"),
    ("m3_aggregated_time.time_s@", "M_III (s)", "lower"),
    ("m4_jerk.mean_sq", "M_IV jerk ((m/s³)²)", "lower"),
)
SCALE = 1000  # positions embedded in millimetres: exact to the drawing's resolution, compact JSON
FAILURES_SHOWN = 3  # collision/timeout episodes added to each cell's viewer list


class ResultRun:
    """One result directory of ``socialnav evaluate``, as the report reads it.

    Args:
        path: The result directory.

    Attributes:
        path: The result directory.
        manifest: Its manifest (policy, preset, run settings).
        rows: Its episodes' result rows (flat metric keys).
        summary: Its ``summary.json`` (aggregated rows).
        label: The policy's display label (made unique by :meth:`relabel` among several runs).
    """

    def __init__(self, path: Path):
        """Reads the run's manifest, episode rows and summary.

        Raises:
            ValueError: The run has no finished episode or no summary.json yet.
        """
        from socialnav.evaluate.results import load_episode_rows, load_manifest

        self.path = path
        self.manifest = load_manifest(path)
        self.rows = load_episode_rows(path)
        if not self.rows:
            raise ValueError(f"{path}: no finished episodes yet (episodes/ is empty)")
        summary_path = path / "summary.json"
        if not summary_path.is_file():
            raise ValueError(
                f"{path}: no summary.json (the run has not finished; run `socialnav evaluate` again)"
            )
        self.summary = read_summary(summary_path, self.rows)
        self.label = str(self.manifest.get("policy", {}).get("label") or self.rows[0]["policy"])

    def relabel(self, label: str) -> None:
        """Shows the run under ``label`` in every table, figure and viewer list."""
        self.label = label
        for r in self.rows:
            r["policy"] = label
        for r in self.summary["rows"]:
            r["policy"] = label


#: The summary rows' text fields and flags; every other field is a number or null.
_TEXT_FIELDS = ("policy", "scenario", "visibility", "information", "pooled_over")
_FLAG_FIELDS = ("single_human",)


def read_summary(path: Path, rows: list[dict[str, Any]]) -> dict[str, Any]:
    """A run's ``summary.json``, checked against its episode rows.

    Args:
        path: The file.
        rows: The run's episode result rows (``episodes/``).

    Returns:
        The summary (``rows`` and the run's other records).

    Raises:
        ValueError: The file is not valid JSON, not a summary (a field of the wrong type is named), or
            stale: a cell's episode count differs from ``episodes/`` (a chunk deleted or added since).
    """
    again = "run the same `socialnav evaluate` command again to rewrite it"
    try:
        data = json.loads(path.read_text())
    except (ValueError, UnicodeDecodeError) as err:
        raise ValueError(f"{path}: not valid JSON ({err}); {again}") from None
    summary_rows = data.get("rows") if isinstance(data, dict) else None
    if not isinstance(summary_rows, list) or not all(isinstance(r, dict) for r in summary_rows):
        raise ValueError(f"{path}: not a summary of `socialnav evaluate` (expected an object whose 'rows' "
                         f"is a list of objects); {again}")
    counts: dict[tuple[str, str], int] = {}
    for r in rows:
        key = (str(r.get("scenario")), str(r.get("visibility")))
        counts[key] = counts.get(key, 0) + 1
    for i, r in enumerate(summary_rows):
        for field in ("policy", "scenario", "visibility"):
            if not isinstance(r.get(field), str):
                raise ValueError(f"{path}: rows[{i}].{field} must be text, got {r.get(field)!r}; {again}")
        for key, value in r.items():
            if key in _FLAG_FIELDS and not isinstance(value, bool):
                raise ValueError(f"{path}: rows[{i}] ({r['scenario']}/{r['visibility']}).{key} must be true "
                                 f"or false, got {value!r}; {again}")
            if key not in _TEXT_FIELDS + _FLAG_FIELDS and value is not None and (
                    isinstance(value, bool) or not isinstance(value, int | float)):
                raise ValueError(f"{path}: rows[{i}] ({r['scenario']}/{r['visibility']}).{key} must be a "
                                 f"number or null, got {value!r}; {again}")
        if r["scenario"] == "pooled":
            continue
        have = counts.get((r["scenario"], r["visibility"]), 0)
        if r.get("episodes") != have:
            raise ValueError(f"{path}: stale: {r['scenario']}/{r['visibility']} has {r.get('episodes')} "
                             f"episodes in the summary but {have} in episodes/ (a chunk deleted or added "
                             f"since); {again}")
    return data


def ranked_picks(cell_rows: list[dict[str, Any]], key: str, direction: str, n: int) -> dict[str, str]:
    """The episodes of one cell at ``n`` evenly spaced ranks of one metric, best first.

    Args:
        cell_rows: The cell's episode rows.
        key: The metric's flat key.
        direction: "lower" or "higher" (which values are better).
        n: Ranks wanted (3: best, median, worst; others are named ``q0.25`` and so on).

    Returns:
        {rank name: episode id}; empty when no row has a finite value of the metric.
    """
    vals = [
        (r[key], r["episode_id"])
        for r in cell_rows
        if isinstance(r.get(key), int | float) and math.isfinite(r[key])
    ]
    if not vals:
        return {}
    vals.sort(key=lambda v: (v[0], v[1]), reverse=direction == "higher")
    names = {0: "best", n - 1: "worst"} if n >= 2 else {0: "best"}
    if n % 2 == 1 and n >= 3:
        names[n // 2] = "median"
    picks = {}
    for j, q in enumerate(np.linspace(0, 1, n) if n > 1 else [0.0]):
        picks[names.get(j, f"q{q:.2f}")] = vals[int(round(q * (len(vals) - 1)))][1]
    return picks


def viewer_data(runs: list[ResultRun], per_metric: int, eps: float, tau: float) -> dict[str, Any] | None:
    """The viewer's embedded episode data of a report (layout: the module docstring).

    Args:
        runs: The report's runs.
        per_metric: Episodes per ranking metric and cell (see :func:`ranked_picks`).
        eps: M_I threshold [m] of the overlays.
        tau: M_II horizon [s] of the overlays.

    Returns:
        The data, or None when no run stored trajectories.
    """
    from socialnav.evaluate.results import ResultsError, find_episode
    from socialnav.trajectory_io import read_trajectories

    metrics, cells, wanted = [], [], {}  # wanted: run index -> {episode id}
    all_rows = [r for run in runs for r in run.rows]
    from socialnav.viz.figures import metric_key

    for prefix, label, direction in RANKING_METRICS:
        key = metric_key(all_rows, prefix)
        if key is not None:
            metrics.append({"key": key, "label": label, "direction": direction})
    for i, run in enumerate(runs):
        by_cell: dict[tuple[str, str], list[dict[str, Any]]] = {}
        for r in run.rows:
            by_cell.setdefault((r["scenario"], r["visibility"]), []).append(r)
        for (scenario, visibility), cell_rows in by_cell.items():
            picks = {
                m["key"]: ranked_picks(cell_rows, m["key"], m["direction"], per_metric) for m in metrics
            }
            ids = [e for p in picks.values() for e in p.values()]
            ids += [r["episode_id"] for r in cell_rows if r["outcome"] != "success"][:FAILURES_SHOWN]
            ids = list(dict.fromkeys(ids))
            wanted.setdefault(i, set()).update(ids)
            cells.append(
                {
                    "run": i,
                    "policy": run.label,
                    "scenario": scenario,
                    "visibility": visibility,
                    "ids": ids,
                    "picks": picks,
                }
            )
    episodes, index = [], {}
    metric_keys = [m["key"] for m in metrics]
    for i, run in enumerate(runs):
        row_of = {r["episode_id"]: r for r in run.rows}
        by_file: dict[Path, list[str]] = {}
        try:
            for eid in sorted(wanted.get(i, ())):
                by_file.setdefault(find_episode(run.path, eid).path, []).append(eid)
        except ResultsError:
            continue  # a run without stored trajectories: tables and figures only
        for path, ids in by_file.items():
            for traj in read_trajectories(path, episodes=ids):
                eid = str(traj.settings["episode"])
                index[(i, eid)] = len(episodes)
                episodes.append(episode_json(traj, run.label, eps, tau, row_of.get(eid, {}), metric_keys,
                                             routes=episode_routes(traj, run.manifest)))
    out_cells = []
    for c in cells:
        eps_idx = [index[(c["run"], e)] for e in c["ids"] if (c["run"], e) in index]
        if not eps_idx:
            continue
        picks = {
            k: {w: index[(c["run"], e)] for w, e in p.items() if (c["run"], e) in index}
            for k, p in c["picks"].items()
        }
        out_cells.append(
            {
                "policy": c["policy"],
                "scenario": c["scenario"],
                "visibility": c["visibility"],
                "episodes": eps_idx,
                "picks": picks,
            }
        )
    if not episodes:
        return None
    return {
        "scale": SCALE,
        "eps": eps,
        "tau": tau,
        "metrics": metrics,
        "metric_labels": {m["key"]: m["label"] for m in metrics},
        "cells": out_cells,
        "episodes": episodes,
    }


def _bits(flags: np.ndarray) -> str:
    return "".join("1" if f else "0" for f in flags)


def episode_json(
    traj: Trajectory,
    policy: str,
    eps: float,
    tau: float,
    row: dict[str, Any],
    metric_keys: list[str],
    routes: Routes = True,
) -> dict[str, Any]:
    """One episode as the viewer draws it (an entry of ``episodes`` in the module docstring).

    Args:
        traj: The episode.
        policy: The label it is listed under.
        eps: M_I threshold [m] of its personal-space flags.
        tau: M_II horizon [s] of its projected-path flags.
        row: Its result row (metric values), possibly empty.
        metric_keys: Flat keys of the values to show beside it.
        routes: The agents' routes around the walls (:mod:`socialnav.viz.routes`): True, those the
            trajectory records enough to plan; False, none; or routes already planned.

    Returns:
        The JSON-ready dict (positions, walls and routes as integers in 1/``SCALE`` m).
    """
    from socialnav.viz.geometry import episode_view

    view = episode_view(traj, eps, tau)
    values = {}
    for k in metric_keys:
        v = row.get(k)
        if isinstance(v, int | float) and math.isfinite(v):
            values[k] = round(float(v), 4)
    among_walls: dict[str, Any] = {}  # walls and routes: only where the episode has walls
    if traj.static_map is not None:
        among_walls["walls"] = [np.rint(p * SCALE).astype(np.int64).reshape(-1).tolist()
                          for p in traj.static_map.polygons]
    drawn = resolve_routes(traj, routes)
    if drawn:
        among_walls["routes"] = {str(a): np.rint(line * SCALE).astype(np.int64).reshape(-1).tolist()
                           for a, line in sorted(drawn.items())}
    return {
        "id": str(traj.settings.get("episode", "")),
        "policy": policy,
        "outcome": traj.outcome,
        "dt": traj.dt,
        "n_main": view.n_main,
        "radii": [round(float(r), 4) for r in traj.radii],
        "goals": np.round(traj.goals, 3).tolist(),
        "pos": _scaled_or_null(view.positions),
        "m1": _bits(view.m1),
        "m2": _bits(view.m2),
        "collision": _bits(view.collision),
        "side": list(view.side) if view.side else None,
        "values": values,
        **among_walls,
    }


def _scaled_or_null(positions: np.ndarray) -> list[int | None]:
    """Positions as integers in 1/SCALE m, None (JSON null) where an agent is not in view (NaN in a log)."""
    flat = np.asarray(positions, dtype=np.float64).reshape(-1)
    finite = np.isfinite(flat)
    scaled = np.rint(np.where(finite, flat, 0.0) * SCALE).astype(np.int64).tolist()
    return [v if ok else None for v, ok in zip(scaled, finite.tolist(), strict=True)]


def single_episode_data(
    traj: Trajectory, *, eps: float = 0.2, tau: float = 1.0, routes: Routes = True
) -> dict[str, Any]:
    """The viewer's data for one episode alone (``socialnav render --format html``).

    Args:
        traj: The episode.
        eps: M_I threshold [m] of the overlays.
        tau: M_II horizon [s] of the overlays.
        routes: The agents' routes, as :func:`episode_json` takes them.

    Returns:
        The data (layout: the module docstring), one cell of one episode ranked by navigation time.
    """
    metrics = [{"key": "navigation_time", "label": "navigation time (s)", "direction": "lower"}]
    ep = episode_json(
        traj,
        str(traj.settings.get("policy", "")),
        eps,
        tau,
        {"navigation_time": traj.duration},
        ["navigation_time"],
        routes=routes,
    )
    return {
        "scale": SCALE,
        "eps": eps,
        "tau": tau,
        "metrics": metrics,
        "metric_labels": {"navigation_time": "navigation time (s)"},
        "cells": [
            {
                "policy": ep["policy"] or "episode",
                "scenario": str(traj.settings.get("scenario", "")),
                "visibility": str(traj.settings.get("visibility", "")),
                "episodes": [0],
                "picks": {},
            }
        ],
        "episodes": [ep],
    }

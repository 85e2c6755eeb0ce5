"""One self-contained HTML report of one or more evaluations (`socialnav report`, `evaluate --report`).

Everything is inside the file (figures as base64 PNG, episode data as JSON, the viewer's plain
JavaScript), so it opens offline and can be mailed as it is. Layout of the embedded episode data
(``<script id="episode-data" type="application/json">``)::

    {"scale": 1000, "eps": 0.2, "tau": 1.0,
     "metrics": [{"key", "label", "direction"}],        # ranking metrics of the viewer
     "metric_labels": {key: label},
     "cells": [{"policy", "scenario", "visibility", "episodes": [episode indices],
                "picks": {metric key: {"best"|"median"|"worst": episode index}}}],
     "episodes": [{"id", "policy", "outcome", "dt", "n_main", "radii", "goals",
                   "pos": [x, y per (sample, agent), integers in 1/scale m],
                   "m1"|"m2"|"collision": "0101…" per sample, "side": [sample, label] | null,
                   "values": {metric key: value},
                   "walls": [[x, y, x, y, ...] per polygon, integers in 1/scale m]}]}
                                                    # walls: only with a static map; 2 vertices = a segment
"""

from __future__ import annotations

import base64
import datetime as _dt
import html
import json
import math
from collections.abc import Sequence
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from socialnav.trajectory import Trajectory

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


class _Run:
    def __init__(self, path: Path):
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
        self.summary = json.loads(summary_path.read_text())
        self.label = str(self.manifest.get("policy", {}).get("label") or self.rows[0]["policy"])

    def relabel(self, label: str) -> None:
        self.label = label
        for r in self.rows:
            r["policy"] = label
        for r in self.summary["rows"]:
            r["policy"] = label


def write_report(
    results: Path | str | Sequence[Path | str],
    out: Path | str,
    *,
    curves: Sequence[Path | str] = (),
    viewer_episodes: int = 3,
    figure_files: bool = True,
    eps: float = 0.2,
    tau: float = 1.0,
    progress: bool = False,
) -> dict[str, Any]:
    """Writes the report of one or more result directories (one per policy) to ``out`` (atomic).

    Args:
        results: Result directories of ``socialnav evaluate``.
        out: The HTML file.
        curves: Training ``curves.csv`` files to plot; a checkpoint's own run directory is looked up
            too (``curves.csv`` beside the checkpoint).
        viewer_episodes: Episodes per metric and cell in the viewer, evenly spaced from best to worst
            (3: best, median, worst); 0 leaves the viewer out.
        figure_files: Also write every figure as PNG and SVG under ``figures/`` beside ``out``.
        eps, tau: M_I threshold [m] and M_II horizon [s] of the viewer's overlays.

    Returns:
        ``{"bytes": size of the file, "viewer_episodes": episodes embedded, "figures": count}``.
    """
    from tqdm.auto import tqdm

    from socialnav._io import atomic_write_text
    from socialnav.viz import require_viz

    require_viz()
    paths = [Path(results)] if isinstance(results, str | Path) else [Path(p) for p in results]
    if not paths:
        raise ValueError("report: give at least one result directory")
    out = Path(out)
    bar = tqdm(total=4, desc="report", unit="part", disable=not progress, leave=False)
    runs = [_Run(p) for p in paths]
    labels = [r.label for r in runs]
    for run in runs:
        if labels.count(run.label) > 1:
            run.relabel(f"{run.label} ({run.path.name})")
    rows = [row for run in runs for row in run.rows]
    summary = [row for run in runs for row in run.summary["rows"]]
    bar.update(1)

    tables = _tables_html(summary)
    bar.set_description("report: figures")
    figures = _figures(rows, runs, list(curves), out.parent / "figures" if figure_files else None)
    bar.update(1)
    bar.set_description("report: episodes")
    data = _viewer_data(runs, viewer_episodes, eps, tau) if viewer_episodes > 0 else None
    bar.update(1)
    page = _page(runs, tables, figures, data)
    atomic_write_text(out, page)
    bar.update(1)
    bar.close()
    return {
        "bytes": out.stat().st_size,
        "viewer_episodes": 0 if data is None else len(data["episodes"]),
        "figures": len(figures),
    }


# ------------------------------------------------------------------------------------------ tables
def md_tables_to_html(md: str) -> str:
    """The Markdown tables written by socialnav.evaluate.report (### title + pipe table) as HTML."""
    parts, title, rows = [], None, []

    def flush() -> None:
        if title is None and not rows:
            return
        head, body = (rows[0], rows[1:]) if rows else ([], [])
        parts.append(
            f"<h3>{html.escape(title or '')}</h3><table class='results'><thead><tr>"
            + "".join(f"<th>{html.escape(c)}</th>" for c in head)
            + "</tr></thead><tbody>"
            + "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in r) + "</tr>" for r in body)
            + "</tbody></table>"
        )

    for line in md.splitlines():
        if line.startswith("### "):
            flush()
            title, rows = line[4:].strip(), []
        elif line.startswith("|") and not set(line) <= set("|-: "):
            rows.append([c.strip() for c in line.strip().strip("|").split("|")])
    flush()
    return "\n".join(parts)


def _tables_html(summary: list[dict[str, Any]]) -> str:
    from socialnav.evaluate.report import table2, table3

    return md_tables_to_html(table2(summary, "md")) + md_tables_to_html(table3(summary, "md"))


# ----------------------------------------------------------------------------------------- figures
def _figures(rows, runs, curves: list, files_dir: Path | None) -> list[tuple[str, str, bytes]]:
    """(name, caption, png bytes) of every figure; also written as PNG+SVG under ``files_dir``."""
    from socialnav.viz.figures import (
        DISTRIBUTION_METRICS,
        figure_png_bytes,
        metric_distribution,
        metric_key,
        outcome_bars,
        read_curves,
        save_figure,
        side_bars,
        training_curves,
    )

    made = [("outcomes", "Outcomes per scenario and policy", outcome_bars(rows))]
    side = side_bars(rows)
    if side is not None:
        made.append(("side_preference", "M_VI side preference per single-human scenario", side))
    for prefix, label, visibility in DISTRIBUTION_METRICS:
        key = metric_key(rows, prefix)
        if key is None or not any(r["visibility"] == visibility and r.get("side") is None for r in rows):
            continue
        name = "dist_" + prefix.split(".")[0].split("@")[0]
        if "eps=1.2" in prefix:
            name += "_eps1.2"
        made.append(
            (
                name,
                f"{label}: distribution per scenario and policy ({key})",
                metric_distribution(rows, prefix, label, visibility),
            )
        )
    curve_files = [Path(c) for c in curves]
    for run in runs:
        ckpt = run.manifest.get("checkpoint") or run.manifest.get("policy", {}).get("checkpoint")
        if ckpt and (Path(ckpt).parent / "curves.csv").is_file():
            curve_files.append(Path(ckpt).parent / "curves.csv")
    for i, path in enumerate(dict.fromkeys(curve_files)):
        made.append(
            (
                f"training_curves_{i}",
                f"Training curves: {path}",
                training_curves(read_curves(path), f"Training curves ({path.parent.name})"),
            )
        )
    out = []
    for name, caption, fig in made:
        if files_dir is not None:
            files_dir.mkdir(parents=True, exist_ok=True)
            save_figure(fig, files_dir / name)
        out.append((name, caption, figure_png_bytes(fig)))
    return out


# ---------------------------------------------------------------------------------------- episodes
def _ranked_picks(cell_rows: list[dict[str, Any]], key: str, direction: str, n: int) -> dict[str, str]:
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


def _viewer_data(runs: list[_Run], per_metric: int, eps: float, tau: float) -> dict[str, Any] | None:
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
                m["key"]: _ranked_picks(cell_rows, m["key"], m["direction"], per_metric) for m in metrics
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
                episodes.append(_episode_json(traj, run.label, eps, tau, row_of.get(eid, {}), metric_keys))
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


def _episode_json(
    traj: Trajectory, policy: str, eps: float, tau: float, row: dict[str, Any], metric_keys: list[str]
) -> dict[str, Any]:
    from socialnav.viz.geometry import episode_view

    view = episode_view(traj, eps, tau)
    values = {}
    for k in metric_keys:
        v = row.get(k)
        if isinstance(v, int | float) and math.isfinite(v):
            values[k] = round(float(v), 4)
    walls = {}
    if traj.static_map is not None:
        walls["walls"] = [np.rint(p * SCALE).astype(np.int64).reshape(-1).tolist()
                          for p in traj.static_map.polygons]
    return {
        "id": str(traj.settings.get("episode", "")),
        "policy": policy,
        "outcome": traj.outcome,
        "dt": traj.dt,
        "n_main": view.n_main,
        "radii": [round(float(r), 4) for r in traj.radii],
        "goals": np.round(traj.goals, 3).tolist(),
        "pos": np.rint(view.positions * SCALE).astype(np.int64).reshape(-1).tolist(),
        "m1": _bits(view.m1),
        "m2": _bits(view.m2),
        "collision": _bits(view.collision),
        "side": list(view.side) if view.side else None,
        "values": values,
        **walls,
    }


def episode_page(traj: Trajectory, *, eps: float = 0.2, tau: float = 1.0) -> str:
    """A self-contained page with the viewer for one episode (`socialnav render --format html`)."""
    from socialnav.viz.draw import describe_episode

    metrics = [{"key": "navigation_time", "label": "navigation time (s)", "direction": "lower"}]
    ep = _episode_json(
        traj,
        str(traj.settings.get("policy", "")),
        eps,
        tau,
        {"navigation_time": traj.duration},
        ["navigation_time"],
    )
    data = {
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
    body = f"<h1>{html.escape(describe_episode(traj))}</h1>" + _viewer_html(data)
    return _document("socialnav episode " + html.escape(ep["id"]), body)


# -------------------------------------------------------------------------------------------- page
_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:0 auto;max-width:1280px;
padding:1em 2em;color:#222}
h1{font-size:1.5em}h2{border-bottom:1px solid #ccc;padding-bottom:.2em;margin-top:1.6em}
h3{font-size:1em;margin-bottom:.3em}
table.results{border-collapse:collapse;font-size:.85em;margin-bottom:1em}
table.results th,table.results td{border:1px solid #ddd;padding:.25em .5em;text-align:right}
table.results th:first-child,table.results td:first-child{text-align:left}
table.results thead th{background:#f4f4f4}
table.mini{font-size:.8em;margin-top:.5em}table.mini td{padding:0 .6em 0 0}
figure{display:inline-block;margin:.5em 1em .5em 0;vertical-align:top}
figure img{max-width:100%;border:1px solid #eee}figcaption{font-size:.8em;color:#555;max-width:60em}
#viewer{display:flex;gap:1.5em;flex-wrap:wrap}#viewer-canvas{border:1px solid #ccc;background:#fff}
.controls label{display:block;font-size:.85em;margin:.4em 0 .1em}
.controls select{min-width:18em;max-width:28em}.controls #sel-speed{min-width:0}
.controls button{font-size:1em;padding:.3em 1em;margin:.6em .4em .2em 0}
pre{background:#f7f7f7;padding:.6em;font-size:.8em;overflow-x:auto}
"""


def _document(title: str, body: str) -> str:
    return (
        "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
        f"<meta name='viewport' content='width=device-width, initial-scale=1'><title>{title}</title>"
        f"<style>{_CSS}</style></head><body>{body}</body></html>\n"
    )


def _viewer_html(data: dict[str, Any]) -> str:
    js = resources.files("socialnav.viz").joinpath("viewer.js").read_text(encoding="utf-8")
    payload = json.dumps(data, separators=(",", ":"), allow_nan=False).replace("</", "<\\/")
    return f"""
<div id="viewer">
  <canvas id="viewer-canvas" width="640" height="640"></canvas>
  <div class="controls">
    <label for="sel-policy">Policy</label><select id="sel-policy"></select>
    <label for="sel-cell">Scenario / visibility</label><select id="sel-cell"></select>
    <label for="sel-metric">Rank episodes by</label><select id="sel-metric"></select>
    <label for="sel-episode">Episode</label><select id="sel-episode"></select>
    <div><button id="btn-play" type="button">▶ Play</button>
      <select id="sel-speed" aria-label="speed"><option value="0.5">0.5×</option>
      <option value="1" selected>1×</option><option value="2">2×</option>
      <option value="4">4×</option></select></div>
    <input id="scrub" type="range" min="0" max="0" value="0" style="width:100%" aria-label="time">
    <div id="time-label"></div>
    <label><input type="checkbox" id="ov-trails" checked> trails</label>
    <label><input type="checkbox" id="ov-m1" checked> M_I personal-space ring (ε = {data["eps"]:g} m)</label>
    <label><input type="checkbox" id="ov-m2"> M_II velocity rectangles (τ = {data["tau"]:g} s)</label>
    <label><input type="checkbox" id="ov-m6" checked> M_VI side-preference frame</label>
    <div id="episode-info"></div>
  </div>
</div>
<script id="episode-data" type="application/json">{payload}</script>
<script>{js}</script>"""


def _settings_html(runs: list[_Run]) -> str:
    from socialnav.metrics import list_metrics

    parts = []
    for run in runs:
        m = dict(run.manifest)
        preset = m.pop("preset", {})
        parts.append(
            f"<h3>{html.escape(run.label)}: {html.escape(str(run.path))}</h3>"
            f"<p>Preset <b>{html.escape(str(preset.get('name')))}</b>; run settings:</p>"
            f"<pre>{html.escape(json.dumps(m, indent=1, default=str))}</pre>"
            f"<details><summary>Preset (world, robot, evaluation, policy defaults)</summary>"
            f"<pre>{html.escape(json.dumps(preset, indent=1, default=str))}</pre></details>"
        )
    rows = "".join(
        "<tr>"
        + "".join(
            f"<td>{html.escape(str(c))}</td>"
            for c in (
                m.name,
                m.unit,
                m.direction,
                json.dumps(dict(m.parameters)),
                "; ".join(json.dumps(dict(v)) for v in m.variants) or "–",
            )
        )
        + "</tr>"
        for m in list_metrics()
    )
    parts.append(
        "<h3>Metrics and thresholds</h3><table class='results'><thead><tr><th>metric</th><th>unit</th>"
        "<th>better</th><th>default parameters</th><th>variants reported</th></tr></thead>"
        f"<tbody>{rows}</tbody></table>"
    )
    return "".join(parts)


def _page(runs: list[_Run], tables: str, figures: list[tuple[str, str, bytes]], data: dict | None) -> str:
    from socialnav import __version__

    names = ", ".join(html.escape(r.label) for r in runs)
    preset = runs[0].manifest.get("preset", {}).get("name", "?")
    stamp = _dt.datetime.now().strftime("%Y-%m-%d %H:%M")
    figs = "".join(
        f"<figure id='fig-{html.escape(name)}'><img alt='{html.escape(caption)}' "
        f"src='data:image/png;base64,{base64.b64encode(png).decode()}'>"
        f"<figcaption>{html.escape(caption)}</figcaption></figure>"
        for name, caption, png in figures
    )
    viewer = (
        _viewer_html(data)
        if data
        else "<p>No stored trajectories (runs made with --no-trajectories): no episode viewer.</p>"
    )
    body = (
        f"<h1>socialnav report: {names} on {html.escape(str(preset))}</h1>"
        f"<p>socialnav {html.escape(__version__)}, generated {stamp}. "
        f"{sum(len(r.rows) for r in runs)} episodes.</p>"
        "<nav><a href='#tables'>Tables</a> · <a href='#viewer-section'>Episode viewer</a> · "
        "<a href='#figures'>Figures</a> · <a href='#settings'>Settings</a></nav>"
        f"<h2 id='tables'>Tables</h2>{tables}"
        f"<h2 id='viewer-section'>Episode viewer</h2>{viewer}"
        f"<h2 id='figures'>Figures</h2>{figs}"
        f"<h2 id='settings'>Settings and thresholds</h2>{_settings_html(runs)}"
    )
    return _document(f"socialnav report: {names}", body)

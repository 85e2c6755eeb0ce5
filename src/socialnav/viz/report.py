"""One self-contained HTML report of one or more evaluations (`socialnav report`, `evaluate --report`).

Everything is inside the file (figures as base64 PNG, episode data as JSON, the viewer's plain
JavaScript), so it opens offline and can be mailed as it is. This module runs the steps: the runs'
data and the viewer's embedded episodes (their layout: :mod:`socialnav.viz.report_data`), the figures
(:mod:`socialnav.viz.figures`), the HTML (:mod:`socialnav.viz.report_html`).
"""

from __future__ import annotations

import html
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from socialnav.trajectory import Trajectory
from socialnav.viz.report_data import ResultRun, single_episode_data, viewer_data
from socialnav.viz.report_html import document, md_tables_to_html, report_page, tables_html, viewer_html
from socialnav.viz.routes import Routes

__all__ = ["episode_page", "md_tables_to_html", "write_report"]


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
        eps: M_I threshold [m] of the viewer's overlays.
        tau: M_II horizon [s] of the viewer's overlays.
        progress: Show a progress bar.

    Returns:
        ``{"bytes": size of the file, "viewer_episodes": episodes embedded, "figures": count}``.

    Raises:
        ValueError: No result directory, one given twice, ``out`` a directory, or a negative
            ``viewer_episodes``; a result directory's own errors name its files.
    """
    from tqdm.auto import tqdm

    from socialnav._io import atomic_write_text
    from socialnav.viz import require_viz

    require_viz()
    paths = [Path(results)] if isinstance(results, str | Path) else [Path(p) for p in results]
    if not paths:
        raise ValueError("report: give at least one result directory")
    out = Path(out)
    if viewer_episodes < 0:
        raise ValueError(f"--viewer-episodes must be >= 0 (0: no viewer), got {viewer_episodes}")
    if out.is_dir():
        raise ValueError(f"--out {out} is a directory; give the report's file name, e.g. "
                         f"{out / 'report.html'}")
    twice = [str(p) for p in paths if sum(q.resolve() == p.resolve() for q in paths) > 1]
    if twice:
        raise ValueError(f"the same result directory is given twice: {', '.join(twice)}")
    bar = tqdm(total=4, desc="report", unit="part", disable=not progress, leave=False)
    runs = [ResultRun(p) for p in paths]
    labels = [r.label for r in runs]
    for run in runs:
        if labels.count(run.label) > 1:
            run.relabel(f"{run.label} ({run.path.name})")
    rows = [row for run in runs for row in run.rows]
    summary = [row for run in runs for row in run.summary["rows"]]
    bar.update(1)

    tables = tables_html(summary)
    bar.set_description("report: figures")
    figures = _figures(rows, runs, list(curves), out.parent / "figures" if figure_files else None)
    bar.update(1)
    bar.set_description("report: episodes")
    data = viewer_data(runs, viewer_episodes, eps, tau) if viewer_episodes > 0 else None
    bar.update(1)
    if viewer_episodes == 0:
        page = report_page(runs, tables, figures, data, "No episode viewer (--viewer-episodes 0).")
    else:
        page = report_page(runs, tables, figures, data)
    atomic_write_text(out, page)
    bar.update(1)
    bar.close()
    return {
        "bytes": out.stat().st_size,
        "viewer_episodes": 0 if data is None else len(data["episodes"]),
        "figures": len(figures),
    }


def _figures(
    rows: list[dict[str, Any]], runs: list[ResultRun], curves: list, files_dir: Path | None
) -> list[tuple[str, str, bytes]]:
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
        made.append(("side_preference", "M_VI side preference per single-human scenario (and one-human "
                     "encounter)", side))
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


def episode_page(traj: Trajectory, *, eps: float = 0.2, tau: float = 1.0, routes: Routes = True) -> str:
    """A self-contained page with the viewer for one episode (`socialnav render --format html`).

    Args:
        traj: The episode.
        eps: M_I threshold [m] of the viewer's overlays.
        tau: M_II horizon [s] of the viewer's overlays.
        routes: The agents' routes around the walls (:mod:`socialnav.viz.routes`): True, those the
            trajectory records enough to plan; False, none; or routes already planned.

    Returns:
        The HTML document.
    """
    from socialnav.viz.draw import describe_episode

    data = single_episode_data(traj, eps=eps, tau=tau, routes=routes)
    body = f"<h1>{html.escape(describe_episode(traj))}</h1>" + viewer_html(data)
    return document("socialnav episode " + html.escape(data["episodes"][0]["id"]), body)

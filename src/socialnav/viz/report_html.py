"""The report's HTML: the page, its tables, settings and the episode viewer's markup.

Everything is inside the page (figures as base64 PNG, the viewer's data as JSON and its plain
JavaScript), so it opens offline; :mod:`socialnav.viz.report_data` assembles what is shown.
"""

from __future__ import annotations

import base64
import datetime as _dt
import html
import json
from importlib import resources
from typing import Any

from socialnav.viz.report_data import ResultRun


def md_tables_to_html(md: str) -> str:
    """The Markdown tables written by socialnav.evaluate.report (### title + pipe table) as HTML.

    Args:
        md: Markdown with ``### title`` lines, each followed by a pipe table.

    Returns:
        One ``<h3>`` and ``<table class='results'>`` per table, and a ``<p class='note'>`` per
        ``Note:`` line; text HTML-escaped.
    """
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
        elif line.startswith("Note: "):  # a caveat under the tables, e.g. what the wall column counts
            flush()
            title, rows = None, []
            parts.append(f"<p class='note'>{html.escape(line)}</p>")
    flush()
    return "\n".join(parts)


def tables_html(summary: list[dict[str, Any]]) -> str:
    """The report's Table II and Table III of the aggregated rows, as HTML.

    Args:
        summary: The runs' summary rows (``summary.json``'s ``rows``).

    Returns:
        The tables' HTML.
    """
    from socialnav.evaluate.report import table2, table3

    return md_tables_to_html(table2(summary, "md")) + md_tables_to_html(table3(summary, "md"))


#: The report's style sheet (also the single-episode page's).
CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:0 auto;max-width:1280px;
padding:1em 2em;color:#222}
h1{font-size:1.5em}h2{border-bottom:1px solid #ccc;padding-bottom:.2em;margin-top:1.6em}
h3{font-size:1em;margin-bottom:.3em}
table.results{border-collapse:collapse;font-size:.85em;margin-bottom:1em}
table.results th,table.results td{border:1px solid #ddd;padding:.25em .5em;text-align:right}
table.results th:first-child,table.results td:first-child{text-align:left}
p.note{color:#555;font-size:.85em;margin:.3em 0}
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


def document(title: str, body: str) -> str:
    """A complete HTML page with the report's style sheet.

    Args:
        title: The page title (HTML-escaped by the caller).
        body: The body's HTML.

    Returns:
        The page, ending with a newline.
    """
    return (
        "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
        f"<meta name='viewport' content='width=device-width, initial-scale=1'><title>{title}</title>"
        f"<style>{CSS}</style></head><body>{body}</body></html>\n"
    )


def viewer_html(data: dict[str, Any]) -> str:
    """The episode viewer: its canvas and controls, the embedded data and the viewer's script.

    Args:
        data: The viewer's data (layout: :mod:`socialnav.viz.report_data`).

    Returns:
        The viewer's HTML (``</`` in the JSON escaped, so the data cannot close its script tag).
    """
    js = resources.files("socialnav.viz").joinpath("viewer.js").read_text(encoding="utf-8")
    payload = json.dumps(data, separators=(",", ":"), allow_nan=False).replace("</", "<\\/")
    # only where an episode has routes (among walls): the controls of other reports stay as they were
    routes = ('\n    <label><input type="checkbox" id="ov-routes" checked> routes planned at the start '
              "(dashed)</label>" if any("routes" in e for e in data["episodes"]) else "")
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
    <label><input type="checkbox" id="ov-m6" checked> M_VI side-preference frame</label>{routes}
    <div id="episode-info"></div>
  </div>
</div>
<script id="episode-data" type="application/json">{payload}</script>
<script>{js}</script>"""


def settings_html(runs: list[ResultRun]) -> str:
    """Each run's settings and preset, and every metric's thresholds, as HTML.

    Args:
        runs: The report's runs.

    Returns:
        The section's HTML.
    """
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


def report_page(
    runs: list[ResultRun], tables: str, figures: list[tuple[str, str, bytes]], data: dict | None,
    no_viewer: str = "No stored trajectories (runs made with --no-trajectories): no episode viewer.",
) -> str:
    """The whole report page.

    Args:
        runs: The report's runs.
        tables: The tables' HTML (:func:`tables_html`).
        figures: (name, caption, PNG bytes) of each figure, embedded as base64.
        data: The viewer's data, or None for a report without the viewer.
        no_viewer: What the page says in the viewer's place when ``data`` is None.

    Returns:
        The self-contained HTML document.
    """
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
        viewer_html(data)
        if data
        else f"<p>{html.escape(no_viewer)}</p>"
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
        f"<h2 id='settings'>Settings and thresholds</h2>{settings_html(runs)}"
    )
    return document(f"socialnav report: {names}", body)

"""Result files and the paper's table layouts (Markdown and LaTeX).

Table II (Wang et al. 2022): success/collision/timeout %, navigation time and M_I–M_V as
mean ± std, pooled over the multi-human scenarios; every column from the invisible pass except
M_III, which comes from the visible pass. Table III: M_VI left/right % per single-human scenario.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from socialnav._io import atomic_write_text, json_text
from socialnav.metrics import get_metric, list_metrics, parse_key, walking_speed_note
from socialnav.presets import Preset

# (header, key prefix, visibility of the pass it comes from, digits)
TABLE2_COLUMNS = [
    ("M_I (s)", "m1_personal_space.duration_s@eps=0.2,", "invisible", 2),
    ("M_II (s)", "m2_projected_path.duration_s@tau=1,", "invisible", 2),
    ("M_III (steps)", "m3_aggregated_time.steps@", "visible", 2),
    ("M_III (s)", "m3_aggregated_time.time_s@", "visible", 2),
    ("M_IV ((m/s³)²)", "m4_jerk.mean_sq", "invisible", 2),
    ("M_V (s)", "m5_walking_speed.duration_s@", "invisible", 2),
    ("M_V≥ (s)", "m5_walking_speed.duration_s_ge@", "invisible", 2),
]
SIDE_SCENARIOS = ("passing", "overtaking", "crossing")
#: Under a Table II with walls: its wall column is easily read as a share of the collisions.
WALL_COLLISION_NOTE = (
    "Wall collision %: the episodes that ended in a collision with a wall or another obstacle, as a share "
    "of all episodes; Collision % counts them too"
)
#: Table II's columns of a run with walls only, after M_V≥ (metrics/progress.py): (header, key prefix,
#: visibility of the pass, digits, as a percentage). The humans' columns come from the visible pass,
#: whose successful episodes carry the humans on to the continuation cap.
WALL_TABLE2_COLUMNS = [
    ("Humans at goal %", "human_arrival.full_time", "visible", 2, True),
    ("Humans stuck", "humans_stuck", "visible", 2, False),
    ("Robot stuck (s)", "robot_stuck_time", "invisible", 2, False),
]
#: Under a Table II with walls: what its progress columns count (docs/metrics.md, "Progress among walls").
PROGRESS_NOTE = (
    "Humans at goal %: the humans that reached their goal, over the visible pass's episodes in which the "
    "robot succeeded (the humans walk on to the continuation cap; after a collision or a timeout they could "
    "not arrive); Humans stuck: humans per episode of the visible pass (continuation included) whose "
    "distance to their goal around the walls shrank by less than 0.5 m in 5 s before they arrived; "
    "Robot stuck (s): the time the robot was stuck so (invisible pass)"
)


def write_reports(
    out: Path, summary: list[dict[str, Any]], rows: list[dict[str, Any]], preset: Preset,
    caveats: Sequence[str] = (), presets_by_policy: Mapping[str, Preset] | None = None,
) -> None:
    """Write summary.json/csv and the Table II/III layouts into ``out``, atomically.

    ``caveats`` (:func:`mismatch_caveats`) are stated above every table; ``presets_by_policy`` (a
    sweep's jobs) gives each policy's own preset where they differ.
    """
    for name, text in render_reports(summary, preset, caveats, presets_by_policy).items():
        atomic_write_text(out / name, text)


#: The files :func:`write_reports` writes.
REPORT_FILES = ("summary.json", "summary.csv", "table2.md", "table2.tex", "table3.md", "table3.tex")


def remove_reports(out: Path) -> list[str]:
    """Delete the files :func:`write_reports` wrote into ``out`` (a run with no rows left to report)."""
    removed = []
    for name in REPORT_FILES:
        if (out / name).exists():
            (out / name).unlink()
            removed.append(name)
    return removed


def mismatch_caveats(description: dict[str, Any]) -> list[str]:
    """What a policy evaluated with ``--allow-preset-mismatch`` differs in, as lines for the tables.

    Args:
        description: The policy's ``describe()`` (its ``preset_mismatch_allowed`` entry, if any).
    """
    return [f"preset mismatch allowed (--allow-preset-mismatch): {d}"
            for d in description.get("preset_mismatch_allowed") or ()]


def with_caveats(table: str, caveats: Sequence[str], fmt: str = "md") -> str:
    """``table`` with each caveat on a line above it (a Markdown quote or a LaTeX comment)."""
    if not table or not caveats:
        return table
    head = "".join(f"> **Caveat:** {c}\n" if fmt == "md" else f"% caveat: {c}\n" for c in caveats)
    return head + "\n" + table


def render_reports(
    summary: list[dict[str, Any]], preset: Preset, caveats: Sequence[str] = (),
    presets_by_policy: Mapping[str, Preset] | None = None,
) -> dict[str, str]:
    """Render the text of every result file :func:`write_reports` writes, by file name.

    A sweep's worker renders them and the driver, which alone writes results, stores them. With
    ``presets_by_policy`` naming several presets, each preset's notes say which rows they are about
    and a note says that the rows of different presets do not compare.
    """
    metrics = [
        {
            "name": m.name,
            "unit": m.unit,
            "direction": m.direction,
            "social": m.social,
            "population": m.population,
            "outputs": dict(m.outputs),
            "description": m.description,
        }
        for m in list_metrics()
        # a map_only metric is listed where its keys are: open-floor summaries stay as they were
        if not m.map_only or any(parse_key(k)[0] == m.name for row in summary for k in row)
    ]
    notes = table_notes(preset)
    document: dict[str, Any] = {"preset": preset.name, "rows": summary, "metrics": metrics, "notes": notes}
    given = dict(presets_by_policy or {})
    by_name: dict[str, list[str]] = {}
    for policy, p in given.items():
        by_name.setdefault(p.name, []).append(policy)
    if len(by_name) > 1:
        first = {p.name: p for p in given.values()}
        notes = [f"{name} ({', '.join(pols)}): {n}" for name, pols in by_name.items()
                 for n in table_notes(first[name])]
        which = "; ".join(f"{name}: {', '.join(pols)}" for name, pols in by_name.items())
        notes.append("the rows come from several presets, whose worlds differ, so rows of different presets "
                     f"do not compare: {which}")
        document.update(preset=", ".join(by_name), presets={k: v.name for k, v in given.items()}, notes=notes)
    if caveats:
        document["caveats"] = list(caveats)
    files = {
        "summary.json": json_text(document),
        "summary.csv": to_csv(summary),
    }
    for name, make, missing in (
        ("table2", lambda s, f: table2(s, f, notes), "no multi-human scenario was evaluated"),
        ("table3", table3, "no single-human scenario (passing, overtaking, crossing) was evaluated"),
    ):
        for fmt, comment in (("md", "<!-- {} -->\n"), ("tex", "% {}\n")):
            files[f"{name}.{fmt}"] = with_caveats(make(summary, fmt), caveats, fmt) or comment.format(missing)
    return files


def table_notes(preset: Preset) -> list[str]:
    """Caveats that apply to a whole table, stated once under it instead of once per episode.

    The caveat: M_V is 0 by construction when the robot's v_pref ≤ v_th (``wang2022``: 1.5 m/s = v_th),
    the metric's warning, said once under the table rather than for every episode.
    """
    v_th = float(get_metric("m5_walking_speed").parameters["v_th"])
    note = walking_speed_note(preset.robot.v_pref, v_th)
    return [note] if note else []


def to_csv(summary: Sequence[dict[str, Any]]) -> str:
    """Summary rows as CSV text: one column per key in order of first appearance."""
    columns: list[str] = []
    for row in summary:
        columns.extend(k for k in row if k not in columns)
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=columns)
    writer.writeheader()
    for row in summary:
        writer.writerow(row)
    return buf.getvalue()


def _find(row: dict[str, Any] | None, prefix: str, stat: str) -> float:
    if row is None:
        return math.nan
    for key, value in row.items():
        if key.startswith(prefix) and key.endswith(f".{stat}"):
            return value
    return math.nan


def _pm(mean: float, std: float, digits: int) -> str:
    if mean is None or not math.isfinite(mean):
        return "–"
    return (
        f"{mean:.{digits}f} ± {std:.{digits}f}"
        if std is not None and math.isfinite(std)
        else f"{mean:.{digits}f}"
    )


def _pct(x: float) -> str:
    return "–" if x is None or not math.isfinite(x) else f"{100 * x:.2f}"


def _index(summary: Sequence[dict[str, Any]]) -> dict[tuple[str, str, str], dict[str, Any]]:
    return {(r["policy"], r["scenario"], r["visibility"]): r for r in summary}


def has_walls(summary: Sequence[dict[str, Any]]) -> bool:
    """Whether any group was run with static maps.

    Such a group's ``wall_collision_rate`` is a number (it is NaN on open floors), and Table II then shows
    wall collisions in a column of their own.
    """
    return any(_finite(r.get("wall_collision_rate")) for r in summary)


def _finite(x: Any) -> bool:
    return isinstance(x, (int, float)) and math.isfinite(x)


def single_human(row: dict[str, Any]) -> bool:
    """Whether a summary row is a single-human sweep's (Table III), not a Table II scenario's.

    Summaries written before rows said so (``single_human``) are told by their M_VI columns, which only
    the sweeps had then.
    """
    return bool(row["single_human"]) if "single_human" in row else "m6_left_pct" in row


#: After a Table II row of a policy evaluated with a visible robot only, in a table of the invisible one.
VISIBLE_ONLY_MARK = "(visible robot only)"


def table2_rows(summary: Sequence[dict[str, Any]], scenario: str = "pooled") -> list[list[str]]:
    """Table II's rows (one per policy and visibility) for ``scenario`` (default: pooled)."""
    idx = _index(summary)
    walls = has_walls(summary)
    policies = list(dict.fromkeys(r["policy"] for r in summary))
    # Where the table is of the invisible robot, a policy run with a visible robot only says so in its row.
    invisible_table = any(r.get("visibility") == "invisible" and not single_human(r) for r in summary)
    out = []
    for p in policies:
        # a run of a single multi-human scenario has no pooled row: its scenario's row is its pooled one
        # (per policy: compared runs may differ, see pooled_coverage)
        own = scenario
        if scenario == "pooled" and not any(k[0] == p and k[1] == "pooled" for k in idx):
            multi = [r["scenario"] for r in summary if r["policy"] == p and not single_human(r)]
            own = multi[0] if multi else scenario
        inv, vis = idx.get((p, own, "invisible")), idx.get((p, own, "visible"))
        base = inv or vis
        if base is None:
            continue
        cells = [
            f"{p} {VISIBLE_ONLY_MARK}" if inv is None and invisible_table else p,
            _pct(base.get("success_rate")),
            _pct(base.get("collision_rate")),
            *([_pct(base.get("wall_collision_rate"))] if walls else []),
            _pct(base.get("timeout_rate")),
            _pm(base.get("nav_time_s"), base.get("nav_time_s_std"), 2),
        ]
        for _, prefix, visibility, digits in TABLE2_COLUMNS:
            row = inv if visibility == "invisible" else vis
            cells.append(_pm(_find(row, prefix, "mean"), _find(row, prefix, "std"), digits))
        for _, key, visibility, digits, percent in WALL_TABLE2_COLUMNS if walls else ():
            row = inv if visibility == "invisible" else vis
            mean, std = (math.nan, math.nan) if row is None else (row.get(f"{key}.mean", math.nan),
                                                                  row.get(f"{key}.std", math.nan))
            cells.append(_pct(mean) if percent else _pm(mean, std, digits))
        out.append(cells)
    return out


def pooled_coverage(summary: Sequence[dict[str, Any]]) -> dict[str, tuple[str, ...]]:
    """The multi-human scenarios each policy's pooled Table II row is over.

    Args:
        summary: Summary rows, possibly of several runs.

    Returns:
        ``{policy: scenarios}`` (its pooled row's ``pooled_over``, or its one multi-human scenario).
    """
    out: dict[str, tuple[str, ...]] = {}
    for r in summary:
        p = r["policy"]
        if r["scenario"] == "pooled" and r.get("pooled_over"):
            out[p] = tuple(str(r["pooled_over"]).split(","))
        elif not single_human(r) and r["scenario"] != "pooled" and p not in out:
            out[p] = (r["scenario"],)
    return out


SPREAD_NOTE = ("mean ± standard deviation over episodes, not a confidence interval; Nav. time and M_I–M_V "
               "over the successful episodes; each mean's 95 % bootstrap confidence interval is in "
               "summary.json and summary.csv (*.ci_low, *.ci_high)")


def table2(summary: Sequence[dict[str, Any]], fmt: str = "md", notes: Sequence[str] = ()) -> str:
    """Table II (pooled) and one per multi-human scenario; ``notes`` (see :func:`table_notes`) follow.

    A run with walls gets a "Wall collision %" column and :data:`WALL_COLLISION_NOTE`, and the columns of
    :data:`WALL_TABLE2_COLUMNS` (humans at their goal, humans and robot stuck) with :data:`PROGRESS_NOTE`,
    "–" where the run lacks their pass or an old run their keys. Policies whose
    pooled rows are over different scenarios (runs of other ``--scenario`` lists compared) get a note
    saying so.
    """
    walls = has_walls(summary)
    notes = [*notes, WALL_COLLISION_NOTE, PROGRESS_NOTE] if walls else list(notes)
    notes.append(SPREAD_NOTE)
    coverage = pooled_coverage(summary)
    if len(set(coverage.values())) > 1:
        notes.append("the pooled rows are over different scenarios, so they do not compare: "
                     + "; ".join(f"{p}: {', '.join(s)}" for p, s in coverage.items()))
    header = [
        "Policy",
        "Success %",
        "Collision %",
        *(["Wall collision %"] if walls else []),
        "Timeout %",
        "Nav. time (s)",
        *[c[0] for c in TABLE2_COLUMNS],
        *([c[0] for c in WALL_TABLE2_COLUMNS] if walls else []),
    ]
    # Tables without rows are left out (a run of single-human scenarios only has no Table II).
    pooled = table2_rows(summary)
    passes = {r.get("visibility") for r in summary if not single_human(r)}
    if "visible" not in passes:
        which = "(invisible robot; M_III needs the visible pass, --visibility both)"
    elif "invisible" not in passes:
        which = "(visible robot only; M_I, M_II, M_IV, M_V need the invisible pass)"
    else:
        which = "(invisible robot; M_III visible)"
    title = f"Table II: pooled over the multi-human scenarios {which}"
    scenarios = [
        s
        for s in dict.fromkeys(r["scenario"] for r in summary)
        if s != "pooled" and not any(single_human(r) for r in summary if r["scenario"] == s)
    ]
    alone = len(scenarios) == 1 and not any(r["scenario"] == "pooled" for r in summary)
    if alone:  # one multi-human scenario: nothing is pooled; its own table says which passes it has
        pooled = []
    parts = [_render(title, header, pooled, fmt)] if pooled else []
    marked = any(VISIBLE_ONLY_MARK in r[0] for r in pooled)
    for s in scenarios:
        rows = table2_rows(summary, s)
        marked = marked or any(VISIBLE_ONLY_MARK in r[0] for r in rows)
        if rows:
            parts.append(_render(f"Table II, {s} {which}" if alone else f"Table II, {s}", header, rows, fmt))
    if marked:
        notes.append(f"a row marked {VISIBLE_ONLY_MARK} is of a policy run with a visible robot only: its "
                     "outcomes and Nav. time are the visible robot's, and M_I, M_II, M_IV, M_V (invisible "
                     "pass) are empty")
    if notes and parts:
        prefix = "% " if fmt == "tex" else ""
        parts.append("".join(f"{prefix}Note: {n}\n" for n in notes))
    return "\n".join(parts)


def table3_rows(summary: Sequence[dict[str, Any]],
                scenarios: Sequence[str] = SIDE_SCENARIOS) -> list[list[str]]:
    """Passing sides per policy and scenario (default: the single-human sweeps), invisible pass.

    Left %, right %, the labelled cases the percentages are of (n) and the episodes that failed (collisions
    ``c`` and timeouts ``t``), which carry no side.
    """
    idx = _index(summary)
    policies = list(dict.fromkeys(r["policy"] for r in summary))
    out = []
    for p in policies:
        cells = [p]
        was_run = False
        for s in scenarios:
            row = idx.get((p, s, "invisible"))
            was_run = was_run or row is not None
            left = row.get("m6_left_pct") if row else None
            right = row.get("m6_right_pct") if row else None
            cells += [_num(left), _num(right), _count(row, "m6_n_labelled"), _failures(row)]
        # A policy run on the single-human scenarios keeps its row even when none of its cases
        # succeeded ("–" throughout): dropping it would read as "not evaluated".
        if was_run:
            out.append(cells)
    return out


def _num(x: Any) -> str:
    return "–" if x is None or not math.isfinite(x) else f"{x:.0f}"


def _count(row: dict[str, Any] | None, key: str) -> str:
    value = row.get(key) if row else None
    return "–" if value is None or not math.isfinite(value) else f"{value:.0f}"


def _failures(row: dict[str, Any] | None) -> str:
    """``"18 (18 c, 0 t)"``: failed episodes, split into collisions and timeouts from the outcome rates."""
    failed = _count(row, "m6_n_failed")
    episodes = row.get("episodes") if row else None
    if failed in ("–", "0") or not episodes:
        return failed
    split = []
    for key, tag in (("collision_rate", "c"), ("timeout_rate", "t")):
        rate = row.get(key)  # type: ignore[union-attr]
        if rate is None or not math.isfinite(rate):
            return failed
        split.append(f"{round(rate * episodes)} {tag}")
    return f"{failed} ({', '.join(split)})"


def table3(summary: Sequence[dict[str, Any]], fmt: str = "md") -> str:
    """Table III: passing sides of every policy in the single-human scenarios.

    Args:
        summary: The evaluation's summary rows.
        fmt: ``md`` (Markdown) or ``csv``.

    Returns:
        The table's text.
    """
    header = ["Policy"]
    for scenario, (left, right) in (
        ("Passing", ("L %", "R %")),
        ("Overtaking", ("L %", "R %")),
        ("Crossing", ("L % (behind)", "R % (front)")),
    ):
        header += [f"{scenario} {left}", f"{scenario} {right}", f"{scenario} n", f"{scenario} failed"]
    rows = table3_rows(summary)
    encounters = encounter_scenarios(summary)
    if not rows and not encounters:
        return ""  # no single-human scenario in the run: no table, not an empty header
    sep = "% " if fmt == "tex" else "\n"
    parts = []
    dashes = any(r[i] == "–" for r in rows for i in TABLE3_PERCENT_COLUMNS)
    if rows:
        parts.append(_render("Table III: M_VI side preference (successful single-human cases)", header, rows,
                             fmt))
    if encounters:
        header = ["Policy"] + [f"{s} {c}" for s in encounters for c in ("L %", "R %", "n", "failed")]
        found = table3_rows(summary, encounters)
        dashes = dashes or any(c == "–" for r in found for c in r[1::4] + r[2::4])
        parts.append(_render("Table III, one-human encounters among the multi-human scenarios: M_VI side "
                             "preference (invisible robot)", header, found, fmt))
    text = "\n".join(parts) + sep + TABLE3_COUNTS_NOTE + "\n"
    if dashes:
        text += sep + TABLE3_DASH_NOTE + "\n"
    return text


def encounter_scenarios(summary: Sequence[dict[str, Any]]) -> list[str]:
    """The Table II scenarios of a run that have an M_VI reading (one human met head-on, Francis (a), (j))."""
    return list(dict.fromkeys(r["scenario"] for r in summary
                              if r["scenario"] != "pooled" and not single_human(r) and "m6_left_pct" in r))


#: Under Table III: what n and failed count.
TABLE3_COUNTS_NOTE = (
    "n: labelled successful cases the percentages are of; failed: episodes without success, which have "
    "no side (c: collisions, t: timeouts); successful cases with no side label are in neither."
)
#: Under Table III when a percentage is empty.
TABLE3_DASH_NOTE = (
    "Note: – : no labelled successful case of that policy in that scenario (n = 0: no success, or no "
    "success with a side label, or the scenario was not run)."
)
#: The left/right percentage columns of a Table III row.
TABLE3_PERCENT_COLUMNS = (1, 2, 5, 6, 9, 10)


_TEX_SPECIAL = {
    "\\": "\\textbackslash{}", "&": "\\&", "%": "\\%", "$": "\\$", "#": "\\#", "_": "\\_", "{": "\\{",
    "}": "\\}", "~": "\\textasciitilde{}", "^": "\\textasciicircum{}",
}


def _render(title: str, header: list[str], rows: list[list[str]], fmt: str) -> str:
    if fmt == "md":
        lines = [f"### {title}", "", "| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
        lines += ["| " + " | ".join(c.replace("|", "\\|") for c in r) + " |" for r in rows]  # a label's |
        return "\n".join(lines) + "\n"
    if fmt == "tex":

        def esc(s: str) -> str:
            # LaTeX's special characters in one pass (a label may hold any), then the table's symbols
            return (
                "".join(_TEX_SPECIAL.get(ch, ch) for ch in s)
                .replace("±", "$\\pm$")
                .replace("³", "$^3$")
                .replace("²", "$^2$")
                .replace("≥", "$\\geq$")
                .replace("Δ", "$\\Delta$")
                .replace("−", "$-$")
                .replace("–", "--")
            )

        lines = [
            f"% {title}",
            "\\begin{tabular}{l" + "r" * (len(header) - 1) + "}",
            "\\hline",
            " & ".join(esc(h) for h in header) + " \\\\",
            "\\hline",
        ]
        lines += [" & ".join(esc(c) for c in r) + " \\\\" for r in rows]
        lines += ["\\hline", "\\end{tabular}"]
        return "\n".join(lines) + "\n"
    raise ValueError(f"unknown table format {fmt!r}; valid: md, tex")

"""Wang et al. 2022's Tables I-III with our values beside the paper's (used by ``socialnav reproduce``).

Each table cell of ours shows the mean (± std over episodes for the social metrics) and the 95 % CI of
the mean; the paper's as printed; a third line per policy the difference ours - paper. Every compared
cell is also recorded in ``comparison`` (for reproduction.json).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from importlib import resources
from typing import Any

from socialnav._io import load_yaml
from socialnav.evaluate.report import _render


@dataclass(frozen=True)
class Column:
    """A column of the paper's tables and where our value comes from.

    ``kind``: ``rate`` (summary ``<key>`` with ``_ci_low/_ci_high``, shown in %), ``nav`` (navigation
    time) or ``metric`` (summary ``<key>.mean/.std/.ci_low/.ci_high``).
    """

    id: str  # key in the paper's YAML
    header: str
    kind: str
    key: str
    visibility: str = "invisible"
    higher_is_better: bool = False
    note: str = ""


M5_STRICT = "m5_walking_speed.duration_s@v_th=1.5"
BASIC = [
    Column("success", "Success %", "rate", "success_rate", higher_is_better=True),
    Column("collision", "Collision %", "rate", "collision_rate"),
    Column("timeout", "Timeout %", "rate", "timeout_rate"),
    Column("nav_time", "Nav. time (s)", "nav", "navigation_time",
           note="mean over successful episodes; the paper prints no spread"),
]
SOCIAL = [
    Column("m1", "M_I (s)", "metric", "m1_personal_space.duration_s@eps=0.2,distance=clearance",
           note="time with clearance < ε = 0.2 m; the paper's values read as durations in s"),
    Column("m2", "M_II (s)", "metric", "m2_projected_path.duration_s@tau=1,anchor=rear",
           note="velocity rectangles with τ = 1 s (the paper does not state τ); durations in s"),
    Column("m3", "M_III (steps)", "metric", "m3_aggregated_time.steps@cap_s=100", visibility="visible",
           note="visible-robot pass; the paper's 138–154 \"s\" match a sum in steps (≈ 4 × seconds at "
           "dt 0.25 s); humans not arrived after 100 s count as the cap"),
    Column("m4", "M_IV ((m/s³)²)", "metric", "m4_jerk.mean_sq", note="mean squared jerk per episode"),
    Column("m5", "M_V≥ (s) vs paper M_V", "metric", "m5_walking_speed.duration_s_ge@v_th=1.5",
           note="not the same definition: the paper's M_V counts speeds strictly above 1.5 m/s, which our "
           "1.5 m/s robot never exceeds (strict M_V is 0 by construction, shown below); the comparable "
           "column is M_V≥, the time at or above 1.5 m/s"),
]
SIDE_SCENARIOS = ("passing", "overtaking", "crossing")


# -- the paper's numbers -----------------------------------------------------------------------
def load_paper_results() -> dict[str, Any]:
    """The paper's Tables I–III as transcribed in ``socialnav/configs/paper/wang2022.yaml``."""
    text = (resources.files("socialnav.configs") / "paper" / "wang2022.yaml").read_text()
    return load_yaml(text)

# -- values ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Value:
    """One table cell: a mean with its spread.

    Attributes:
        mean: The value (rates in %).
        std: Standard deviation over episodes (NaN: not given).
        low: Lower end of the 95 % confidence interval (NaN: not given).
        high: Upper end of the 95 % confidence interval (NaN: not given).
        n: The number of episodes it is over, where known.
    """
    mean: float
    std: float = math.nan
    low: float = math.nan
    high: float = math.nan
    n: int | None = None


def our_value(row: dict[str, Any] | None, col: Column) -> Value:
    """Our value of column ``col`` in summary row ``row`` (rates as %, with their CI).

    Args:
        row: A summary row, or None where the policy was not run (the value is NaN).
        col: The table column.

    Returns:
        The cell's value.
    """
    if row is None:
        return Value(math.nan)
    if col.kind == "rate":
        return Value(100 * _f(row.get(col.key)), math.nan, 100 * _f(row.get(f"{col.key}_ci_low")),
                     100 * _f(row.get(f"{col.key}_ci_high")), row.get("episodes"))
    return Value(_f(row.get(f"{col.key}.mean")), _f(row.get(f"{col.key}.std")),
                 _f(row.get(f"{col.key}.ci_low")), _f(row.get(f"{col.key}.ci_high")), row.get(f"{col.key}.n"))


def paper_value(entry: dict[str, Any] | None, col: Column) -> Value:
    """The paper's value of column ``col``: ``[mean, std]`` or a bare mean in the transcription.

    Args:
        entry: The paper's row (configs/paper/wang2022.yaml), or None where the paper has none.
        col: The table column.

    Returns:
        The cell's value (NaN where the paper gives none).
    """
    if entry is None or col.id not in entry:
        return Value(math.nan)
    v = entry[col.id]
    return Value(float(v[0]), float(v[1])) if isinstance(v, list) else Value(float(v))


def _f(x: Any) -> float:
    return math.nan if x is None else float(x)


def _row(summary: Sequence[dict[str, Any]], policy: str, scenario: str, visibility: str) -> dict | None:
    for r in summary:
        if (r["policy"], r["scenario"], r["visibility"]) == (policy, scenario, visibility):
            return r
    return None


def pooled_row(summary: Sequence[dict[str, Any]], policy: str, visibility: str) -> dict | None:
    """The summary row of ``policy`` pooled over the multi-human scenarios, or None."""
    return _row(summary, policy, "pooled", visibility)


def fmt(x: float, digits: int = 2) -> str:
    """``x`` with ``digits`` decimals, or an en dash where it is not finite."""
    return "–" if not math.isfinite(x) else f"{x:.{digits}f}"


def _ours_cell(v: Value, digits: int = 2, with_std: bool = True) -> str:
    if not math.isfinite(v.mean):
        return "–"
    text = fmt(v.mean, digits)
    if with_std and math.isfinite(v.std):
        text += f" ± {fmt(v.std, digits)}"
    if math.isfinite(v.low):
        text += f" [{fmt(v.low, digits)}, {fmt(v.high, digits)}]"
    return text


def _paper_cell(v: Value, digits: int = 2) -> str:
    if not math.isfinite(v.mean):
        return "–"
    return fmt(v.mean, digits) + (f" ± {fmt(v.std, digits)}" if math.isfinite(v.std) else "")


def _diff(ours: Value, paper: Value) -> float:
    return ours.mean - paper.mean if math.isfinite(ours.mean) and math.isfinite(paper.mean) else math.nan


def _diff_cell(d: float, digits: int = 2) -> str:
    return "–" if not math.isfinite(d) else f"{d:+.{digits}f}"


def _record(comparison: list, table: str, spec_name: str, label: str, paper_row: str | None, col: Column,
            ours: Value, paper: Value) -> float:
    d = _diff(ours, paper)
    comparison.append({
        "table": table, "policy": spec_name, "label": label, "paper_row": paper_row, "column": col.id,
        "header": col.header, "ours": ours.mean, "ours_std": ours.std, "ours_ci_low": ours.low,
        "ours_ci_high": ours.high, "ours_n": ours.n, "paper": paper.mean, "paper_std": paper.std,
        "difference": d,
        "paper_inside_ci": bool(ours.low <= paper.mean <= ours.high) if math.isfinite(d) and math.isfinite(
            ours.low) else None,
    })
    return d


def _both(title: str, header: list[str], rows: list[list[str]], notes: list[str]) -> tuple[str, str]:
    md = _render(title, header, rows, "md")
    if notes:
        md += "\n" + "\n".join(f"- {n}" for n in notes) + "\n"
    tex = _render(title, header, rows, "tex")
    if notes:
        tex += "".join(f"% {n}\n" for n in notes)
    return md, tex


def _side_by_side(label: str, ours: list[Value], paper: list[Value] | None, cols: list[Column],
                  with_std: bool) -> list[list[str]]:
    rows = [[f"{label} (ours)", *[_ours_cell(v, with_std=with_std and c.kind == "metric")
                                   for v, c in zip(ours, cols, strict=True)]]]
    if paper is not None:
        rows.append([f"{label} (paper)", *[_paper_cell(v) for v in paper]])
        rows.append([f"{label} Δ ours − paper",
                     *[_diff_cell(_diff(o, p)) for o, p in zip(ours, paper, strict=True)]])
    return rows


CI_NOTE = ("ours: mean (± std over episodes for the social metrics) [95 % bootstrap CI of the mean, 1000 "
           "resamples]; paper: as printed (one training run; ± is a std over episodes, not a CI); "
           "Δ = ours − paper")


# -- Table I -----------------------------------------------------------------------------------
def table1(summary, specs, paper, comparison, notes) -> tuple[str, str]:
    """Table I: CADRL trained the original way vs under the protocol, ours beside the paper's.

    Args:
        summary: The evaluation's summary rows.
        specs: The policies evaluated (PolicySpec).
        paper: The paper's tables (:func:`load_paper_results`).
        comparison: List the ours-vs-paper records of every cell are appended to.
        notes: Notes stated under the table.

    Returns:
        The table as Markdown and as LaTeX.
    """
    cols = BASIC
    rows: list[list[str]] = []
    extra = list(notes)
    for paper_name, variant in (("Original", "original"), ("Retrained", "protocol")):
        spec = next((s for s in specs if s.policy == "cadrl" and (s.shipped or {}).get("variant") == variant),
                    None)
        p = [paper_value(paper["table1"][paper_name], c) for c in cols]
        if spec is None:
            extra.append(f"CADRL {paper_name.lower()}: no shipped checkpoint "
                         f"({'cadrl_circle_wang2022.pt' if variant == 'original' else 'cadrl_wang2022.pt'}).")
            ours = [Value(math.nan)] * len(cols)
        else:
            row = pooled_row(summary, spec.name, "invisible")
            ours = [our_value(row, c) for c in cols]
            for c, o, pv in zip(cols, ours, p, strict=True):
                _record(comparison, "I", spec.name, spec.label, paper_name, c, o, pv)
        # The paper's row name alone: the checkpoint's label ("CADRL (original)") would say it twice.
        rows += _side_by_side(f"CADRL, {paper_name.lower()}", ours, p, cols, with_std=False)
    header = ["CADRL", *[c.header for c in cols]]
    return _both("Table I: CADRL trained the original way vs under the protocol (wang2022 test protocol, "
                 "pooled over the multi-human scenarios)", header, rows, [*extra, CI_NOTE])


# -- Table II ----------------------------------------------------------------------------------
def table2(summary, specs, paper, comparison, notes) -> tuple[str, str]:
    """Table II: basic and social metrics of every policy, ours beside the paper's.

    Args:
        summary: The evaluation's summary rows.
        specs: The policies evaluated (PolicySpec).
        paper: The paper's tables (:func:`load_paper_results`).
        comparison: List the ours-vs-paper records of every cell are appended to.
        notes: Notes stated under the table.

    Returns:
        The table as Markdown and as LaTeX.
    """
    cols = [*BASIC, *SOCIAL]
    rows: list[list[str]] = []
    strict = []
    for spec in specs:
        inv, vis = pooled_row(summary, spec.name, "invisible"), pooled_row(summary, spec.name, "visible")
        if inv is None and vis is None:
            continue
        ours = [our_value(vis if c.visibility == "visible" else inv, c) for c in cols]
        paper_row = (spec.shipped or {}).get("paper_row")
        entry = paper["table2"].get(paper_row) if paper_row else None
        # The original-training CADRL belongs to Table I; Table II compares the retrained one.
        if (spec.shipped or {}).get("variant") == "original":
            entry = None
        p = [paper_value(entry, c) for c in cols] if entry else None
        if p is not None:
            for c, o, pv in zip(cols, ours, p, strict=True):
                _record(comparison, "II", spec.name, spec.label, paper_row, c, o, pv)
        rows += _side_by_side(spec.label, ours, p, cols, with_std=True)
        m5 = our_value(inv, Column("m5s", "", "metric", M5_STRICT))
        strict.append(f"{spec.label} {fmt(m5.mean)} s")
    col_notes = [f"{c.header}: {c.note}" for c in cols if c.note]
    col_notes.append("strict M_V (speed > 1.5 m/s) of ours, pooled: " + ", ".join(strict))
    col_notes.append("invisible robot for every column except M_III (visible); social metrics over "
                     "successful episodes")
    header = ["Policy", *[c.header for c in cols]]
    return _both("Table II: pooled over the four multi-human scenarios", header, rows,
                 [*notes, CI_NOTE, *col_notes])


# -- Table III ---------------------------------------------------------------------------------
def wilson_interval(successes: float, n: int, z: float = 1.959963984540054) -> tuple[float, float]:
    """95 % Wilson score interval of a proportion, in [0, 1]; NaN for n = 0."""
    if n <= 0:
        return math.nan, math.nan
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


def table3(summary, specs, paper, comparison, notes) -> tuple[str, str]:
    """Table III: passing sides in the single-human scenarios, ours beside the paper's.

    Args:
        summary: The evaluation's summary rows.
        specs: The policies evaluated (PolicySpec).
        paper: The paper's tables (:func:`load_paper_results`).
        comparison: List the ours-vs-paper records of every cell are appended to.
        notes: Notes stated under the table.

    Returns:
        The table as Markdown and as LaTeX.
    """
    header = ["Policy"] + [f"{s.capitalize()} {side} %" for s in SIDE_SCENARIOS for side in ("L", "R")]
    rows: list[list[str]] = []
    for spec in specs:
        ours: list[Value] = []
        was_run = False  # on any single-human scenario (run with no success: a row of "–")
        for scenario in SIDE_SCENARIOS:
            row = _row(summary, spec.name, scenario, "invisible")
            was_run = was_run or row is not None
            n = int(row.get("m6_n_labelled") or 0) if row else 0
            for side in ("left", "right"):
                pct = _f(row.get(f"m6_{side}_pct")) if row else math.nan
                low, high = wilson_interval(pct / 100 * n, n) if math.isfinite(pct) else (math.nan, math.nan)
                ours.append(Value(pct, math.nan, 100 * low, 100 * high, n))
        if not was_run:
            continue
        paper_row = (spec.shipped or {}).get("paper_row")
        entry = paper["table3"].get(paper_row) if paper_row and (spec.shipped or {}).get(
            "variant") != "original" else None
        p = None
        if entry:
            p = [Value(float(entry[s][i])) for s in SIDE_SCENARIOS for i in (0, 1)]
            for j, (o, pv) in enumerate(zip(ours, p, strict=True)):
                col = Column(f"{SIDE_SCENARIOS[j // 2]}_{'LR'[j % 2]}", header[1 + j], "side", "")
                _record(comparison, "III", spec.name, spec.label, paper_row, col, o, pv)
        cells = [f"{fmt(v.mean, 0)} [{fmt(v.low, 0)}, {fmt(v.high, 0)}] n={v.n}" if math.isfinite(v.mean)
                 else f"– n={v.n}" for v in ours]
        rows.append([f"{spec.label} (ours)", *cells])
        if p is not None:
            rows.append([f"{spec.label} (paper)", *[fmt(v.mean, 0) for v in p]])
            rows.append([f"{spec.label} Δ ours − paper",
                         *[_diff_cell(_diff(o, pv), 0) for o, pv in zip(ours, p, strict=True)]])
    table_notes = [
        "ours: % of labelled successful single-human cases [95 % Wilson score interval] n = labelled cases",
        *(["– n=0: no labelled case (no success, or no success that passed the human on a side)"]
          if any(cell.startswith("– n=0") for row in rows for cell in row[1:]) else []),
        "crossing: L = passing behind the human, R = in front of it",
        f"paper: {paper.get('table3_note', '')} OM-SARL is absent from the paper's Table III.",
    ]
    return _both("Table III: M_VI side preference (successful single-human cases)", header, rows,
                 [*notes, *table_notes])

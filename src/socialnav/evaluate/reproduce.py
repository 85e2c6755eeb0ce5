"""`socialnav reproduce`: Wang et al. 2022's Tables I–III, ours beside the paper's, and the ranking's
robustness to the human model.

    <out>/<human_model>/            one multi-policy run (``evaluate.multi``) per human model
    <out>/table1.md/.tex            Table I: CADRL trained the original way vs under the protocol
    <out>/table2.md/.tex            Table II: every policy, pooled over the multi-human scenarios
    <out>/table3.md/.tex            Table III: M_VI side preference
    <out>/ranking.md/.json          per metric: the policies' ranking under ORCA and social-force humans,
                                    Kendall's τ-b (with --human-model both)
    <out>/reproduction.json         every compared cell (ours, CI, paper, difference) and the ranking

The paper's numbers are package data (``socialnav/configs/paper/wang2022.yaml``). Nothing here is
hard-coded about which checkpoints exist: the policies are whatever ships at run time
(``socialnav/checkpoints/index.yaml``) plus the native ones.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

from socialnav.evaluate.files import atomic_write_json, atomic_write_text
from socialnav.evaluate.multi import MultiResult, PolicySpec, default_specs, run_policies
from socialnav.evaluate.ranking import kendall_tau_b, ranking_text
from socialnav.evaluate.report import _render
from socialnav.presets import Preset, load_preset

PRESET = "wang2022"
HUMAN_MODELS = ("orca", "social_force")
QUICK_EPISODES = 3  # per scenario (multi-human) and per single-human sweep


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
    import yaml

    text = (resources.files("socialnav.configs") / "paper" / "wang2022.yaml").read_text()
    return yaml.safe_load(text)


# -- running -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Reproduction:
    out_dir: Path
    runs: dict[str, MultiResult]  # human model -> run
    comparison: list[dict[str, Any]]
    ranking: list[dict[str, Any]]
    tables: dict[str, str]  # file stem -> Markdown


def preset_for(human_model: str, base: Preset | None = None) -> Preset:
    preset = base or load_preset(PRESET)
    if human_model == preset.world.human_model:
        return preset
    return dataclasses.replace(preset, world=dataclasses.replace(preset.world, human_model=human_model))


def run_reproduction(
    out_dir: str | Path,
    *,
    human_models: Sequence[str] = ("orca",),
    quick: bool = False,
    episodes: int | None = None,
    progress: bool = True,
    batch_size: int = 256,
    workers: int | None = None,
    specs: Sequence[PolicySpec] | None = None,
    log: Callable[[str], None] | None = None,
) -> Reproduction:
    """Evaluates every shipped ``wang2022`` checkpoint and the native policies, writes every table.

    Args:
        out_dir: Result directory (resumed if it exists).
        human_models: ``orca`` (the paper's) and/or ``social_force``; both adds the ranking table.
        quick: A few episodes per scenario (smoke test; the numbers mean nothing).
        episodes: Episodes per scenario (default: the preset's, or 3 with ``quick``).
        specs: Policies (default: shipped checkpoints + native policies).
    """
    for hm in human_models:
        if hm not in HUMAN_MODELS:
            raise ValueError(f"human model {hm!r}: must be one of {', '.join(HUMAN_MODELS)}")
    out = Path(out_dir)
    specs = list(specs) if specs is not None else default_specs(PRESET)
    if quick and episodes is None:
        episodes = QUICK_EPISODES
    runs = {}
    for hm in dict.fromkeys(human_models):
        if log is not None:
            log(f"human model {hm}:")
        runs[hm] = run_policies(
            specs, preset_for(hm), out / hm, episodes=episodes, progress=progress,
            batch_size=batch_size, workers=workers, log=log,
        )
    return write_reproduction(out, runs, specs, quick=quick, episodes=episodes)


def write_reproduction(
    out: Path, runs: dict[str, MultiResult], specs: Sequence[PolicySpec], *, quick: bool = False,
    episodes: int | None = None,
) -> Reproduction:
    paper = load_paper_results()
    main_model = "orca" if "orca" in runs else next(iter(runs))
    summary = runs[main_model].summary
    header_notes = _header_notes(main_model, quick, episodes)
    comparison: list[dict[str, Any]] = []
    tables = {
        "table1": table1(summary, specs, paper, comparison, header_notes),
        "table2": table2(summary, specs, paper, comparison, header_notes),
        "table3": table3(summary, specs, paper, comparison, header_notes),
    }
    ranking: list[dict[str, Any]] = []
    if "orca" in runs and "social_force" in runs:
        ranking = ranking_rows(runs["orca"].summary, runs["social_force"].summary, specs)
        tables["ranking"] = ranking_markdown(ranking, quick)
    for stem, (md, tex) in tables.items():
        atomic_write_text(out / f"{stem}.md", md)
        if tex is not None:
            atomic_write_text(out / f"{stem}.tex", tex)
    if ranking:
        atomic_write_json(out / "ranking.json", {"rows": ranking})
    atomic_write_json(
        out / "reproduction.json",
        {"preset": PRESET, "quick": quick, "episodes": episodes, "human_models": list(runs),
         "compared_on": main_model, "comparison": _json_safe(comparison), "ranking": _json_safe(ranking),
         "timings": {hm: r.timings for hm, r in runs.items()}},
    )
    return Reproduction(out, runs, comparison, ranking, {k: v[0] for k, v in tables.items()})


def _header_notes(human_model: str, quick: bool, episodes: int | None) -> list[str]:
    notes = []
    if quick:
        notes.append(f"**--quick: {episodes} episodes per scenario; these numbers are a smoke test, "
                     "not a reproduction.**")
    elif episodes is not None:
        notes.append(f"{episodes} episodes per scenario instead of the protocol's 500.")
    if human_model != "orca":
        notes.append(f"Humans: {human_model} (the paper's humans are ORCA).")
    return notes


# -- values ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Value:
    mean: float
    std: float = math.nan
    low: float = math.nan
    high: float = math.nan
    n: int | None = None


def our_value(row: dict[str, Any] | None, col: Column) -> Value:
    if row is None:
        return Value(math.nan)
    if col.kind == "rate":
        return Value(100 * _f(row.get(col.key)), math.nan, 100 * _f(row.get(f"{col.key}_ci_low")),
                     100 * _f(row.get(f"{col.key}_ci_high")), row.get("episodes"))
    return Value(_f(row.get(f"{col.key}.mean")), _f(row.get(f"{col.key}.std")),
                 _f(row.get(f"{col.key}.ci_low")), _f(row.get(f"{col.key}.ci_high")), row.get(f"{col.key}.n"))


def paper_value(entry: dict[str, Any] | None, col: Column) -> Value:
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


def _pooled(summary: Sequence[dict[str, Any]], policy: str, visibility: str) -> dict | None:
    return _row(summary, policy, "pooled", visibility)


def _fmt(x: float, digits: int = 2) -> str:
    return "–" if not math.isfinite(x) else f"{x:.{digits}f}"


def _ours_cell(v: Value, digits: int = 2, with_std: bool = True) -> str:
    if not math.isfinite(v.mean):
        return "–"
    text = _fmt(v.mean, digits)
    if with_std and math.isfinite(v.std):
        text += f" ± {_fmt(v.std, digits)}"
    if math.isfinite(v.low):
        text += f" [{_fmt(v.low, digits)}, {_fmt(v.high, digits)}]"
    return text


def _paper_cell(v: Value, digits: int = 2) -> str:
    if not math.isfinite(v.mean):
        return "–"
    return _fmt(v.mean, digits) + (f" ± {_fmt(v.std, digits)}" if math.isfinite(v.std) else "")


def _diff(ours: Value, paper: Value, digits: int = 2) -> float:
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
            label = f"CADRL {paper_name.lower()}"
        else:
            row = _pooled(summary, spec.name, "invisible")
            ours = [our_value(row, c) for c in cols]
            label = spec.label
            for c, o, pv in zip(cols, ours, p, strict=True):
                _record(comparison, "I", spec.name, label, paper_name, c, o, pv)
        rows += _side_by_side(f"{label} [{paper_name}]", ours, p, cols, with_std=False)
    header = ["CADRL", *[c.header for c in cols]]
    return _both("Table I: CADRL trained the original way vs under the protocol (wang2022 test protocol, "
                 "pooled over the multi-human scenarios)", header, rows, [*extra, CI_NOTE])


# -- Table II ----------------------------------------------------------------------------------
def table2(summary, specs, paper, comparison, notes) -> tuple[str, str]:
    cols = [*BASIC, *SOCIAL]
    rows: list[list[str]] = []
    strict = []
    for spec in specs:
        inv, vis = _pooled(summary, spec.name, "invisible"), _pooled(summary, spec.name, "visible")
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
        strict.append(f"{spec.label} {_fmt(m5.mean)} s")
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
    header = ["Policy"] + [f"{s.capitalize()} {side} %" for s in SIDE_SCENARIOS for side in ("L", "R")]
    rows: list[list[str]] = []
    for spec in specs:
        ours: list[Value] = []
        for scenario in SIDE_SCENARIOS:
            row = _row(summary, spec.name, scenario, "invisible")
            n = int(row.get("m6_n_labelled") or 0) if row else 0
            for side in ("left", "right"):
                pct = _f(row.get(f"m6_{side}_pct")) if row else math.nan
                low, high = wilson_interval(pct / 100 * n, n) if math.isfinite(pct) else (math.nan, math.nan)
                ours.append(Value(pct, math.nan, 100 * low, 100 * high, n))
        if all(not math.isfinite(v.mean) for v in ours):
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
        cells = [f"{_fmt(v.mean, 0)} [{_fmt(v.low, 0)}, {_fmt(v.high, 0)}] n={v.n}" if math.isfinite(v.mean)
                 else "–" for v in ours]
        rows.append([f"{spec.label} (ours)", *cells])
        if p is not None:
            rows.append([f"{spec.label} (paper)", *[_fmt(v.mean, 0) for v in p]])
            rows.append([f"{spec.label} Δ ours − paper",
                         *[_diff_cell(_diff(o, pv), 0) for o, pv in zip(ours, p, strict=True)]])
    table_notes = [
        "ours: % of labelled successful single-human cases [95 % Wilson score interval] n = labelled cases",
        "crossing: L = passing behind the human, R = in front of it",
        f"paper: {paper.get('table3_note', '')} OM-SARL is absent from the paper's Table III.",
    ]
    return _both("Table III: M_VI side preference (successful single-human cases)", header, rows,
                 [*notes, *table_notes])


# -- ranking robustness ------------------------------------------------------------------------
RANKED = [*BASIC, *SOCIAL[:4],
          Column("m5", "M_V≥ (s)", "metric", "m5_walking_speed.duration_s_ge@v_th=1.5")]


def ranking_rows(
    orca: Sequence[dict], social_force: Sequence[dict], specs: Sequence[PolicySpec]
) -> list[dict]:
    """Per metric: each policy's pooled value under both human models, the rankings and τ-b."""
    out = []
    for col in RANKED:
        names, a, b = [], [], []
        for spec in specs:
            va = our_value(_pooled(orca, spec.name, col.visibility), col).mean
            vb = our_value(_pooled(social_force, spec.name, col.visibility), col).mean
            if math.isfinite(va) and math.isfinite(vb):
                names.append(spec.name)
                a.append(va)
                b.append(vb)
        out.append({
            "metric": col.id, "header": col.header, "higher_is_better": col.higher_is_better,
            "policies": names, "orca": a, "social_force": b,
            "orca_ranking": ranking_text(names, a, col.higher_is_better),
            "social_force_ranking": ranking_text(names, b, col.higher_is_better),
            "kendall_tau_b": kendall_tau_b(a, b), "n": len(names),
        })
    return out


def ranking_markdown(rows: Sequence[dict], quick: bool) -> tuple[str, None]:
    lines = ["### Robustness of the ranking: ORCA humans vs social-force humans", ""]
    if quick:
        lines += ["**--quick: a few episodes per scenario; the rankings are a smoke test.**", ""]
    lines += ["| Metric | Ranking, ORCA humans (best first) | Ranking, social-force humans "
              "| Kendall τ-b | n |",
              "|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['header']} | {r['orca_ranking']} | {r['social_force_ranking']} | "
                     f"{_fmt(r['kendall_tau_b'])} | {r['n']} |")
    lines += ["", "- Pooled over the four multi-human scenarios (M_III: visible pass); policies without a "
              "value under both models are left out of that metric.",
              "- Kendall's τ-b handles ties (τ = 1: same order, −1: reversed; NaN for fewer than two "
              "policies or a constant column).", ""]
    values = ["| Metric | Policy | ORCA | Social force |", "|---|---|---|---|"]
    for r in rows:
        for name, va, vb in zip(r["policies"], r["orca"], r["social_force"], strict=True):
            values.append(f"| {r['header']} | {name} | {va:.3f} | {vb:.3f} |")
    return "\n".join(lines + ["#### Values", "", *values]) + "\n", None


def _json_safe(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_safe(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value

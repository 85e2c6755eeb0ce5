"""`socialnav reproduce`: Wang et al. 2022's Tables I–III, ours beside the paper's.

Also reports the ranking's robustness to the human model.

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
from pathlib import Path
from typing import Any

from socialnav import __version__
from socialnav._io import DirectoryLock, atomic_write_json, atomic_write_text, json_safe
from socialnav.evaluate.manifest import refuse_other_kind
from socialnav.evaluate.multi import MultiResult, PolicySpec, default_specs, run_policies
from socialnav.evaluate.paper_tables import (
    BASIC,
    SOCIAL,
    Column,
    fmt,
    load_paper_results,
    our_value,
    pooled_row,
    table1,
    table2,
    table3,
)
from socialnav.evaluate.ranking import kendall_tau_b, ranking_text
from socialnav.presets import Preset, load_preset

PRESET = "wang2022"
HUMAN_MODELS = ("orca", "social_force")
QUICK_EPISODES = 3  # per scenario (multi-human) and per single-human sweep


# -- running -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Reproduction:
    """What ``socialnav reproduce`` produced.

    Attributes:
        out_dir: The result directory.
        runs: The evaluation under each human model, by human model.
        comparison: One ours-vs-paper record per table cell.
        ranking: The ranking of the policies per metric under each human model.
        tables: The Markdown tables, by file stem.
    """
    out_dir: Path
    runs: dict[str, MultiResult]  # human model -> run
    comparison: list[dict[str, Any]]
    ranking: list[dict[str, Any]]
    tables: dict[str, str]  # file stem -> Markdown


def preset_for(human_model: str, base: Preset | None = None) -> Preset:
    """The wang2022 preset (or ``base``) with its humans driven by ``human_model``."""
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
        progress: Show progress bars.
        batch_size: Episodes simulated in lockstep.
        workers: Processes that score finished chunks (None: the evaluator's default; see
            :func:`~socialnav.evaluate.runner.run_protocol`).
        specs: Policies (default: shipped checkpoints + native policies).
        log: Called with a line per human model and policy evaluated (None: no lines).

    Returns:
        What was written.

    Raises:
        ValueError: An unknown human model.
    """
    for hm in human_models:
        if hm not in HUMAN_MODELS:
            raise ValueError(f"human model {hm!r}: must be one of {', '.join(HUMAN_MODELS)}")
    out = Path(out_dir)
    refuse_other_kind(out, "reproduction")
    specs = list(specs) if specs is not None else default_specs(PRESET)
    if quick and episodes is None:
        episodes = QUICK_EPISODES
    runs = {}
    out.mkdir(parents=True, exist_ok=True)
    with DirectoryLock(out, "reproduction"):  # the tables and reproduction.json of `out` are shared
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
    """Write Tables I–III, the comparison with the paper and the ranking's robustness into ``out``.

    Args:
        out: The result directory.
        runs: The evaluation under each human model, by human model.
        specs: The policies evaluated.
        quick: The runs had a few episodes per scenario (stated above every table).
        episodes: The episodes per scenario, where not the preset's.

    Returns:
        What was written.
    """
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
    else:  # a run of one human model: an earlier run's ranking would read as this one's
        for stale in ("ranking.md", "ranking.tex", "ranking.json"):
            (out / stale).unlink(missing_ok=True)
    atomic_write_json(
        out / "reproduction.json",
        {"socialnav_version": __version__, "preset": PRESET, "quick": quick, "episodes": episodes,
         "human_models": list(runs),
         "compared_on": main_model, "comparison": json_safe(comparison), "ranking": json_safe(ranking),
         "timings": {hm: r.recorded_timings for hm, r in runs.items()}},
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
            va = our_value(pooled_row(orca, spec.name, col.visibility), col).mean
            vb = our_value(pooled_row(social_force, spec.name, col.visibility), col).mean
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
    """The ranking's robustness to the human model as Markdown (``None``: it has no LaTeX form)."""
    lines = ["### Robustness of the ranking: ORCA humans vs social-force humans", ""]
    if quick:
        lines += ["**--quick: a few episodes per scenario; the rankings are a smoke test.**", ""]
    lines += ["| Metric | Ranking, ORCA humans (best first) | Ranking, social-force humans "
              "| Kendall τ-b | n |",
              "|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['header']} | {r['orca_ranking']} | {r['social_force_ranking']} | "
                     f"{fmt(r['kendall_tau_b'])} | {r['n']} |")
    lines += ["", "- Pooled over the four multi-human scenarios (M_III: visible pass); policies without a "
              "value under both models are left out of that metric.",
              "- Kendall's τ-b handles ties (τ = 1: same order, −1: reversed; NaN for fewer than two "
              "policies or a constant column).", ""]
    values = ["| Metric | Policy | ORCA | Social force |", "|---|---|---|---|"]
    for r in rows:
        for name, va, vb in zip(r["policies"], r["orca"], r["social_force"], strict=True):
            values.append(f"| {r['header']} | {name} | {va:.3f} | {vb:.3f} |")
    return "\n".join(lines + ["#### Values", "", *values]) + "\n", None

"""What each kinematics costs: wang2022's protocol with a holonomic robot, a unicycle, a differential drive.

Reads the full-protocol results of each (preset, policy) in ``benchmarks/results`` (written by
``socialnav evaluate --preset P --policy X [--checkpoint runs/train/P-X-sS/best.pt]``):

- ``orca_<preset>_summary.json``: the ORCA robot (one row; it has no seeds);
- ``crowdnav_pp_<preset>_summary.json`` (seed 0), ``..._s1_summary.json``, ``..._s2_summary.json``;
- RGL the same way (``rgl_<preset>_summary.json``, ``_s1``, ``_s2``), except the unicycle's seed 0,
  ``rgl_unicycle_wang2022_s0_summary.json``.

PPO's earlier recipes have rows of their own (``PPO_RECIPES``): ``crowdnav_pp_<preset>_val100_*`` (the
default's training with ``best.pt`` chosen on 100 validation episodes), ``crowdnav_pp_<preset>_span_*``
(outputs spanning the commands, σ e⁻¹, no turn penalty) and ``crowdnav_pp_<preset>_clip_*`` (the
unicycle's v clipped to [0, v_pref], σ 1); the default's files have no suffix (docs/kinematics.md).

Prints one Markdown table (Table II's pooled columns, then M_VI as the share of labelled passes on the
left in passing, overtaking and crossing), a row per (kinematics, policy): the value of a single run or
the mean ± std (ddof 1) over its seeds; the last line is one JSON object with every value.

    python benchmarks/analysis/kinematics_table.py [--results benchmarks/results]
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
from pathlib import Path

from seed_spread import COLUMNS, pooled_values

#: (label, preset) of the three robots, all on the wang2022 protocol.
ROBOTS = (("holonomic", "wang2022"), ("unicycle", "wang2022_unicycle"),
          ("differential drive", "wang2022_diffdrive"))
SIDE = ("passing", "overtaking", "crossing")


def side_values(path: Path) -> dict[str, float]:
    """M_VI: the share [%] of labelled successful cases passed on the left, per single-human scenario."""
    rows = json.loads(path.read_text())["rows"]
    out = {}
    for scenario in SIDE:
        row = next((r for r in rows if r["scenario"] == scenario), None)
        value = None if row is None else row.get("m6_left_pct")
        out[f"M_VI {scenario} left %"] = math.nan if value is None else float(value)
    return out


#: The PPO rows: the file suffix of each recipe and its label; "" is the default (docs/kinematics.md).
PPO_RECIPES = (("", "crowdnav_pp"), ("_val100", "crowdnav_pp, 100 validation episodes"),
               ("_span", "crowdnav_pp, no turn penalty"), ("_clip", "crowdnav_pp, v clipped, σ 1"))


def run_files(results: Path, policy: str, preset: str, recipe: str = "") -> list[Path]:
    """The seeds' summary files of ``policy`` (its ``recipe`` suffix) under ``preset`` that exist, seed 0
    first."""
    if policy == "orca":
        names = [f"orca_{preset}_summary.json"]
    elif policy == "rgl" and preset == "wang2022_unicycle":  # seed 0 predates the unicycle preset's name
        names = ["rgl_unicycle_wang2022_s0_summary.json",
                 *(f"rgl_{preset}_s{s}_summary.json" for s in (1, 2))]
    else:
        stem = f"{policy}_{preset}{recipe}"
        names = [f"{stem}_summary.json", *(f"{stem}_s{s}_summary.json" for s in (1, 2))]
    return [results / n for n in names if (results / n).is_file()]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--results", default=str(Path(__file__).resolve().parents[1] / "results"))
    results = Path(ap.parse_args().results)
    columns = [c[0] for c in COLUMNS] + [f"M_VI {s} left %" for s in SIDE]
    print("| Robot | Policy | runs | " + " | ".join(columns) + " |")
    print("|" + "---|" * (len(columns) + 3))
    report: dict[str, dict] = {}
    for label, preset in ROBOTS:
        rows = [("orca", "", "orca"), ("rgl", "", "rgl"), *(("crowdnav_pp", r, n) for r, n in PPO_RECIPES)]
        for policy, recipe, name in rows:
            files = run_files(results, policy, preset, recipe)
            if not files:
                continue
            runs = [{**pooled_values(p), **side_values(p)} for p in files]
            stats = {}
            for column in columns:
                xs = [r[column] for r in runs if not math.isnan(r[column])]
                mean = statistics.fmean(xs) if xs else math.nan
                std = statistics.stdev(xs) if len(xs) > 1 else math.nan
                stats[column] = {"mean": mean, "std": std}  # NaN: no value (written as null)
            cells = ["–" if math.isnan(s["mean"]) else f"{s['mean']:.2f}" if math.isnan(s["std"])
                     else f"{s['mean']:.2f} ± {s['std']:.2f}" for s in stats.values()]
            print(f"| {label} | {name} | {len(runs)} | " + " | ".join(cells) + " |")
            plain = {c: {k: None if math.isnan(v) else v for k, v in s.items()} for c, s in stats.items()}
            names = [p.name for p in files]
            report[f"{preset}/{policy}{recipe}"] = {"runs": len(runs), "files": names, "stats": plain}
    print(json.dumps(report))


if __name__ == "__main__":
    main()

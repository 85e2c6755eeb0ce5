"""Seed spread of the trained baselines: Table II's pooled columns per training seed, mean ± std.

Reads the full-protocol results of every seed that was trained and evaluated
(`benchmarks/results/<policy>_wang2022_summary.json` for seed 0, `..._s1_summary.json`,
`..._s2_summary.json`; written by `socialnav evaluate --preset wang2022 --policy P --checkpoint
runs/train/wang2022-P-sS/best.pt`) and prints a Markdown table: one row per policy and seed, then the
mean ± std (ddof 1) over the seeds present, beside the paper's row. The last line is one JSON object
with every value.

    python benchmarks/analysis/seed_spread.py [--results benchmarks/results] [--preset wang2022_partial]

``--preset`` reads another preset's files (``<policy>_<preset>_summary.json``, ``..._s1_...``); the
protocol must be ``wang2022``'s (its scenarios and columns), e.g. ``wang2022_partial``.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
from pathlib import Path

POLICIES = ("cadrl", "lstm_rl", "sarl", "om_sarl", "rgl", "mp_rgl", "crowdnav_pp")
NAMES = {
    "cadrl": "CADRL",
    "lstm_rl": "GA3C-CADRL",
    "sarl": "SARL",
    "om_sarl": "OM-SARL",
    "rgl": "RGL",
    "mp_rgl": "MP-RGL",
    "crowdnav_pp": "CrowdNav++ attention graph (PPO)",
}
#: (column, summary key, visibility, scale): the pooled columns of Table II.
COLUMNS = (
    ("Success %", "success_rate", "invisible", 100.0),
    ("Collision %", "collision_rate", "invisible", 100.0),
    ("Timeout %", "timeout_rate", "invisible", 100.0),
    ("Nav. time (s)", "nav_time_s", "invisible", 1.0),
    ("M_I (s)", "m1_personal_space.duration_s@eps=0.2,distance=clearance.mean", "invisible", 1.0),
    ("M_II (s)", "m2_projected_path.duration_s@tau=1,anchor=rear.mean", "invisible", 1.0),
    ("M_III (steps)", "m3_aggregated_time.steps@cap_s=100.mean", "visible", 1.0),
    ("M_IV", "m4_jerk.mean_sq.mean", "invisible", 1.0),
    ("M_V≥ (s)", "m5_walking_speed.duration_s_ge@v_th=1.5.mean", "invisible", 1.0),
)


def pooled_values(path: Path) -> dict[str, float]:
    rows = json.loads(path.read_text())["rows"]
    out = {}
    for column, key, visibility, scale in COLUMNS:
        row = next(r for r in rows if r["scenario"] == "pooled" and r["visibility"] == visibility)
        value = row.get(key)
        out[column] = math.nan if value is None else float(value) * scale
    return out


def seed_files(results: Path, policy: str, preset: str = "wang2022") -> dict[int, Path]:
    files = {0: results / f"{policy}_{preset}_summary.json"}
    files.update({s: results / f"{policy}_{preset}_s{s}_summary.json" for s in (1, 2)})
    return {s: p for s, p in files.items() if p.is_file()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--results", default=str(Path(__file__).resolve().parents[1] / "results"))
    ap.add_argument("--preset", default="wang2022", help="whose result files (default wang2022)")
    args = ap.parse_args()
    results = Path(args.results)
    header = ["Policy", "seed", *[c[0] for c in COLUMNS]]
    print("| " + " | ".join(header) + " |")
    print("|" + "---|" * len(header))
    report: dict[str, dict] = {}
    for policy in POLICIES:
        files = seed_files(results, policy, args.preset)
        if not files:
            continue
        per_seed = {s: pooled_values(p) for s, p in sorted(files.items())}
        for s, values in per_seed.items():
            cells = [f"{values[c[0]]:.2f}" for c in COLUMNS]
            print(f"| {NAMES[policy]} | {s} | " + " | ".join(cells) + " |")
        stats = {}
        for column, *_ in COLUMNS:
            xs = [v[column] for v in per_seed.values()]
            mean = statistics.fmean(xs)
            std = statistics.stdev(xs) if len(xs) > 1 else math.nan
            stats[column] = {"mean": mean, "std": std, "n_seeds": len(xs)}
        cells = [f"**{stats[c[0]]['mean']:.2f} ± {stats[c[0]]['std']:.2f}**" for c in COLUMNS]
        print(f"| {NAMES[policy]} | mean ± std ({len(per_seed)} seeds) | " + " | ".join(cells) + " |")
        report[policy] = {"seeds": {str(s): v for s, v in per_seed.items()}, "stats": stats}
    print(json.dumps(report))


if __name__ == "__main__":
    main()

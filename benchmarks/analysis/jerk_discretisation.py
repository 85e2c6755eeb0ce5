"""M_IV under the discretisations a reader of Wang et al. could have used, beside the paper's values.

The paper says only that the jerk "is computed in discrete time". For every successful episode of the
four multi-human scenarios, invisible pass (the episodes of its Table II), this re-scores M_IV with
every ``difference`` (forward, central, commanded) and ``dt_power`` (3, 2) of the ``m4_jerk`` metric
(``socialnav.metrics.naturalness.JERK_DIFFERENCES``) and reports the motion behind it: the mean |Δv|
per step and the share of steps turning by more than 10°.

    PYTHONPATH=src python benchmarks/analysis/jerk_discretisation.py runs/evaluate/wang2022-all \
        [more result directories ...] [--out benchmarks/results/jerk_discretisation.json]

A directory is one ``socialnav evaluate`` result (with ``trajectories/``) or a ``--policy all`` result
(one per policy under ``policies/``). The last line printed is one JSON object.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from motion_decomposition import episode_motion, successful_multi_human  # noqa: E402

from socialnav._io import atomic_write_json  # noqa: E402
from socialnav.metrics.naturalness import JERK_DIFFERENCES, squared_jerk  # noqa: E402

VARIANTS = [(d, q) for q in (3, 2) for d in JERK_DIFFERENCES]
PAPER_M4 = {"cadrl": (5.63, 3.10), "ga3c_cadrl": (10.88, 6.77), "om_sarl": (9.77, 5.59), "rgl": (9.22, 5.32)}
"""Wang et al., Table II: M_IV mean ± std per baseline [(m/s³)²] (shared/spec/paper_results.md)."""
PAPER_BAND = (5.63, 10.88)


def variant_name(difference: str, dt_power: int) -> str:
    return f"{difference}/dt{dt_power}"


def result_dirs(paths: list[Path]) -> dict[str, Path]:
    """Policy label -> result directory holding ``trajectories/``."""
    found: dict[str, Path] = {}
    for path in paths:
        if (path / "trajectories").is_dir():
            found[path.name] = path
        for sub in sorted((path / "policies").glob("*")):
            if (sub / "trajectories").is_dir():
                found[sub.name] = sub
    if not found:
        raise SystemExit(f"no result directory with trajectories/ under {[str(p) for p in paths]}")
    return found


def summarise(results_dir: Path) -> dict[str, float]:
    rows = []
    for traj in successful_multi_human(results_dir):
        if traj.n_steps < 3:
            continue
        motion = episode_motion(traj)
        row = {key: motion[key] for key in ("mean_abs_dv", "share_turns_over_10deg")}
        for d, q in VARIANTS:
            row[variant_name(d, q)] = squared_jerk(traj, difference=d, dt_power=q)["mean_sq"]
        rows.append(row)
    if not rows:
        raise SystemExit(f"{results_dir}: no successful multi-human episode with a stored trajectory")
    out: dict[str, float] = {"episodes": len(rows)}
    for key in rows[0]:
        values = np.array([r[key] for r in rows], dtype=float)
        out[key] = float(np.nanmean(values))
        out[f"{key}.std"] = float(np.nanstd(values))
    return out


def markdown(results: dict[str, dict[str, float]]) -> str:
    names = [variant_name(d, q) for d, q in VARIANTS]
    head = ("| policy | episodes | " + " | ".join(names)
            + " | mean \\|Δv\\| (m/s) | turns > 10° | paper M_IV |")
    lines = [head, "|" + "---|" * (len(names) + 5)]
    for label, r in results.items():
        paper = PAPER_M4.get(label)
        cells = [f"{r[n]:.3g}" + (" ✓" if PAPER_BAND[0] <= r[n] <= PAPER_BAND[1] else "") for n in names]
        lines.append(f"| {label} | {r['episodes']} | " + " | ".join(cells)
                     + f" | {r['mean_abs_dv']:.3f} | {100 * r['share_turns_over_10deg']:.1f} % | "
                     + (f"{paper[0]} ± {paper[1]}" if paper else "—") + " |")
    lines.append(f"\n✓: inside the paper's band of learned baselines, "
                 f"{PAPER_BAND[0]}–{PAPER_BAND[1]} (m/s³)².")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("results", nargs="+", type=Path)
    ap.add_argument("--out", type=Path, help="also write the JSON object here (atomically)")
    args = ap.parse_args()
    results = {label: summarise(d) for label, d in result_dirs(args.results).items()}
    print(markdown(results))
    payload = {"variants": [variant_name(d, q) for d, q in VARIANTS], "paper_band": list(PAPER_BAND),
               "policies": results}
    if args.out:
        atomic_write_json(args.out, payload)
    print(json.dumps(payload))


if __name__ == "__main__":
    main()

"""How the paper-comparable social metrics move with the settings the paper does not state.

Wang et al. 2022 give M_II without its horizon τ, M_I with ε = 0.2 m but not whether the distance is
between bodies or centres, and M_V without saying how "above walking speed" treats a robot whose
preferred speed *is* walking speed. This script re-scores stored trajectories (successful multi-human
episodes, invisible robot, as Table II) under a grid of those settings, so that one can read which
setting, if any, brings our values to the paper's, without retraining anything:

- M_II duration [s] for τ ∈ {0.5, 1, 1.5, 2, 3, 4} s, rectangle anchored at the rear (spec default)
  and at the front of the body;
- M_I duration [s] for ε ∈ {0.2, 0.5, 1.2} m, clearance (spec default) and centre distance;
- M_V≥ duration [s] for thresholds v_th − 1e-6 with v_th ∈ {1.2, 1.3, 1.4, 1.5} m/s.

    PYTHONPATH=src python benchmarks/analysis/metric_sensitivity.py runs/evaluate/wang2022-rgl \
        runs/evaluate/wang2022-orca [--out benchmarks/results/metric_sensitivity.json]

The last line printed is one JSON object (one entry per result directory).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from socialnav.metrics.comfort import personal_space, projected_path
from socialnav.trajectory import read_trajectories

TAUS = (0.5, 1.0, 1.5, 2.0, 3.0, 4.0)
EPSILONS = (0.2, 0.5, 1.2)
SPEEDS = (1.2, 1.3, 1.4, 1.5)


def speed_at_or_above(traj, v_th: float) -> float:
    pos = np.asarray(traj.positions)[:, 0]
    speed = np.linalg.norm(np.diff(pos, axis=0), axis=1) / float(traj.dt)
    return float(np.count_nonzero(speed >= v_th - 1e-6) * traj.dt)


def episode_values(traj) -> dict[str, float]:
    out: dict[str, float] = {}
    for anchor in ("rear", "front"):
        for tau in TAUS:
            out[f"M_II tau={tau:g} {anchor}"] = projected_path(traj, tau, anchor)["duration_s"]
    for distance in ("clearance", "centre"):
        for eps in EPSILONS:
            out[f"M_I eps={eps:g} {distance}"] = personal_space(traj, eps, distance)["duration_s"]
    for v_th in SPEEDS:
        out[f"M_V>= {v_th:g} m/s"] = speed_at_or_above(traj, v_th)
    return out


def summarise(results_dir: Path) -> dict[str, object]:
    rows = []
    for path in sorted((results_dir / "trajectories").glob("*__invisible/*.parquet")):
        if path.parent.name.split("__")[0] in ("passing", "overtaking", "crossing"):
            continue
        rows.extend(episode_values(t) for t in read_trajectories(path) if t.outcome == "success")
    if not rows:
        raise SystemExit(f"{results_dir}: no successful multi-human episode with a stored trajectory")
    return {
        "episodes": len(rows),
        "mean": {k: round(float(np.mean([r[k] for r in rows])), 4) for k in rows[0]},
        "std": {k: round(float(np.std([r[k] for r in rows])), 4) for k in rows[0]},
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("results", nargs="+", type=Path, help="result directories of socialnav evaluate")
    ap.add_argument("--out", type=Path, help="also write the JSON object here")
    args = ap.parse_args()
    result = {str(d): summarise(d) for d in args.results}
    for d, entry in result.items():
        print(f"{d} ({entry['episodes']} successful multi-human episodes)")
        for k, v in entry["mean"].items():
            print(f"  {k:28s} {v:8.3f} ± {entry['std'][k]:.3f}")
    text = json.dumps(result)
    if args.out:
        args.out.write_text(text + "\n")
    print(text)


if __name__ == "__main__":
    main()

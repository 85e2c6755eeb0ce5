"""Share of time a robot spends at each of CrowdSim's speed levels, from stored protocol trajectories.

CrowdSim's holonomic action set has five speeds, (e^{k/5} − 1)/(e − 1)·v_pref for k = 1..5 (0.129,
0.286, 0.479, 0.713 and 1.0 × v_pref), and standing still. For every successful episode of the four
multi-human scenarios, invisible pass (Table II's episodes), each executed step's speed is matched to
the nearest level (within 1 mm/s; "other" otherwise, e.g. ORCA's continuous speeds).

    PYTHONPATH=src python benchmarks/analysis/speed_levels.py \\
        runs/evaluate/wang2022-rgl-s0=1.5 runs/evaluate/wang2022_vpref2-rgl-s0=2 [--out FILE]

Each argument is a result directory and the robot's v_pref. The last line printed is one JSON object.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from motion_decomposition import successful_multi_human  # noqa: E402

from socialnav._io import atomic_write_json  # noqa: E402

TOLERANCE = 1e-3  # [m/s]


def speed_levels(v_pref: float) -> np.ndarray:
    """CrowdSim's five non-zero holonomic speeds for ``v_pref`` [m/s]."""
    return (np.exp(np.arange(1, 6) / 5) - 1) / (np.e - 1) * v_pref


def shares(results_dir: Path, v_pref: float) -> dict:
    levels = speed_levels(v_pref)
    counts = np.zeros(len(levels) + 2)  # standing, the five levels, other
    for traj in successful_multi_human(results_dir):
        speed = np.linalg.norm(np.diff(traj.positions[:, 0], axis=0) / traj.dt, axis=1)
        nearest = np.argmin(np.abs(speed[:, None] - levels[None, :]), axis=1)
        on_level = np.abs(levels[nearest] - speed) < TOLERANCE
        standing = speed < TOLERANCE
        counts[0] += standing.sum()
        np.add.at(counts, 1 + nearest[on_level & ~standing], 1)
        counts[-1] += (~on_level & ~standing).sum()
    if counts.sum() == 0:
        raise SystemExit(f"{results_dir}: no successful multi-human episode with a stored trajectory")
    labels = ["0"] + [f"{v:.3f}" for v in levels] + ["other"]
    share = counts / counts.sum()
    return {"v_pref": v_pref, "steps": int(counts.sum()), "levels_m_s": labels,
            "share": [float(s) for s in share],
            "share_above_1.5": float(share[1:-1][levels > 1.5 + 1e-6].sum())}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+", help="DIR=V_PREF")
    ap.add_argument("--out", type=Path, help="also write the JSON object here (atomically)")
    args = ap.parse_args()
    out = {}
    for item in args.runs:
        path, _, v = item.rpartition("=")
        out[Path(path).name] = result = shares(Path(path), float(v))
        pairs = zip(result["levels_m_s"], result["share"], strict=True)
        cells = " ".join(f"{lab}: {100 * s:.1f} %" for lab, s in pairs)
        print(f"{Path(path).name} (v_pref {result['v_pref']:g} m/s, {result['steps']} steps): {cells}")
    if args.out:
        atomic_write_json(args.out, out)
    print(json.dumps(out))


if __name__ == "__main__":
    main()

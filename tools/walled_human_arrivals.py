"""How many humans of the walled scenarios reach their goal (docs/walls_maps.md, "Humans among walls").

Humans are ORCA agents heading straight for their goals, local planners like the ORCA robot: where a wall
stands between a human's start and its goal, the human can stay pressed against it. This runs the
francis2023 protocol's visible pass (with the continuation after the robot's arrival, up to the cap) with
the ORCA robot and counts the humans whose centre came within their radius of their goal.

    PYTHONPATH=src python tools/walled_human_arrivals.py [--episodes 40] [--out DIR]

Prints one line per scenario, then one JSON object last.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np

from socialnav.evaluate import run_protocol
from socialnav.policies.loading import build_policy
from socialnav.presets import load_preset
from socialnav.trajectory_io import read_trajectories


def arrivals(run_dir: Path) -> tuple[int, int]:
    """(humans, humans that reached their goal) over a run's stored trajectories."""
    total = reached = 0
    for path in sorted(run_dir.glob("trajectories/**/*.parquet")):
        for tr in read_trajectories(path):
            for h in range(1, tr.n_agents):
                seen = tr.positions[:, h][tr.presence[:, h]]
                if tr.continuation is not None:  # after the robot's arrival, up to the cap
                    seen = np.concatenate([seen, tr.continuation[:, h]])
                d = np.linalg.norm(seen - tr.goals[h], axis=-1)
                total += 1
                reached += bool((d <= tr.radii[h] + 1e-9).any())
    return total, reached


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--episodes", type=int, default=40, help="episodes per scenario (default 40)")
    ap.add_argument("--out", type=Path, help="where the runs go (default: a temporary directory)")
    args = ap.parse_args()
    preset = load_preset("francis2023")
    result = {"preset": preset.name, "robot": "orca", "visibility": "visible", "episodes": args.episodes,
              "scenarios": {}}
    with tempfile.TemporaryDirectory() as tmp:
        root = args.out or Path(tmp)
        for scenario in preset.evaluation.multi_human:
            run_dir = root / scenario
            run_protocol(build_policy("orca", preset), preset, run_dir, scenarios=[scenario],
                         episodes=args.episodes, visibility="visible", progress=False)
            total, reached = arrivals(run_dir)
            result["scenarios"][scenario] = {"humans": total, "reached_goal": reached,
                                             "fraction": round(reached / total, 3) if total else None}
            print(f"{scenario}: {reached} of {total} humans reached their goal", flush=True)
    print(json.dumps(result))


if __name__ == "__main__":
    main()

"""Wall time of the full `wang2022` protocol for the ORCA robot, scoring and writing included.

Runs `run_protocol` into a fresh temporary directory (4060 episodes: 2000 invisible, 2000 visible
with the M_III continuation, 60 single-human), with every episode's trajectory stored (the default)
and again without (`trajectories=False`), alternating, and reports the time and disk cost of the
trajectories; then, in the same run, simulates the same cells without scoring or writing as the
reference for the simulator's share. Prints one JSON object last.

    python benchmarks/bench_protocol.py [--repeats 1]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
import warnings
from pathlib import Path

from socialnav.evaluate.plan import cell_scenario, cell_world_settings, plan_cells
from socialnav.evaluate.runner import run_protocol
from socialnav.policies import make_policy
from socialnav.presets import load_preset
from socialnav.sim.world import World

TARGET_SECONDS = 5.0
TRAJ_TIME_GOAL = 1.20  # stored trajectories: <= 20 % more time ...
TRAJ_MB_GOAL = 50.0  # ... and <= 50 MB for the whole protocol


def _megabytes(path: Path) -> float:
    return sum(f.stat().st_size for f in path.rglob("*") if f.is_file()) / 1e6


def simulate_only(preset, policy) -> float:
    start = time.perf_counter()
    for cell in plan_cells(preset):
        world = World(
            cell_world_settings(preset, cell),
            cell_scenario(preset, cell),
            min(256, cell.episodes),
            split="test",
            count=cell.episodes,
            record=True,
        )
        world.reset()
        while world.busy:
            world.step(policy.act(world.observe()))
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=1)
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    preset = load_preset("wang2022")
    policy = make_policy("orca", **preset.policy_params("orca"))
    times: dict[bool, list[float]] = {True: [], False: []}
    traj_mb = results_mb = 0.0
    for _ in range(args.repeats):
        for keep in (True, False):
            with tempfile.TemporaryDirectory() as out:
                start = time.perf_counter()
                result = run_protocol(policy, preset, out, progress=False, trajectories=keep)
                times[keep].append(time.perf_counter() - start)
                if keep:
                    traj_mb = _megabytes(Path(out) / "trajectories")
                    results_mb = _megabytes(Path(out)) - traj_mb
    seconds = min(times[True])
    without = min(times[False])
    sim = simulate_only(preset, policy)
    episodes = len(result.rows)
    ratio = seconds / without
    print(
        f"wang2022 protocol, ORCA robot: {episodes} episodes in {seconds:.2f} s with trajectories, "
        f"{without:.2f} s without (x{ratio:.2f}, goal <= x{TRAJ_TIME_GOAL}); trajectories {traj_mb:.1f} MB "
        f"(goal <= {TRAJ_MB_GOAL:.0f} MB), other results {results_mb:.1f} MB; simulation alone {sim:.2f} s; "
        f"target <= {TARGET_SECONDS} s"
    )
    print(
        json.dumps(
            {
                "seconds": round(seconds, 3),
                "seconds_without_trajectories": round(without, 3),
                "trajectory_time_ratio": round(ratio, 3),
                "trajectory_mb": round(traj_mb, 2),
                "other_results_mb": round(results_mb, 2),
                "trajectory_goal_met": ratio <= TRAJ_TIME_GOAL and traj_mb <= TRAJ_MB_GOAL,
                "episodes": episodes,
                "episodes_per_s": round(episodes / seconds, 1),
                "simulation_only_seconds": round(sim, 3),
                "ratio_to_simulation": round(seconds / sim, 2),
                "target_seconds": TARGET_SECONDS,
                "meets_target": seconds <= TARGET_SECONDS,
            }
        )
    )


if __name__ == "__main__":
    main()

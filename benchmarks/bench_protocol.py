"""Wall time of the full `wang2022` protocol for the ORCA robot, scoring and writing included.

Runs `run_protocol` into a fresh temporary directory (4060 episodes: 2000 invisible, 2000 visible
with the M_III continuation, 60 single-human), then, in the same run, simulates the same cells
without scoring or writing as the reference for the simulator's share. Prints one JSON object last.

    python benchmarks/bench_protocol.py [--repeats 1]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
import warnings

from socialnav.evaluate.plan import cell_scenario, cell_world_settings, plan_cells
from socialnav.evaluate.runner import run_protocol
from socialnav.policies import make_policy
from socialnav.presets import load_preset
from socialnav.sim.world import World

TARGET_SECONDS = 5.0


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
    times = []
    for _ in range(args.repeats):
        with tempfile.TemporaryDirectory() as out:
            start = time.perf_counter()
            result = run_protocol(policy, preset, out, progress=False)
            times.append(time.perf_counter() - start)
    seconds = min(times)
    sim = simulate_only(preset, policy)
    episodes = len(result.rows)
    print(
        f"wang2022 protocol, ORCA robot: {episodes} episodes in {seconds:.2f} s "
        f"(simulation alone {sim:.2f} s); target <= {TARGET_SECONDS} s"
    )
    print(
        json.dumps(
            {
                "seconds": round(seconds, 3),
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

"""Scoring simulated episodes from Parquet: read, score every metric, summarise (`socialnav metrics`).

Simulates N episodes (default 10 000) of the `wang2022` circle-crossing cell with the batched World
(ORCA robot, as in bench_protocol.py), writes them to one Parquet file in the long format, then times
`socialnav.logs.score_file` on it with 2 worker processes (the target: <= 10 s on 2 cores), and with
0 workers as the in-run reference. The single process's CPU seconds and the load average are
reported too: on a shared machine the wall time says little. Prints one JSON object last.

    python benchmarks/bench_metrics.py [--episodes 10000] [--workers 2]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
import warnings
from pathlib import Path

from socialnav.evaluate.plan import cell_scenario, cell_world_settings, plan_cells
from socialnav.logs import score_file
from socialnav.policies import make_policy
from socialnav.presets import load_preset
from socialnav.sim.world import World
from socialnav.trajectory import write_trajectories

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _machine import add_record_arguments, emit, run_record  # noqa: E402  (benchmarks/ is not a package)

TARGET_SECONDS = 10.0


def simulate(n: int) -> tuple[list, float]:
    preset = load_preset("wang2022")
    policy = make_policy("orca", **preset.policy_params("orca"))
    cell = next(c for c in plan_cells(preset) if c.visibility == "invisible" and not c.single_human)
    start = time.perf_counter()
    world = World(cell_world_settings(preset, cell), cell_scenario(preset, cell), 256, split="train",
                  count=n, record=True)
    world.reset()
    trajs = []
    while world.busy:
        trajs.extend(world.step(policy.act(world.observe())).finished)
    for i, tr in enumerate(trajs):
        tr.settings["episode"] = i
    return trajs, time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--episodes", type=int, default=10_000)
    parser.add_argument("--workers", type=int, default=2)
    add_record_arguments(parser, "bench_metrics")
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    trajs, sim_s = simulate(args.episodes)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "episodes.parquet"
        write_trajectories(path, trajs)
        size_mb = path.stat().st_size / 1e6
        start = time.perf_counter()
        scores = score_file(path, workers=args.workers)
        seconds = time.perf_counter() - start
        start, cpu0 = time.perf_counter(), time.process_time()
        serial = score_file(path, workers=0)
        serial_s = time.perf_counter() - start
        serial_cpu = time.process_time() - cpu0
    assert len(scores.rows) == len(serial.rows) == len(trajs)
    assert scores.rows[-1] == serial.rows[-1] or str(scores.rows[-1]) == str(serial.rows[-1])
    print(f"scored {len(trajs)} episodes from Parquet ({size_mb:.1f} MB) in {seconds:.2f} s with "
          f"{args.workers} workers (one process: {serial_s:.2f} s; simulating them: {sim_s:.2f} s); "
          f"target <= {TARGET_SECONDS} s")
    emit(run_record() | {
        "seconds": round(seconds, 3),
        "episodes": len(trajs),
        "workers": args.workers,
        "episodes_per_s": round(len(trajs) / seconds, 1),
        "single_process_seconds": round(serial_s, 3),
        "single_process_cpu_seconds": round(serial_cpu, 3),
        "load_average_1min": round(os.getloadavg()[0], 2),
        "ratio_to_single_process": round(seconds / serial_s, 3),
        "simulation_seconds": round(sim_s, 3),
        "ratio_to_simulation": round(seconds / sim_s, 2),
        "parquet_mb": round(size_mb, 2),
        "target_seconds": TARGET_SECONDS,
        "meets_target": seconds <= TARGET_SECONDS,
    }, args)


if __name__ == "__main__":
    main()

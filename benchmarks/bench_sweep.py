"""Sweep executors on this machine: local scaling from 1 to 2 worker processes, and Ray's overhead.

One sweep (linear, ORCA and social-force robots × ORCA and social-force humans on the `wang2022`
protocol, `--episodes` per multi-human scenario, visible and invisible passes, single-human sweeps;
66 chunks of work) is run into fresh directories with the local executor at 1 and 2 workers and with
the Ray executor on a Ray instance of 2 CPUs started in this run, in alternation over `--repeats`
rounds; the minimum of each is kept. Ray runs only while the Ray executor is timed: an idle Ray
instance (GCS, raylet, pre-started workers) takes ≈ 7 % of a core here, which a user of the local
executor does not pay, so each round starts Ray after the local runs and shuts it down before the
next round. Ray's start-up is timed apart (on a cluster it is already running) but its idle cost is
not: `ray_overhead_fraction` = Ray sweep time / local 2-worker sweep time (no Ray running) − 1.
Every run's per-episode results are checked identical before anything is reported. Prints one JSON
object last.

    python benchmarks/bench_sweep.py [--episodes 200] [--repeats 2]
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
import warnings
from pathlib import Path

import pyarrow.parquet as pq

from socialnav.sweep.driver import run_sweep
from socialnav.sweep.executors import LocalExecutor, RayExecutor
from socialnav.sweep.spec import parse_sweep

SPEEDUP_GOAL = 1.8
RAY_OVERHEAD_GOAL = 0.10


def rows_of(out: Path) -> list[dict]:
    rows = []
    for f in sorted(out.glob("evaluate/*/episodes/*/*.parquet")):
        rows.extend(pq.read_table(f).to_pylist())
    return [{k: (repr(v) if isinstance(v, float) else v) for k, v in r.items()} for r in rows]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--episodes", type=int, default=200, help="episodes per multi-human scenario")
    parser.add_argument("--repeats", type=int, default=2)
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    spec = parse_sweep(
        {
            "defaults": {"preset": "wang2022", "episodes": args.episodes},
            "grid": {
                "kind": "evaluate",
                "policy": ["linear", "orca", "social_force"],
                "human_model": ["orca", "social_force"],
            },
        }
    )
    # As RayExecutor does when it starts Ray itself: no usage report, workers at normal priority.
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    os.environ.setdefault("RAY_worker_niceness", "0")
    import ray

    def start_ray() -> float:
        t0 = time.perf_counter()
        ray.init(
            num_cpus=2,
            include_dashboard=False,
            logging_level="ERROR",
            log_to_driver=False,
            _node_ip_address="127.0.0.1",
        )
        return time.perf_counter() - t0

    executors = {
        "local_1": lambda: LocalExecutor(1),
        "local_2": lambda: LocalExecutor(2),
        "ray_2": lambda: RayExecutor(),
    }
    times: dict[str, list[float]] = {k: [] for k in executors}
    startups: list[float] = []
    reference = None
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.repeats):
            for name, make in executors.items():
                if name == "ray_2":
                    startups.append(start_ray())
                out = Path(tmp) / f"{name}-{r}"
                try:
                    start = time.perf_counter()
                    result = run_sweep(spec, out, make(), progress=False)
                    times[name].append(time.perf_counter() - start)
                finally:
                    if name == "ray_2":
                        ray.shutdown()
                        time.sleep(1.0)  # let Ray's processes exit before the next local run
                assert result.ok, result.failures
                rows = rows_of(out)
                reference = reference or rows
                if rows != reference:
                    raise SystemExit(f"{name}: per-episode results differ from the first run's")
    ray_startup = min(startups)
    best = {k: min(v) for k, v in times.items()}
    episodes = len(reference)
    speedup = best["local_1"] / best["local_2"]
    overhead = best["ray_2"] / best["local_2"] - 1.0
    print(
        f"{len(spec.jobs)} jobs, {episodes} episodes; best of {args.repeats}: local 1 worker "
        f"{best['local_1']:.2f} s, 2 workers {best['local_2']:.2f} s "
        f"(x{speedup:.2f}, goal >= {SPEEDUP_GOAL}); "
        f"ray 2 CPUs {best['ray_2']:.2f} s (overhead {overhead:+.1%}, goal <= {RAY_OVERHEAD_GOAL:.0%}), "
        f"ray start-up {ray_startup:.1f} s apart; load average {os.getloadavg()[0]:.2f}"
    )
    print(
        json.dumps(
            {
                "jobs": len(spec.jobs),
                "episodes": episodes,
                "local_1_worker_s": round(best["local_1"], 3),
                "local_2_workers_s": round(best["local_2"], 3),
                "ray_2_cpus_s": round(best["ray_2"], 3),
                "ray_startup_s": round(ray_startup, 3),
                "local_speedup_2_vs_1": round(speedup, 3),
                "ray_overhead_fraction": round(overhead, 4),
                "speedup_goal": SPEEDUP_GOAL,
                "ray_overhead_goal": RAY_OVERHEAD_GOAL,
                "identical_results": True,
                "cpu_count": os.cpu_count(),
                "load_average_1min": round(os.getloadavg()[0], 2),
                "times_s": {k: [round(x, 3) for x in v] for k, v in times.items()},
            }
        )
    )


if __name__ == "__main__":
    main()

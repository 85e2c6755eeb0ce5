"""Sweep executors on this machine: local scaling from 1 to 2 worker processes, and Ray's overhead.

One sweep (linear, ORCA and social-force robots × ORCA and social-force humans on the `wang2022`
protocol, `--episodes` per multi-human scenario, visible and invisible passes, single-human sweeps;
66 chunks of work) is run into fresh directories with the local executor at 1 and 2 workers and with
the Ray executor on a Ray instance of 2 CPUs started in this run, in two phases of `--repeats`
rounds each; the minimum of each configuration is kept. Phase 1, without Ray: local 1 and 2 workers
alternate (`local_speedup_2_vs_1`; an idle Ray instance takes ≈ 0.07 of a core here, which a user
of the local executor does not pay). Phase 2, with Ray started once, as on a cluster where it
already runs: the Ray executor and the local 2-worker one alternate beside the same Ray daemons,
both with warm worker start-up (the local pool forks from a preloaded forkserver; Ray reuses its
worker processes from the second round on): `ray_overhead_fraction` = Ray sweep time / local
2-worker sweep time − 1. Ray's start-up is timed apart. Every run's per-episode results are checked
identical before anything is reported. Prints one JSON object last.

    python benchmarks/bench_sweep.py [--episodes 200] [--repeats 2]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
import warnings
from pathlib import Path

import pyarrow.parquet as pq

from socialnav.sweep.driver import run_sweep
from socialnav.sweep.executors import LocalExecutor, RayExecutor, init_ray
from socialnav.sweep.spec import parse_sweep

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _machine import add_record_arguments, emit, run_record  # noqa: E402  (benchmarks/ is not a package)

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
    add_record_arguments(parser, "bench_sweep")
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
    import ray

    executors = {
        "local_1": lambda: LocalExecutor(1),
        "local_2": lambda: LocalExecutor(2),
        "ray_2": lambda: RayExecutor(),
    }
    times: dict[str, list[float]] = {"local_1": [], "local_2": [], "ray_2": [], "local_2_beside_ray": []}
    reference = None

    def timed(name: str, key: str, out: Path) -> None:
        nonlocal reference
        start = time.perf_counter()
        result = run_sweep(spec, out, executors[name](), progress=False)
        times[key].append(time.perf_counter() - start)
        assert result.ok, result.failures
        rows = rows_of(out)
        reference = reference or rows
        if rows != reference:
            raise SystemExit(f"{key}: per-episode results differ from the first run's")

    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.repeats):  # phase 1: no Ray running
            for name in ("local_1", "local_2"):
                timed(name, name, Path(tmp) / f"{name}-{r}")
        t0 = time.perf_counter()
        init_ray(cpus=2)  # as the Ray executor starts Ray itself
        ray_startup = time.perf_counter() - t0
        try:
            for r in range(args.repeats):  # phase 2: Ray running, as on a cluster
                timed("ray_2", "ray_2", Path(tmp) / f"ray_2-{r}")
                timed("local_2", "local_2_beside_ray", Path(tmp) / f"local_2_beside_ray-{r}")
        finally:
            ray.shutdown()
    best = {k: min(v) for k, v in times.items()}
    episodes = len(reference)
    speedup = best["local_1"] / best["local_2"]
    overhead = best["ray_2"] / best["local_2_beside_ray"] - 1.0
    print(
        f"{len(spec.jobs)} jobs, {episodes} episodes; best of {args.repeats}: local 1 worker "
        f"{best['local_1']:.2f} s, 2 workers {best['local_2']:.2f} s "
        f"(x{speedup:.2f}, goal >= {SPEEDUP_GOAL}); "
        f"ray 2 CPUs {best['ray_2']:.2f} s against local 2 workers beside Ray "
        f"{best['local_2_beside_ray']:.2f} s "
        f"(overhead {overhead:+.1%}, goal <= {RAY_OVERHEAD_GOAL:.0%}), "
        f"ray start-up {ray_startup:.1f} s apart; load average {os.getloadavg()[0]:.2f}"
    )
    emit(
        run_record()
        | {
            "jobs": len(spec.jobs),
            "episodes": episodes,
            "local_1_worker_s": round(best["local_1"], 3),
            "local_2_workers_s": round(best["local_2"], 3),
            "ray_2_cpus_s": round(best["ray_2"], 3),
            "local_2_workers_beside_ray_s": round(best["local_2_beside_ray"], 3),
            "ray_startup_s": round(ray_startup, 3),
            "local_speedup_2_vs_1": round(speedup, 3),
            "ray_overhead_fraction": round(overhead, 4),
            "speedup_goal": SPEEDUP_GOAL,
            "ray_overhead_goal": RAY_OVERHEAD_GOAL,
            "identical_results": True,
            "cpu_count": os.cpu_count(),
            "load_average_1min": round(os.getloadavg()[0], 2),
            "times_s": {k: [round(x, 3) for x in v] for k, v in times.items()},
        },
        args,
    )


if __name__ == "__main__":
    main()

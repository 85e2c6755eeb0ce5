"""Where a world step's time goes at 1..N threads (issue #32's scaling question).

Times, per batch call of bench_world's workload (circle crossing, 5 ORCA humans, ORCA robot):
the robot policy's ``act``, ``World.step`` as a whole, and inside it the native refill + observation
pass (``_refill_natively``); the remainder of ``World.step`` is the core's step pass plus Python.
Prints one JSON object last: per thread count, milliseconds per call of each part and their speed-ups
against 1 thread.

    PYTHONPATH=src python benchmarks/gpu/world_breakdown.py --batch 4096 --threads 1 8 16 [--map spokes]

``--map`` runs the same workload among bench_world.py's walls (spokes or room).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import sys
import time

import numpy as np

from socialnav.maps.static_map import StaticMap
from socialnav.policies import make_policy
from socialnav.scenarios import make_scenario
from socialnav.sim.settings import WorldSettings
from socialnav.sim.world import World

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from bench_world import MAPS  # noqa: E402  (benchmarks/ is not a package)


def breakdown(batch: int, threads: int, seconds: float, static_map: StaticMap | None = None) -> dict:
    scenario = make_scenario("circle_crossing", n_humans=5)
    settings = WorldSettings(time_limit=25.0, threads=threads)
    world = World(settings, scenario, batch, split="train", record=False, static_map=static_map)
    policy = make_policy("orca", safety_space=0.0, threads=threads)
    spent = {"refill": 0.0}
    refill = world._refill_natively

    def timed_refill(*args, **kwargs):
        t = time.perf_counter()
        out = refill(*args, **kwargs)
        spent["refill"] += time.perf_counter() - t
        return out

    world._refill_natively = timed_refill
    obs = world.reset()
    for _ in range(50):
        obs = world.step(policy.act(obs), observe=True).observation
    spent["refill"] = 0.0
    act = step = 0.0
    calls = 0
    faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    start = time.perf_counter()
    while time.perf_counter() - start < seconds:
        t0 = time.perf_counter()
        actions = policy.act(obs)
        t1 = time.perf_counter()
        obs = world.step(actions, observe=True).observation
        t2 = time.perf_counter()
        act += t1 - t0
        step += t2 - t1
        calls += 1
    faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt - faults
    world.close()
    ms = 1e3 / calls
    return {
        "calls": calls,
        "act_ms": act * ms,
        "step_ms": step * ms,
        "refill_observe_ms": spent["refill"] * ms,
        "core_step_and_python_ms": (step - spent["refill"]) * ms,
        "total_ms": (act + step) * ms,
        "minor_faults_per_call": faults / calls,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--batch", type=int, default=4096)
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 8, 16])
    ap.add_argument("--seconds", type=float, default=2.0)
    ap.add_argument("--map", choices=sorted(MAPS), help="bench_world.py's walls (default: the open floor)")
    args = ap.parse_args()
    static_map = StaticMap(tuple(np.array(w) for w in MAPS[args.map]())) if args.map else None
    result = {"batch": args.batch, "map": args.map, "by_threads": {}}
    for t in args.threads:
        r = breakdown(args.batch, t, args.seconds, static_map)
        result["by_threads"][str(t)] = {k: round(v, 4) for k, v in r.items()}
        print(f"{t:2d} threads: " + ", ".join(f"{k} {v:.3f}" for k, v in r.items() if k != "calls"))
    one = result["by_threads"].get("1")
    if one:
        result["speedup_vs_1"] = {
            t: {k: round(one[k] / v[k], 2) for k in ("act_ms", "refill_observe_ms", "core_step_and_python_ms",
                                                     "total_ms") if v[k] > 0}
            for t, v in result["by_threads"].items()
        }
    print(json.dumps(result))


if __name__ == "__main__":
    main()

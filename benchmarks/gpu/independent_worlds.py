"""The ceiling of the world's thread scaling on a machine: N independent 1-thread worlds at once.

Runs bench_world.py's workload in N processes pinned to the first N usable CPUs, each with one thread
and its own batch, all at the same time (``bench_world.independent_worlds``), and compares their summed
env-steps/s with one such process alone (pinned to ``--alone-cpu``). No thread pool, no shared memory
and no Python between threads: what the sum falls short of N is the machine's (shared caches, memory,
the vCPUs' clock under load), and bounds what any threading of one world can reach.
``bench_world.py --scaling-ceiling`` measures the same beside the thread scaling. Last line: one JSON
object.

    PYTHONPATH=src python benchmarks/gpu/independent_worlds.py --processes 16 --batch 4096 --seconds 3
"""

from __future__ import annotations

import argparse
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from bench_world import independent_worlds, usable_cpus  # noqa: E402  (benchmarks/ is not a package)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--processes", type=int, default=os.cpu_count())
    ap.add_argument("--batch", type=int, default=4096, help="each process's batch")
    ap.add_argument("--seconds", type=float, default=3.0)
    ap.add_argument("--alone-cpu", type=int, default=1, help="the CPU of the lone process")
    args = ap.parse_args()
    alone = independent_worlds([args.alone_cpu], args.batch, args.seconds)[0]
    together = independent_worlds(usable_cpus()[: args.processes], args.batch, args.seconds)
    ratio = sum(together) / alone
    print(f"alone on cpu {args.alone_cpu}: {alone:,.0f} env-steps/s; {args.processes} at once: "
          f"{sum(together):,.0f} in all ({ratio:.2f}x), "
          f"per process {min(together):,.0f}-{max(together):,.0f}")
    print(json.dumps({
        "batch": args.batch,
        "processes": args.processes,
        "alone_env_steps_per_s": round(alone),
        "together_env_steps_per_s": [round(x) for x in together],
        "ratio_vs_alone": round(ratio, 3),
    }))


if __name__ == "__main__":
    main()

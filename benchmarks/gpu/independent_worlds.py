"""The ceiling of the world's thread scaling on a machine: N independent 1-thread worlds at once.

Runs bench_world.py's workload (``measure_socialnav``) in N processes pinned to CPUs 0..N-1, each with
one thread and its own batch, all at the same time, and compares their summed env-steps/s with one
such process alone (pinned to one CPU). No thread pool, no shared memory and no Python between
threads: what the sum falls short of N is the machine's (shared caches, memory, the vCPUs' clock under
load), and bounds what any threading of one world can reach. Last line: one JSON object.

    PYTHONPATH=src python benchmarks/gpu/independent_worlds.py --processes 16 --batch 4096 --seconds 3
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ONE = (
    "import json, sys; sys.path.insert(0, {bench!r}); from bench_world import measure_socialnav; "
    "print(json.dumps(measure_socialnav({batch}, {seconds}, 1)))"
)


def run_pinned(cpus: list[int], batch: int, seconds: float) -> list[float]:
    """env-steps/s of one 1-thread world per CPU in ``cpus``, all running at the same time."""
    code = ONE.format(bench=os.path.dirname(HERE), batch=batch, seconds=seconds)
    procs = [
        subprocess.Popen(["taskset", "-c", str(c), sys.executable, "-c", code], stdout=subprocess.PIPE,
                         text=True)
        for c in cpus
    ]
    return [json.loads(p.communicate()[0].strip().splitlines()[-1])["env_steps_per_s"] for p in procs]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--processes", type=int, default=os.cpu_count())
    ap.add_argument("--batch", type=int, default=4096, help="each process's batch")
    ap.add_argument("--seconds", type=float, default=3.0)
    ap.add_argument("--alone-cpu", type=int, default=1, help="the CPU of the lone process")
    args = ap.parse_args()
    alone = run_pinned([args.alone_cpu], args.batch, args.seconds)[0]
    together = run_pinned(list(range(args.processes)), args.batch, args.seconds)
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

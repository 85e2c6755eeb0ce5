"""Wall time of the evaluation half of `socialnav reproduce` on 2 cores (goal: <= 15 min, all policies).

Runs what `socialnav reproduce` runs (every shipped `wang2022` checkpoint plus linear, ORCA and social
force on the full protocol, ORCA humans by default) into a fresh temporary directory, pinned to
``--cores`` cores (default 2; child processes inherit the pinning), and reports the time per policy
so that the total for six learned policies can be extrapolated while fewer ship.

Reference, measured in the same run: the learned policies on a subset (``--reference-episodes`` per
scenario) simulated the previous way, in this process with torch's intra-op threads, against the
current way, chunks simulated in worker processes with one torch thread each. Both give
bit-identical results (tests/evaluate/test_parallel_simulation.py). Prints one JSON object last.

    PYTHONPATH=src python benchmarks/bench_reproduce.py [--episodes 500] [--reference-episodes 10]
    PYTHONPATH=src python benchmarks/bench_reproduce.py --human-model both
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
import warnings
from pathlib import Path

from socialnav.evaluate.multi import default_specs, run_policies
from socialnav.evaluate.reproduce import HUMAN_MODELS, PRESET, preset_for
from socialnav.evaluate.runner import run_protocol
from socialnav.policies.building import build_policy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _machine import add_record_arguments, emit, run_record  # noqa: E402  (benchmarks/ is not a package)

GOAL_SECONDS = 15 * 60
LEARNED_POLICIES_EXPECTED = 6  # cadrl, lstm_rl, sarl, om_sarl, rgl, mp_rgl (+ cadrl_original: 7)


def pin(cores: int) -> list[int]:
    available = sorted(os.sched_getaffinity(0))
    if cores and len(available) > cores:
        os.sched_setaffinity(0, available[:cores])
    return sorted(os.sched_getaffinity(0))


def reference(specs, episodes: int, tmp: Path) -> dict:
    """Learned policies on ``episodes`` per scenario: in-process (previous) vs worker simulation."""
    preset = preset_for("orca")
    out = {}
    for spec in specs:
        if spec.checkpoint is None:
            continue
        times = {}
        for mode, in_workers in (("in_process", False), ("workers", True)):
            policy = build_policy(spec.policy, preset, spec.checkpoint)
            t0 = time.perf_counter()
            run_protocol(policy, preset, tmp / f"ref-{spec.name}-{mode}", episodes=episodes, progress=False,
                         simulate_in_workers=in_workers, workers=None if in_workers else 0)
            times[mode] = round(time.perf_counter() - t0, 2)
        times["speedup"] = round(times["in_process"] / times["workers"], 2)
        out[spec.name] = times
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, help="episodes per scenario (default: the protocol's 500)")
    parser.add_argument("--reference-episodes", type=int, default=10,
                        help="episodes per scenario of the in-process vs workers reference (0: skip)")
    parser.add_argument("--human-model", choices=["orca", "social_force", "both"], default="orca")
    parser.add_argument("--cores", type=int, default=2, help="cores to pin to (0: all)")
    parser.add_argument("--keep", type=Path, help="write results here instead of a temporary directory")
    add_record_arguments(parser, "bench_reproduce")
    args = parser.parse_args()
    cores = pin(args.cores)
    models = HUMAN_MODELS if args.human_model == "both" else (args.human_model,)
    specs = default_specs(PRESET)
    with tempfile.TemporaryDirectory() as tmpdir, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        root = args.keep or Path(tmpdir)
        ref = reference(specs, args.reference_episodes, Path(tmpdir)) if args.reference_episodes else {}
        per_policy: dict[str, float] = {}
        episodes: dict[str, int] = {}
        t0 = time.perf_counter()
        for hm in models:
            result = run_policies(specs, preset_for(hm), root / hm, episodes=args.episodes, progress=False,
                                  log=lambda line: print(line, file=sys.stderr))
            for name, t in result.timings.items():
                per_policy[name] = per_policy.get(name, 0.0) + t["seconds"]
                episodes[name] = episodes.get(name, 0) + t["episodes"]
        seconds = time.perf_counter() - t0
    learned = [s.name for s in specs if s.checkpoint is not None]
    native = [s.name for s in specs if s.checkpoint is None]
    mean_learned = statistics.mean(per_policy[n] for n in learned) if learned else float("nan")
    extrapolated = sum(per_policy[n] for n in native) + LEARNED_POLICIES_EXPECTED * mean_learned
    result = {
        "benchmark": "bench_reproduce",
        "seconds": round(seconds, 2),
        "goal_seconds": GOAL_SECONDS,
        "within_goal": seconds <= GOAL_SECONDS,
        "cores": len(cores),
        "human_models": list(models),
        "episodes_per_scenario": args.episodes or 500,
        "per_policy_seconds": {k: round(v, 2) for k, v in per_policy.items()},
        "per_policy_episodes": episodes,
        "learned_policies": learned,
        "extrapolated_seconds_6_learned": round(extrapolated, 1),
        "reference": {"episodes_per_scenario": args.reference_episodes, "policies": ref},
        "load_average": os.getloadavg(),
    }
    emit(run_record() | result, args)
    return 0


if __name__ == "__main__":
    sys.exit(main())

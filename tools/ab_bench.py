"""A/B speed check of two revisions: the world, the protocol and the trainer, run alternately.

A refactoring must leave the speed where it was (issue #31). This builds the native core of a base
revision in a scratch worktree, then runs the same benchmarks from both trees in turns (base, head,
base, head, ...) so that a change in the machine's load hits both sides alike, and prints one JSON
object with each side's runs and the ratio of the medians (head / base; above 1 is faster for rates,
slower for seconds).

Usage: ``python tools/ab_bench.py BASE_REV [--repeats 3] [--only world protocol train]``. The head is
the working tree this script sits in (its ``src/socialnav/_core*.so`` must be built:
``tools/dev_build.sh``).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

HEAD = Path(__file__).resolve().parent.parent

# Each benchmark: its command (relative to a tree's root) and the key of its JSON last line that is
# compared, with whether larger is better.
BENCHMARKS: dict[str, tuple[list[str], str, bool]] = {
    "world": (["benchmarks/bench_world.py", "--seconds", "2", "--scaling-threads", "1",
               "--scaling-repeats", "1"], "env_steps_per_s", True),
    "protocol": (["benchmarks/bench_protocol.py", "--policy", "orca", "--repeats", "1",
                  "--no-simulation-reference"], "seconds", False),
    # A short fixed-seed schedule: the trainer's own loop (imitation, collection, gradient steps), not
    # the learning result, is what a refactoring could slow down.
    # `--target 2` is never reached, so both sides run the whole short schedule.
    "train": (["benchmarks/bench_train.py", "--policy", "cadrl", "--il-episodes", "200", "--il-epochs", "5",
               "--rl-episodes", "300", "--validate-every", "100", "--target", "2", "--threads", "1",
               "--skip-step-timing"], "wall_seconds", False),
}


def _run(tree: Path, command: list[str]) -> dict:
    env = dict(os.environ, PYTHONPATH=str(tree / "src"))
    out = subprocess.run([sys.executable, *command], cwd=tree, env=env, capture_output=True, text=True)
    if out.returncode != 0:
        raise SystemExit(f"ab_bench: {' '.join(command)} failed in {tree} (exit {out.returncode}):\n"
                         f"{out.stderr[-3000:]}")
    last = [line for line in out.stdout.splitlines() if line.strip()][-1]
    return json.loads(last)


def _base_tree(rev: str, scratch: Path) -> Path:
    tree = scratch / "base"
    subprocess.run(["git", "-C", str(HEAD), "worktree", "add", "--detach", "-q", str(tree), rev], check=True)
    subprocess.run(["bash", "tools/dev_build.sh"], cwd=tree, check=True, capture_output=True)
    return tree


def main(argv: list[str] | None = None) -> None:
    """Run the A/B comparison and print its JSON object as the last line."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("base", help="git revision to compare against (e.g. a commit before a refactoring)")
    parser.add_argument("--repeats", type=int, default=3, help="runs per side and benchmark (alternating)")
    parser.add_argument("--only", nargs="+", choices=sorted(BENCHMARKS), default=sorted(BENCHMARKS))
    args = parser.parse_args(argv)
    if args.repeats < 1:
        parser.error(f"--repeats must be >= 1, got {args.repeats}")
    head_rev = subprocess.run(["git", "-C", str(HEAD), "rev-parse", "--short", "HEAD"], capture_output=True,
                              text=True, check=True).stdout.strip()
    result: dict = {"base": args.base, "head": f"{head_rev} (working tree)", "repeats": args.repeats,
                    "cpu_count": os.cpu_count()}
    with tempfile.TemporaryDirectory(prefix="ab_bench_") as scratch:
        base = _base_tree(args.base, Path(scratch))
        try:
            for name in args.only:
                command, key, larger_is_better = BENCHMARKS[name]
                runs: dict[str, list[float]] = {"base": [], "head": []}
                for _ in range(args.repeats):
                    for side, tree in (("base", base), ("head", HEAD)):
                        runs[side].append(float(_run(tree, command)[key]))
                        print(f"{name} {side}: {key} = {runs[side][-1]}", file=sys.stderr, flush=True)
                ratio = statistics.median(runs["head"]) / statistics.median(runs["base"])
                result[name] = {"key": key, "larger_is_better": larger_is_better, **runs,
                                "head_over_base": round(ratio, 3)}
        finally:
            subprocess.run(["git", "-C", str(HEAD), "worktree", "remove", "--force", str(base)], check=False)
    result["load_average_1min"] = round(os.getloadavg()[0], 2)
    print(json.dumps(result))


if __name__ == "__main__":
    main()

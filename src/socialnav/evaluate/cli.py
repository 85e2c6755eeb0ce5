"""`socialnav replay` argument parsing and command (kept free of torch imports)."""

from __future__ import annotations

import argparse
import sys


def add_replay_parser(sub: argparse._SubParsersAction) -> None:
    rp = sub.add_parser(
        "replay",
        help="re-simulate one stored episode of an evaluation and check it bit for bit",
        description="Re-simulates one episode from the result directory's manifest (preset, policy, "
        "checkpoint, information setting) and compares it with the stored trajectory. Exit status 0 "
        "when identical, 1 when not.",
    )
    rp.add_argument("results", help="result directory of `socialnav evaluate`")
    rp.add_argument("--episode", required=True, help="episode id <scenario>/<visibility>/<index>")
    rp.add_argument("--out", help="also write the replayed trajectory here (.parquet or .csv)")
    rp.add_argument("--quiet", action="store_true", help="print nothing; the exit status tells")
    rp.set_defaults(run=_run_replay)


def _run_replay(args: argparse.Namespace) -> int:
    from socialnav.evaluate.replay import replay_episode

    result = replay_episode(args.results, args.episode)
    if args.out:
        from socialnav.trajectory import write_trajectories

        write_trajectories(args.out, [result.replayed])
    if not args.quiet:
        steps = result.replayed.n_steps
        if result.identical:
            print(
                f"{result.episode_id}: replay identical to the stored trajectory "
                f"({steps} steps, {result.replayed.outcome}; max |difference| {result.max_abs_diff:g})"
            )
        else:
            print(
                f"{result.episode_id}: replay DIFFERS from the stored trajectory "
                f"(max |difference| {result.max_abs_diff:.3g})"
            )
            for line in result.differences:
                print(f"  {line}")
        if args.out:
            print(f"replayed trajectory written to {args.out}", file=sys.stderr)
    return 0 if result.identical else 1

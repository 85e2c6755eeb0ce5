"""The ``replay``, ``reproduce`` and ``evaluate --policy all`` subcommands.

`socialnav replay`, `socialnav reproduce` and `socialnav evaluate --policy all`; the argument parsing is kept
free of torch imports.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from socialnav._progress import warnings_said_once


def add_replay_parser(sub: argparse._SubParsersAction) -> None:
    """Add the ``replay`` subcommand to ``sub``."""
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


def add_reproduce_parser(sub: argparse._SubParsersAction) -> None:
    """Add the ``reproduce`` subcommand to ``sub``."""
    rp = sub.add_parser(
        "reproduce",
        help="Wang et al. 2022's Tables I-III: every shipped wang2022 checkpoint plus linear, ORCA and "
        "social force on the full protocol, beside the paper's numbers",
    )
    rp.add_argument("--quick", action="store_true",
                    help="a few episodes per scenario (smoke test, < 1 min)")
    rp.add_argument(
        "--out", help="result directory (default runs/reproduce, or runs/reproduce-quick); resumed"
    )
    rp.add_argument(
        "--human-model",
        dest="human_model",
        choices=["orca", "social_force", "both"],
        default="orca",
        help="humans of the evaluation: orca (the paper's, default), social_force, or both (adds the "
        "ranking-robustness table ranking.md)",
    )
    rp.add_argument(
        "--episodes", type=int, help="episodes per scenario (default: the protocol's 500; 3 with --quick)"
    )
    rp.add_argument("--workers", type=int,
                    help="worker processes (default: one per core, at most 4; 0: all in this process)")
    rp.add_argument("--batch-size", type=int, default=256,
                    help="episodes simulated in lockstep (default 256)")
    rp.add_argument("--json", action="store_true", help="print one JSON object last (rows of every summary)")
    rp.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    rp.set_defaults(run=cmd_reproduce)


def cmd_reproduce(args: argparse.Namespace) -> int:
    """``socialnav reproduce``: evaluate the wang2022 checkpoints and write Tables I–III.

    Args:
        args: The parsed command line.

    Returns:
        The exit status.
    """
    from socialnav._io import json_safe
    from socialnav.evaluate.reproduce import HUMAN_MODELS, PRESET, run_reproduction

    if args.episodes is not None and args.episodes < 1:
        raise ValueError(f"--episodes must be >= 1, got {args.episodes}")
    if args.workers is not None and args.workers < 0:
        raise ValueError(f"--workers must be >= 0 (0: simulate and score in this process), got "
                         f"{args.workers}")
    models = HUMAN_MODELS if args.human_model == "both" else (args.human_model,)
    out = Path(args.out or ("runs/reproduce-quick" if args.quick else "runs/reproduce"))
    log = None if args.json else (lambda line: print(line, file=sys.stderr))
    with warnings_said_once():
        result = run_reproduction(
            out, human_models=models, quick=args.quick, episodes=args.episodes,
            progress=not args.no_progress, batch_size=args.batch_size, workers=args.workers, log=log,
        )
    if args.json:
        rows = [
            {"human_model": hm, **row} for hm, run in result.runs.items() for row in run.summary
        ]
        print(json.dumps(json_safe({
            "preset": PRESET, "out": str(out), "quick": args.quick, "human_models": list(models),
            "rows": rows, "comparison": result.comparison, "ranking": result.ranking,
            "timings": {hm: run.recorded_timings for hm, run in result.runs.items()},
        })))
        return 0
    for text in result.tables.values():
        print(text)
    files = ", ".join(f"{stem}.md" for stem in result.tables)
    print(f"results in {out}/ ({files}, .tex, reproduction.json; per human model and policy under "
          f"{'/'.join(models)}/policies/)")
    return 0


def cmd_evaluate_all(args: argparse.Namespace, write_report: Any = None) -> int:
    """`socialnav evaluate --policy all`: shipped checkpoints for the preset + native policies.

    Args:
        args: The parsed command line.
        write_report: ``socialnav.viz.report.write_report`` for ``--report`` (the viz layer lies above
            this one, so the command line passes it in), else None.

    Returns:
        The exit status.
    """
    from socialnav._io import json_safe
    from socialnav.evaluate.multi import default_specs, run_policies
    from socialnav.evaluate.report import table2, table3, table_notes
    from socialnav.presets import load_preset

    refused = [
        flag for flag, value in (
            ("--checkpoint", args.checkpoint), ("--label", args.label), ("--information", args.information),
            ("--planning-depth", args.planning_depth), ("--planning-width", args.planning_width),
            ("--policy-arg", args.policy_arg or None),
            ("--allow-preset-mismatch", args.allow_preset_mismatch or None),
        ) if value is not None
    ]
    if refused:
        raise ValueError(f"--policy all takes no {', '.join(refused)} (each policy uses its own settings: "
                         "a preset's `policies:` section sets a policy's parameters)")
    preset = load_preset(args.preset)
    from socialnav.policies.loading import check_preset_policies

    check_preset_policies(preset, args.preset)
    specs = default_specs(preset.name)
    out = Path(args.out or f"runs/evaluate/{preset.name}-all")
    quiet = args.json or args.quiet
    if not any(s.checkpoint for s in specs) and not quiet:
        from socialnav.policies.loading import shipped_checkpoints

        shipped = sorted({e.preset for e in shipped_checkpoints()})
        print(f"note: no checkpoint ships for preset {preset.name!r} (checkpoints ship for "
              f"{', '.join(shipped) or 'no preset'}), so only the native policies run; evaluate a learned "
              "policy with --policy P --checkpoint FILE", file=sys.stderr)
    log = None if quiet else (lambda line: print(line, file=sys.stderr))
    with warnings_said_once():
        result = run_policies(
            specs, preset, out, scenarios=args.scenario, episodes=args.episodes, visibility=args.visibility,
            progress=not (args.no_progress or quiet), batch_size=args.batch_size, log=log,
            trajectories=not args.no_trajectories,
        )
    if write_report is not None:
        write_report([out / "policies" / s.name for s in specs], out / "report.html",
                     progress=not (quiet or args.no_progress))
        if args.quiet:
            print(out / "report.html")  # quiet prints no tables, but the file asked for is named
    if args.json:
        print(json.dumps({"preset": preset.name, "out": str(out), "policies": [s.name for s in specs],
                          "rows": json_safe(result.summary)}))
        return 0
    if args.quiet:
        return 0
    for table in (table2(result.summary, "md", table_notes(preset)), table3(result.summary, "md")):
        if table:
            print(table)
    computed = sum(t["episodes"] for t in result.timings.values())
    print(f"{len(specs)} policies ({', '.join(s.name for s in specs)}), {computed} episodes simulated; "
          f"results in {out}/ (summary.json/csv, table2/3 .md and .tex"
          + (", report.html" if args.report else "") + "; per policy under policies/)")
    return 0

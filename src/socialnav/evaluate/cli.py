"""The ``evaluate``, ``replay`` and ``reproduce`` subcommands.

`socialnav evaluate` (one policy, or ``--policy all``), `socialnav replay` and `socialnav reproduce`: their
parsers and commands; the argument parsing is kept free of torch imports.
"""

from __future__ import annotations

import argparse
import functools
import json
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from socialnav._io import json_safe, load_yaml
from socialnav._progress import warnings_said_once


def add_evaluate_parser(sub: argparse._SubParsersAction,
                        report_writer: Callable[[], Callable[..., Any]]) -> None:
    """Add the ``evaluate`` subcommand to ``sub``.

    Args:
        sub: The subcommands of ``socialnav``.
        report_writer: Gives ``socialnav.viz.report.write_report`` for ``--report`` (see
            :func:`cmd_evaluate`).
    """
    from socialnav.configs import shipped_presets  # the help lists them: it cannot go stale

    ev = sub.add_parser("evaluate", help="run a protocol preset for one policy and print the paper's tables")
    ev.add_argument(
        "--policy",
        default="orca",
        help="registered policy name (see `socialnav list`), an entry point of group socialnav.policies, "
        "module.path:ClassName (docs/custom_policies.md), or all: every shipped checkpoint for the preset "
        "and the native policies into one directory; default orca",
    )
    ev.add_argument(
        "--policy-arg",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="policy parameter, repeatable (e.g. safety_space=0.2); VALUE is read as YAML: "
        "numbers, true/false, null, [lists] and strings",
    )
    ev.add_argument("--checkpoint", help="checkpoint of a learned policy (from `socialnav train`)")
    ev.add_argument(
        "--preset",
        default="wang2022",
        help=f"a shipped preset ({', '.join(shipped_presets())}; see `socialnav preset list`) or a YAML file "
        "(default wang2022)",
    )
    ev.add_argument(
        "--allow-preset-mismatch",
        action="store_true",
        help="evaluate a checkpoint under a preset whose world (dt, kinematics, reward, v_pref...) differs "
        "from the one it was trained for; the differences are recorded in manifest.json",
    )
    ev.add_argument(
        "--information",
        choices=["constant_velocity", "oracle", "learned"],
        help="learned policies: how the humans' next states are predicted in the lookahead "
        "(default: the checkpoint's; learned needs a checkpoint with a state predictor)",
    )
    ev.add_argument(
        "--planning-depth",
        type=int,
        dest="planning_depth",
        help="learned policies: planning depth d (1: one-step lookahead; default: the checkpoint's)",
    )
    ev.add_argument(
        "--planning-width",
        type=int,
        dest="planning_width",
        help="learned policies: planning width w (default: the checkpoint's)",
    )
    ev.add_argument("--scenario", nargs="+", help="only these scenarios (default: the preset's)")
    ev.add_argument("--episodes", type=int, help="episodes per scenario (default: the preset's)")
    ev.add_argument("--visibility", choices=["invisible", "visible", "both"], help="default: the preset's")
    ev.add_argument(
        "--out", help="result directory (default runs/evaluate/<preset>-<policy>); resumed if it exists"
    )
    ev.add_argument("--label", help="policy name in the results (default: the policy's name)")
    ev.add_argument("--batch-size", type=int, default=256,
                    help="episodes simulated in lockstep (default 256)")
    ev.add_argument("--json", action="store_true", help="print one JSON summary object instead of tables")
    ev.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    ev.add_argument(
        "--quiet",
        action="store_true",
        help="no progress bar, no tables (errors still print; with --report, the report's path)",
    )
    ev.add_argument(
        "--no-trajectories",
        action="store_true",
        help="do not keep each episode's trajectory (then replay, render and the viewer are unavailable)",
    )
    ev.add_argument("--report", action="store_true", help="also write the HTML report (report.html)")
    ev.set_defaults(run=functools.partial(cmd_evaluate, report_writer=report_writer))


def cmd_evaluate(args: argparse.Namespace, report_writer: Callable[[], Callable[..., Any]]) -> int:
    """``socialnav evaluate``: run the protocol for one policy and write its results and tables.

    Args:
        args: The parsed command line.
        report_writer: Gives ``socialnav.viz.report.write_report`` for ``--report``, or raises naming the
            extra to install (the viz layer lies above this one, so the command line passes it in).

    Returns:
        The exit status.
    """
    from socialnav.evaluate.plan import preset_for_scenarios
    from socialnav.evaluate.report import mismatch_caveats, table2, table3, table_notes, with_caveats
    from socialnav.evaluate.runner import run_protocol
    from socialnav.policies.building import LOOKAHEAD_SETTINGS, build_policy, refuse_lookahead_setting
    from socialnav.policies.registry import policy_record
    from socialnav.presets import load_preset

    if args.batch_size < 1:
        raise ValueError(f"--batch-size must be >= 1, got {args.batch_size}")
    write_report = report_writer() if args.report else None  # checked before a long evaluation, not after it
    if args.policy != "all" and args.policy.lower() == "all":
        raise ValueError(f"unknown policy {args.policy!r} (did you mean 'all': every shipped checkpoint for "
                         "the preset and the native policies?)")
    if args.policy == "all":
        return cmd_evaluate_all(args, write_report)
    preset = load_preset(args.preset)
    from socialnav.policies.building import check_preset_policies

    check_preset_policies(preset, args.preset)
    overrides = parse_policy_args(args.policy_arg)
    for key in LOOKAHEAD_SETTINGS:
        value = getattr(args, key)
        if value is None:
            continue
        flag = f"--{key.replace('_', '-')}"
        if key in overrides and overrides[key] != value:
            raise ValueError(f"{flag} {value} and --policy-arg {key}={overrides[key]} disagree; give one "
                             "of them")
        refuse_lookahead_setting(args.policy, key, flag)
        overrides[key] = value
    # checked against the scenarios this run evaluates (--scenario may name ones outside the preset's)
    with warnings_said_once(sort=False):
        policy = build_policy(
            args.policy, preset_for_scenarios(preset, args.scenario), args.checkpoint,
            allow_preset_mismatch=args.allow_preset_mismatch, **overrides,
        )
    for difference in getattr(policy, "preset_mismatch", []):
        print(f"warning: preset mismatch allowed: {difference}", file=sys.stderr)
    # A module path would make a poor directory name: such policies are labelled by their own name.
    label = args.label or args.policy
    if not args.label and ":" in args.policy:
        label = str(getattr(policy, "name", "") or args.policy.rpartition(":")[2])
    if not args.out and (Path(label).name != label or label in (".", "..")):
        raise ValueError(f"--label {label!r} would name the result directory runs/evaluate/{preset.name}-"
                         f"{label}, outside runs/evaluate: pass --out, or a label without path separators")
    out = Path(args.out or f"runs/evaluate/{preset.name}-{label}")
    extra: dict[str, Any] = {"checkpoint": str(args.checkpoint) if args.checkpoint else None}
    if ":" in args.policy and not args.policy.startswith("sb3:"):
        # a policy of the user's module: how to build it again (replay), and its arguments, which its own
        # describe() may not record (a changed --policy-arg must not resume into the old results)
        extra["policy_entry"] = args.policy
        extra["policy_args"] = overrides
    sensors = dict(getattr(policy, "sensors", None) or {})
    if sensors and "sensors" not in policy_record(policy):
        # the lidar it brings to the preset's world (the manifest's world.sensing is the preset's)
        extra["policy_sensors"] = sensors
    if args.checkpoint:  # by content: a resume never mixes two networks saved at one path
        from socialnav._io import file_sha256

        extra["checkpoint_sha256"] = file_sha256(args.checkpoint)
    with warnings_said_once():  # once per run, not once per episode
        result = run_protocol(
            policy,
            preset,
            out,
            label=label,
            scenarios=args.scenario,
            episodes=args.episodes,
            visibility=args.visibility,
            progress=not (args.no_progress or args.quiet),
            batch_size=args.batch_size,
            trajectories=not args.no_trajectories,
            extra_manifest=extra,
        )
    if write_report is not None:
        write_report(out, out / "report.html", progress=not (args.no_progress or args.quiet))
        if args.quiet:
            print(out / "report.html")  # quiet prints no tables, but the file asked for is named
    if args.json:
        print(json.dumps({"preset": preset.name, "out": str(out), "rows": json_safe(result.summary)}))
    elif not args.quiet:
        caveats = mismatch_caveats(policy.describe())
        for table in (table2(result.summary, "md", table_notes(preset)), table3(result.summary, "md")):
            if table:  # a run without multi- or single-human scenarios has no such table
                print(with_caveats(table, caveats))
        print(
            f"{result.computed_episodes} episodes simulated, results in {out}/ "
            f"(summary.json, summary.csv, table2/3 .md and .tex, episodes/*.parquet"
            + ("" if args.no_trajectories else ", trajectories/*.parquet")
            + (", report.html" if args.report else "")
            + ")"
        )
    return 0


def parse_policy_args(items: list[str]) -> dict[str, Any]:
    """``["safety_space=0.2", "mode=fast"]`` -> ``{"safety_space": 0.2, "mode": "fast"}`` (YAML values)."""
    import yaml

    params: dict[str, Any] = {}
    for item in items:
        key, sep, text = item.partition("=")
        key = key.strip()
        if not sep or not key.isidentifier():
            raise ValueError(f"--policy-arg {item!r}: expected KEY=VALUE with KEY a parameter name")
        if key in params:
            raise ValueError(f"--policy-arg {key} given twice")
        try:
            params[key] = load_yaml(text) if text.strip() else ""
        except yaml.YAMLError as err:
            raise ValueError(f"--policy-arg {item!r}: VALUE is not valid YAML ({err})") from None
    return params


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

    with warnings_said_once(sort=False):  # the policy's load notes, as `evaluate` says them
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
    from socialnav.policies.building import check_preset_policies

    check_preset_policies(preset, args.preset)
    from socialnav.policies.learned_loading import walled_scenarios

    evaluated = [*preset.evaluation.multi_human, *preset.evaluation.single_human]
    specs = default_specs(preset.name, walls=bool(walled_scenarios(evaluated)))
    out = Path(args.out or f"runs/evaluate/{preset.name}-all")
    quiet = args.json or args.quiet
    if not any(s.checkpoint for s in specs) and not quiet:
        from socialnav.policies.building import shipped_checkpoints

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

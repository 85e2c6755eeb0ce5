"""The ``socialnav`` command line: evaluate, metrics, list, train.

socialnav evaluate --policy orca --preset wang2022
socialnav metrics my_robot_log.parquet --json
socialnav list
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import warnings
from pathlib import Path
from typing import Any

USER_ERRORS: tuple[type[BaseException], ...] = (ValueError, KeyError, FileNotFoundError, RuntimeError)


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not hasattr(args, "run"):
        parser.print_help()
        return 2
    try:
        return args.run(args) or 0
    except USER_ERRORS as err:
        # Bad input is the user's to fix: one clear line, no traceback.
        message = err.args[0] if isinstance(err, KeyError) and err.args else str(err)
        print(f"socialnav {args.command}: error: {message}", file=sys.stderr)
        return 2


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="socialnav", description="Crowd navigation: simulate, evaluate, train."
    )
    sub = parser.add_subparsers(dest="command")

    ev = sub.add_parser("evaluate", help="run a protocol preset for one policy and print the paper's tables")
    ev.add_argument(
        "--policy",
        default="orca",
        help="registered policy name (see `socialnav list`), or all: every shipped checkpoint for the "
        "preset and the native policies into one directory; default orca",
    )
    ev.add_argument("--checkpoint", help="checkpoint of a learned policy (from `socialnav train`)")
    ev.add_argument("--preset", default="wang2022", help="wang2022, crowdnav or a YAML file")
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
    ev.add_argument("--batch-size", type=int, default=256, help="episodes simulated in lockstep")
    ev.add_argument("--json", action="store_true", help="print one JSON summary object instead of tables")
    ev.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    ev.set_defaults(run=cmd_evaluate)

    me = sub.add_parser("metrics", help="score trajectories from a Parquet/CSV file (e.g. a robot log)")
    me.add_argument("file", help="trajectory file (.parquet or .csv; schema in docs/trajectory_format.md)")
    me.add_argument("--resample", action="store_true", help="resample irregular timestamps to a fixed dt")
    me.add_argument("--dt", type=float, help="dt for --resample [s] (default: the median step)")
    me.add_argument(
        "--all-episodes",
        action="store_true",
        help="score social metrics on every episode, not only successful ones (logs)",
    )
    me.add_argument("--json", action="store_true", help="print one JSON object")
    me.set_defaults(run=cmd_metrics)

    ls = sub.add_parser("list", help="registered scenarios, policies, human models, metrics and presets")
    ls.add_argument("--json", action="store_true")
    ls.set_defaults(run=cmd_list)

    from socialnav.train.cli import add_train_parser  # torch is imported only when training runs

    add_train_parser(sub)
    from socialnav.evaluate.cli import add_reproduce_parser

    add_reproduce_parser(sub)
    return parser


def cmd_evaluate(args: argparse.Namespace) -> int:
    from socialnav.evaluate.report import table2, table3
    from socialnav.evaluate.runner import run_protocol
    from socialnav.policies.loading import build_policy
    from socialnav.presets import load_preset

    if args.policy == "all":
        from socialnav.evaluate.cli import cmd_evaluate_all

        return cmd_evaluate_all(args)
    preset = load_preset(args.preset)
    overrides = {
        k: getattr(args, k)
        for k in ("information", "planning_depth", "planning_width")
        if getattr(args, k) is not None
    }
    policy = build_policy(args.policy, preset, args.checkpoint, **overrides)
    label = args.label or args.policy
    out = Path(args.out or f"runs/evaluate/{preset.name}-{label}")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = run_protocol(
            policy,
            preset,
            out,
            label=label,
            scenarios=args.scenario,
            episodes=args.episodes,
            visibility=args.visibility,
            progress=not args.no_progress,
            batch_size=args.batch_size,
            extra_manifest={"checkpoint": str(args.checkpoint) if args.checkpoint else None},
        )
    for note in sorted({str(w.message) for w in caught}):  # once per run, not once per episode
        print(f"warning: {note}", file=sys.stderr)
    if args.json:
        print(json.dumps({"preset": preset.name, "out": str(out), "rows": _clean(result.summary)}))
    else:
        print(table2(result.summary, "md"))
        print(table3(result.summary, "md"))
        print(
            f"{result.computed_episodes} episodes simulated, results in {out}/ "
            f"(summary.json, summary.csv, table2/3 .md and .tex, episodes/*.parquet)"
        )
    return 0


def cmd_metrics(args: argparse.Namespace) -> int:
    from socialnav.evaluate.summary import summarize_episodes
    from socialnav.metrics import score_episode
    from socialnav.trajectory import read_trajectories

    trajs = read_trajectories(args.file, resample=args.resample, dt=args.dt)
    rows = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for i, traj in enumerate(trajs):
            episode = traj.settings.get("episode", i)
            rows.append(
                {
                    "policy": str(traj.settings.get("policy", "log")),
                    "scenario": str(traj.settings.get("scenario", "log")),
                    "visibility": str(traj.settings.get("visibility", "unknown")),
                    "index": i,
                    "episode": str(episode),
                    "outcome": traj.outcome,
                    **score_episode(traj, require_success=not args.all_episodes),
                }
            )
    summary = summarize_episodes([{k: v for k, v in r.items() if k != "episode"} for r in rows])
    notes = sorted({str(w.message) for w in caught})
    if args.json:
        print(
            json.dumps(
                {"file": args.file, "episodes": _clean(rows), "summary": _clean(summary), "warnings": notes}
            )
        )
        return 0
    for note in notes:
        print(f"warning: {note}", file=sys.stderr)
    ids = ("policy", "scenario", "visibility", "index", "episode", "outcome")
    keys = [k for k in rows[0] if k not in ids]
    for row in rows:
        print(f"episode {row['episode']} ({row['outcome']}):")
        for k in keys:
            print(f"  {k:60s} {row[k]:.4g}")
    for group in summary:
        print(f"summary over {group['episodes']} episode(s) [{group['scenario']}, {group['visibility']}]:")
        for k in keys:
            mean, std = group.get(f"{k}.mean"), group.get(f"{k}.std")
            if mean is not None:
                print(f"  {k:60s} {mean:.4g} ± {std:.3g} (n={group.get(f'{k}.n')})")
    return 0


def cmd_list(args: argparse.Namespace) -> int:
    from socialnav.metrics import list_metrics
    from socialnav.policies import list_policies
    from socialnav.presets import shipped_presets
    from socialnav.scenarios import list_scenarios
    from socialnav.sim.settings import HUMAN_MODELS

    data = {
        "scenarios": {
            name: [{"name": p.name, "default": p.default, "doc": p.doc} for p in params]
            for name, params in list_scenarios().items()
        },
        "policies": [
            {"name": p.name, "description": p.description, "learned": p.learned, "parameters": p.parameters}
            for p in list_policies()
        ],
        "human_models": list(HUMAN_MODELS),
        "metrics": [
            {
                "name": m.name,
                "unit": m.unit,
                "direction": m.direction,
                "parameters": dict(m.parameters),
                "variants": [dict(v) for v in m.variants],
                "outputs": dict(m.outputs),
            }
            for m in list_metrics()
        ],
        "presets": shipped_presets(),
    }
    if args.json:
        print(json.dumps(data, default=str))
        return 0
    print("Scenarios:")
    for name, params in data["scenarios"].items():
        print(f"  {name}: " + ", ".join(f"{p['name']}={p['default']}" for p in params))
    print("Policies:")
    for p in data["policies"]:
        extra = ", ".join(f"{k}={v}" for k, v in p["parameters"].items())
        print(
            f"  {p['name']}{' (learned)' if p['learned'] else ''}: {p['description']}"
            + (f" [{extra}]" if extra else "")
        )
    print("Human models: " + ", ".join(data["human_models"]))
    print("Metrics:")
    for m in data["metrics"]:
        params = ", ".join(f"{k}={v}" for k, v in m["parameters"].items())
        print(f"  {m['name']} [{m['unit']}, {m['direction']} is better]" + (f" ({params})" if params else ""))
    print("Presets: " + ", ".join(data["presets"]))
    return 0


def _clean(value: Any) -> Any:
    """JSON-safe copy: NaN/inf become null (JSON has no NaN)."""
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_clean(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if hasattr(value, "item"):
        return _clean(value.item())
    return value


if __name__ == "__main__":
    sys.exit(main())

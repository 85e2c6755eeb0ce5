"""The ``socialnav`` command line.

Subcommands: evaluate, metrics, list, preset, train, replay, render, report, reproduce, sweep.

socialnav evaluate --policy orca --preset wang2022 --report
socialnav metrics my_robot_log.parquet --json
socialnav list
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from typing import Any

USER_ERRORS: tuple[type[BaseException], ...] = (
    ImportError,  # an optional dependency not installed (the extra is named), or no compiled core
    ValueError,  # ConfigError, CheckpointError, TrajectoryFormatError, ResumeMismatchError's base too
    KeyError,
    LookupError,
    RuntimeError,
    OSError,  # missing, unreadable, unwritable file or directory; disk full
    TypeError,
    AttributeError,
    OverflowError,
    MemoryError,
    EOFError,
)
#: Set this environment variable to see the traceback behind a one-line error.
TRACEBACK_ENV = "SOCIALNAV_TRACEBACK"


class Terminated(BaseException):
    """SIGTERM (a scheduler, ``timeout`` or a CI cancel): unwinds like Ctrl-C so finished work is kept."""


def main(argv: list[str] | None = None) -> int:
    """Run the ``socialnav`` command line.

    Args:
        argv: The arguments after the program name (default: ``sys.argv[1:]``).

    Returns:
        The process exit status (0 on success).
    """
    parser = build_parser()
    args = parser.parse_args(argv)
    if not hasattr(args, "run"):
        parser.print_help()
        return 2
    for option in ("out", "checkpoint", "preset", "config"):
        if getattr(args, option, None) == "":  # `--out "$OUT"` with OUT unset: not the default directory
            print(f"socialnav {args.command}: error: --{option} is empty (an unset shell variable?): give a "
                  f"value or leave --{option} out", file=sys.stderr)
            return 2
    previous = _on_sigterm()
    try:
        return args.run(args) or 0
    except KeyboardInterrupt:
        print(f"socialnav {args.command}: interrupted; {_resume_hint(args)}", file=sys.stderr)
        return 130
    except BrokenPipeError:  # `socialnav list | head`: the reader has gone; nothing to report
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0
    except Terminated:
        print(f"socialnav {args.command}: terminated (SIGTERM); {_resume_hint(args)}", file=sys.stderr)
        return 143
    except (*USER_ERRORS, _pickle_error()) as err:
        # Bad input is the user's to fix: one clear line, no traceback.
        if os.environ.get(TRACEBACK_ENV):
            raise
        print(f"socialnav {args.command}: error: {error_line(err)}", file=sys.stderr)
        return 2
    finally:
        _restore_sigterm(previous)


#: The extra that installs an optional dependency (pyproject.toml, docs/installation.md).
_EXTRAS = {"torch": "learn", "matplotlib": "viz", "PIL": "viz", "ray": "ray", "stable_baselines3": "sb3",
           "navground": "reference"}


def error_line(err: BaseException) -> str:
    """One line naming the problem: the message (a KeyError's unquoted), else the error's type."""
    if isinstance(err, ImportError):
        root = (err.name or "").split(".")[0]
        if root in _EXTRAS:
            return (f"this needs {root}, which is not installed: pip install 'socialnav[{_EXTRAS[root]}]' "
                    "(docs/installation.md)")
        if "_core" in str(err):
            return ("socialnav's compiled core (_core) is missing: install the package (python -m pip "
                    "install .), or build it in a source checkout (bash tools/dev_build.sh)")
    message = err.args[0] if isinstance(err, KeyError) and err.args else str(err)
    if isinstance(err, OSError) and err.strerror:
        message = f"{err.filename}: {err.strerror}" if err.filename is not None else err.strerror
    if isinstance(err, MemoryError) or not message.strip():
        message = f"{type(err).__name__}{': ' + message if message.strip() else ''}"
        if isinstance(err, MemoryError):
            message += " (out of memory: reduce --batch-size, episodes or the world's horizon)"
    lines = [line.strip() for line in str(message).splitlines() if line.strip()]
    return " ".join(lines)


def _resume_hint(args: argparse.Namespace) -> str:
    if args.command == "train":
        return ("re-run the same command to resume from the last checkpoint (during imitation il_state.pt, "
                "then last.pt, written every checkpoint_every RL episodes or PPO updates; the work since it "
                "is done again)")
    if args.command in ("evaluate", "sweep", "reproduce"):
        return "finished results are kept; re-run the same command to resume"
    return "nothing was written"


def _pickle_error() -> type[BaseException]:
    import pickle

    return pickle.UnpicklingError


def _raise_terminated(signum, frame) -> None:
    raise Terminated()


def _on_sigterm():
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return None
    return signal.signal(signal.SIGTERM, _raise_terminated)


def _restore_sigterm(previous) -> None:
    import signal

    if previous is not None:
        signal.signal(signal.SIGTERM, previous)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``socialnav`` with every subcommand."""
    from socialnav.evaluate.cli import add_evaluate_parser, add_replay_parser, add_reproduce_parser

    parser = argparse.ArgumentParser(
        prog="socialnav", description="Crowd navigation: simulate, evaluate, train."
    )
    parser.add_argument("--version", action="version", version=f"socialnav {_version()}")
    sub = parser.add_subparsers(dest="command")

    add_evaluate_parser(sub, _report_writer)

    from socialnav.logs.command import add_metrics_parser

    add_metrics_parser(sub)

    ls = sub.add_parser("list", help="registered scenarios, policies, human models, metrics and presets")
    ls.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    ls.set_defaults(run=cmd_list)

    pr = sub.add_parser("preset", help="the shipped protocol presets: list them, print one to start from")
    pr_sub = pr.add_subparsers(dest="preset_command", metavar="{list,show}", required=True)
    pr_show = pr_sub.add_parser(
        "show",
        help="print a shipped preset's YAML (comments included); save it, edit it, pass it with "
        "--preset FILE.yaml",
    )
    pr_show.add_argument("name", help="shipped preset name (see `socialnav preset list`)")
    pr_show.set_defaults(run=cmd_preset_show)
    pr_list = pr_sub.add_parser("list", help="the shipped presets with their descriptions")
    pr_list.set_defaults(run=cmd_preset_list)

    from socialnav.train.cli import add_train_parser  # torch is imported only when training runs
    from socialnav.viz.cli import add_viz_parsers

    add_train_parser(sub)
    add_replay_parser(sub)
    add_viz_parsers(sub)
    add_reproduce_parser(sub)
    from socialnav.sweep.cli import add_sweep_parser

    add_sweep_parser(sub)
    return parser


def _report_writer() -> Any:
    """``socialnav.viz.report.write_report``, once the viz extra is known to be installed.

    ``socialnav evaluate --report`` asks for it before a long evaluation, not after it; the viz layer
    lies above evaluate, so the command line hands it down.
    """
    from socialnav.viz import require_viz

    require_viz()
    from socialnav.viz.report import write_report

    return write_report


def _version() -> str:
    from socialnav import __version__

    return __version__


def cmd_preset_show(args: argparse.Namespace) -> int:
    """``socialnav preset show NAME``: print a shipped preset's YAML.

    Args:
        args: The parsed command line.

    Returns:
        The exit status.
    """
    from socialnav.presets import shipped_preset_text

    text = shipped_preset_text(args.name)
    print(
        f"# The shipped preset {args.name!r} (socialnav {_version()}). To start your own:\n"
        f"#   socialnav preset show {args.name} > my_preset.yaml; edit name: and the settings; then\n"
        "#   socialnav evaluate --preset my_preset.yaml"
    )
    print(text, end="" if text.endswith("\n") else "\n")
    return 0


def cmd_preset_list(args: argparse.Namespace) -> int:
    """``socialnav preset list``: print every shipped preset with its description.

    Args:
        args: The parsed command line.

    Returns:
        The exit status.
    """
    from socialnav.presets import load_preset, shipped_presets

    for name in shipped_presets():
        print(f"{name}: {load_preset(name).description}")
    return 0


def cmd_list(args: argparse.Namespace) -> int:
    """``socialnav list``: registered policies, metrics, scenarios, observation parts, presets, checkpoints.

    Args:
        args: The parsed command line.

    Returns:
        The exit status.
    """
    from socialnav.envs.registration import ENV_IDS
    from socialnav.metrics import list_metrics
    from socialnav.policies import list_policies
    from socialnav.policies.building import list_shipped_checkpoints
    from socialnav.presets import shipped_presets
    from socialnav.scenarios import list_scenarios
    from socialnav.sim.behaviours import list_human_behaviours
    from socialnav.sim.parts import list_observation_parts
    from socialnav.train.registry import list_trainers

    trainers = list_trainers()  # first: a trainer's plugin may register the learned policies it trains
    data = {
        "scenarios": {
            name: [
                {"name": p.name, "default": p.default, "doc": p.doc, "type": p.type, "unit": p.unit,
                 "constraint": p.constraint}
                for p in params
            ]
            for name, params in list_scenarios().items()
        },
        "policies": [
            {"name": p.name, "description": p.description, "learned": p.learned, "parameters": p.parameters}
            for p in list_policies()
        ],
        "trainers": [t.describe() for t in trainers],
        "human_models": [b.name for b in list_human_behaviours()],
        "pedestrian_behaviours": [b.describe() for b in list_human_behaviours()],
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
        "observations": [
            {"name": part.name, "description": part.description, "frames": list(part.frames()),
             "columns": {key: {frame: list(names) for frame, names in per_frame.items()}
                         for key, per_frame in part.columns.items()}}
            for part in list_observation_parts()
        ],
        "presets": shipped_presets(),
        "gym_ids": {env_id: kwargs["scenario"] for env_id, kwargs in ENV_IDS.items()},
        "checkpoints": list_shipped_checkpoints(),
    }
    if args.json:
        print(json.dumps(data, default=str))
        return 0
    print("Scenarios (parameter=default unit (constraint)):")
    for name, params in data["scenarios"].items():
        print(f"  {name}: " + ", ".join(_parameter_text(p) for p in params))
    import importlib.util

    without_torch = importlib.util.find_spec("torch") is None
    no_torch = " (learned ones need PyTorch, not installed here: pip install 'socialnav[learn]')"
    print("Policies [settings=default]:" + (no_torch if without_torch else ""))
    print("  (a learned policy's information and planning settings come from its checkpoint unless given;"
          " the defaults shown are a new training run's)")
    for p in data["policies"]:
        extra = ", ".join(f"{k}={v}" for k, v in p["parameters"].items())
        print(
            f"  {p['name']}{' (learned)' if p['learned'] else ''}: {p['description']}"
            + (f" [{extra}]" if extra else "")
        )
    print("Trainers (socialnav train --policy P trains P with its trainer; docs/extending.md):")
    for t in data["trainers"]:
        print(f"  {t['name']}: {t['description']} [policies: {', '.join(t['policies']) or 'none'}; "
              f"settings {t['settings']}, default config {t['default_config'] or 'none'}, "
              f"writes {', '.join(t['checkpoints'])}]")
    print("Pedestrian behaviours (world.human_model; parameter=default unit (constraint); "
          "docs/extending.md):")
    for b in data["pedestrian_behaviours"]:
        params = ", ".join(_parameter_text(p) for p in b["parameters"])
        print(f"  {b['name']}{'' if b['native'] else ' (Python)'}: {b['description']}"
              + (f" [{params}]" if params else ""))
    print("Metrics:")
    for m in data["metrics"]:
        params = ", ".join(f"{k}={v}" for k, v in m["parameters"].items())
        print(f"  {m['name']} [{m['unit']}, {m['direction']} is better]" + (f" ({params})" if params else ""))
    print("Observation parts (ObservationSettings.parts, the envs' observation_parts; docs/extending.md):")
    for o in data["observations"]:
        widths = ", ".join(f"{key} {'/'.join(f'{len(c)} ({f})' for f, c in cols.items())}"
                           for key, cols in o["columns"].items())
        # a key's columns per row (per human slot, per obstacle point, per lidar beam)
        print(f"  {o['name']}: {o['description']}" + (f" [columns per row: {widths}]" if widths else ""))
    print("Presets: " + ", ".join(data["presets"]))
    print("Gymnasium ids (gym.make / gym.make_vec; docs/simulator.md):")
    for env_id, scenario in data["gym_ids"].items():
        print(f"  {env_id}: {scenario}")
    print(
        "Shipped checkpoints (<policy>_<preset>, used by `evaluate --policy P --preset S` without "
        "--checkpoint): " + (", ".join(data["checkpoints"]) or "none")
    )
    return 0


def _parameter_text(p: dict[str, Any]) -> str:
    """One scenario parameter as ``socialnav list`` prints it: ``robot_radius=0.3 m (> 0)``."""
    unit = f" {p['unit']}" if p["unit"] else ""
    constraint = f" ({p['constraint']})" if p["constraint"] else ""
    return f"{p['name']}={p['default']}{unit}{constraint}"


if __name__ == "__main__":
    sys.exit(main())

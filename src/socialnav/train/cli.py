"""`socialnav train`: its options, their checks, and the dispatch to the policy's trainer (no torch import).

The policy's record names its trainer (train/registry.py); the trainer's record says which config it
takes by default, which options it takes and how they map onto its settings, and what its summary
reports. Nothing here names a trainer.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from socialnav._io import load_yaml
from socialnav.configs import shipped_presets
from socialnav.policies.learned_catalog import canonical_name, learned_policy_names
from socialnav.train.registry import OPTIONS, Trainer, list_trainers, trainer_for_policy


def add_train_parser(sub: argparse._SubParsersAction) -> None:
    """Adds ``socialnav train`` and its options to the console script's subcommands.

    Args:
        sub: the console script's subparsers.
    """
    trainers = [t for t in list_trainers(plugins=False) if t.policies()]  # plugins: when a command trains
    tr = sub.add_parser(
        "train",
        help="train a learned policy with its trainer (" + "; ".join(
            f"{t.label}: {', '.join(t.policies())}" for t in trainers) + ")",
    )
    tr.add_argument(
        "--policy",
        required=True,
        help="; ".join(f"{', '.join(t.policies())} ({t.label}{', ' + t.docs if t.docs else ''})"
                       for t in trainers),
    )
    tr.add_argument(
        "--preset",
        default="wang2022",
        help=f"a shipped preset ({', '.join(shipped_presets())}; see `socialnav preset list`) or a YAML file "
        "(default wang2022)",
    )
    tr.add_argument(
        "--out", help="run directory (default runs/train/<preset>-<policy>-s<seed>); resumed if it exists"
    )
    tr.add_argument("--seed", type=int, default=None, help="master seed (default: the config's, 0)")
    tr.add_argument(
        "--device",
        default=None,
        choices=["cpu", "cuda", "auto"],
        help="cpu (default), cuda, or auto (cuda when available)",
    )
    defaults = "; ".join(f"{t.label}: default {t.default_config or 'the settings defaults'}"
                         + (f", smoke test {t.smoke_config}" if t.smoke_config else "") for t in trainers)
    tr.add_argument(
        "--config",
        help=f"YAML file or shipped config name overriding the trainer's settings ({defaults}; "
        "docs/training.md, docs/ppo.md)",
    )
    takes = {option: [t.label for t in trainers if option in t.options] for option in OPTIONS}

    def only(option: str) -> str:
        if len(takes[option]) == len(trainers):
            return ""
        return f"{'/'.join(takes[option]) or 'no'} trainer only: "

    tr.add_argument(
        "--env-steps",
        type=int,
        dest="env_steps",
        help=f"{only('env_steps')}total environment steps (default: the config's total_env_steps)",
    )
    tr.add_argument(
        "--information",
        choices=["constant_velocity", "oracle", "learned"],
        help=f"{only('information')}lookahead prediction of the humans' next states (default "
        "constant_velocity; mp_rgl: learned, a state predictor trained in the same run)",
    )
    tr.add_argument(
        "--collection-batch",
        type=int,
        dest="collection_batch",
        help="episodes stepped in lockstep while collecting (default: the config's, 128 in the default "
        "schedule; PPO: n_envs)",
    )
    tr.add_argument("--rl-episodes", type=int, dest="rl_episodes",
                    help=f"{only('rl_episodes')}RL episodes (default: the config's, 10000 in the default "
                    "schedule)")
    tr.add_argument(
        "--compile",
        action="store_true",
        default=None,
        help=f"{only('compile')}compile the training steps (RL: one compiled graph per gradient step where "
        "the network allows; faster; needs a C++ compiler; a compiled run's floating-point results differ "
        "from an eager one's, see docs/training_speed.md)",
    )
    tr.add_argument("--no-progress", action="store_true", help="hide the progress bars")
    tr.add_argument("--quiet", action="store_true", dest="no_progress", help="same as --no-progress")
    tr.set_defaults(run=_run)


def _read_config(config: str | None) -> dict[str, Any] | None:
    """A training config's mapping, or None where there is none or it cannot be read.

    An unreadable file is left to the trainer's own loader, which says why.
    """
    import yaml

    from socialnav.settings import ConfigError
    from socialnav.train.settings_files import resolve_config_path

    if config is None:
        return None
    try:
        data = load_yaml(resolve_config_path(config).read_text(encoding="utf-8"))
    except (ConfigError, OSError, UnicodeDecodeError, yaml.YAMLError):
        return None
    return data if isinstance(data, dict) else None


def _config_trainer(data: dict[str, Any] | None) -> str | None:
    """The trainer whose settings a training config's keys are, or None.

    None where the keys fit several trainers' settings (e.g. only ``threads``) or none (the
    trainer's own loader then names the unknown ones), or there is no readable config. A run's record
    names its trainer.
    """
    from socialnav.train.settings_files import is_run_record, record_trainer

    if data is None:
        return None
    if is_run_record(data):  # its trainer is written there
        return record_trainer(data)
    fits = [t.name for t in list_trainers() if t.fits(data)]
    return fits[0] if len(fits) == 1 else None


def _config_policy(data: dict[str, Any] | None) -> str | None:
    """The learned policy a plain training config names with ``policy:``, else None.

    A run's record is left out: reusing one run's settings for another policy is what it is for.
    """
    from socialnav.train.settings_files import is_run_record

    if data is None or is_run_record(data):
        return None
    named = data.get("policy")
    return str(named) if isinstance(named, str) and named in learned_policy_names() else None


def _given_options(args: argparse.Namespace) -> dict[str, Any]:
    """The trainer options (:data:`~socialnav.train.registry.OPTIONS`) the command line gives."""
    given = {option: getattr(args, option, None) for option in OPTIONS}
    return {option: value for option, value in given.items() if value is not None}


def _check_args(args: argparse.Namespace) -> Trainer:
    """Refuses what the command line itself gets wrong, naming the option (before any config is read).

    Returns:
        The policy's trainer.
    """
    from socialnav.settings import ConfigError
    from socialnav.train.registry import get_trainer
    from socialnav.train.settings_files import shipped_train_configs

    trainer = trainer_for_policy(args.policy)
    config = getattr(args, "config", None)
    data = _read_config(config)
    other = _config_trainer(data)
    if other is not None and other != trainer.name:
        theirs = get_trainer(other).label if other in {t.name for t in list_trainers()} else other
        own = [name for name in shipped_train_configs()
               if _config_trainer(_read_config(name)) == trainer.name]
        raise ConfigError(
            f"--config {config}: a {theirs} config, and {args.policy} trains with the {trainer.label} "
            f"trainer (its shipped configs: {', '.join(own) or 'none'})"
        )
    named = _config_policy(data)
    if named is not None and canonical_name(named) != canonical_name(args.policy):
        raise ConfigError(f"--config {config} sets policy: {named}, and --policy {args.policy}: the run "
                          "would train one of them silently; give one (remove policy: from the file)")
    for option, value, least in (
        ("--env-steps", getattr(args, "env_steps", None), 1),
        ("--collection-batch", getattr(args, "collection_batch", None), 1),
        ("--rl-episodes", getattr(args, "rl_episodes", None), 0),
    ):
        if value is not None and value < least:
            raise ConfigError(f"{option} must be >= {least}, got {value}")
    refused = [option for option in _given_options(args) if option not in trainer.options]
    if refused:
        raise trainer.refuse_options(refused, args.policy)
    return trainer


def _check_config_device(config: str | None, device: str, given: str | None) -> None:
    """Names the config file where a ``device: cuda`` it sets cannot be had (not the command line's).

    Raises:
        ConfigError: The file asks for CUDA and this machine has none.
    """
    import torch

    from socialnav.settings import ConfigError

    if given is None and config is not None and device == "cuda" and not torch.cuda.is_available():
        raise ConfigError(f"--config {config}: device: cuda, and torch.cuda.is_available() is False here "
                          "(give --device cpu, or device: auto in the file)")


def _run(args: argparse.Namespace) -> int:
    from socialnav._progress import warnings_said_as_they_come

    with warnings_said_as_they_come():
        return _train(args)


def _train(args: argparse.Namespace) -> int:
    """Trains the policy with its trainer; the summary is printed as one JSON line (exit status 0)."""
    from socialnav.presets import load_preset

    trainer = _check_args(args)
    config, device = getattr(args, "config", None), getattr(args, "device", None)
    settings = trainer.load_settings(config, policy=args.policy, seed=getattr(args, "seed", None),
                                     device=device, **_given_options(args))
    _check_config_device(config, settings.device, device)
    preset = load_preset(args.preset)
    out = Path(args.out or f"runs/train/{preset.name}-{args.policy}-s{settings.seed}")
    result = trainer.run(args.policy, preset, out, settings, progress=not getattr(args, "no_progress", False))
    print(json.dumps(trainer.summary(result)))
    return 0

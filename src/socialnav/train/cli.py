"""`socialnav train` argument parsing (kept free of torch imports)."""

from __future__ import annotations

import argparse
from typing import Any

from socialnav._io import load_yaml
from socialnav.configs import shipped_presets
from socialnav.policies.learned_catalog import canonical_name, get_learned_spec, learned_policy_names


def add_train_parser(sub: argparse._SubParsersAction) -> None:
    """Adds ``socialnav train`` and its options to the console script's subcommands.

    Args:
        sub: the console script's subparsers.
    """
    tr = sub.add_parser(
        "train",
        help="train a learned policy (value-based: imitation from ORCA, then RL; crowdnav_pp: PPO)",
    )
    tr.add_argument(
        "--policy",
        required=True,
        help=f"{', '.join(learned_policy_names('value'))} (value-based, docs/training.md); "
        f"{', '.join(learned_policy_names('ppo'))} (PPO, docs/ppo.md)",
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
    tr.add_argument(
        "--config",
        help="YAML file or shipped config name overriding training settings (docs/training.md; PPO: "
        "docs/ppo.md, default ppo, or ppo_repo, ppo_smoke)",
    )
    tr.add_argument(
        "--env-steps",
        type=int,
        dest="env_steps",
        help="PPO only: total environment steps (default: the config's total_env_steps)",
    )
    tr.add_argument(
        "--information",
        choices=["constant_velocity", "oracle", "learned"],
        help="lookahead prediction of the humans' next states (default constant_velocity; mp_rgl: "
        "learned, a state predictor trained in the same run)",
    )
    tr.add_argument(
        "--collection-batch",
        type=int,
        dest="collection_batch",
        help="episodes stepped in lockstep while collecting (default: the config's, 128 in the default "
        "schedule; PPO: n_envs)",
    )
    tr.add_argument("--rl-episodes", type=int, dest="rl_episodes",
                    help="RL episodes (default: the config's, 10000 in the default schedule)")
    tr.add_argument(
        "--compile",
        action="store_true",
        default=None,
        help="compile the training steps (RL: one compiled graph per gradient step where the network allows; "
        "faster; needs a C++ compiler; a compiled run's floating-point results differ from an eager "
        "one's, see docs/training.md)",
    )
    tr.add_argument("--no-progress", action="store_true", help="hide the progress bars")
    tr.add_argument("--quiet", action="store_true", dest="no_progress", help="same as --no-progress")
    tr.set_defaults(run=_run)


def _read_config(config: str | None) -> dict[str, Any] | None:
    """A training config's mapping, or None where there is none or it cannot be read.

    An unreadable file is left to the trainer's own loader, which says why.
    """
    import yaml

    from socialnav.config import ConfigError
    from socialnav.train.config import _resolve_config

    if config is None:
        return None
    try:
        data = load_yaml(_resolve_config(config).read_text(encoding="utf-8"))
    except (ConfigError, OSError, UnicodeDecodeError, yaml.YAMLError):
        return None
    return data if isinstance(data, dict) else None


def _config_trainer(data: dict[str, Any] | None) -> str | None:
    """The trainer whose settings a training config's keys are: "value", "ppo", or None.

    None where the keys fit both (e.g. only ``threads``) or neither (the trainer's own loader then names
    the unknown ones), or there is no readable config.
    """
    import dataclasses

    from socialnav.train.config import TrainSettings, is_run_record
    from socialnav.train.ppo_config import PPOSettings

    if data is None:
        return None
    if is_run_record(data):  # its trainer is written there
        return "ppo" if "ppo_policy" in data else "value"
    keys = {str(k) for k in data}
    fits = [t for t, cls in (("value", TrainSettings), ("ppo", PPOSettings))
            if keys <= {f.name for f in dataclasses.fields(cls)}]
    return fits[0] if len(fits) == 1 else None


def _config_policy(data: dict[str, Any] | None) -> str | None:
    """The learned policy a plain training config names with ``policy:``, else None.

    A run's record is left out: reusing one run's settings for another policy is what it is for.
    """
    from socialnav.train.config import is_run_record

    if data is None or is_run_record(data):
        return None
    named = data.get("policy")
    return str(named) if isinstance(named, str) and named in learned_policy_names() else None


def _check_args(args: argparse.Namespace) -> None:
    """Refuses what the command line itself gets wrong, naming the option (before any config is read)."""
    from socialnav.config import ConfigError

    if args.policy not in learned_policy_names():
        raise ConfigError(
            f"--policy {args.policy!r}: not a policy that `socialnav train` trains; value-based: "
            f"{', '.join(learned_policy_names('value'))}; PPO: {', '.join(learned_policy_names('ppo'))}"
        )
    trainer = get_learned_spec(args.policy).trainer
    data = _read_config(args.config)
    other = _config_trainer(data)
    if other is not None and other != trainer:
        from socialnav.train.config import shipped_train_configs

        kind = "a PPO" if other == "ppo" else "a value-based training"
        own = [name for name in shipped_train_configs() if _config_trainer(_read_config(name)) == trainer]
        raise ConfigError(
            f"--config {args.config}: {kind} config, and {args.policy} trains with the "
            f"{'PPO' if trainer == 'ppo' else 'value-based'} trainer (its shipped configs: {', '.join(own)})"
        )
    named = _config_policy(data)
    if named is not None and canonical_name(named) != canonical_name(args.policy):
        raise ConfigError(f"--config {args.config} sets policy: {named}, and --policy {args.policy}: the run "
                          "would train one of them silently; give one (remove policy: from the file)")
    for option, value, least in (
        ("--env-steps", getattr(args, "env_steps", None), 1),
        ("--collection-batch", getattr(args, "collection_batch", None), 1),
        ("--rl-episodes", getattr(args, "rl_episodes", None), 0),
    ):
        if value is not None and value < least:
            raise ConfigError(f"{option} must be >= {least}, got {value}")


def _run(args: argparse.Namespace) -> int:
    from socialnav._progress import warnings_said_as_they_come

    with warnings_said_as_they_come():
        return _train(args)


def _train(args: argparse.Namespace) -> int:
    _check_args(args)
    if get_learned_spec(args.policy).trainer == "ppo":
        from socialnav.train.ppo import train_ppo_from_args

        return train_ppo_from_args(args)
    if getattr(args, "env_steps", None) is not None:
        from socialnav.config import ConfigError

        raise ConfigError(f"--env-steps: a PPO setting; {args.policy} trains by episodes (--rl-episodes)")
    from socialnav.train.trainer import train_from_args

    return train_from_args(args)

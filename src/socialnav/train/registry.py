"""The trainers, registered by name: what `socialnav train`, sweeps and `socialnav list` dispatch through.

A learned policy's record (``policies/learned_catalog.py``) names the trainer that trains it; a
:class:`Trainer` record says everything the rest of the package needs of that trainer: its settings
class and the config it trains with by default, the command-line options it takes, the function that
trains, the checkpoints it writes and how they load (``checkpoint_kind``), the counters its result
reports. The two built-in trainers are ``value`` (imitation from ORCA, then value-based RL:
train/value/) and ``ppo`` (train/ppo/). Another one is registered with :func:`register_trainer`, or
from an installed package through the entry-point group ``socialnav.trainers`` (docs/extending.md,
"A trainer").

Plain data: importing this module imports neither torch nor any trainer (a record names its settings
class and training function as ``"module:attribute"``, imported when used), so ``socialnav list`` and
``socialnav train --help`` stay cheap.
"""

from __future__ import annotations

import dataclasses
import importlib
import re
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any

from socialnav.plugins import load_entry_points
from socialnav.policies.learned_catalog import CHECKPOINT_KINDS
from socialnav.settings import ConfigError

__all__ = [
    "OPTIONS",
    "REQUIRED_FIELDS",
    "ENTRY_POINT_GROUP",
    "Trainer",
    "BUILTIN",
    "register_trainer",
    "get_trainer",
    "list_trainers",
    "trainer_for_policy",
    "load_trainer_plugins",
]

#: The options of ``socialnav train`` (and keys of a sweep's training job) that a trainer may map onto
#: its settings (:attr:`Trainer.options`), with their command-line flags. ``--seed`` and ``--device``
#: are every trainer's (:data:`REQUIRED_FIELDS`).
OPTIONS: Mapping[str, str] = MappingProxyType({
    "collection_batch": "--collection-batch",
    "information": "--information",
    "rl_episodes": "--rl-episodes",
    "env_steps": "--env-steps",
    "compile": "--compile",
})
#: Fields every trainer's settings class has: the policy trained, the master seed, the torch device
#: and threads (a sweep sets ``threads`` to its worker's share of the cores).
REQUIRED_FIELDS = ("policy", "seed", "device", "threads")
#: Entry-point group of trainers in other packages: each entry names a :class:`Trainer` (registered
#: under its own name) or a module whose import registers trainers.
ENTRY_POINT_GROUP = "socialnav.trainers"
_NAME = re.compile(r"^[a-z][a-z0-9_]*$")


def _imported(target: str | Callable[..., Any], what: str) -> Any:
    """The object a ``"module:attribute"`` reference names (an object is returned as it is)."""
    if not isinstance(target, str):
        return target
    module, _, attr = target.partition(":")
    try:
        return getattr(importlib.import_module(module), attr)
    except (ImportError, AttributeError) as err:
        raise ImportError(f"{what} {target!r} cannot be imported: {err}") from err


@dataclass(frozen=True)
class Trainer:
    """One training algorithm, as the command line, sweeps, ``socialnav list`` and checkpoints see it.

    Attributes:
        name: what a learned policy's record names as its ``trainer`` (lower case, ``[a-z0-9_]``).
        label: how messages name it ("value-based", "PPO").
        description: one line for ``socialnav list``.
        settings: its settings class (a ``socialnav.settings.Settings`` subclass with the fields of
            :data:`REQUIRED_FIELDS`), or its ``"module:Class"``.
        train: ``train(policy, preset, out_dir, settings, *, progress, stop_after, log)`` returning a
            result with ``out_dir``, ``best_checkpoint``, ``last_checkpoint``, ``curves``,
            ``best_val``, ``wall_time``, ``resumed``, ``finished`` and the :attr:`counters`; or its
            ``"module:function"``. It resumes from ``out_dir/last.pt`` and keeps the run directory
            with train/run_directory.py (lock, record, resume checks, curves).
        checkpoint_kind: the record its checkpoints' config holds (:data:`CHECKPOINT_KINDS`):
            ``value_policy`` (a value network acting through the lookahead) or ``ppo_policy`` (an
            actor-critic acting with its mean action); its policies' records must say the same.
        checkpoints: the checkpoint files it writes into the run directory.
        counters: the result's attributes that the command's JSON summary and a sweep's log report.
        default_config: the shipped config (``socialnav/configs/train``) a run takes without
            ``--config``; None: the settings class's defaults.
        smoke_config: a shipped config that runs every stage in seconds (an installation check).
        options: :data:`OPTIONS` it takes → the dotted settings field each sets (``rl.episodes``);
            an option it does not take is refused, naming the option and the trainer.
        docs: the page that explains it.
    """

    name: str
    label: str
    description: str
    settings: str | type
    train: str | Callable[..., Any]
    checkpoint_kind: str
    checkpoints: tuple[str, ...] = ("best.pt", "last.pt")
    counters: tuple[str, ...] = ()
    default_config: str | None = None
    smoke_config: str | None = None
    options: Mapping[str, str] = field(default_factory=dict)
    docs: str = ""

    def __post_init__(self) -> None:
        if not _NAME.match(self.name):
            raise ValueError(f"trainer {self.name!r}: a name is lower case letters, digits and _")
        if self.checkpoint_kind not in CHECKPOINT_KINDS:
            raise ValueError(f"trainer {self.name!r}: checkpoint_kind {self.checkpoint_kind!r} must be one "
                             f"of {CHECKPOINT_KINDS}")
        unknown = sorted(set(self.options) - set(OPTIONS))
        if unknown:
            raise ValueError(f"trainer {self.name!r}: unknown option(s) {unknown}; valid: {sorted(OPTIONS)}")

    def settings_class(self) -> type:
        """Its settings class (imported now if the record names it by path).

        Raises:
            TypeError: the class lacks a field of :data:`REQUIRED_FIELDS`.
        """
        cls = _imported(self.settings, f"trainer {self.name!r}: settings")
        names = {f.name for f in dataclasses.fields(cls)}
        missing = [f for f in REQUIRED_FIELDS if f not in names]
        if missing:
            raise TypeError(f"trainer {self.name!r}: its settings class {cls.__name__} has no field(s) "
                            f"{', '.join(missing)} (every trainer's settings have "
                            f"{', '.join(REQUIRED_FIELDS)})")
        return cls

    def train_function(self) -> Callable[..., Any]:
        """Its training function (imported now if the record names it by path)."""
        return _imported(self.train, f"trainer {self.name!r}: train")

    def policies(self) -> list[str]:
        """The learned policies (and aliases) whose records name this trainer."""
        from socialnav.policies.learned_catalog import learned_policy_names

        return learned_policy_names(self.name)

    def fits(self, data: Mapping[str, Any]) -> bool:
        """Whether every top-level key of a config mapping is a field of this trainer's settings."""
        return {str(k) for k in data} <= {f.name for f in dataclasses.fields(self.settings_class())}

    def load_settings(self, config: str | Path | None = None, *, policy: str | None = None,
                      seed: int | None = None, device: str | None = None, **options: Any) -> Any:
        """Its settings: the config file (default :attr:`default_config`), then the options given.

        Args:
            config: a YAML file, a shipped config's name, or a run's ``config.yaml``; None: the default.
            policy: the policy trained (its settings' ``policy``).
            seed: the master seed.
            device: the torch device.
            **options: :data:`OPTIONS` values (None: not given).

        Returns:
            The settings.

        Raises:
            ConfigError: a bad file or value (naming the file and the field, or the option), or an
                option this trainer does not take.
        """
        from socialnav.train.settings_files import load_settings_file

        given = {k: v for k, v in options.items() if v is not None}
        refused = [k for k in given if k not in self.options]
        if refused:
            raise self.refuse_options(refused, policy or "")
        overrides: dict[str, Any] = {"seed": seed, "device": device, "policy": policy}
        flags = {"seed": "--seed", "device": "--device", "policy": "--policy"}
        for option, value in given.items():
            overrides[self.options[option]] = value
            flags[self.options[option]] = OPTIONS[option]
        path = config if config is not None else self.default_config
        return load_settings_file(self.settings_class(), path, overrides, flags)

    def refuse_options(self, options: list[str], policy: str, flags: bool = True) -> ConfigError:
        """The error for options (of :data:`OPTIONS`) this trainer does not take.

        Args:
            options: the options given.
            policy: the policy trained.
            flags: name them as command-line flags (``--rl-episodes``), else as sweep keys.

        Returns:
            The error, naming the options, the trainer and its page.
        """
        named = ", ".join(OPTIONS.get(k, k) if flags else k for k in options)
        page = f" ({self.docs})" if self.docs else ""
        return ConfigError(f"{named}: not a setting of the {self.label} trainer of {policy!r}{page}")

    def run(self, policy: str, preset: Any, out_dir: str | Path, settings: Any = None, *,
            progress: bool = True, stop_after: int | None = None,
            log: Callable[[str], None] | None = None) -> Any:
        """Trains ``policy`` into ``out_dir`` (resuming it) with this trainer.

        Args:
            policy: a learned policy whose record names this trainer.
            preset: a Preset or a preset name/path.
            out_dir: the run directory.
            settings: its settings (None: :meth:`load_settings`'s defaults); ``policy`` replaces theirs.
            progress: progress bars on stderr.
            stop_after: stop after this many units of work (episodes, updates) in this call, as if
                killed (tests of resumption).
            log: where progress lines go (default: stderr).

        Returns:
            The training function's result.
        """
        settings = self.load_settings() if settings is None else settings
        settings = dataclasses.replace(settings, policy=policy)
        train = self.train_function()
        return train(policy, preset, out_dir, settings, progress=progress, stop_after=stop_after, log=log)

    def describe(self) -> dict[str, Any]:
        """What ``socialnav list`` shows of it (plain data; imports nothing)."""
        settings = self.settings if isinstance(self.settings, str) else (
            f"{self.settings.__module__}:{self.settings.__qualname__}")
        return {
            "name": self.name,
            "label": self.label,
            "description": self.description,
            "policies": self.policies(),
            "settings": settings,
            "default_config": self.default_config,
            "smoke_config": self.smoke_config,
            "options": [OPTIONS[k] for k in self.options],
            "checkpoints": list(self.checkpoints),
            "checkpoint_kind": self.checkpoint_kind,
            "docs": self.docs,
        }

    def summary(self, result: Any) -> dict[str, Any]:
        """The JSON summary of a result: run directory, best checkpoint, counters, best validation."""
        import math

        best = result.best_val or {}
        return {
            "out": str(result.out_dir),
            "best_checkpoint": str(result.best_checkpoint),
            **{k: getattr(result, k) for k in self.counters},
            "best_val": {k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in best.items()},
            "wall_time_s": round(result.wall_time, 1),
            "resumed": result.resumed,
        }


#: The trainers that ship.
BUILTIN: tuple[Trainer, ...] = (
    Trainer(
        name="value",
        label="value-based",
        description="imitation from ORCA, then value-based RL with a replay memory and a target network "
        "(CrowdNav/RGL)",
        settings="socialnav.train.value.settings:TrainSettings",
        train="socialnav.train.value.trainer:train",
        checkpoint_kind="value_policy",
        checkpoints=("il.pt", "best.pt", "last.pt"),
        counters=("episodes", "gradient_steps"),
        smoke_config="smoke",
        options={"collection_batch": "collection_batch", "information": "information",
                 "rl_episodes": "rl.episodes", "compile": "compile"},
        docs="docs/training.md",
    ),
    Trainer(
        name="ppo",
        label="PPO",
        description="PPO with a recurrent actor-critic, every environment stepped in lockstep "
        "(CleanRL-style)",
        settings="socialnav.train.ppo.settings:PPOSettings",
        train="socialnav.train.ppo.algorithm:train_ppo_policy",
        checkpoint_kind="ppo_policy",
        counters=("updates", "env_steps", "episodes"),
        default_config="ppo",
        smoke_config="ppo_smoke",
        options={"collection_batch": "n_envs", "env_steps": "total_env_steps"},
        docs="docs/ppo.md",
    ),
)

_TRAINERS: dict[str, Trainer] = {}
_plugins_loaded = False


def register_trainer(trainer: Trainer) -> Trainer:
    """Adds a trainer; from then on ``socialnav train``, sweeps and ``socialnav list`` know it.

    Registering the same record twice is a no-op (a plugin module imported by two entry points).

    Args:
        trainer: the record.

    Returns:
        The record.

    Raises:
        ValueError: another trainer has its name.
    """
    taken = _TRAINERS.get(trainer.name)
    if taken is not None and taken != trainer:
        raise ValueError(f"trainer {trainer.name!r} is already registered ({taken.description})")
    _TRAINERS[trainer.name] = trainer
    return trainer


for _trainer in BUILTIN:
    register_trainer(_trainer)


def load_trainer_plugins() -> None:
    """Imports the entry points of group ``socialnav.trainers`` once (a broken one is a warning).

    Call it before looking a policy up where a trainer plugin may be what registers it.
    """
    global _plugins_loaded
    if _plugins_loaded:
        return
    _plugins_loaded = True
    for ep, obj in load_entry_points(ENTRY_POINT_GROUP, "trainer"):
        if not isinstance(obj, Trainer):  # a module whose import registered its trainers
            continue
        if obj.name != ep.name:
            warnings.warn(f"trainer plugin {ep.name!r} ({ep.value}) is not registered: its record is named "
                          f"{obj.name!r}; give the entry point that name", RuntimeWarning, stacklevel=2)
            continue
        try:
            register_trainer(obj)
        except ValueError as err:
            warnings.warn(f"trainer plugin {ep.name!r} ({ep.value}) is not registered: {err}", RuntimeWarning,
                          stacklevel=2)


def list_trainers(plugins: bool = True) -> list[Trainer]:
    """Every registered trainer, built-in ones first.

    Args:
        plugins: load the entry points of ``socialnav.trainers`` first (False: those registered so far).
    """
    if plugins:
        load_trainer_plugins()
    return list(_TRAINERS.values())


def get_trainer(name: str) -> Trainer:
    """A registered trainer by name.

    Raises:
        KeyError: no trainer of that name (the registered ones are listed).
    """
    load_trainer_plugins()
    try:
        return _TRAINERS[name]
    except KeyError:
        raise KeyError(f"unknown trainer {name!r}; registered: {', '.join(_TRAINERS)}") from None


def trainer_for_policy(policy: str) -> Trainer:
    """The trainer of a learned policy (its record names it).

    Raises:
        ConfigError: not a learned policy (the trainable ones are listed by trainer), a record naming
            a trainer that is not registered, or one whose checkpoints would load otherwise than the
            trainer writes them.
    """
    from socialnav.policies.learned_catalog import get_learned_spec, learned_policy_names

    trainers = list_trainers()
    if policy not in learned_policy_names():
        known = "; ".join(f"{t.label}: {', '.join(t.policies())}" for t in trainers if t.policies())
        raise ConfigError(f"--policy {policy!r}: not a policy that `socialnav train` trains; {known}")
    spec = get_learned_spec(policy)
    if spec.trainer not in _TRAINERS:
        raise ConfigError(f"policy {policy!r}: its record names trainer {spec.trainer!r}, which is not "
                          f"registered (registered: {', '.join(_TRAINERS)}; "
                          "socialnav.train.register_trainer)")
    trainer = _TRAINERS[spec.trainer]
    if spec.kind != trainer.checkpoint_kind:
        raise ConfigError(f"policy {policy!r}: its record's checkpoint_kind is {spec.kind!r}, and its "
                          f"trainer {trainer.name!r} writes {trainer.checkpoint_kind!r} checkpoints")
    return trainer

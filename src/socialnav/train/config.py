"""Training settings: frozen dataclasses loadable from YAML with strict keys (``socialnav.config``).

Defaults follow RGL's configuration (CrowdNav's `train.config`) with one measured deviation:
``rl.gradient_steps_per_episode`` (the replay ratio) is 10, not 100. RGL's 100 steps of batch 100
per collected episode costs about 1 M gradient steps for 10 000 episodes, i.e. hours on a 2-core CPU;
docs/training.md has the measurements behind the chosen default. Set it back to 100 in a YAML file
(``rl: {gradient_steps_per_episode: 100}``) for RGL's ratio.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
import yaml

from socialnav.config import ConfigError, check, from_dict
from socialnav.policies.learned_catalog import VALUE_DEFAULTS, get_learned_spec

INFORMATION = ("constant_velocity", "oracle", "learned")
REWARD_RULES = ("end", "swept")
#: How RL's value targets are formed (docs/training.md, "TD targets"): ``recomputed`` (ours: every
#: transition kept, the target r + γ̄·V_target(s')·(1 − terminal) computed at each gradient step) or
#: ``rgl_repo`` (the RGL repository's explorer as first published, commit 012e4af: a finished episode's
#: last transition and every timed-out episode are dropped; the target r + γ̄·V_target(s') is computed
#: once, when the episode is stored, with the target network of that moment) or ``rgl_repo_final`` (the
#: repository's final version, commit 8dcd445: the same storage rule, the target r + γ̄·V_target(s')
#: computed at each gradient step).
TD_TARGETS = ("recomputed", "rgl_repo", "rgl_repo_final")
#: Settings added after runs were started: a resumed run whose saved config lacks one of these keys is
#: taken to have had this value (so older run directories stay resumable).
ADDED_SETTINGS: dict[str, Any] = {
    "train.planning_depth": 1,
    "train.planning_width": 1,
    "train.reward_rule": "end",
    "train.predictor_lr": 1e-3,
    "value_policy.planning_depth": 1,
    "value_policy.planning_width": 1,
    "value_policy.reward_rule": "end",
    "train.rl.td_targets": "recomputed",
    "train.compile": False,
}
DEVICES = ("cpu", "cuda", "auto")

#: Train-setting keys that may change between a run and its resumption (everything else must match).
RESUMABLE_CHANGES = (
    "device", "threads", "compile", "checkpoint_every", "log_every", "rl.episodes", "progress"
)


T = TypeVar("T")


@dataclass(frozen=True)
class ImitationSettings:
    """Imitation learning from ORCA demonstrations (the robot invisible, teacher safety space 0.15 m)."""

    episodes: int = 2000  # teacher episodes collected (timeouts are dropped, as CrowdNav does)
    epochs: int = 50
    lr: float = 1e-3  # Adam
    batch_size: int = 100
    teacher_safety_space: float = 0.15  # [m]

    def __post_init__(self) -> None:
        check(self.episodes >= 0, "imitation.episodes", self.episodes, "must be >= 0")
        check(self.epochs >= 0, "imitation.epochs", self.epochs, "must be >= 0")
        check(self.lr > 0, "imitation.lr", self.lr, "must be > 0")
        check(self.batch_size >= 1, "imitation.batch_size", self.batch_size, "must be >= 1")
        check(
            self.teacher_safety_space >= 0,
            "imitation.teacher_safety_space",
            self.teacher_safety_space,
            "must be >= 0",
        )


@dataclass(frozen=True)
class RLSettings:
    """Value-based RL with a replay memory and a target network (CrowdNav/RGL style)."""

    episodes: int = 10000
    epsilon_start: float = 0.5
    epsilon_end: float = 0.1
    epsilon_decay_episodes: int = 4000  # linear decay over the first episodes
    capacity: int = 100000  # replay memory [transitions]
    batch_size: int = 100
    gradient_steps_per_episode: float = 10.0  # replay ratio; RGL: 100 (see docs/training.md)
    warmup_transitions: int = 1000  # no gradient step before the memory holds this many transitions
    lr: float = 1e-3  # Adam
    target_update_every: int = 1000  # [episodes]
    validate_every: int = 1000  # [episodes]
    val_episodes: int = 100  # split over the scenarios of the training mix
    gamma: float = 0.9  # discount per second of travel at v_pref: γ^(dt·v_pref) per step
    td_targets: str = "recomputed"  # or "rgl_repo", "rgl_repo_final" (TD_TARGETS)

    def __post_init__(self) -> None:
        check(self.episodes >= 0, "rl.episodes", self.episodes, "must be >= 0")
        check(
            self.td_targets in TD_TARGETS,
            "rl.td_targets",
            self.td_targets,
            f"must be one of {', '.join(TD_TARGETS)}",
        )
        for name in ("epsilon_start", "epsilon_end"):
            v = getattr(self, name)
            check(0 <= v <= 1, f"rl.{name}", v, "must be in [0, 1]")
        check(
            self.epsilon_decay_episodes >= 0,
            "rl.epsilon_decay_episodes",
            self.epsilon_decay_episodes,
            "must be >= 0",
        )
        check(self.capacity >= 1, "rl.capacity", self.capacity, "must be >= 1")
        check(self.batch_size >= 1, "rl.batch_size", self.batch_size, "must be >= 1")
        check(
            math.isfinite(self.gradient_steps_per_episode) and self.gradient_steps_per_episode >= 0,
            "rl.gradient_steps_per_episode",
            self.gradient_steps_per_episode,
            "must be a finite number >= 0",
        )
        check(self.warmup_transitions >= 0, "rl.warmup_transitions", self.warmup_transitions, "must be >= 0")
        # The memory never holds more than `capacity` transitions, and a gradient step waits for
        # max(batch_size, warmup_transitions) of them: beyond capacity, the run would never learn.
        check(
            self.batch_size <= self.capacity, "rl.batch_size", self.batch_size,
            f"must be <= rl.capacity ({self.capacity}): the replay memory can never fill a minibatch",
        )
        check(
            self.warmup_transitions <= self.capacity, "rl.warmup_transitions", self.warmup_transitions,
            f"must be <= rl.capacity ({self.capacity}): the replay memory never holds that many, so no "
            "gradient step would ever be taken",
        )
        check(self.lr > 0, "rl.lr", self.lr, "must be > 0")
        check(
            self.target_update_every >= 1, "rl.target_update_every", self.target_update_every, "must be >= 1"
        )
        check(self.validate_every >= 1, "rl.validate_every", self.validate_every, "must be >= 1")
        check(self.val_episodes >= 1, "rl.val_episodes", self.val_episodes, "must be >= 1")
        check(0 < self.gamma <= 1, "rl.gamma", self.gamma, "must be in (0, 1]")


@dataclass(frozen=True)
class TrainSettings:
    """Everything that defines a training run besides the preset.

    Attributes:
        policy: a value-based learned policy's name (``learned_policy_names("value")`` of
            :mod:`socialnav.policies.learned_catalog`: cadrl, lstm_rl / ga3c_cadrl, sarl, ...).
        information: how the lookahead predicts the humans' next states ("constant_velocity", the
            fair default, "oracle", what CrowdNav's paper used, or "learned", a state predictor
            trained in the same run); "" takes the policy's default (mp_rgl: learned).
        planning_depth, planning_width: model-predictive planning (d, w); 0 takes the policy's
            default (mp_rgl: 2, 2; the others: 1, 1, the one-step lookahead).
        reward_rule: the lookahead's reward estimate, "end" (clearances at the end of the step, as
            CrowdNav/RGL) or "swept" (the world's rule); "" takes the policy's default (mp_rgl: swept).
        predictor_lr: Adam learning rate of the state predictor (``learned`` only).
        collection_batch: episodes stepped in lockstep while collecting (split over the scenarios of
            the training mix).
        seed: master seed; the scenario stream offset, exploration, network initialisation and
            replay sampling use separate seeds derived from it (see :func:`derive_seeds`).
        device: "cpu", "cuda" or "auto" (cuda when available).
        threads: torch intra-op threads (0: all cores, at most 8).
        compile: compile the training steps. RL: the whole gradient step as one graph
            (train/fused_step.py) for networks that trace into one (SARL, OM-SARL, RGL, MP-RGL),
            the loss alone with ``torch.compile`` for the others (CADRL, LSTM-RL); imitation: the
            value regression's loss. SARL's gradient step ≈ 2.2x faster at 2 threads on the 2-core
            VM, after a compilation at the start of RL (≈ 35 s cold, seconds with Inductor's cache);
            needs a C++ compiler at run time. Off by default: a compiled run is reproducible for its
            seed, but its floating-point results differ from the eager run's (the shipped
            checkpoints come from eager runs). See docs/training.md, "Compiled training".
        checkpoint_every: write last.pt every this many RL episodes (and at the end).
        log_every: one curves.csv row every this many RL episodes.
        cadrl_one_human: train CADRL with one human (its authors' setting) in every scenario of the mix.
    """

    policy: str = "sarl"
    information: str = ""
    collection_batch: int = 128
    seed: int = 0
    device: str = "cpu"
    threads: int = 0
    compile: bool = False
    checkpoint_every: int = 500
    log_every: int = 100
    cadrl_one_human: bool = True
    planning_depth: int = 0
    planning_width: int = 0
    reward_rule: str = ""
    predictor_lr: float = 1e-3
    imitation: ImitationSettings = field(default_factory=ImitationSettings)
    rl: RLSettings = field(default_factory=RLSettings)

    def __post_init__(self) -> None:
        check(
            self.information in ("", *INFORMATION),
            "information",
            self.information,
            f"must be one of {', '.join(INFORMATION)}",
        )
        check(self.planning_depth >= 0, "planning_depth", self.planning_depth, "must be >= 1 (0: default)")
        check(self.planning_width >= 0, "planning_width", self.planning_width, "must be >= 1 (0: default)")
        check(
            self.reward_rule in ("", *REWARD_RULES),
            "reward_rule",
            self.reward_rule,
            f"must be one of {', '.join(REWARD_RULES)}",
        )
        check(self.predictor_lr > 0, "predictor_lr", self.predictor_lr, "must be > 0")
        check(self.collection_batch >= 1, "collection_batch", self.collection_batch, "must be >= 1")
        check(self.seed >= 0, "seed", self.seed, "must be >= 0")
        check(self.device in DEVICES, "device", self.device, f"must be one of {', '.join(DEVICES)}")
        check(self.threads >= 0, "threads", self.threads, "must be >= 0")
        check(isinstance(self.compile, bool), "compile", self.compile, "must be true or false")
        check(self.checkpoint_every >= 1, "checkpoint_every", self.checkpoint_every, "must be >= 1")
        check(self.log_every >= 1, "log_every", self.log_every, "must be >= 1")

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    def resolved(self, policy: str) -> TrainSettings:
        """These settings with the policy's defaults filled in (information, planning, reward rule).

        Raises:
            ConfigError: a combination the policy cannot train with (mp_rgl without its predictor,
                planning beyond one step with the one-step oracle).
        """
        try:
            spec = get_learned_spec(policy)
        except KeyError:  # the trainer names unknown policies; their settings are the generic ones
            spec = None
        defaults = spec.value_defaults if spec is not None else dict(VALUE_DEFAULTS)
        out = dataclasses.replace(
            self,
            policy=policy,
            information=self.information or defaults["information"],
            planning_depth=self.planning_depth or defaults["planning_depth"],
            planning_width=self.planning_width or defaults["planning_width"],
            reward_rule=self.reward_rule or defaults["reward_rule"],
        )
        needed = spec.required_information if spec is not None else None
        if needed is not None and out.information != needed:
            why = "plans with the state predictor it trains" if needed == "learned" else "trains with it only"
            raise ConfigError(f"information: {policy} {why}, so it needs {needed!r}, got {out.information!r}")
        if out.planning_depth > 1 and out.information == "oracle":
            raise ConfigError(
                f"planning_depth: {out.planning_depth} needs predictions beyond one step; the oracle "
                "gives one (use information 'learned' or 'constant_velocity')"
            )
        return out


def load_train_settings(path: str | Path | None = None, **overrides: Any) -> TrainSettings:
    """Settings from a YAML file (strict keys: a typo is an error naming the valid keys).

    Args:
        path: YAML file with any subset of the fields of :class:`TrainSettings` (nested
            ``imitation:`` / ``rl:`` sections), or None for the defaults.
        **overrides: top-level fields applied after the file (e.g. ``seed`` from the command line);
            None values are ignored.
    """
    return load_settings_file(TrainSettings, path, overrides)


def load_settings_file(cls: type[T], path: str | Path | None, overrides: dict[str, Any]) -> T:
    """``cls`` from a YAML file (a path or a shipped config's name) with top-level ``overrides``
    applied after it (None values ignored); errors name the file and the field."""
    data: dict[str, Any] = {}
    if path is not None:
        path = _resolve_config(path)
        if path.is_dir():
            raise ConfigError(f"training config {path} is a directory, not a YAML file")
        try:
            data = yaml.safe_load(path.read_text()) or {}
        except UnicodeDecodeError:
            raise ConfigError(f"training config {path} is not a text (YAML) file") from None
        except yaml.YAMLError as err:
            raise ConfigError(f"{path}: not valid YAML: {' '.join(str(err).split())}") from None
        if not isinstance(data, dict):
            raise ConfigError(f"{path}: expected a mapping of settings, got {type(data).__name__}")
    data.update({k: v for k, v in overrides.items() if v is not None})
    try:
        return from_dict(cls, data)
    except ConfigError as err:
        raise ConfigError(f"{path}: {err}" if path is not None else str(err)) from None


def resolve_train_settings(
    config: str | Path | None = None,
    *,
    seed: int | None = None,
    device: str | None = None,
    collection_batch: int | None = None,
    information: str | None = None,
    rl_episodes: int | None = None,
    compile: bool | None = None,
) -> TrainSettings:
    """The settings of ``socialnav train`` (and of a sweep's training job): the config file, then the
    command-line options that override it (None: not given)."""
    settings = load_train_settings(config, seed=seed, device=device)
    for key, value in (
        ("collection_batch", collection_batch), ("information", information), ("compile", compile)
    ):
        if value is not None:
            settings = dataclasses.replace(settings, **{key: value})
    if rl_episodes is not None:
        settings = dataclasses.replace(settings, rl=dataclasses.replace(settings.rl, episodes=rl_episodes))
    return settings


def shipped_train_configs() -> list[str]:
    """Names of the training configs shipped in ``socialnav/configs/train`` (``smoke`` …)."""
    from importlib import resources

    folder = resources.files("socialnav.configs") / "train"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".yaml"))


def _resolve_config(path: str | Path) -> Path:
    """A YAML path, or the name of a shipped training config (``--config smoke``)."""
    p = Path(path)
    if p.exists():
        return p
    if p.suffix not in (".yaml", ".yml") and str(path) in shipped_train_configs():
        from importlib import resources

        return Path(str(resources.files("socialnav.configs") / "train" / f"{path}.yaml"))
    raise ConfigError(
        f"training config {p} does not exist (shipped configs: {', '.join(shipped_train_configs())})"
    )


def derive_seeds(seed: int) -> dict[str, int]:
    """Independent seeds for the parts of a run, derived from the master seed.

    ``scenario_start`` is the first training-episode index (disjoint ranges of 10 M episodes per
    master seed; validation uses the ``val`` split, indices 0..val_episodes-1, whatever the seed).
    """
    exploration, init, sampling = (
        int(x) for x in np.random.SeedSequence([int(seed), 0x50C1A1]).generate_state(3)
    )
    return {
        "scenario_start": int(seed) * 10_000_000,
        "exploration": exploration,
        "init": init,
        "sampling": sampling,
    }


def resume_diff(saved: dict[str, Any], current: dict[str, Any]) -> list[str]:
    """Dotted keys where a saved run config and the current one differ, ignoring the settings a
    resumed run may change (:data:`RESUMABLE_CHANGES`) and settings added since the run was saved
    when the current value is the one such runs had (:data:`ADDED_SETTINGS`)."""
    out = []
    for key in flat_diff(saved, current):
        if any(key == f"train.{r}" or key.startswith(f"train.{r}.") for r in RESUMABLE_CHANGES):
            continue
        if key in ADDED_SETTINGS and _lookup(saved, key) is _MISSING:
            if _lookup(current, key) == ADDED_SETTINGS[key]:
                continue
        out.append(key)
    return out


_MISSING = object()


def _lookup(data: Any, dotted: str) -> Any:
    for part in dotted.split("."):
        if not isinstance(data, dict) or part not in data:
            return _MISSING
        data = data[part]
    return data


def flat_diff(a: Any, b: Any, prefix: str = "") -> list[str]:
    """Dotted keys where two nested plain dicts differ."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in sorted(set(a) | set(b)):
            out += flat_diff(a.get(k), b.get(k), f"{prefix}{k}.")
        return out
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        a, b = list(a), list(b)
    return [] if a == b else [prefix.rstrip(".")]

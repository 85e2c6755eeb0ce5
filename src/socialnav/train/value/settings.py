"""The value-based trainer's settings: frozen dataclasses loadable from YAML with strict keys.

Defaults follow RGL's configuration (CrowdNav's `train.config`) with one measured deviation:
``rl.gradient_steps_per_episode`` (the replay ratio) is 10, not 100. RGL's 100 steps of batch 100
per collected episode costs about 1 M gradient steps for 10 000 episodes, i.e. hours on a 2-core CPU;
docs/training_speed.md ("Replay ratio") has the measurements behind the chosen default. Set it back
to 100 in a YAML file (``rl: {gradient_steps_per_episode: 100}``) for RGL's ratio.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

from socialnav.policies.learned_catalog import VALUE_DEFAULTS, get_learned_spec
from socialnav.settings import ConfigError, Settings, setting
from socialnav.train.settings_files import DEVICES, flat_diff, load_settings_file

INFORMATION = ("constant_velocity", "oracle", "learned")
REWARD_RULES = ("end", "swept")
#: How RL's value targets are formed (docs/training.md, "The RGL repository's value targets"):
#: ``recomputed`` (ours: every transition kept, the target r + γ̄·V_target(s')·(1 − terminal) computed
#: at each gradient step) or ``rgl_repo`` (the RGL repository's explorer as first published, commit
#: 012e4af: a finished episode's last transition and every timed-out episode are dropped; the target
#: r + γ̄·V_target(s') is computed once, when the episode is stored, with the target network of that
#: moment) or ``rgl_repo_final`` (the repository's final version, commit 8dcd445: the same storage rule,
#: the target r + γ̄·V_target(s') computed at each gradient step).
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

#: Train-setting keys that may change between a run and its resumption (everything else must match).
RESUMABLE_CHANGES = (
    "device", "threads", "compile", "checkpoint_every", "log_every", "rl.episodes", "progress"
)


@dataclass(frozen=True)
class ImitationSettings(Settings):
    """Imitation learning from ORCA demonstrations (the robot invisible, teacher safety space 0.15 m)."""

    section: ClassVar[str] = "imitation"

    episodes: int = setting(2000, "teacher episodes collected (timeouts are dropped, as CrowdNav does)", ge=0)
    epochs: int = setting(50, "passes over the demonstrations", ge=0)
    lr: float = setting(1e-3, "Adam learning rate", gt=0)
    batch_size: int = setting(100, "minibatch size", ge=1)
    teacher_safety_space: float = setting(0.15, "the ORCA teacher's safety space", unit="m", ge=0)


@dataclass(frozen=True)
class RLSettings(Settings):
    """Value-based RL with a replay memory and a target network (CrowdNav/RGL style)."""

    section: ClassVar[str] = "rl"

    episodes: int = setting(10000, "training episodes", ge=0)
    epsilon_start: float = setting(0.5, "epsilon-greedy exploration at the start", ge=0, le=1)
    epsilon_end: float = setting(0.1, "epsilon after the decay", ge=0, le=1)
    epsilon_decay_episodes: int = setting(4000, "linear decay over the first episodes", ge=0)
    capacity: int = setting(100000, "replay memory [transitions]", ge=1)
    batch_size: int = setting(100, "minibatch size", ge=1)
    gradient_steps_per_episode: float = setting(
        10.0, "replay ratio; RGL: 100 (see docs/training_speed.md, \"Replay ratio\")", ge=0
    )
    warmup_transitions: int = setting(
        1000, "no gradient step before the memory holds this many transitions", ge=0
    )
    lr: float = setting(1e-3, "Adam learning rate", gt=0)
    target_update_every: int = setting(1000, "target network update period [episodes]", ge=1)
    validate_every: int = setting(1000, "validation period [episodes]", ge=1)
    val_episodes: int = setting(
        100, "validation episodes, split over the scenarios of the training mix", ge=1
    )
    gamma: float = setting(
        0.9, "discount per second of travel at v_pref: γ^(dt·v_pref) per step", gt=0, le=1
    )
    td_targets: str = setting(
        "recomputed",
        "how the value targets are formed (docs/training.md, \"The RGL repository's value targets\")",
        choices=TD_TARGETS,
    )

    def cross_check(self) -> None:
        """Refuses a replay memory that can never feed a gradient step.

        The memory never holds more than `capacity` transitions, and a gradient step waits for
        max(batch_size, warmup_transitions) of them: beyond capacity, the run would never learn.

        Raises:
            ConfigError: naming rl.batch_size or rl.warmup_transitions.
        """
        if self.batch_size > self.capacity:
            self.refuse("batch_size", f"must be <= rl.capacity ({self.capacity}): the replay memory can "
                        "never fill a minibatch")
        if self.warmup_transitions > self.capacity:
            self.refuse("warmup_transitions", f"must be <= rl.capacity ({self.capacity}): the replay memory "
                        "never holds that many, so no gradient step would ever be taken")


@dataclass(frozen=True)
class TrainSettings(Settings):
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
            (train/value/fused_step.py) for networks that trace into one (SARL, OM-SARL, RGL, MP-RGL),
            the loss alone with ``torch.compile`` for the others (CADRL, LSTM-RL); imitation: the
            value regression's loss. SARL's gradient step ≈ 2.2x faster at 2 threads on the 2-core
            VM, after a compilation at the start of RL (≈ 35 s cold, seconds with Inductor's cache);
            needs a C++ compiler at run time. Off by default: a compiled run is reproducible for its
            seed, but its floating-point results differ from the eager run's (the shipped
            checkpoints come from eager runs). See docs/training_speed.md, "Compiled training".
        checkpoint_every: write last.pt every this many RL episodes (and at the end).
        log_every: one curves.csv row every this many RL episodes.
        cadrl_one_human: train CADRL with one human (its authors' setting) in every scenario of the mix.
    """

    policy: str = setting("sarl", "value-based learned policy to train (socialnav train --policy)")
    information: str = setting(
        "", "how the lookahead predicts the humans' next states; \"\": the policy's default",
        choices=("", *INFORMATION),
    )
    collection_batch: int = setting(128, "episodes stepped in lockstep while collecting", ge=1)
    seed: int = setting(0, "master seed (the run's other seeds derive from it)", ge=0, le=2**32 - 1)
    device: str = setting("cpu", "torch device; auto: cuda when available", choices=DEVICES)
    threads: int = setting(0, "torch intra-op threads (0: all cores, at most 8)", ge=0)
    compile: bool = setting(False,
                            "compile the training steps (docs/training_speed.md, \"Compiled training\")")
    checkpoint_every: int = setting(500, "write last.pt every this many RL episodes (and at the end)", ge=1)
    log_every: int = setting(100, "one curves.csv row every this many RL episodes", ge=1)
    cadrl_one_human: bool = setting(True, "train CADRL with one human (its authors' setting)")
    planning_depth: int = setting(0, "model-predictive planning depth d; 0: the policy's default", ge=0)
    planning_width: int = setting(0, "model-predictive planning width w; 0: the policy's default", ge=0)
    reward_rule: str = setting(
        "", "the lookahead's reward estimate; \"\": the policy's default", choices=("", *REWARD_RULES)
    )
    predictor_lr: float = setting(1e-3, "Adam learning rate of the state predictor (information learned)",
                                  gt=0)
    imitation: ImitationSettings = setting(default_factory=ImitationSettings)
    rl: RLSettings = setting(default_factory=RLSettings)

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


def resume_diff(saved: dict[str, Any], current: dict[str, Any]) -> list[str]:
    """Dotted keys where a saved run config and the current one differ.

    Ignores the settings a resumed run may change (:data:`RESUMABLE_CHANGES`) and settings added
    since the run was saved when the current value is the one such runs had (:data:`ADDED_SETTINGS`).
    """
    from socialnav.policies.learned_catalog import canonical_name

    out = []
    for key in flat_diff(saved, current):
        if any(key == f"train.{r}" or key.startswith(f"train.{r}.") for r in RESUMABLE_CHANGES):
            continue
        if key in ("policy", "train.policy") and canonical_name(str(_lookup(saved, key))) == canonical_name(
                str(_lookup(current, key))):
            continue  # an alias names the same policy (ga3c_cadrl is lstm_rl)
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

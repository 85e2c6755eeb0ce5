"""PPO training settings: frozen dataclasses loadable from YAML with strict keys (``socialnav.config``).

Defaults follow CrowdNav++'s repository (``arguments.py``: 30-step rollouts, 5 epochs, 2 minibatches,
clip 0.2, value coefficient 0.5, no entropy bonus, γ 0.99, λ 0.95, gradient norm 0.5, Adam ε 1e-5),
with the deviations documented in docs/ppo.md: more environments per rollout (the batched world
steps them in one native call instead of 16 processes), a larger learning rate to go with the larger
batch, and a smaller total budget (``total_env_steps``) measured to fit a 2-core CPU.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from socialnav.config import check
from socialnav.train.config import DEVICES, load_settings_file

#: PPO-setting keys that may change between a run and its resumption (everything else must match).
PPO_RESUMABLE_CHANGES = ("device", "threads", "checkpoint_every", "log_every", "total_env_steps")


@dataclass(frozen=True)
class NetworkSettings:
    """Sizes of the attention-graph network (AttnGraphNet); defaults are the CrowdNav++ repository's."""

    prediction_steps: int = 5  # constant-velocity predicted positions per human (0: no prediction)
    robot_embed: int = 256
    human_hidden: int = 128
    attn_size: int = 512
    attn_heads: int = 8
    human_out: int = 256
    rh_attention: int = 64
    gru_input: int = 64
    gru_hidden: int = 128
    node_out: int = 256
    head_hidden: int = 256
    self_attention: bool = True
    log_std_init: float = 0.0

    def __post_init__(self) -> None:
        """Checks every size.

        Raises:
            ConfigError: a size out of range (the field and value are named).
        """
        check(
            0 <= self.prediction_steps <= 50,
            "network.prediction_steps",
            self.prediction_steps,
            "must be in [0, 50]",
        )
        for name in (
            "robot_embed",
            "human_hidden",
            "attn_size",
            "attn_heads",
            "human_out",
            "rh_attention",
            "gru_input",
            "gru_hidden",
            "node_out",
            "head_hidden",
        ):
            value = getattr(self, name)
            check(isinstance(value, int) and value >= 1, f"network.{name}", value, "must be an integer >= 1")
        check(
            self.attn_size % self.attn_heads == 0,
            "network.attn_size",
            self.attn_size,
            f"must be a multiple of network.attn_heads ({self.attn_heads})",
        )


@dataclass(frozen=True)
class PPOSettings:
    """Everything that defines a PPO run besides the preset.

    Attributes:
        n_envs: episodes stepped in lockstep (split over the scenarios of the training mix).
        rollout_steps: steps per environment per update (CrowdNav++: 30).
        total_env_steps: the budget, in robot steps summed over environments.
        epochs, minibatches: passes over a rollout and minibatches per pass (minibatches are sets of
            whole environment sequences, so the GRU sees each sequence in order).
        lr: Adam learning rate (``adam_eps`` its ε); ``anneal_lr`` decays it linearly to 0.
        gamma, gae_lambda: discount per step and GAE's λ.
        clip: ε of the clipped surrogate; ``value_clip``: ε_V of the clipped value loss (0: off).
        value_coef, entropy_coef, max_grad_norm: loss weights and gradient-norm clipping (0: off).
        normalize_advantages: standardise advantages per minibatch.
        normalize_obs: running mean/variance normalisation of the network's inputs.
        goal_shaping: weight of CrowdNav++'s potential reward, added to the world's (CrowdSim's)
            reward in training only: goal_shaping · (d_goal before the step − d_goal after it) [per m].
            Liu et al. use 2 with a collision penalty of −20; 0.025 keeps that ratio to the world's
            −0.25 (docs/ppo.md, "Reward"); 0 trains on CrowdSim's sparse reward alone.
        bootstrap_timeouts: add γ·V(final state) to the reward of a step that ends an episode by the
            time limit (a truncation, not a terminal state).
        validate_every, val_episodes: deterministic validation every this many updates, on this many
            ``val`` episodes (split over the training mix).
        checkpoint_every, log_every: write last.pt / one curves.csv row every this many updates.
        network: the attention graph's sizes (crowdnav_pp); ppo_mlp uses its ``prediction_steps`` and
            ``log_std_init`` only.
        mlp_hidden: ppo_mlp's hidden width (two tanh layers for the actor, two for the critic).
        seed, device, threads: master seed; "cpu", "cuda" or "auto"; torch threads (0: all cores, ≤ 8).
            Default 1: the network's matrices are small, and 2 threads made training 4x slower on the
            2-core VM (benchmarks/bench_ppo_trainer.py --threads 2); run one training per core instead.
    """

    policy: str = "crowdnav_pp"
    n_envs: int = 128
    rollout_steps: int = 30
    total_env_steps: int = 10_000_000
    epochs: int = 5
    minibatches: int = 2
    lr: float = 3e-4
    anneal_lr: bool = True
    adam_eps: float = 1e-5
    gamma: float = 0.99
    gae_lambda: float = 0.95
    clip: float = 0.2
    value_clip: float = 0.2
    value_coef: float = 0.5
    entropy_coef: float = 0.0
    max_grad_norm: float = 0.5
    normalize_advantages: bool = True
    normalize_obs: bool = True
    goal_shaping: float = 0.025
    bootstrap_timeouts: bool = True
    validate_every: int = 50
    val_episodes: int = 100
    checkpoint_every: int = 10
    log_every: int = 1
    seed: int = 0
    device: str = "cpu"
    threads: int = 1
    network: NetworkSettings = field(default_factory=NetworkSettings)
    mlp_hidden: int = 256

    def __post_init__(self) -> None:
        """Checks every setting.

        Raises:
            ConfigError: a setting out of range (the field and value are named).
        """
        check(self.n_envs >= 1, "n_envs", self.n_envs, "must be >= 1")
        check(self.rollout_steps >= 1, "rollout_steps", self.rollout_steps, "must be >= 1")
        check(self.total_env_steps >= 0, "total_env_steps", self.total_env_steps, "must be >= 0")
        check(self.epochs >= 1, "epochs", self.epochs, "must be >= 1")
        check(self.minibatches >= 1, "minibatches", self.minibatches, "must be >= 1")
        check(self.lr > 0, "lr", self.lr, "must be > 0")
        check(self.adam_eps > 0, "adam_eps", self.adam_eps, "must be > 0")
        check(0 < self.gamma <= 1, "gamma", self.gamma, "must be in (0, 1]")
        check(0 <= self.gae_lambda <= 1, "gae_lambda", self.gae_lambda, "must be in [0, 1]")
        check(0 < self.clip < 1, "clip", self.clip, "must be in (0, 1)")
        check(self.value_clip >= 0, "value_clip", self.value_clip, "must be >= 0 (0: off)")
        check(self.value_coef >= 0, "value_coef", self.value_coef, "must be >= 0")
        check(self.entropy_coef >= 0, "entropy_coef", self.entropy_coef, "must be >= 0")
        check(self.max_grad_norm >= 0, "max_grad_norm", self.max_grad_norm, "must be >= 0 (0: off)")
        check(self.goal_shaping >= 0, "goal_shaping", self.goal_shaping, "must be >= 0 (0: off)")
        check(self.validate_every >= 1, "validate_every", self.validate_every, "must be >= 1")
        check(self.val_episodes >= 1, "val_episodes", self.val_episodes, "must be >= 1")
        check(self.checkpoint_every >= 1, "checkpoint_every", self.checkpoint_every, "must be >= 1")
        check(self.log_every >= 1, "log_every", self.log_every, "must be >= 1")
        check(self.seed >= 0, "seed", self.seed, "must be >= 0")
        check(self.device in DEVICES, "device", self.device, f"must be one of {', '.join(DEVICES)}")
        check(self.threads >= 0, "threads", self.threads, "must be >= 0")
        check(self.mlp_hidden >= 1, "mlp_hidden", self.mlp_hidden, "must be >= 1")

    @property
    def batch_steps(self) -> int:
        """Robot steps per update (n_envs · rollout_steps; n_envs as the worlds round it)."""
        return self.n_envs * self.rollout_steps

    def to_dict(self) -> dict[str, Any]:
        """The settings as plain data (the run's config records them)."""
        return dataclasses.asdict(self)


def load_ppo_settings(path: str | Path | None = None, **overrides: Any) -> PPOSettings:
    """PPO settings from a YAML file (or a shipped config's name, e.g. ``ppo_smoke``).

    Then the top-level ``overrides`` (None values ignored).

    Args:
        path: a YAML file or shipped config name; None: the defaults.
        **overrides: top-level settings that replace the file's.

    Returns:
        The settings.

    Raises:
        ConfigError: an unknown key (the valid ones are named) or a bad value.
    """
    return load_settings_file(PPOSettings, path, overrides)

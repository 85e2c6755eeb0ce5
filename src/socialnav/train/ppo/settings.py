"""PPO training settings: frozen dataclasses loadable from YAML with strict keys (``socialnav.settings``).

Defaults follow CrowdNav++'s repository (``arguments.py``: 30-step rollouts, 5 epochs, 2 minibatches,
clip 0.2, value coefficient 0.5, no entropy bonus, γ 0.99, λ 0.95, gradient norm 0.5, Adam ε 1e-5),
with the deviations documented in docs/ppo.md: more environments per rollout (the batched world
steps them in one native call instead of 16 processes), a larger learning rate to go with the larger
batch, and a smaller total budget (``total_env_steps``) measured to fit a 2-core CPU.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

from socialnav.settings import Settings, setting
from socialnav.train.settings_files import DEVICES, load_settings_file

#: The most environments a PPO run steps in lockstep (docs/ppo.md, "Settings"): 128 times the default.
#: One update holds every environment's rollout and its activations, about 1.7 MB per environment at the
#: repository's widths (30-step rollouts, 5 humans), so this is ~28 GB; a larger value is a typo (an
#: extra zero or three), refused with the file's name instead of an out-of-memory error minutes later.
MAX_N_ENVS = 16_384

#: The command-line options of the PPO settings whose names differ from ``--<setting>`` (``socialnav train``).
PPO_FLAGS = {"n_envs": "--collection-batch", "total_env_steps": "--env-steps"}

#: The planners a PPO run may imitate first (``imitation_teacher``): the native ones that see the walls.
IMITATION_TEACHERS = ("orca_route", "orca", "social_force_route", "social_force")

#: PPO-setting keys that may change between a run and its resumption (everything else must match).
PPO_RESUMABLE_CHANGES = ("device", "threads", "checkpoint_every", "log_every", "total_env_steps")


@dataclass(frozen=True)
class NetworkSettings(Settings):
    """Sizes of the attention-graph network (AttnGraphNet); defaults are the CrowdNav++ repository's."""

    section: ClassVar[str] = "network"

    prediction_steps: int = setting(
        5, "constant-velocity predicted positions per human, K (0: no prediction)", ge=0, le=50
    )
    robot_embed: int = setting(256, "robot node embedding width", ge=1)
    human_hidden: int = setting(128, "human node's first layer width", ge=1)
    attn_size: int = setting(512, "human node's second layer and the human-human self-attention width", ge=1)
    attn_heads: int = setting(8, "heads of the human-human self-attention", ge=1)
    human_out: int = setting(256, "human output layer width", ge=1)
    rh_attention: int = setting(64, "robot-human attention width (query the robot, keys the humans)", ge=1)
    gru_input: int = setting(64, "width of each of the robot and attention embeddings fed to the GRU", ge=1)
    gru_hidden: int = setting(128, "GRU hidden state width", ge=1)
    node_out: int = setting(256, "GRU output layer width", ge=1)
    head_hidden: int = setting(256, "width of the actor's and the critic's two tanh layers", ge=1)
    self_attention: bool = setting(True, "human-human self-attention (false: each human embedded alone)")
    log_std_init: float = setting(0.0, "initial log σ of the Gaussian action (state-independent)")

    def cross_check(self) -> None:
        """Refuses an attention width that the heads do not divide (each head gets attn_size / attn_heads).

        Raises:
            ConfigError: naming network.attn_size.
        """
        if self.attn_size % self.attn_heads:
            self.refuse("attn_size", f"must be a multiple of network.attn_heads ({self.attn_heads})")


@dataclass(frozen=True)
class PPOSettings(Settings):
    """Everything that defines a PPO run besides the preset (each field's meaning: its `setting()`).

    Why some defaults are what they are:

    - goal_shaping: Liu et al. use 2 per metre with a collision penalty of −20; 0.025 keeps that ratio
      to the world's −0.25 (docs/ppo.md, "Reward").
    - threads: 1, because the network's matrices are small and 2 threads made training 4x slower on
      the 2-core VM (benchmarks/bench_ppo_trainer.py --threads 2); run one training per core instead.
    - network: the attention graph's sizes (crowdnav_pp); ppo_mlp uses only its ``prediction_steps``
      and ``log_std_init``.
    """

    policy: str = setting("crowdnav_pp",
                          "PPO policy to train: crowdnav_pp, ppo_mlp or lidar_ppo (train --policy)")
    n_envs: int = setting(
        128, "environments stepped in lockstep (split over the training mix)", ge=1, le=MAX_N_ENVS
    )
    rollout_steps: int = setting(30, "steps per environment per update (CrowdNav++: 30)", ge=1)
    total_env_steps: int = setting(
        10_000_000, "training budget [robot steps, summed over environments; at least one update]", gt=0
    )
    epochs: int = setting(5, "passes over each rollout", ge=1)
    minibatches: int = setting(2, "minibatches per pass, each a set of whole environment sequences", ge=1)
    lr: float = setting(3e-4, "Adam learning rate", gt=0)
    anneal_lr: bool = setting(True, "decay the learning rate linearly to 0 over the budget")
    adam_eps: float = setting(1e-5, "Adam's ε", gt=0)
    gamma: float = setting(0.99, "discount per step", gt=0, le=1)
    gae_lambda: float = setting(0.95, "GAE's λ", ge=0, le=1)
    clip: float = setting(0.2, "ε of the clipped surrogate objective", gt=0, lt=1)
    value_clip: float = setting(0.2, "ε_V of the clipped value loss (0: off)", ge=0)
    value_coef: float = setting(0.5, "weight of the value loss", ge=0)
    entropy_coef: float = setting(0.0, "weight of the entropy bonus", ge=0)
    max_grad_norm: float = setting(0.5, "gradient-norm clipping (0: off)", ge=0)
    normalize_advantages: bool = setting(True, "standardise advantages per minibatch")
    normalize_obs: bool = setting(True, "running mean/variance normalisation of the network's inputs")
    goal_shaping: float = setting(
        0.025, "weight of CrowdNav++'s potential reward (metres gained towards the goal), training only "
        "(0: CrowdSim's reward alone; docs/ppo.md, \"Reward\")", unit="1/m", ge=0,
    )
    turn_penalty: float = setting(
        0.05625, "weight of CrowdNav++'s rotational penalty on a unicycle or diff_drive robot, training "
        "only: -turn_penalty·dθ² per step, dθ the commanded heading change (its 4.5 against a -20 collision, "
        "scaled to wang2022's -0.25; docs/kinematics.md); a holonomic robot's runs neither use nor record it",
        unit="1/rad²", ge=0, record_default=False,
    )
    collision_penalty: float | None = setting(
        None, "training only: the reward of a step that ends in a collision (with a person or a wall) in "
        "place of the preset's (null: the preset's; docs/ppo.md, \"Reward\"; left out of records while null)",
        le=0, record_default=False,
    )
    collision_penalty_ramp_start: float = setting(
        0.0, "with collision_penalty: the share of the updates after which a collision's reward starts to "
        "move from the preset's towards collision_penalty (docs/ppo.md, \"Reward\"; left out of records "
        "while 0)",
        ge=0, le=1, record_default=False,
    )
    collision_penalty_ramp_end: float = setting(
        0.0, "with collision_penalty: the share of the updates from which a collision earns "
        "collision_penalty, reached linearly from collision_penalty_ramp_start (0: from the first update; "
        "left out of records while 0)",
        ge=0, le=1, record_default=False,
    )
    bootstrap_timeouts: bool = setting(True, "a timeout's last reward adds γ·V(final state) (a truncation)")
    validate_every: int = setting(50, "deterministic validation period [updates]", ge=1)
    val_episodes: int = setting(100, "validation episodes (val split, split over the training mix)", ge=1)
    checkpoint_every: int = setting(10, "write last.pt every this many updates (and at the end)", ge=1)
    log_every: int = setting(1, "one curves.csv row every this many updates", ge=1)
    seed: int = setting(0, "master seed (the run's other seeds derive from it)", ge=0, le=2**32 - 1)
    device: str = setting("cpu", "torch device; auto: cuda when available", choices=DEVICES)
    threads: int = setting(
        1, "torch threads (0: all cores, at most 8; 1 is fastest for these small matrices)", ge=0
    )
    network: NetworkSettings = setting(default_factory=NetworkSettings)
    mlp_hidden: int = setting(256, "ppo_mlp's hidden width (two tanh layers each for actor and critic)", ge=1)
    lidar_beams: int = setting(
        180, "lidar_ppo's lidar: beams over the full circle, added to the training world's sensing (left out "
        "of records while 180)", ge=4, le=4096, record_default=False,
    )
    lidar_range: float = setting(
        10.0, "lidar_ppo's lidar: maximum range (left out of records while 10)", unit="m", gt=0, le=100.0,
        record_default=False,
    )
    lidar_history: int = setting(
        1, "lidar_ppo's scans read each step: the current one and the ones before it, as the convolutions' "
        "channels (motion is the shift between them; 1: the current scan alone; left out of records while 1)",
        ge=1, le=16, record_default=False,
    )
    lidar_route_goal: bool = setting(
        False, "lidar_ppo reads its goal as its shortest route around the map's walls heads for it (a global "
        "planner's sub-goal, as DRL-VO's; docs/ppo.md; left out of records while false)",
        record_default=False,
    )
    imitation_updates: int = setting(
        0, "the schedule's first updates imitate imitation_teacher instead of the policy gradient (DAgger: "
        "the teacher acts in a share of the environments falling linearly from all to none, the network in "
        "the rest, and the network fits the teacher's action there; docs/ppo.md, \"A warm start by "
        "imitation\"; 0: none; left out of records while 0)",
        ge=0, record_default=False,
    )
    imitation_teacher: str = setting(
        "orca_route", "the planner imitated in the imitation_updates, with the preset's parameters for it "
        "(left out of records while orca_route)",
        choices=IMITATION_TEACHERS, record_default=False,
    )
    imitation_lr: float | None = setting(
        None, "the imitation updates' Adam learning rate, decayed linearly to 0 over them with anneal_lr "
        "(null: the schedule's lr; left out of records while null)", gt=0, record_default=False,
    )
    imitation_epochs: int | None = setting(
        None, "passes over each imitation rollout (null: epochs; left out of records while null)", ge=1,
        record_default=False,
    )
    imitation_minibatches: int | None = setting(
        None, "minibatches per pass of an imitation update (null: minibatches; left out of records while "
        "null)", ge=1, record_default=False,
    )
    nonholonomic_log_std_init: float = setting(
        -1.0, "initial log σ of the Gaussian action on a unicycle or diff_drive robot, in place of "
        "network.log_std_init (its actions span the commands; docs/kinematics.md; left out of records while "
        "-1)",
        ge=-10.0, le=2.0, record_default=False,
    )

    def cross_check(self) -> None:
        """Refuses more minibatches than environments.

        A minibatch is a set of whole environment sequences (the GRU sees each in order), so with
        more minibatches than environments some would be empty, and the mean of an empty loss is NaN.

        Raises:
            ConfigError: naming minibatches (or imitation_minibatches).
        """
        for key in ("imitation_minibatches", "minibatches"):
            if (getattr(self, key) or 0) > self.n_envs:
                self.refuse(key, f"must be <= n_envs ({self.n_envs}): a minibatch is a set of whole "
                            "environment sequences")
        if self.collision_penalty is None:
            for ramp in ("collision_penalty_ramp_start", "collision_penalty_ramp_end"):
                if getattr(self, ramp) > 0:
                    self.refuse(ramp, "needs collision_penalty: the ramp leads from the preset's collision "
                                "reward to it")
        if self.collision_penalty_ramp_start > self.collision_penalty_ramp_end:
            self.refuse("collision_penalty_ramp_start", f"must be <= collision_penalty_ramp_end "
                        f"({self.collision_penalty_ramp_end})")

    def collision_weight(self, update: int, n_updates: int) -> float:
        """How far a collision's reward has moved from the preset's to ``collision_penalty`` (0 to 1).

        In the rollout of update ``update + 1`` of ``n_updates``: linear between the ramp's start and end.
        """
        done = update / max(n_updates, 1)
        start, end = self.collision_penalty_ramp_start, self.collision_penalty_ramp_end
        if done >= end:
            return 1.0
        if done <= start:
            return 0.0
        return (done - start) / (end - start)

    @property
    def batch_steps(self) -> int:
        """Robot steps per update (n_envs · rollout_steps; n_envs as the worlds round it)."""
        return self.n_envs * self.rollout_steps


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
    return load_settings_file(PPOSettings, path, overrides, PPO_FLAGS)

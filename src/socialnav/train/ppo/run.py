"""The setup phase of a PPO training run.

Settings, seeds, the network (its arguments from the policy's record in
``policies/learned_catalog.py``), the optimizer, the generators and the worlds are built once and
shared by the later phases as one :class:`PPORun`; nothing is written to the run directory before
they and a resumed checkpoint have been checked.
"""

from __future__ import annotations

import contextlib
import dataclasses
import inspect
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch

from socialnav._progress import say_line
from socialnav.policies.learned.ppo_inputs import network_sensors
from socialnav.presets import Preset, load_preset
from socialnav.settings import ConfigError
from socialnav.sim.obstacle_points import ObstaclePoints
from socialnav.sim.settings import HEADED_KINEMATICS
from socialnav.train.curves import Curves
from socialnav.train.optim import load_optimizer_state
from socialnav.train.ppo.imitation import build_teacher
from socialnav.train.ppo.settings import PPO_RESUMABLE_CHANGES, PPOSettings
from socialnav.train.ppo.worlds import restore_worlds
from socialnav.train.run_directory import (
    RunFiles,
    derive_seeds,
    open_run_directory,
    run_device,
    run_record,
    start_run_files,
)
from socialnav.train.settings_files import flat_diff
from socialnav.train.worlds import MultiWorld, mix_human_slots, ppo_policy_config

PPO_STREAM_OFFSET = 5_000_000  # training episodes start here within the seed's range (as the RL stream)
PPO_CURVE_COLUMNS = (
    "phase",
    "update",
    "env_steps",
    "episodes",
    "train_episodes",
    "train_success",
    "train_collision",
    "train_timeout",
    "train_return",
    "loss",
    "policy_loss",
    "value_loss",
    "entropy",
    "approx_kl",
    "clip_fraction",
    "explained_variance",
    "std",
    "lr",
    "val_success",
    "val_collision",
    "val_timeout",
    "val_nav_time",
    "env_steps_per_s",
    "wall_time",
)


@dataclass(frozen=True)
class PPORun(RunFiles):
    """What every phase of a PPO run reads: built by :func:`setup_ppo_run`, never replaced.

    The network, optimizer, generators and worlds are mutable objects the phases advance in place;
    the counters and the episodes in flight live in :class:`socialnav.train.ppo.state.PPOState`.

    Attributes:
        settings: the PPO settings.
        preset: the preset trained under.
        config: the run's record (config.json; every checkpoint's ``config``).
        n_humans: human slots of the rollout (the training mix's largest crowd).
        obstacle_encoding: the obstacle points the network reads after the human slots (a training
            mix with walls), or None.
        device: the torch device.
        out: the run directory.
        net: the actor-critic (the policy's record builds it).
        optimizer: its Adam.
        action_gen: the Gaussian action draws.
        minibatch_gen: the minibatch orders.
        world: the training worlds, in lockstep.
        val_world: the validation episodes (``val`` split).
        n_updates: updates in the whole budget.
        teacher: the planner the first ``imitation_updates`` imitate (ppo/imitation.py), or None.
        resumed: the resume record of ``last.pt`` when the run continues, else None.
        curves: curves.csv of the run.
        say: where progress lines go.
        progress: whether progress bars are shown.
        started: ``time.perf_counter()`` when this call began.
    """

    settings: PPOSettings
    preset: Preset
    config: dict[str, Any]
    n_humans: int
    obstacle_encoding: ObstaclePoints | None
    device: torch.device
    out: Path
    net: Any  # AttnGraphNet or MLPActorCritic: step, sequence, log_std, observation statistics
    optimizer: torch.optim.Optimizer
    action_gen: torch.Generator
    minibatch_gen: torch.Generator
    world: MultiWorld
    val_world: MultiWorld
    n_updates: int
    teacher: Any | None
    resumed: dict[str, Any] | None
    curves: Curves
    say: Callable[[str], None]
    progress: bool
    started: float

    @property
    def n_envs(self) -> int:
        """Environments stepped in lockstep."""
        return self.world.batch_size

    @property
    def n_slots(self) -> int:
        """Agent slots of the network's input: the human slots, then the obstacle points (if any)."""
        return self.n_humans + (0 if self.obstacle_encoding is None else self.obstacle_encoding.count)

    def save(self, path: Path, extra: dict[str, Any]) -> None:
        """Writes a learned-policy checkpoint of the network atomically.

        Args:
            path: the checkpoint file.
            extra: the checkpoint's ``extra`` record.
        """
        from socialnav.policies.learned import save_checkpoint

        save_checkpoint(path, self.settings.policy, self.net, config=self.config, extra=extra)


def _network_arguments(s: PPOSettings, n_humans: int, encoding: ObstaclePoints | None,
                       kinematics: str = "holonomic") -> dict[str, Any]:
    """The network's arguments from the policy's record.

    Among walls with the point slots; for a unicycle or a differential drive with its own initial σ
    (``nonholonomic_log_std_init``), and for a differential drive with its twist (the (v, ω) its
    acceleration limits act from).

    Raises:
        ConfigError: The policy's network cannot read the walls, or a differential drive's twist.
    """
    from socialnav.policies.learned_catalog import get_learned_spec
    from socialnav.train.worlds import check_observation_parts

    check_observation_parts(s.policy)
    spec = get_learned_spec(s.policy)
    headed: dict[str, Any] = {}
    if kinematics in HEADED_KINEMATICS:
        headed = {"log_std_init": s.nonholonomic_log_std_init}
    if kinematics == "diff_drive":
        if "twist_features" not in inspect.signature(spec.network_factory()).parameters:
            raise ConfigError(f"policy {s.policy!r}: its network cannot read a differential drive's (v, ω), "
                              "which its acceleration limits act from; crowdnav_pp can (docs/kinematics.md)")
        headed = {"twist_features": True, **headed}
    network_kwargs = spec.network_kwargs
    assert network_kwargs is not None  # a PPO record always has one (LearnedPolicySpec checks)
    if encoding is None:
        return {**network_kwargs(s, n_humans), **headed}
    params = inspect.signature(network_kwargs).parameters.values()
    if not any(p.name == "obstacle_slots" or p.kind is p.VAR_KEYWORD for p in params):
        raise ConfigError(
            f"policy {s.policy!r}: its record's network_kwargs takes no obstacle_slots, so its network "
            "cannot read the obstacles of a training mix with walls (docs/ppo.md, 'Among walls')"
        )
    return {**network_kwargs(s, n_humans, obstacle_slots=encoding.count), **headed}


def resume_diff(saved: dict[str, Any], config: dict[str, Any]) -> list[str]:
    """Dotted keys where a saved run record and this one differ, less those a resumed run may change."""
    return [k for k in flat_diff(saved, config) if not any(k == f"train.{r}" for r in PPO_RESUMABLE_CHANGES)]


def _check_budget(saved: dict[str, Any], s: PPOSettings, done: int, steps_per_update: int, out: Path,
                  say: Callable[[str], None]) -> None:
    """A resumed run's new ``total_env_steps``: refused below the updates done; its learning rate said.

    Raises:
        ConfigError: The budget ends before the updates the run has done.
    """
    before = (saved.get("train") or {}).get("total_env_steps")
    n_updates = math.ceil(s.total_env_steps / steps_per_update)
    if n_updates < min(done, math.ceil((before or s.total_env_steps) / steps_per_update)):
        raise ConfigError(f"{out}: total_env_steps {s.total_env_steps} ({n_updates} updates) is below "
                          f"the {done} updates this run has done (total_env_steps {before}): give at least "
                          "as many")
    if before is not None and before != s.total_env_steps and s.anneal_lr and done < n_updates:
        old_n = math.ceil(before / steps_per_update)
        say(f"total_env_steps {before} -> {s.total_env_steps}: with anneal_lr the learning rate decays to 0 "
            f"over the new budget from update {done} on ({s.lr * (1 - done / n_updates):.3g} there, not "
            f"{max(0.0, s.lr * (1 - done / old_n)):.3g}): the run follows neither schedule throughout")


def setup_ppo_run(
    preset: Preset | str,
    out_dir: str | Path,
    s: PPOSettings,
    stack: contextlib.ExitStack,
    *,
    progress: bool,
    log: Callable[[str], None] | None,
) -> PPORun:
    """Builds the run and takes its directory.

    The network (seeded; its arguments from the policy's record), optimizer, generators and worlds
    first; then the run directory's lock, ``last.pt`` when present (network, optimizer, generators
    and the worlds' episodes in flight restored), config.json/config.yaml and curves.csv.

    Args:
        preset: a Preset or a preset name/path.
        out_dir: the run directory (created).
        s: the PPO settings.
        stack: closes the worlds and curves and releases the lock when the training call ends.
        progress: show progress bars.
        log: callable taking a line of text (default: print to stderr).

    Returns:
        The run.

    Raises:
        ConfigError: not a PPO policy, too many minibatches, or ``last.pt`` holds no PPO training
            state or a run with other settings.
        DirectoryLockedError: another training is writing to ``out_dir``.
    """
    from socialnav.policies.learned import build
    from socialnav.policies.learned_catalog import learned_policy_names

    if s.policy not in (ppo := learned_policy_names("ppo")):
        raise ConfigError(f"policy: {s.policy!r} is not trained with PPO (PPO policies: {', '.join(ppo)})")
    started = time.perf_counter()
    say = log or say_line  # above the progress bar, not glued to its line
    preset = load_preset(preset) if not isinstance(preset, Preset) else preset
    device = run_device(s)
    seeds = derive_seeds(s.seed)
    # the rollout's human slots: scenarios that fix their own crowd (francis2023) may exceed the preset's
    crowd = int(preset.training.n_humans)
    n_humans = mix_human_slots(preset, crowd)
    encoding = ppo_policy_config(preset).get("obstacle_encoding")
    encoding = None if encoding is None else ObstaclePoints.from_dict(encoding)
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seeds["init"])
        net = build(s.policy, **_network_arguments(s, n_humans, encoding, preset.world.kinematics))
    # A network that reads the robot's sensors (lidar_ppo) brings them to the worlds it trains in.
    preset = dataclasses.replace(preset, world=preset.world.with_sensors(network_sensors(net)))
    config = run_record("ppo", {"ppo_policy": ppo_policy_config(preset)}, s.policy, preset, s, seeds,
                        n_humans=n_humans, ppo_stream_offset=PPO_STREAM_OFFSET)
    if preset.world.kinematics in HEADED_KINEMATICS:
        # recorded even at its default: a run from before the penalty (no key) is not resumed with it
        config["train"]["turn_penalty"] = s.turn_penalty
    out = Path(out_dir)
    net.to(device)
    optimizer = torch.optim.Adam(net.parameters(), lr=s.lr, eps=s.adam_eps)
    action_gen = torch.Generator().manual_seed(seeds["exploration"])
    minibatch_gen = torch.Generator().manual_seed(seeds["sampling"])

    # Refused settings stop here, before anything is written.
    val_world = MultiWorld(preset, crowd, min(s.n_envs, s.val_episodes), "val", 0, s.val_episodes)
    stack.callback(val_world.close)
    world = MultiWorld(preset, crowd, s.n_envs, "train", seeds["scenario_start"] + PPO_STREAM_OFFSET)
    stack.callback(world.close)
    n_updates = math.ceil(s.total_env_steps / (world.batch_size * s.rollout_steps))
    if s.imitation_updates > n_updates:
        raise ConfigError(f"imitation_updates {s.imitation_updates} must be <= the schedule's {n_updates} "
                          f"updates (total_env_steps {s.total_env_steps})")
    teacher = build_teacher(s, preset)
    for key in ("minibatches", "imitation_minibatches"):
        if (getattr(s, key) or 0) > world.batch_size:
            raise ConfigError(
                f"{key} {getattr(s, key)} must be <= the number of environments ({world.batch_size})"
            )
    found = open_run_directory(out, config, stack, policy=s.policy, diff=resume_diff, expected_input_dim=-1,
                               map_location=device)
    resumed, ck = found.resume, found.checkpoint
    if ck is not None:
        assert resumed is not None
        _check_budget(ck.config, s, int(resumed["update"]), world.batch_size * s.rollout_steps, out, say)
        net.load_state_dict(ck.model.state_dict())
        load_optimizer_state(optimizer, resumed["optimizer"])
        action_gen.set_state(resumed["action_rng"])
        minibatch_gen.set_state(resumed["minibatch_rng"])
        restore_worlds(world, resumed["worlds"])
        say(f"resuming {out} at update {resumed['update']} ({resumed['env_steps']} env steps)")
    else:
        world.reset()
    curves = start_run_files(out, config, stack, say=say,
                             banner=f"training {s.policy} under preset {preset.name!r} on {device} "
                             f"into {out}",
                             resumed_at=None if resumed is None else int(resumed["update"]),
                             columns=PPO_CURVE_COLUMNS, key="update")
    return PPORun(
        settings=s,
        preset=preset,
        config=config,
        n_humans=n_humans,
        obstacle_encoding=encoding,
        device=device,
        out=out,
        net=net,
        optimizer=optimizer,
        action_gen=action_gen,
        minibatch_gen=minibatch_gen,
        world=world,
        val_world=val_world,
        n_updates=n_updates,
        teacher=teacher,
        resumed=resumed,
        curves=curves,
        say=say,
        progress=progress,
        started=started,
    )

"""The setup phase of a value-based training run.

Settings, seeds, networks, policy, validation worlds and the run directory are built once and
shared by the later phases as one :class:`ValueRun`.

Nothing is written to the run directory before the settings, the worlds and a resumed checkpoint
have been checked, so a refused run leaves no half-written directory behind.
"""

from __future__ import annotations

import contextlib
import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch

from socialnav._progress import say_line
from socialnav.presets import Preset, load_preset
from socialnav.settings import ConfigError
from socialnav.train.curves import Curves
from socialnav.train.optim import make_optimizer
from socialnav.train.run_directory import (
    RunFiles,
    derive_seeds,
    open_run_directory,
    run_device,
    run_record,
    start_run_files,
)
from socialnav.train.value.settings import TrainSettings, resume_diff
from socialnav.train.worlds import (
    MultiWorld,
    check_observation_parts,
    obstacle_encoding_entry,
    reward_config,
    training_n_humans,
)

#: Offset of the RL episode stream after the imitation episodes (same ``scenario_start``), recorded
#: in the run's config.
RL_STREAM_OFFSET = 5_000_000


@dataclass(frozen=True)
class ValueRun(RunFiles):
    """What every phase of a value-based run reads: built by :func:`setup_run`, never replaced.

    The networks, generators and optimizers are mutable objects the phases train in place; the
    counters that change live in :class:`socialnav.train.value.state.TrainState`.

    Attributes:
        policy_name: the name asked for (an alias is kept, e.g. ``ga3c_cadrl``).
        name: its canonical name (what checkpoints store).
        preset: the preset trained under.
        settings: the resolved training settings (``settings.policy`` is ``policy_name``).
        config: the run's record (config.json; every checkpoint's ``config``).
        seeds: the derived seeds (``derive_seeds``).
        n_humans: humans per training episode.
        device: the torch device.
        out: the run directory.
        net: the value network being trained.
        target: the target network.
        predictor: the learned state predictor (information ``learned``), else None.
        policy: the ε-greedy lookahead policy over ``net``.
        optimizer: the RL optimizer of ``net`` (imitation has its own).
        predictor_optimizer: the predictor's optimizer, else None.
        explore_gen: ε-greedy draws.
        sample_gen: replay minibatch draws.
        val_world: the validation episodes (``val`` split).
        resumed: the resume record of ``last.pt`` when the run continues, else None.
        curves: curves.csv of the run.
        say: where progress lines go.
        progress: whether progress bars are shown.
        started: ``time.perf_counter()`` when this call began.
    """

    policy_name: str
    name: str
    preset: Preset
    settings: TrainSettings
    config: dict[str, Any]
    seeds: dict[str, int]
    n_humans: int
    device: torch.device
    out: Path
    net: torch.nn.Module
    target: torch.nn.Module
    predictor: Any  # StatePredictor or None
    policy: Any  # ValuePolicy
    optimizer: torch.optim.Optimizer
    predictor_optimizer: torch.optim.Optimizer | None
    explore_gen: torch.Generator
    sample_gen: torch.Generator
    val_world: MultiWorld
    resumed: dict[str, Any] | None
    curves: Curves
    say: Callable[[str], None]
    progress: bool
    started: float

    @property
    def oracle(self) -> bool:
        """Whether the policy is shown the humans' true next states."""
        return self.settings.information == "oracle"

    @property
    def success_reward(self) -> float:
        """The preset's reward for reaching the goal."""
        return self.preset.world.reward.success_reward

    def save(self, path: Path, extra: dict[str, Any]) -> None:
        """Writes a learned-policy checkpoint of the network (and predictor) atomically.

        Args:
            path: the checkpoint file.
            extra: the checkpoint's ``extra`` record (episode, validation, resume state).
        """
        from socialnav.policies.learned import save_checkpoint

        save_checkpoint(
            path, self.policy_name, self.net, config=self.config, extra=extra, predictor=self.predictor
        )


def refuse_ending_before_best(out: Path, name: str, resumed_at: int, episodes: int, device: Any) -> None:
    """Refuses to resume a run so that it ends before the episode whose network best.pt holds.

    A validation that found a new best after last.pt was written, before the run stopped, left best.pt
    ahead of last.pt. The resumed run is bit-identical, so it writes the same best.pt again when it gets
    there; a run shortened to end before that episode would report another best than best.pt holds.

    Raises:
        ConfigError: ``episodes`` ends the run before best.pt's episode (both named).
    """
    from socialnav.policies.learned import load_checkpoint

    path = out / "best.pt"
    if not path.is_file():
        return
    best_at = int(load_checkpoint(path, name, -1, map_location=device).extra.get("episode", 0))
    if resumed_at < best_at and episodes < best_at:
        raise ConfigError(
            f"{out}: best.pt holds the network of the validation at RL episode {best_at}, written after "
            f"last.pt (episode {resumed_at}) before the run stopped; rl.episodes {episodes} would end the "
            f"run before it, reporting another best than best.pt holds: give rl.episodes >= {best_at} (the "
            "resumed run writes that best.pt again), or remove best.pt"
        )


def value_policy_config(preset: Preset, settings: TrainSettings) -> dict[str, Any]:
    """The keyword arguments the evaluator passes to ValuePolicy (policies/learned_loading.py).

    A network trained among walls records the obstacle encoding it saw (docs/walls_learned.md); one
    trained on open floors records none (its checkpoints load as those of every open-floor run).

    Args:
        preset: the preset trained under.
        settings: the resolved training settings.

    Returns:
        Plain data: kinematics, gamma, lookahead settings, reward constants (and obstacle encoding, and a
        differential drive's limits).
    """
    w = preset.world
    return {
        "kinematics": w.kinematics,
        "gamma": settings.rl.gamma,
        "information": settings.information,
        "planning_depth": settings.planning_depth,
        "planning_width": settings.planning_width,
        "reward_rule": settings.reward_rule,
        "rotation_limit": w.rotation_limit,
        "dt": w.dt,
        "reward": reward_config(w),
        **obstacle_encoding_entry(preset),
        # a differential drive's limits, which the lookahead applies (docs/kinematics.md)
        **({"diff_drive": w.diff_drive.to_dict()} if w.kinematics == "diff_drive" else {}),
    }


def resolve_policy_settings(policy_name: str, settings: TrainSettings | None) -> TrainSettings:
    """The settings a value-based policy trains with (its record's defaults filled in).

    Args:
        policy_name: a value-based learned policy or alias.
        settings: the settings asked for (default: ``TrainSettings()``).

    Returns:
        The resolved settings, ``policy`` set to ``policy_name``.

    Raises:
        ValueError: the policy is trained with PPO.
        KeyError: not a learned policy (the known ones are listed).
    """
    from socialnav.policies.learned import LEARNED_POLICIES
    from socialnav.policies.learned_catalog import canonical_name, get_learned_spec

    known = canonical_name(policy_name) in LEARNED_POLICIES
    trainer = get_learned_spec(policy_name).trainer if known else "value"
    if trainer != "value":
        raise ValueError(f"{policy_name} is trained with the {trainer!r} trainer, not the value-based one "
                         "(socialnav.train.trainer_for_policy; PPO: docs/ppo.md)")
    if canonical_name(policy_name) not in LEARNED_POLICIES:
        raise KeyError(
            f"unknown learned policy {policy_name!r}; known: {', '.join(sorted(LEARNED_POLICIES))}"
        )
    resolved = (settings or TrainSettings()).resolved(canonical_name(policy_name))
    return dataclasses.replace(resolved, policy=policy_name)


def setup_run(
    policy_name: str,
    preset: Preset | str,
    out_dir: str | Path,
    settings: TrainSettings | None,
    stack: contextlib.ExitStack,
    *,
    progress: bool,
    log: Callable[[str], None] | None,
) -> ValueRun:
    """Builds the run and takes its directory.

    Networks (seeded), policy, generators and validation worlds first; then the run directory's
    lock, ``last.pt`` when present (checked against these settings), config.json/config.yaml.

    Args:
        policy_name: a value-based learned policy (or alias).
        preset: a Preset or a preset name/path.
        out_dir: the run directory (created).
        settings: training settings (default: ``TrainSettings()``).
        stack: closes the worlds and releases the lock when the training call ends.
        progress: show progress bars.
        log: callable taking a line of text (default: print to stderr).

    Returns:
        The run.

    Raises:
        ConfigError: ``last.pt`` holds no training state, or a run with other settings.
        DirectoryLockedError: another training is writing to ``out_dir``.
    """
    from socialnav.policies.learned import ValuePolicy, build
    from socialnav.policies.learned.state import RewardParams
    from socialnav.policies.learned_catalog import canonical_name

    started = time.perf_counter()
    say = log or say_line  # above the progress bar, not glued to its line
    preset = load_preset(preset) if not isinstance(preset, Preset) else preset
    settings = resolve_policy_settings(policy_name, settings)
    name = canonical_name(policy_name)
    check_observation_parts(name)
    rl = settings.rl
    device = run_device(settings)
    seeds = derive_seeds(settings.seed)
    n_humans = training_n_humans(preset, name, settings.cadrl_one_human)
    vp_config = value_policy_config(preset, settings)
    config = run_record("value", {"value_policy": vp_config}, policy_name, preset, settings, seeds,
                        n_humans=n_humans, rl_stream_offset=RL_STREAM_OFFSET)
    out = Path(out_dir)

    # The initial weights come from their own seeds; the target network's are overwritten (it is
    # built last, from the global generator: the draw order is part of a run's identity).
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seeds["init"])
        net = build(name)
    net.to(device)
    predictor = None
    if settings.information == "learned":
        from socialnav.policies.learned.predictor import StatePredictor

        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(seeds["init"] ^ 0x5EED)
            predictor = StatePredictor()
        predictor.to(device).eval()
    policy = ValuePolicy(
        net,
        kinematics=vp_config["kinematics"],
        gamma=rl.gamma,
        reward_params=RewardParams(**vp_config["reward"]),
        information=settings.information,
        dt=preset.world.dt,
        rotation_limit=preset.world.rotation_limit,
        device=device,
        planning_depth=settings.planning_depth,
        planning_width=settings.planning_width,
        reward_rule=settings.reward_rule,
        predictor=predictor,
        obstacle_encoding=vp_config.get("obstacle_encoding"),
        diff_drive=vp_config.get("diff_drive"),
    )
    target = build(name).to(device)
    explore_gen = torch.Generator().manual_seed(seeds["exploration"])
    sample_gen = torch.Generator().manual_seed(seeds["sampling"])

    # Settings the worlds refuse are refused here, before anything is written.
    val_world = MultiWorld(
        preset, n_humans, min(settings.collection_batch, rl.val_episodes), "val", 0, rl.val_episodes
    )
    stack.callback(val_world.close)
    found = open_run_directory(out, config, stack, policy=name, diff=resume_diff, map_location=device)
    resumed, ck = found.resume, found.checkpoint
    if ck is not None:
        assert resumed is not None
        # rl.episodes may change on resume (extend a run, or end it earlier), not fall below what is done
        # (lockstep batches may finish a few episodes past the budget: the same budget again is fine)
        saved_budget = int(((ck.config.get("train") or {}).get("rl") or {}).get("episodes", rl.episodes))
        if rl.episodes < min(saved_budget, int(resumed["episode"])):
            raise ConfigError(f"{out}: rl.episodes {rl.episodes} is below the {resumed['episode']} RL "
                              "episodes this run has done: give at least as many (more extends it)")
        refuse_ending_before_best(out, name, int(resumed["episode"]), rl.episodes, device)
        net.load_state_dict(ck.model.state_dict())
        if predictor is not None and ck.predictor is not None:
            predictor.load_state_dict(ck.predictor.state_dict())
        say(f"resuming {out} at RL episode {resumed['episode']} ({resumed['gradient_steps']} gradient steps)")
    curves = start_run_files(out, config, stack, say=say,
                             banner=f"training {name} under preset {preset.name!r} on {device} into {out}",
                             resumed_at=None if resumed is None else int(resumed["episode"]))
    return ValueRun(
        policy_name=policy_name,
        name=name,
        preset=preset,
        settings=settings,
        config=config,
        seeds=seeds,
        n_humans=n_humans,
        device=device,
        out=out,
        net=net,
        target=target,
        predictor=predictor,
        policy=policy,
        optimizer=make_optimizer(net.parameters(), rl.lr, device),
        predictor_optimizer=None
        if predictor is None
        else make_optimizer(predictor.parameters(), settings.predictor_lr, device),
        explore_gen=explore_gen,
        sample_gen=sample_gen,
        val_world=val_world,
        resumed=resumed,
        curves=curves,
        say=say,
        progress=progress,
        started=started,
    )

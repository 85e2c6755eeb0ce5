"""A trainer from outside the package: random search over a tiny actor's weights (tests only).

``tiny_actor`` is a learned policy registered with ``register_learned_policy`` (an MLP actor-critic a
few units wide, trained by ``random_search``); ``random_search`` is a trainer registered with
``register_trainer``: each candidate perturbs the best weights so far by Gaussian noise, is validated
on the ``val`` split, and the better ones become ``best.pt``. It keeps its run directory with the
shared bookkeeping (``socialnav.train``: ``open_run_directory``, ``start_run_files``) and writes
``ppo_policy`` checkpoints, which ``socialnav evaluate`` loads as actors.

Importing this module registers both (an entry point of group ``socialnav.trainers`` may name it or
its :data:`TRAINER`); it imports no torch, so ``socialnav list`` stays cheap.
"""

from __future__ import annotations

import contextlib
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from socialnav.policies import LearnedPolicySpec, register_learned_policy
from socialnav.policies.learned_catalog import learned_policy_names
from socialnav.settings import Settings, setting
from socialnav.train import Trainer, register_trainer

#: curves.csv of a random-search run: one row per candidate.
COLUMNS = ("candidate", "val_success", "val_collision", "val_timeout", "val_nav_time", "sigma")


@dataclass(frozen=True)
class RandomSearchSettings(Settings):
    """Settings of the random-search trainer."""

    policy: str = setting("tiny_actor", "the learned policy trained")
    candidates: int = setting(3, "perturbed networks tried", ge=1)
    sigma: float = setting(0.3, "standard deviation of each candidate's weight perturbation", gt=0)
    hidden: int = setting(4, "hidden width of the actor and the critic", ge=1)
    val_episodes: int = setting(2, "validation episodes per candidate", ge=1)
    seed: int = setting(0, "master seed", ge=0, le=2**32 - 1)
    device: str = setting("cpu", "torch device", choices=("cpu", "cuda", "auto"))
    threads: int = setting(1, "torch threads (0: all cores)", ge=0)


@dataclass(frozen=True)
class RandomSearchResult:
    """What a random-search run produced (the fields every trainer's result has, and its counter)."""

    out_dir: Path
    best_checkpoint: Path
    last_checkpoint: Path
    curves: Path
    candidates: int
    best_val: dict[str, Any] | None
    wall_time: float
    resumed: bool
    finished: bool


def tiny_actor_kwargs(settings: Any, n_humans: int, obstacle_slots: int = 0) -> dict[str, Any]:
    """The tiny actor's network arguments from the run's settings."""
    return {"prediction_steps": 0, "max_humans": n_humans, "hidden": settings.hidden, "normalize_obs": False}


def train_random_search(policy: str, preset: Any, out_dir: str | Path, settings: RandomSearchSettings, *,
                        progress: bool = True, stop_after: int | None = None, log=None) -> RandomSearchResult:
    """Random search over ``policy``'s weights; resumes from ``out_dir/last.pt``."""
    import time

    import torch

    from socialnav.policies.learned import build, save_checkpoint
    from socialnav.policies.learned.ppo_policy import RecurrentActorPolicy
    from socialnav.policies.learned_catalog import get_learned_spec
    from socialnav.presets import Preset, load_preset
    from socialnav.train import (
        GreedyActor,
        MultiWorld,
        better,
        derive_seeds,
        flat_diff,
        open_run_directory,
        ppo_policy_config,
        run_device,
        run_record,
        start_run_files,
        validate,
    )

    started = time.perf_counter()
    say = log or (lambda line: print(line, file=sys.stderr))
    preset = preset if isinstance(preset, Preset) else load_preset(preset)
    device, seeds, out = run_device(settings), derive_seeds(settings.seed), Path(out_dir)
    n_humans = int(preset.training.n_humans)
    config = run_record("random_search", {"ppo_policy": ppo_policy_config(preset)}, policy, preset, settings,
                        seeds, n_humans=n_humans)
    with contextlib.ExitStack() as stack:
        val_world = MultiWorld(preset, n_humans, settings.val_episodes, "val", 0, settings.val_episodes)
        stack.callback(val_world.close)
        found = open_run_directory(out, config, stack, policy=policy, diff=flat_diff, expected_input_dim=-1,
                                   map_location=device)
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(seeds["init"])
            net = build(policy, **get_learned_spec(policy).network_kwargs(settings, n_humans)).to(device)
        generator = torch.Generator().manual_seed(seeds["exploration"])
        done, best, wall_before = 0, None, 0.0
        if found.checkpoint is not None:
            net.load_state_dict(found.checkpoint.model.state_dict())
            generator.set_state(found.resume["rng"])
            resume = found.resume
            done, best, wall_before = resume["candidate"], resume["best_val"], resume["wall"]
            say(f"resuming {out} at candidate {done}")
        banner = f"training {policy} under preset {preset.name!r} on {device} into {out}"
        curves = start_run_files(out, config, stack, say=say, banner=banner, columns=COLUMNS, key="candidate",
                                 resumed_at=done if found.resume else None)
        w = preset.world
        actor = RecurrentActorPolicy(policy, net, kinematics=w.kinematics, rotation_limit=w.rotation_limit,
                                     dt=w.dt, device=device)
        base = {k: v.detach().clone() for k, v in net.state_dict().items()}
        this_call = 0
        while done < settings.candidates and (stop_after is None or this_call < stop_after):
            with torch.no_grad():
                for name, param in net.named_parameters():
                    noise = torch.randn(param.shape, generator=generator) * settings.sigma
                    param.copy_(base[name] + noise.to(device))
            actor.reset()
            val = validate(GreedyActor(actor), val_world, False, w.reward.success_reward)
            done, this_call = done + 1, this_call + 1
            val["candidate"] = done
            if better(val, best):
                best, base = val, {k: v.detach().clone() for k, v in net.state_dict().items()}
                save_checkpoint(out / "best.pt", policy, net, config=config, extra={"val": val})
            net.load_state_dict(base)
            curves.write({"candidate": done, "sigma": settings.sigma,
                          **{f"val_{k}": val[k] for k in ("success", "collision", "timeout", "nav_time")}})
            wall = wall_before + time.perf_counter() - started
            resume = {"candidate": done, "best_val": best, "rng": generator.get_state(), "wall": wall}
            save_checkpoint(out / "last.pt", policy, net, config=config, extra={"resume": resume})
        return RandomSearchResult(out, out / "best.pt", out / "last.pt", out / "curves.csv", done, best,
                                  wall_before + time.perf_counter() - started, found.checkpoint is not None,
                                  done >= settings.candidates)


TRAINER = Trainer(
    name="random_search",
    label="random-search",
    description="random search over a tiny actor's weights (a test's trainer)",
    settings=RandomSearchSettings,
    train=train_random_search,
    checkpoint_kind="ppo_policy",
    counters=("candidates",),
    options={"collection_batch": "val_episodes"},
)
SPEC = LearnedPolicySpec(
    name="tiny_actor",
    network="socialnav.policies.learned.ppo_mlp:MLPActorCritic",
    description="a test's tiny MLP actor, trained by random search",
    label="Tiny actor (test)",
    trainer="random_search",
    checkpoint_kind="ppo_policy",
    observes="robot state + the nearest humans' positions and velocities",
    paper="none",
    network_kwargs=tiny_actor_kwargs,
)


def register() -> None:
    """Registers the trainer and its policy (once per process)."""
    register_trainer(TRAINER)
    if SPEC.name not in learned_policy_names():
        register_learned_policy(SPEC)


register()

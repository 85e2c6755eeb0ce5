"""`socialnav train`: imitation from ORCA, then value-based RL, with checkpoints, curves and resumption.

Run directory layout::

    config.yaml / config.json   resolved settings (policy, preset, training settings, derived seeds)
    il.pt                       the network after imitation learning
    best.pt                     best validation success so far (ties: fewer collisions, then faster)
    last.pt                     latest state: model + target network + optimizer + counters + RNG
                                states + best validation (no replay memory); re-running the same
                                command on the same directory resumes from it
    curves.csv                  one row per ``log_every`` RL episodes (and one per validation)
    tb/                         TensorBoard scalars, when ``torch.utils.tensorboard`` imports

Every checkpoint is a regular learned-policy checkpoint (``socialnav evaluate --checkpoint`` loads
any of them); its config holds ``value_policy`` so the evaluator scores actions as the trainer did.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from socialnav._io import (
    DirectoryLock,
    atomic_write_json,
    atomic_write_text,
    make_output_dir,
    remove_orphan_temporaries,
)
from socialnav.config import ConfigError
from socialnav.presets import Preset, load_preset
from socialnav.train.common import (
    AdamSteps,
    better,
    check_same_run,
    load_optimizer_state,
    make_optimizer,
    optimizer_state,
    progress_bar,
    reward_config,
)
from socialnav.train.config import TrainSettings, derive_seeds, resolve_train_settings
from socialnav.train.curves import Curves, validation_columns, window_columns
from socialnav.train.envs import MultiWorld, training_n_humans
from socialnav.train.fused_step import FusedTDStep
from socialnav.train.imitation_phase import run_imitation
from socialnav.train.memory import ReplayMemory
from socialnav.train.rl import (
    EpisodeStats,
    RGLRepoEpisodes,
    TrainingDiverged,
    encoded_step,
    epsilon_at,
    push_step,
    replay_td_loss,
    validate,
)

RL_STREAM_OFFSET = 5_000_000


@dataclass(frozen=True)
class TrainResult:
    """What a training call produced."""

    out_dir: Path
    best_checkpoint: Path
    last_checkpoint: Path
    curves: Path
    episodes: int  # RL episodes done in all (across resumptions)
    gradient_steps: int
    best_val: dict[str, Any]
    last_val: dict[str, Any] | None
    wall_time: float  # [s] across resumptions
    resumed: bool
    finished: bool  # False when stopped early by ``stop_after``


def resolve_device(name: str) -> torch.device:
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if name == "cuda" and not torch.cuda.is_available():
        raise RuntimeError(
            "device 'cuda' requested but torch.cuda.is_available() is False (use --device cpu)"
        )
    return torch.device(name)


def trains_among_walls(preset: Preset) -> bool:
    """Whether the preset's training mix has a scenario with walls."""
    from socialnav.scenarios.registry import get_scenario
    from socialnav.scenarios.walls import WalledScenario

    return any(issubclass(get_scenario(name), WalledScenario) for name in preset.training.scenarios)


def value_policy_config(preset: Preset, settings: TrainSettings) -> dict[str, Any]:
    """The keyword arguments the evaluator passes to ValuePolicy (learned_entries.py). A network
    trained among walls records the obstacle encoding it saw (docs/walls_learned.md); one trained on
    open floors records none, as before."""
    w = preset.world
    walls = {}
    if trains_among_walls(preset):
        from socialnav.sim.obstacle_points import ObstaclePoints

        walls = {"obstacle_encoding": ObstaclePoints().to_dict()}
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
        **walls,
    }


def _plain(x: Any) -> Any:
    return json.loads(json.dumps(x, default=lambda v: list(v) if isinstance(v, tuple) else str(v)))


def train(
    policy_name: str,
    preset: Preset | str,
    out_dir: str | Path,
    settings: TrainSettings | None = None,
    *,
    progress: bool = True,
    stop_after: int | None = None,
    log=None,
    on_validation=None,
) -> TrainResult:
    with contextlib.ExitStack() as stack:  # holds the run directory's lock once it is taken
        return _train(
            policy_name,
            preset,
            out_dir,
            settings,
            stack,
            progress=progress,
            stop_after=stop_after,
            log=log,
            on_validation=on_validation,
        )


def _train(
    policy_name: str,
    preset: Preset | str,
    out_dir: str | Path,
    settings: TrainSettings | None,
    stack: contextlib.ExitStack,
    *,
    progress: bool = True,
    stop_after: int | None = None,
    log=None,
    on_validation=None,
) -> TrainResult:
    """Imitation learning from ORCA, then value-based RL; resumes from ``out_dir/last.pt`` if present.

    Args:
        policy_name: a value-based learned policy: cadrl, lstm_rl (ga3c_cadrl), sarl, om_sarl, rgl, mp_rgl.
        preset: a Preset or a preset name/path (world semantics, robot, training scenario mix).
        out_dir: run directory (created; resumed when it holds last.pt).
        settings: training settings (default: TrainSettings()); ``settings.policy`` is replaced by
            ``policy_name``.
        progress: tqdm progress bars on stderr.
        stop_after: stop after this many RL episodes in THIS call without a final checkpoint (as if
            the process were killed; for tests of resumption).
        log: callable taking a line of text (default: print to stderr).
        on_validation: callable ``(episode, val_metrics, wall_time) -> bool`` called after every
            validation (episode 0 is the one after imitation); True stops training there (last.pt is
            written first, so the run can be resumed).

    Raises:
        TrainingDiverged: the loss became NaN/inf (last.pt and best.pt keep the last good state).
        ConfigError: resuming with settings that differ from the run's (the keys are named).
        DirectoryLockedError: another training is writing to ``out_dir``.

    Nothing is written to ``out_dir`` before the settings, the worlds and a resumed checkpoint have
    been checked, so a refused run leaves no half-written directory behind.
    """
    from socialnav.policies.learned import (
        LEARNED_POLICIES,
        ValuePolicy,
        build,
        load_checkpoint,
        save_checkpoint,
    )
    from socialnav.policies.learned.registry import canonical_name
    from socialnav.policies.learned.state import RewardParams

    t_call = time.perf_counter()
    say = log or (lambda s: print(s, file=sys.stderr, flush=True))
    preset = load_preset(preset) if not isinstance(preset, Preset) else preset
    from socialnav.policies.learned_catalog import learned_policy_names

    if policy_name in learned_policy_names("ppo"):
        raise ValueError(f"{policy_name} is trained with PPO: socialnav.train.ppo.train_ppo (docs/ppo.md)")
    if canonical_name(policy_name) not in LEARNED_POLICIES:
        raise KeyError(
            f"unknown learned policy {policy_name!r}; known: {', '.join(sorted(LEARNED_POLICIES))}"
        )
    settings = (settings or TrainSettings()).resolved(canonical_name(policy_name))
    settings = dataclasses.replace(settings, policy=policy_name)
    rl = settings.rl
    device = resolve_device(settings.device)
    threads = settings.threads or max(1, min(os.cpu_count() or 1, 8))
    torch.set_num_threads(threads)
    seeds = derive_seeds(settings.seed)
    n_humans = training_n_humans(preset, canonical_name(policy_name), settings.cadrl_one_human)
    vp_config = value_policy_config(preset, settings)
    config = _plain(
        {
            "value_policy": vp_config,
            "policy": policy_name,
            "preset": preset.to_dict(),
            "train": settings.to_dict(),
            "seeds": seeds,
            "n_humans": n_humans,
            "rl_stream_offset": RL_STREAM_OFFSET,
            "kinematics": preset.world.kinematics,
        }
    )
    out = Path(out_dir)
    last_path, best_path, curves_path = out / "last.pt", out / "best.pt", out / "curves.csv"

    # -- network, policy, optimizer, generators ------------------------------------------------
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seeds["init"])
        net = build(canonical_name(policy_name))
    net.to(device)
    predictor = None
    if settings.information == "learned":
        from socialnav.policies.learned.predictor import StatePredictor

        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(seeds["init"] ^ 0x5EED)
            predictor = StatePredictor()
        predictor.to(device).eval()
    reward_params = RewardParams(**vp_config["reward"])
    policy = ValuePolicy(
        net,
        kinematics=vp_config["kinematics"],
        gamma=rl.gamma,
        reward_params=reward_params,
        information=settings.information,
        dt=preset.world.dt,
        rotation_limit=preset.world.rotation_limit,
        device=device,
        planning_depth=settings.planning_depth,
        planning_width=settings.planning_width,
        reward_rule=settings.reward_rule,
        predictor=predictor,
        obstacle_encoding=vp_config.get("obstacle_encoding"),
    )
    target = build(canonical_name(policy_name)).to(device)
    explore_gen = torch.Generator().manual_seed(seeds["exploration"])
    sample_gen = torch.Generator().manual_seed(seeds["sampling"])
    oracle = settings.information == "oracle"
    success_reward = preset.world.reward.success_reward

    # Settings the worlds refuse are refused here, before anything is written.
    val_world = MultiWorld(
        preset, n_humans, min(settings.collection_batch, rl.val_episodes), "val", 0, rl.val_episodes
    )
    stack.callback(val_world.close)
    make_output_dir(out)
    stack.enter_context(DirectoryLock(out, "training"))
    remove_orphan_temporaries(out)

    resume: dict[str, Any] | None = None
    if last_path.exists():
        ck = load_checkpoint(last_path, canonical_name(policy_name), map_location=device)
        resume = ck.extra.get("resume")
        if not isinstance(resume, dict):
            raise ConfigError(
                f"{last_path} is not a training state (no 'resume' record); move it away to restart"
            )
        check_same_run(ck.config, config, out)
        net.load_state_dict(ck.model.state_dict())
        if predictor is not None and ck.predictor is not None:
            predictor.load_state_dict(ck.predictor.state_dict())
        say(f"resuming {out} at RL episode {resume['episode']} ({resume['gradient_steps']} gradient steps)")

    atomic_write_json(out / "config.json", config)
    import yaml

    atomic_write_text(out / "config.yaml", yaml.safe_dump(config, sort_keys=False))
    curves = Curves(curves_path, None if resume is None else int(resume["episode"]))
    if curves.dropped:
        say(f"{curves_path}: {curves.dropped} damaged row(s) left out")

    elapsed0 = 0.0 if resume is None else float(resume["wall_time"])

    def wall() -> float:
        return elapsed0 + time.perf_counter() - t_call

    if predictor is not None:
        predictor_opt = make_optimizer(predictor.parameters(), settings.predictor_lr, device)

    def save(path: Path, extra: dict[str, Any]) -> None:
        save_checkpoint(path, policy_name, net, config=config, extra=extra, predictor=predictor)

    # -- imitation learning --------------------------------------------------------------------
    if resume is None:
        il = settings.imitation
        if il.episodes > 0 and il.epochs > 0:
            il_loss, predictor_losses = run_imitation(
                policy_name, preset, settings, config, out, policy, net, device, n_humans, seeds,
                success_reward, progress, say, predictor, predictor_opt if predictor is not None else None,
            )
        else:
            il_loss = math.nan
            predictor_losses = []
        val = validate(policy, val_world, oracle, success_reward)
        say(
            f"after imitation: validation success {val['success']:.3f} collision {val['collision']:.3f} "
            f"timeout {val['timeout']:.3f} nav_time {val['nav_time']:.2f}"
        )
        curves.write(
            {
                "phase": "il",
                "episode": 0,
                "loss": il_loss,
                "val_success": val["success"],
                "val_collision": val["collision"],
                "val_timeout": val["timeout"],
                "val_nav_time": val["nav_time"],
                "predictor_loss": predictor_losses[-1] if predictor_losses else math.nan,
                "gradient_steps": 0,
                "transitions": 0,
                "wall_time": wall(),
            }
        )
        best_val = {**val, "episode": 0}
        stop_now = bool(on_validation and on_validation(0, best_val, wall()))
        save(best_path, {"episode": 0, "val": best_val})
        target.load_state_dict(net.state_dict())
        optimizer = make_optimizer(net.parameters(), rl.lr, device)
        state = {
            "episode": 0,
            "gradient_steps": 0,
            "transitions": 0,
            "credit": 0.0,
            "next_target": rl.target_update_every,
            "next_val": rl.validate_every,
            "next_ckpt": settings.checkpoint_every,
            "next_log": settings.log_every,
            "stream_positions": None,
            "best_val": best_val,
            "last_val": best_val,
        }
    else:
        target.load_state_dict(resume["target_state_dict"])
        optimizer = make_optimizer(net.parameters(), rl.lr, device)
        load_optimizer_state(optimizer, resume["optimizer"])
        if predictor is not None:
            load_optimizer_state(predictor_opt, resume["predictor_optimizer"])
        explore_gen.set_state(resume["explore_rng"])
        sample_gen.set_state(resume["sample_rng"])
        state = {
            k: resume[k]
            for k in (
                "episode",
                "gradient_steps",
                "transitions",
                "credit",
                "next_target",
                "next_val",
                "next_ckpt",
                "next_log",
                "stream_positions",
                "best_val",
                "last_val",
            )
        }
        stop_now = False
    target.eval()
    for p in target.parameters():
        p.requires_grad_(False)

    def save_last() -> None:
        extra = {
            "phase": "rl",
            "resume": {
                **state,
                "target_state_dict": {k: v.detach().cpu().clone() for k, v in target.state_dict().items()},
                "optimizer": optimizer_state(optimizer),
                "explore_rng": explore_gen.get_state(),
                "sample_rng": sample_gen.get_state(),
                "stream_positions": world.stream_positions(),
                "wall_time": wall(),
            },
        }
        if predictor is not None:
            extra["resume"]["predictor_optimizer"] = optimizer_state(predictor_opt)
        save(last_path, extra)

    # -- RL ------------------------------------------------------------------------------------
    world = MultiWorld(
        preset, n_humans, settings.collection_batch, "train", seeds["scenario_start"] + RL_STREAM_OFFSET
    )
    stack.callback(world.close)
    world.reset(state["stream_positions"])
    encoding = policy.obstacle_encoding
    slots = world.n_human_slots + (0 if encoding is None else encoding.count)
    memory = ReplayMemory(rl.capacity, slots, device=device)
    fixed_targets = rl.td_targets == "rgl_repo"
    # compile: the whole gradient step as one compiled graph where the network traces into one
    # (train/fused_step.py), else the loss alone compiled
    fused_step = None
    if settings.compile:
        fused_step, refusal = FusedTDStep.build(
            policy, target, memory, optimizer, rl.gamma, preset.world.dt, rl.batch_size, fixed_targets
        )
        if fused_step is None:
            say(f"compile: {policy_name}'s gradient step does not trace into one graph ({refusal}); "
                "its loss is compiled instead")
    loss_at = replay_td_loss(
        policy, target, memory, rl.gamma, preset.world.dt, fixed_targets,
        compiled=settings.compile and fused_step is None,
    )
    # optimizer.step() without its per-call Python, bit-identical (train/common.py: AdamSteps)
    adam = AdamSteps(optimizer)
    predictor_adam = AdamSteps(predictor_opt) if predictor is not None else None
    rgl_repo_episodes = (
        RGLRepoEpisodes(world.batch_size, fixed=fixed_targets) if rl.td_targets != "recomputed" else None
    )
    if resume is None:
        save_last()
    window = EpisodeStats()
    window_loss, window_steps, window_pred = 0.0, 0, 0.0
    bar = progress_bar(rl.episodes, int(state["episode"]), f"{policy_name} RL", progress)
    episodes_this_call = 0
    stopped_early = stop_now
    obs = policy.encode(world.observe(oracle=oracle))  # obstacle points appended, if any
    dt = preset.world.dt

    def check_loss(value: float, gradient_step: int) -> None:
        if not math.isfinite(value):
            raise TrainingDiverged(
                f"RL loss became {value} at episode {state['episode']} (gradient step {gradient_step}); "
                f"training stopped; {last_path} and {best_path} keep the last good state"
            )
    net.eval()
    try:
        while state["episode"] < rl.episodes and not stopped_early:
            eps = epsilon_at(int(state["episode"]), rl)
            _, actions = policy.act(
                obs, epsilon=eps, generator=explore_gen, next_humans=obs.next_humans if oracle else None
            )
            res = encoded_step(policy, world.step(np.asarray(actions, dtype=np.float64)))
            if rgl_repo_episodes is not None:
                rgl_repo_episodes.add_step(obs, res)
                rgl_repo_episodes.finish(memory, res, policy, target, rl.gamma, dt)
            else:
                push_step(memory, obs, res)
            state["transitions"] += int(obs.active.sum())
            # Training stops at exactly rl.episodes: when more episodes end in the last lockstep step
            # than are still needed (untrained policies often time out together), only the first ones
            # (in slot order) count; the others' transitions stay in the memory but are not counted.
            counted = res.terminated | res.truncated
            need = rl.episodes - int(state["episode"])
            if int(counted.sum()) > need:
                counted[np.flatnonzero(counted)[need:]] = False
            finished = int(counted.sum())
            window.add(res.terminated & counted, res.truncated & counted, res.reward, res.final_time,
                       success_reward)
            state["episode"] += finished
            episodes_this_call += finished
            bar.update(finished)
            # gradient steps at the replay ratio
            if len(memory) >= max(rl.batch_size, rl.warmup_transitions):
                state["credit"] += rl.gradient_steps_per_episode * finished
                n_steps = int(state["credit"])
                if n_steps:
                    state["credit"] -= n_steps
                    net.train()
                    fused_losses = []  # checked once per burst: no synchronisation per step
                    for _ in range(n_steps):
                        idx = memory.sample_indices(rl.batch_size, sample_gen)
                        if fused_step is not None:
                            fused_losses.append(fused_step(idx))
                        else:
                            loss = loss_at(idx)
                            lv = float(loss.detach())
                            check_loss(lv, state["gradient_steps"])
                            adam.zero_grad()
                            loss.backward()
                            adam.step()
                            window_loss += lv
                        if predictor is not None:
                            predictor.train()
                            batch = memory.take(idx)
                            pl = predictor.loss(
                                batch.robot, batch.humans, batch.mask, batch.next_humans, batch.next_mask, dt
                            )
                            predictor_adam.zero_grad()
                            pl.backward()
                            predictor_adam.step()
                            predictor.eval()
                            window_pred += float(pl.detach())
                        state["gradient_steps"] += 1
                        window_steps += 1
                    if fused_losses:
                        first = state["gradient_steps"] - len(fused_losses)
                        for j, lv in enumerate(torch.stack(fused_losses).tolist()):
                            check_loss(lv, first + j)
                            window_loss += lv
                    net.eval()
            ep = int(state["episode"])
            if ep >= state["next_target"]:
                target.load_state_dict(net.state_dict())
                while state["next_target"] <= ep:
                    state["next_target"] += rl.target_update_every
            val = None
            if ep >= state["next_val"] or ep >= rl.episodes:
                val = validate(policy, val_world, oracle, success_reward)
                val["episode"] = ep
                state["last_val"] = val
                while state["next_val"] <= ep:
                    state["next_val"] += rl.validate_every
                if better(val, state["best_val"]):
                    state["best_val"] = val
                    save(best_path, {"episode": ep, "val": val})
                say(
                    f"episode {ep}: validation success {val['success']:.3f} collision {val['collision']:.3f} "
                    f"timeout {val['timeout']:.3f} nav_time {val['nav_time']:.2f} "
                    f"(best {state['best_val']['success']:.3f} at {state['best_val']['episode']})"
                )
            if ep >= state["next_log"] or val is not None or ep >= rl.episodes:
                rates = window.rates()
                row = {
                    "phase": "rl",
                    "episode": ep,
                    "epsilon": eps,
                    **window_columns(rates, window.total),
                    "loss": window_loss / window_steps if window_steps else math.nan,
                    "predictor_loss": window_pred / window_steps
                    if window_steps and predictor is not None
                    else math.nan,
                    "gradient_steps": state["gradient_steps"],
                    "transitions": state["transitions"],
                    "wall_time": wall(),
                }
                row.update(validation_columns(val))
                curves.write(row)
                bar.set_postfix(eps=f"{eps:.2f}", succ=f"{rates['success']:.2f}", loss=f"{row['loss']:.3g}")
                window, window_loss, window_steps, window_pred = EpisodeStats(), 0.0, 0, 0.0
                while state["next_log"] <= ep:
                    state["next_log"] += settings.log_every
            if ep >= state["next_ckpt"] or ep >= rl.episodes:
                save_last()
                while state["next_ckpt"] <= ep:
                    state["next_ckpt"] += settings.checkpoint_every
            if (
                val is not None
                and on_validation is not None
                and ep < rl.episodes
                and on_validation(ep, val, wall())
            ):
                save_last()
                stopped_early = True
                break
            if stop_after is not None and episodes_this_call >= stop_after and ep < rl.episodes:
                stopped_early = True
                break
            obs = policy.encode(world.observe(oracle=oracle))
        if not stopped_early and state["episode"] >= rl.episodes and not last_path.exists():
            save_last()
    finally:
        bar.close()
        curves.close()
    return TrainResult(
        out,
        best_path,
        last_path,
        curves_path,
        int(state["episode"]),
        int(state["gradient_steps"]),
        dict(state["best_val"]),
        state["last_val"],
        wall(),
        resume is not None,
        not stopped_early,
    )


def train_from_args(args) -> int:
    """Entry point of ``socialnav train`` (see train/cli.py)."""
    settings = resolve_train_settings(
        getattr(args, "config", None),
        **{key: getattr(args, key, None)
           for key in ("seed", "device", "collection_batch", "information", "rl_episodes", "compile")},
    )
    preset = load_preset(args.preset)
    out = Path(args.out or f"runs/train/{preset.name}-{args.policy}-s{settings.seed}")
    result = train(args.policy, preset, out, settings, progress=not getattr(args, "no_progress", False))
    best = result.best_val
    print(
        json.dumps(
            {
                "out": str(result.out_dir),
                "best_checkpoint": str(result.best_checkpoint),
                "episodes": result.episodes,
                "gradient_steps": result.gradient_steps,
                "best_val": {
                    k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in best.items()
                },
                "wall_time_s": round(result.wall_time, 1),
                "resumed": result.resumed,
            }
        )
    )
    return 0

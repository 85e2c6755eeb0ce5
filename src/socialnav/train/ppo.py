"""`socialnav train --policy crowdnav_pp` (or `ppo_mlp`): PPO with a recurrent actor-critic.

Reads top to bottom like a CleanRL script (Huang et al., "CleanRL", JMLR 2022): settings and seeds,
the network and the worlds, then per update a rollout collected from every environment in lockstep
(one native call per world of the training mix per step), GAE, and epochs of clipped-objective
minibatch steps over whole environment sequences (the GRU replays each sequence from its stored
initial state). The network is in policies/learned/attn_graph.py, the objective in
train/ppo_objective.py, the settings in train/ppo_config.py; docs/ppo.md explains the choices.

Run directory layout (as the value-based trainer's)::

    config.yaml / config.json   resolved settings (policy, preset, PPO settings, derived seeds)
    best.pt                     best validation success so far (ties: fewer collisions, then faster)
    last.pt                     network + optimizer + generators + counters + the worlds' state and
                                the GRU states of the episodes in flight: re-running the same command
                                resumes exactly where it stopped (bit-identical on CPU)
    curves.csv                  one row per ``log_every`` updates

Actions: the Gaussian's sample is the log-probability's argument; the world receives it squashed
(holonomic: scaled onto the v_pref disc; unicycle: clipped), see ``squash_actions``.
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
from socialnav.train.common import better, load_optimizer_state, optimizer_state, progress_bar
from socialnav.train.config import derive_seeds, flat_diff
from socialnav.train.curves import Curves, validation_columns, window_columns
from socialnav.train.envs import MultiWorld, mix_human_slots
from socialnav.train.ppo_config import PPO_RESUMABLE_CHANGES, PPOSettings
from socialnav.train.ppo_objective import (
    explained_variance,
    gae,
    gaussian_entropy,
    gaussian_log_prob,
    ppo_loss,
)
from socialnav.train.ppo_worlds import (
    GreedyActor,
    goal_distance,
    ppo_policy_config,
    restore_worlds,
    step_worlds,
    world_snapshot,
)
from socialnav.train.rl import EpisodeStats, TrainingDiverged, validate

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
class PPOResult:
    out_dir: Path
    best_checkpoint: Path
    last_checkpoint: Path
    curves: Path
    updates: int
    env_steps: int
    episodes: int
    best_val: dict[str, Any] | None
    wall_time: float  # [s] across resumptions
    resumed: bool
    finished: bool  # False when stopped early by ``stop_after``
    collect_time: float  # [s] in this call: stepping the worlds and acting
    update_time: float  # [s] in this call: GAE and the gradient steps


def network_kwargs(s: PPOSettings, n_humans: int) -> dict[str, Any]:
    """The constructor arguments of the policy's network: ``network`` for crowdnav_pp; for ppo_mlp the
    shared prediction steps and initial σ, ``mlp_hidden``, and the training mix's number of humans."""
    if s.policy == "ppo_mlp":
        n = s.network
        return dict(
            prediction_steps=n.prediction_steps,
            max_humans=n_humans,
            hidden=s.mlp_hidden,
            normalize_obs=s.normalize_obs,
            log_std_init=n.log_std_init,
        )
    return dict(normalize_obs=s.normalize_obs, **dataclasses.asdict(s.network))


def train_ppo(
    preset: Preset | str,
    out_dir: str | Path,
    settings: PPOSettings | None = None,
    *,
    progress: bool = True,
    stop_after: int | None = None,
    log=None,
) -> PPOResult:
    """PPO under ``preset``'s training mix; resumes from ``out_dir/last.pt`` if present.

    ``stop_after``: stop after this many updates in THIS call, as if killed after the checkpoint of
    that update (for tests of resumption; the checkpoint is written there).

    Raises:
        ConfigError: resuming with settings that differ from the run's (the keys are named).
        TrainingDiverged: the loss became NaN/inf (last.pt keeps the last good state).
    """
    with contextlib.ExitStack() as stack:
        return _train(preset, out_dir, settings or PPOSettings(), stack, progress, stop_after, log)


def _train(preset, out_dir, s: PPOSettings, stack, progress, stop_after, log) -> PPOResult:
    from socialnav.policies.learned import build, load_checkpoint, save_checkpoint
    from socialnav.policies.learned.attn_graph import ROBOT_FEATURES, observation_tensors, squash_actions
    from socialnav.policies.learned.ppo_policy import RecurrentActorPolicy
    from socialnav.policies.learned_catalog import learned_policy_names
    from socialnav.train.trainer import resolve_device

    if s.policy not in (ppo := learned_policy_names("ppo")):
        raise ConfigError(f"policy: {s.policy!r} is not trained with PPO (PPO policies: {', '.join(ppo)})")
    t_call = time.perf_counter()
    say = log or (lambda line: print(line, file=sys.stderr, flush=True))
    preset = load_preset(preset) if not isinstance(preset, Preset) else preset
    device = resolve_device(s.device)
    torch.set_num_threads(s.threads or max(1, min(os.cpu_count() or 1, 8)))
    seeds = derive_seeds(s.seed)
    dt, kinematics, rotation_limit = preset.world.dt, preset.world.kinematics, preset.world.rotation_limit
    # the rollout's human slots: scenarios that fix their own crowd (francis2023) may exceed the preset's
    crowd = int(preset.training.n_humans)
    n_humans = mix_human_slots(preset, crowd)
    config = json.loads(
        json.dumps(
            {
                "ppo_policy": ppo_policy_config(preset),
                "policy": s.policy,
                "preset": preset.to_dict(),
                "train": s.to_dict(),
                "seeds": seeds,
                "n_humans": n_humans,
                "ppo_stream_offset": PPO_STREAM_OFFSET,
                "kinematics": kinematics,
            },
            default=lambda v: list(v) if isinstance(v, tuple) else str(v),
        )
    )
    out = Path(out_dir)
    last_path, best_path, curves_path = out / "last.pt", out / "best.pt", out / "curves.csv"

    # -- network, optimizer, generators ---------------------------------------------------------
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seeds["init"])
        net = build(s.policy, **network_kwargs(s, n_humans))
    net.to(device)
    steps_ahead = net.prediction_steps
    optimizer = torch.optim.Adam(net.parameters(), lr=s.lr, eps=s.adam_eps)
    action_gen = torch.Generator().manual_seed(seeds["exploration"])
    minibatch_gen = torch.Generator().manual_seed(seeds["sampling"])

    # -- worlds (refused settings stop here, before anything is written) --------------------------
    val_world = MultiWorld(preset, crowd, min(s.n_envs, s.val_episodes), "val", 0, s.val_episodes)
    stack.callback(val_world.close)
    world = MultiWorld(preset, crowd, s.n_envs, "train", seeds["scenario_start"] + PPO_STREAM_OFFSET)
    stack.callback(world.close)
    n_envs, T = world.batch_size, s.rollout_steps
    n_updates = math.ceil(s.total_env_steps / (n_envs * T))
    if s.minibatches > n_envs:
        raise ConfigError(f"minibatches {s.minibatches} must be <= the number of environments ({n_envs})")
    make_output_dir(out)
    stack.enter_context(DirectoryLock(out, "training"))
    remove_orphan_temporaries(out)

    resume: dict[str, Any] | None = None
    if last_path.exists():
        ck = load_checkpoint(last_path, s.policy, expected_input_dim=-1, map_location=device)
        resume = ck.extra.get("resume")
        if not isinstance(resume, dict):
            raise ConfigError(f"{last_path} is not a PPO training state (no 'resume' record); move it away")
        diff = [
            k
            for k in flat_diff(ck.config, config)
            if not any(k == f"train.{r}" for r in PPO_RESUMABLE_CHANGES)
        ]
        if diff:
            raise ConfigError(
                f"{out} holds a run with other settings ({', '.join(diff[:6])}); use another --out"
            )
        net.load_state_dict(ck.model.state_dict())
        load_optimizer_state(optimizer, resume["optimizer"])
        action_gen.set_state(resume["action_rng"])
        minibatch_gen.set_state(resume["minibatch_rng"])
        restore_worlds(world, resume["worlds"])
        say(f"resuming {out} at update {resume['update']} ({resume['env_steps']} env steps)")
    else:
        world.reset()
    atomic_write_json(out / "config.json", config)
    import yaml

    atomic_write_text(out / "config.yaml", yaml.safe_dump(config, sort_keys=False))
    curves = Curves(
        curves_path,
        None if resume is None else int(resume["update"]),
        columns=PPO_CURVE_COLUMNS,
        key="update",
    )
    stack.callback(curves.close)
    state = {"update": 0, "env_steps": 0, "episodes": 0, "wall_time": 0.0, "best_val": None, "last_val": None}
    if resume is not None:
        state.update({k: resume[k] for k in state})
    h = resume["h"].to(device) if resume is not None else net.initial_state(n_envs, device)
    start = (
        resume["start"].to(device)
        if resume is not None
        else torch.ones(n_envs, dtype=torch.bool, device=device)
    )
    elapsed0 = float(state["wall_time"])

    def wall() -> float:
        return elapsed0 + time.perf_counter() - t_call

    def save(path: Path, extra: dict[str, Any]) -> None:
        save_checkpoint(path, s.policy, net, config=config, extra=extra)

    def save_last() -> None:
        save(
            last_path,
            {
                "phase": "ppo",
                "resume": {
                    **state,
                    "wall_time": wall(),
                    "optimizer": optimizer_state(optimizer),
                    "action_rng": action_gen.get_state(),
                    "minibatch_rng": minibatch_gen.get_state(),
                    "worlds": world_snapshot(world),
                    "h": h.detach().cpu().clone(),
                    "start": start.cpu().clone(),
                    "window": {
                        "stats": dataclasses.asdict(stats),
                        "returns_sum": returns_sum,
                        "returns_n": returns_n,
                        "losses": dict(window),
                        "episode_return": torch.from_numpy(episode_return.copy()),
                    },
                },
            },
        )

    actor = RecurrentActorPolicy(
        s.policy, net, kinematics=kinematics, rotation_limit=rotation_limit, dt=dt, device=device
    )
    success_reward = preset.world.reward.success_reward
    obs = world.observe()
    # The curves' window (training outcomes, returns, losses since the last row) is saved with last.pt
    # too, so that a resumed run writes the rows an uninterrupted one would.
    stats, returns_sum, returns_n = EpisodeStats(), 0.0, 0
    episode_return = np.zeros(n_envs)  # undiscounted, of the episodes in flight
    window: dict[str, float] = {}
    if resume is not None:
        saved = resume["window"]
        stats = EpisodeStats(**saved["stats"])
        returns_sum, returns_n, window = (
            float(saved["returns_sum"]),
            int(saved["returns_n"]),
            dict(saved["losses"]),
        )
        episode_return = saved["episode_return"].numpy().copy()
    if resume is None and s.normalize_obs:  # statistics of the first observation for the first rollout
        net.update_obs_stats(*observation_tensors(obs, dt, steps_ahead, device))
    collect_time = update_time = 0.0
    updates_this_call = 0
    bar = progress_bar(n_updates, int(state["update"]), f"{s.policy} PPO", progress)
    stack.callback(bar.close)
    finished = True
    while state["update"] < n_updates:
        frac = 1.0 - state["update"] / n_updates
        lr_now = s.lr * frac if s.anneal_lr else s.lr
        for group in optimizer.param_groups:
            group["lr"] = lr_now
        # -- rollout: T lockstep steps of every environment ----------------------------------------
        t0 = time.perf_counter()
        net.eval()
        h0, starts = h.clone(), torch.zeros(T, n_envs, dtype=torch.bool, device=device)
        robots = torch.zeros(T, n_envs, ROBOT_FEATURES, device=device)
        humans = torch.zeros(T, n_envs, n_humans, net.input_dim, device=device)
        masks = torch.zeros(T, n_envs, n_humans, dtype=torch.bool, device=device)
        raws, logps, values = (
            torch.zeros(T, n_envs, 2, device=device),
            torch.zeros(T, n_envs, device=device),
            torch.zeros(T, n_envs, device=device),
        )
        rewards, dones = (
            torch.zeros(T, n_envs, device=device),
            torch.zeros(T, n_envs, dtype=torch.bool, device=device),
        )
        with torch.no_grad():
            for t in range(T):
                rf, hf, mk = observation_tensors(obs, dt, steps_ahead, device)
                robots[t], humans[t], masks[t], starts[t] = rf, hf, mk, start
                mean, value, h = net.step(rf, hf, mk, h, start)
                raw = mean + torch.randn(mean.shape, generator=action_gen).to(device) * net.log_std.exp()
                raws[t], values[t] = raw, value
                logps[t] = gaussian_log_prob(raw, mean, net.log_std)
                action = squash_actions(
                    raw.double().cpu().numpy(), kinematics, obs.robot[:, 7], rotation_limit
                )
                goal_before = goal_distance(obs.robot)
                reward, term, trunc, final, obs = step_worlds(world, action)
                done = term | trunc
                # CrowdNav++'s potential term: goal_shaping x (metres gained towards the goal this step)
                shaped = reward + s.goal_shaping * (goal_before - goal_distance(final.robot))
                r = torch.as_tensor(shaped, dtype=torch.float32, device=device)
                if s.bootstrap_timeouts and trunc.any():
                    rows = np.flatnonzero(trunc)
                    frf, fhf, fmk = observation_tensors(final.take(rows), dt, steps_ahead, device)
                    _, v_final, _ = net.step(
                        frf, fhf, fmk, h[rows], torch.zeros(len(rows), dtype=torch.bool, device=device)
                    )
                    r[rows] += s.gamma * v_final
                rewards[t], dones[t] = r, torch.as_tensor(done, device=device)
                start = dones[t].clone()
                episode_return += reward
                stats.add(term, trunc, reward, final.time, success_reward)
                returns_sum += float(episode_return[done].sum())
                returns_n += int(done.sum())
                episode_return[done] = 0.0
                state["episodes"] += int(done.sum())
            rf, hf, mk = observation_tensors(obs, dt, steps_ahead, device)
            _, last_value, _ = net.step(rf, hf, mk, h, start)
            advantages, returns = gae(rewards, values, dones, last_value, s.gamma, s.gae_lambda)
        state["env_steps"] += n_envs * T
        t1 = time.perf_counter()
        collect_time += t1 - t0

        # -- update: epochs of minibatches of whole environment sequences -----------------------------
        net.train()
        sums = {
            k: 0.0 for k in ("loss", "policy_loss", "value_loss", "entropy", "approx_kl", "clip_fraction")
        }
        n_steps = 0
        for _ in range(s.epochs):
            order = torch.randperm(n_envs, generator=minibatch_gen)
            for envs in torch.tensor_split(order, s.minibatches):
                envs = envs.to(device)
                mean, value = net.sequence(
                    robots[:, envs], humans[:, envs], masks[:, envs], h0[envs], starts[:, envs]
                )
                loss = ppo_loss(
                    gaussian_log_prob(raws[:, envs], mean, net.log_std),
                    logps[:, envs],
                    advantages[:, envs],
                    value,
                    values[:, envs],
                    returns[:, envs],
                    gaussian_entropy(net.log_std).expand(value.shape),
                    clip=s.clip,
                    value_clip=s.value_clip or None,
                    value_coef=s.value_coef,
                    entropy_coef=s.entropy_coef,
                    normalize_advantages=s.normalize_advantages,
                )
                if not math.isfinite(float(loss.total.detach())):
                    raise TrainingDiverged(
                        f"PPO loss became {float(loss.total.detach())} at update {state['update']}; "
                        f"{last_path} keeps the last good state"
                    )
                optimizer.zero_grad(set_to_none=True)
                loss.total.backward()
                if s.max_grad_norm > 0:
                    torch.nn.utils.clip_grad_norm_(net.parameters(), s.max_grad_norm)
                optimizer.step()
                for k, v in (
                    ("loss", loss.total),
                    ("policy_loss", loss.policy),
                    ("value_loss", loss.value),
                    ("entropy", loss.entropy),
                    ("approx_kl", loss.approx_kl),
                    ("clip_fraction", loss.clip_fraction),
                ):
                    sums[k] += float(v.detach())
                n_steps += 1
        # The observation statistics change only here, after the update: the rollout was collected
        # and is re-evaluated with the same ones, so the first minibatch's probability ratio is 1.
        if s.normalize_obs:
            net.update_obs_stats(robots.flatten(0, 1), humans.flatten(0, 1), masks.flatten(0, 1))
        update_time += time.perf_counter() - t1
        state["update"] += 1
        updates_this_call += 1
        bar.update(1)
        for k, v in sums.items():
            window[k] = window.get(k, 0.0) + v / n_steps
        window["n"] = window.get("n", 0) + 1

        # -- validation, curves, checkpoints -----------------------------------------------------------
        u = int(state["update"])
        val = None
        if u % s.validate_every == 0 or u == n_updates:
            actor.reset()
            net.eval()
            val = validate(GreedyActor(actor), val_world, False, success_reward)
            val["update"] = u
            state["last_val"] = val
            if better(val, state["best_val"]):
                state["best_val"] = val
                save(best_path, {"update": u, "val": val})
            say(
                f"update {u}: validation success {val['success']:.3f} collision {val['collision']:.3f} "
                f"timeout {val['timeout']:.3f} (best {state['best_val']['success']:.3f})"
            )
        if u % s.log_every == 0 or val is not None or u == n_updates:
            rates = stats.rates()
            n = window.pop("n")
            row = {
                "phase": "ppo",
                "update": u,
                "env_steps": state["env_steps"],
                "episodes": state["episodes"],
                **window_columns(rates, stats.total),
                "train_return": returns_sum / returns_n if returns_n else math.nan,
                **{k: v / n for k, v in window.items()},
                "explained_variance": explained_variance(values.flatten(), returns.flatten()),
                "std": float(net.log_std.detach().exp().mean()),
                "lr": lr_now,
                "env_steps_per_s": (n_envs * T * updates_this_call) / max(collect_time + update_time, 1e-9),
                "wall_time": wall(),
            }
            row.update(validation_columns(val))
            curves.write(row)
            bar.set_postfix(succ=f"{rates['success']:.2f}", kl=f"{row['approx_kl']:.3g}")
            stats, returns_sum, returns_n, window = EpisodeStats(), 0.0, 0, {}
        stopping = stop_after is not None and updates_this_call >= stop_after and u < n_updates
        if u % s.checkpoint_every == 0 or u == n_updates or stopping:
            save_last()
        if stopping:
            finished = False
            break
    if finished and not last_path.exists():
        save_last()  # a run with no update at all (total_env_steps 0)
    return PPOResult(
        out,
        best_path,
        last_path,
        curves_path,
        int(state["update"]),
        int(state["env_steps"]),
        int(state["episodes"]),
        state["best_val"],
        wall(),
        resume is not None,
        finished,
        collect_time,
        update_time,
    )


def train_ppo_from_args(args) -> int:
    """``socialnav train --policy crowdnav_pp`` (see train/cli.py)."""
    from socialnav.train.ppo_config import load_ppo_settings

    refused = [
        flag
        for flag, key in (
            ("--information", "information"),
            ("--rl-episodes", "rl_episodes"),
            ("--compile", "compile"),
        )
        if getattr(args, key, None) is not None
    ]
    if refused:
        raise ConfigError(
            f"{', '.join(refused)}: not a setting of PPO training (policy {args.policy}); "
            "see docs/ppo.md for its settings"
        )
    settings = load_ppo_settings(
        getattr(args, "config", None) or "ppo",  # the shipped default schedule
        seed=args.seed,
        device=args.device,
        n_envs=getattr(args, "collection_batch", None),
        total_env_steps=getattr(args, "env_steps", None),
        policy=args.policy,
    )
    preset = load_preset(args.preset)
    out = Path(args.out or f"runs/train/{preset.name}-{args.policy}-s{settings.seed}")
    result = train_ppo(preset, out, settings, progress=not getattr(args, "no_progress", False))
    best = result.best_val or {}
    print(
        json.dumps(
            {
                "out": str(result.out_dir),
                "best_checkpoint": str(result.best_checkpoint),
                "updates": result.updates,
                "env_steps": result.env_steps,
                "episodes": result.episodes,
                "best_val": {
                    k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in best.items()
                },
                "wall_time_s": round(result.wall_time, 1),
                "resumed": result.resumed,
            }
        )
    )
    return 0

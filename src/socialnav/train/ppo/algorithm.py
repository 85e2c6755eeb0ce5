"""PPO (``socialnav train --policy crowdnav_pp`` or ``ppo_mlp``), read top to bottom like a CleanRL script.

Huang et al., "CleanRL", JMLR 2022. :func:`train_ppo` is the loop: setup (settings, seeds, the network
and the worlds: ppo/run.py), resume or start (ppo/state.py), then per update the learning rate
(:func:`set_learning_rate`), a rollout collected from every environment in lockstep, one native call
per world of the training mix per step (:func:`collect_rollout`), GAE (:func:`gae`), epochs of
clipped-objective minibatch steps over whole environment sequences (:func:`ppo_update`,
:func:`ppo_loss`), validation and curves (ppo/validation.py) and the checkpoint. With
``imitation_updates`` the first updates imitate a planner instead (ppo/imitation.py). The network is in
policies/learned/attn_graph.py (or ppo_mlp.py), the settings in ppo/settings.py; docs/ppo.md explains
the choices.

References: J. Schulman, P. Moritz, S. Levine, M. Jordan, P. Abbeel, "High-Dimensional Continuous Control
Using Generalized Advantage Estimation", ICLR 2016 (GAE); J. Schulman, F. Wolski, P. Dhariwal, A. Radford,
O. Klimov, "Proximal Policy Optimization Algorithms", arXiv 1707.06347, 2017 (clipped surrogate, value
clipping as in its reference implementation).

Run directory (as every trainer's, train/run_directory.py)::

    config.yaml / config.json   the run's record (trainer, policy, preset, PPO settings, derived seeds)
    best.pt                     best validation success so far (ties: fewer collisions, then faster)
    last.pt                     network + optimizer + generators + counters + the worlds' state and
                                the GRU states of the episodes in flight: re-running the same command
                                resumes exactly where it stopped (bit-identical on CPU)
    curves.csv                  one row per ``log_every`` updates
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from socialnav._progress import progress_bar
from socialnav.presets import Preset
from socialnav.sim.settings import HEADED_KINEMATICS
from socialnav.train.episodes import collisions
from socialnav.train.optim import TrainingDiverged
from socialnav.train.ppo.imitation import imitation_actions, imitation_loss, teacher_share
from socialnav.train.ppo.loss import gaussian_entropy, gaussian_log_prob, ppo_loss
from socialnav.train.ppo.run import PPO_CURVE_COLUMNS, PPO_STREAM_OFFSET, PPORun, setup_ppo_run
from socialnav.train.ppo.settings import PPOSettings
from socialnav.train.ppo.state import PPOState, initial_state, save_last
from socialnav.train.ppo.validation import validate_if_due, write_row_if_due
from socialnav.train.ppo.worlds import goal_distance, route_distance, step_worlds

__all__ = ["PPOResult", "train_ppo", "train_ppo_policy", "PPO_CURVE_COLUMNS", "PPO_STREAM_OFFSET"]

#: The losses and diagnostics averaged over an update's minibatch steps (curves columns).
LOSS_TERMS = ("loss", "policy_loss", "value_loss", "entropy", "approx_kl", "clip_fraction")


@dataclass(frozen=True)
class PPOResult:
    """What a PPO training call produced.

    Attributes:
        out_dir: the run directory.
        best_checkpoint: best.pt.
        last_checkpoint: last.pt.
        curves: curves.csv.
        updates: updates done in all (across resumptions).
        env_steps: environment steps in all.
        episodes: training episodes ended in all.
        best_val: the best validation (with its ``update``), or None.
        wall_time: [s] across resumptions.
        resumed: this call continued a run.
        finished: False when stopped early by ``stop_after``.
        collect_time: [s] in this call: stepping the worlds and acting.
        update_time: [s] in this call: GAE and the gradient steps.
    """

    out_dir: Path
    best_checkpoint: Path
    last_checkpoint: Path
    curves: Path
    updates: int
    env_steps: int
    episodes: int
    best_val: dict[str, Any] | None
    wall_time: float
    resumed: bool
    finished: bool
    collect_time: float
    update_time: float


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

    Args:
        preset: a Preset or a preset name/path (world semantics, robot, training scenario mix).
        out_dir: run directory (created; resumed when it holds last.pt).
        settings: PPO settings (default: ``PPOSettings()``, crowdnav_pp).
        progress: tqdm progress bar on stderr.
        stop_after: stop after this many updates in THIS call, as if killed after the checkpoint of
            that update (for tests of resumption; the checkpoint is written there).
        log: callable taking a line of text (default: print to stderr).

    Returns:
        The run's files, counters and timings.

    Raises:
        ConfigError: resuming with settings that differ from the run's (the keys are named).
        TrainingDiverged: the loss became NaN/inf (last.pt keeps the last good state).
    """
    from socialnav.policies.learned.ppo_policy import RecurrentActorPolicy

    with contextlib.ExitStack() as stack:  # closes the worlds and releases the run directory's lock
        run = setup_ppo_run(preset, out_dir, settings or PPOSettings(), stack, progress=progress, log=log)
        w = run.preset.world
        actor = RecurrentActorPolicy(
            run.settings.policy, run.net, kinematics=w.kinematics, rotation_limit=w.rotation_limit, dt=w.dt,
            device=run.device, obstacle_encoding=run.obstacle_encoding, diff_drive=w.diff_drive.to_dict(),
        )
        state = initial_state(run)
        if run.resumed is not None and state.update > run.n_updates:
            run.say(f"note: {run.out} already holds {state.update} updates ({state.env_steps} env steps), "
                    f"more than this budget's {run.n_updates}: nothing to train (the run is not shortened)")
        bar = progress_bar(run.n_updates, state.update, desc=f"{run.settings.policy} PPO", enabled=progress)
        stack.callback(bar.close)
        finished = True
        while state.update < run.n_updates:
            lr = set_learning_rate(run, state)
            rollout = collect_rollout(run, state)
            ppo_update(run, state, rollout)
            bar.update(1)
            val = validate_if_due(run, state, actor)
            write_row_if_due(run, state, rollout, val, lr, bar)
            u = state.update
            stopping = stop_after is not None and state.updates_this_call >= stop_after and u < run.n_updates
            if u % run.settings.checkpoint_every == 0 or u == run.n_updates or stopping:
                save_last(run, state)
            if stopping:
                finished = False
                break
        if finished and not run.last_path.exists():
            save_last(run, state)  # a run with no update at all (total_env_steps 0)
        return PPOResult(
            run.out,
            run.best_path,
            run.last_path,
            run.out / "curves.csv",
            int(state.update),
            int(state.env_steps),
            int(state.episodes),
            state.best_val,
            state.wall(run),
            run.resumed is not None,
            finished,
            state.collect_time,
            state.update_time,
        )


def train_ppo_policy(policy: str, preset: Preset | str, out_dir: str | Path,
                     settings: PPOSettings | None = None, **kwargs: Any) -> PPOResult:
    """:func:`train_ppo` of ``policy`` (set as the settings' ``policy``): the ``ppo`` trainer's ``train``.

    Args:
        policy: a PPO policy.
        preset: a Preset or a preset name/path.
        out_dir: run directory.
        settings: PPO settings (default: ``PPOSettings()``).
        **kwargs: ``progress``, ``stop_after``, ``log``.

    Returns:
        The result.
    """
    return train_ppo(preset, out_dir, dataclasses.replace(settings or PPOSettings(), policy=policy), **kwargs)


def set_learning_rate(run: PPORun, state: PPOState) -> float:
    """Sets the coming update's learning rate (linearly annealed to 0 with ``anneal_lr``).

    An imitation update with ``imitation_lr`` set uses that rate instead, annealed to 0 over the
    imitation updates.

    Args:
        run: the run.
        state: its state (``update``: the updates done).

    Returns:
        The learning rate.
    """
    s = run.settings
    if state.update < s.imitation_updates and s.imitation_lr is not None:
        # the imitation's own rate, decayed over the imitation updates; PPO's schedule takes over after
        frac = 1.0 - state.update / s.imitation_updates
        lr_now = s.imitation_lr * frac if s.anneal_lr else s.imitation_lr
    else:
        frac = 1.0 - state.update / run.n_updates
        lr_now = s.lr * frac if s.anneal_lr else s.lr
    for group in run.optimizer.param_groups:
        group["lr"] = lr_now
    return lr_now


@dataclass(frozen=True)
class Rollout:
    """One update's experience, time-major: T steps × n_envs environments.

    Attributes:
        h0: the GRU state of each environment before the rollout (the update replays from it).
        starts: (T, n_envs) bool, an episode starts at this step (the GRU state is reset).
        robots: (T, n_envs, ROBOT_FEATURES) robot features.
        humans: (T, n_envs, n_slots, input_dim) human features, then the obstacle points' (if any).
        masks: (T, n_envs, n_slots) bool, real humans and points.
        raws: (T, n_envs, 2) the Gaussian samples (before squashing).
        logps: (T, n_envs) their log-probabilities under the collecting policy.
        values: (T, n_envs) the critic's values.
        rewards: (T, n_envs) rewards, shaped and (timeouts) bootstrapped.
        dones: (T, n_envs) bool, the episode ended at this step.
        advantages: (T, n_envs) GAE advantages.
        returns: (T, n_envs) advantages + values.
        imitation: the rollout of an imitation update: ``raws`` hold the teacher's actions, the labels.
    """

    h0: torch.Tensor
    starts: torch.Tensor
    robots: torch.Tensor
    humans: torch.Tensor
    masks: torch.Tensor
    raws: torch.Tensor
    logps: torch.Tensor
    values: torch.Tensor
    rewards: torch.Tensor
    dones: torch.Tensor
    advantages: torch.Tensor
    returns: torch.Tensor
    imitation: bool = False


def collect_rollout(run: PPORun, state: PPOState) -> Rollout:
    """Steps every environment ``rollout_steps`` times with the stochastic policy, then computes GAE.

    Rewards get CrowdNav++'s potential term (``goal_shaping`` × metres gained towards the goal; along
    its route around the walls for a network with ``route_goal``), on a unicycle or differential drive
    its rotational penalty (``turn_penalty`` × dθ²), with ``collision_penalty`` set that reward on a
    collision in place of the preset's (moved towards it linearly over the updates between
    ``collision_penalty_ramp_start`` and ``_end``), and,
    with ``bootstrap_timeouts``, γ·V(final state) on a timeout.

    Args:
        run: the run.
        state: its state (GRU states, observation, episodes in flight and the curves' window
            advance; ``env_steps`` and ``collect_time`` too).

    Returns:
        The rollout.
    """
    from socialnav.policies.learned.attn_graph import squash_actions
    from socialnav.policies.learned.ppo_inputs import network_inputs, robot_width

    s, net, device, n_envs, n_slots = run.settings, run.net, run.device, run.n_envs, run.n_slots
    walls = run.obstacle_encoding
    dt, kinematics = run.preset.world.dt, run.preset.world.kinematics
    rotation_limit, success_reward = run.preset.world.rotation_limit, run.preset.world.reward.success_reward
    reverse = run.preset.world.diff_drive.max_reverse_speed if kinematics == "diff_drive" else 0.0
    T = s.rollout_steps
    collision_weight = s.collision_weight(state.update, run.n_updates)  # (1.0 without a ramp)
    beta = teacher_share(state.update, s.imitation_updates)  # the teacher's share of the steps (DAgger)
    # a network heading along its route gains the metres it walks along the route
    distance = route_distance if getattr(net, "route_goal", False) else (lambda o: goal_distance(o.robot))
    t0 = time.perf_counter()
    net.eval()
    h0, starts = state.h.clone(), torch.zeros(T, n_envs, dtype=torch.bool, device=device)
    robots = torch.zeros(T, n_envs, robot_width(net), device=device)
    humans = torch.zeros(T, n_envs, n_slots, net.input_dim, device=device)
    masks = torch.zeros(T, n_envs, n_slots, dtype=torch.bool, device=device)
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
            obs = state.obs
            rf, hf, mk = network_inputs(net, obs, dt, device, walls)
            robots[t], humans[t], masks[t], starts[t] = rf, hf, mk, state.start
            mean, value, state.h = net.step(rf, hf, mk, state.h, state.start)
            if beta > 0:  # an imitation update: raw is the teacher's action, the network's label
                raw, action = imitation_actions(run.teacher, obs, mean, beta, run.action_gen, kinematics,
                                                rotation_limit, reverse)
            else:
                raw = mean + torch.randn(mean.shape, generator=run.action_gen).to(device) * net.log_std.exp()
                action = squash_actions(raw.double().cpu().numpy(), kinematics, obs.robot[:, 7],
                                        rotation_limit, reverse)
            raws[t], values[t] = raw, value
            logps[t] = gaussian_log_prob(raw, mean, net.log_std)
            goal_before = distance(obs)
            reward, term, trunc, final, state.obs = step_worlds(run.world, action)
            done = term | trunc
            # CrowdNav++'s potential term: goal_shaping x (metres gained towards the goal this step)
            shaped = reward + s.goal_shaping * (goal_before - distance(final))
            if s.collision_penalty is not None:
                collided = collisions(term, reward, success_reward)
                shaped[collided] += collision_weight * (s.collision_penalty - reward[collided])
            if s.turn_penalty and kinematics in HEADED_KINEMATICS:
                # CrowdNav++'s rotational penalty on a unicycle, on the heading change commanded: without
                # it the network can learn to weave between its turn limits (docs/kinematics.md)
                shaped = shaped - s.turn_penalty * action[:, 1] ** 2
            r = torch.as_tensor(shaped, dtype=torch.float32, device=device)
            if s.bootstrap_timeouts and trunc.any():
                rows = np.flatnonzero(trunc)
                frf, fhf, fmk = network_inputs(net, final.take(rows), dt, device, walls)
                _, v_final, _ = net.step(
                    frf, fhf, fmk, state.h[rows], torch.zeros(len(rows), dtype=torch.bool, device=device)
                )
                r[rows] += s.gamma * v_final
            rewards[t], dones[t] = r, torch.as_tensor(done, device=device)
            state.start = dones[t].clone()
            state.episode_return += reward
            state.stats.add(term, trunc, reward, final.time, success_reward)
            state.returns_sum += float(state.episode_return[done].sum())
            state.returns_n += int(done.sum())
            state.episode_return[done] = 0.0
            state.episodes += int(done.sum())
        rf, hf, mk = network_inputs(net, state.obs, dt, device, walls)
        _, last_value, _ = net.step(rf, hf, mk, state.h, state.start)
        advantages, returns = gae(rewards, values, dones, last_value, s.gamma, s.gae_lambda)
    state.env_steps += n_envs * T
    state.collect_time += time.perf_counter() - t0
    return Rollout(
        h0=h0,
        starts=starts,
        robots=robots,
        humans=humans,
        masks=masks,
        raws=raws,
        logps=logps,
        values=values,
        rewards=rewards,
        dones=dones,
        advantages=advantages,
        returns=returns,
        imitation=beta > 0,
    )


def gae(
    rewards: torch.Tensor,
    values: torch.Tensor,
    dones: torch.Tensor,
    last_value: torch.Tensor,
    gamma: float,
    lam: float,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Advantages and returns of a (T, B) rollout.

    ``dones[t]`` is True where the episode ended with step t (its next state is not bootstrapped:
    a timeout's bootstrap value is added to its reward by the caller); ``last_value`` (B,) is the
    value of the state after the last step.

        δ_t = r_t + γ V_{t+1} (1 − d_t) − V_t,   A_t = δ_t + γ λ (1 − d_t) A_{t+1},   R_t = A_t + V_t
    """
    t_len = rewards.shape[0]
    adv = torch.zeros_like(rewards)
    running = torch.zeros_like(last_value)
    for t in reversed(range(t_len)):
        next_value = last_value if t == t_len - 1 else values[t + 1]
        keep = 1.0 - dones[t].to(rewards.dtype)
        delta = rewards[t] + gamma * next_value * keep - values[t]
        running = delta + gamma * lam * keep * running
        adv[t] = running
    return adv, adv + values


def ppo_update(run: PPORun, state: PPOState, rollout: Rollout) -> None:
    """``epochs`` passes over the rollout in ``minibatches`` random sets of environments each.

    An imitation rollout's passes (``imitation_epochs`` of ``imitation_minibatches``, where set) minimise
    :func:`~socialnav.train.ppo.imitation.imitation_loss` instead of PPO's.

    The observation statistics change only after the update: the rollout was collected and is
    re-evaluated with the same ones, so the first minibatch's probability ratio is 1.

    Args:
        run: the run (network and optimizer are stepped).
        state: its state (``update`` advances; the update's mean losses join the curves' window).
        rollout: the update's experience.

    Raises:
        TrainingDiverged: the loss became NaN/inf (last.pt keeps the last good state).
    """
    s, net, optimizer = run.settings, run.net, run.optimizer
    t0 = time.perf_counter()
    net.train()
    sums = dict.fromkeys(LOSS_TERMS, 0.0)
    n_steps = 0
    epochs, minibatches = s.epochs, s.minibatches
    if rollout.imitation:
        epochs, minibatches = s.imitation_epochs or epochs, s.imitation_minibatches or minibatches
    for _ in range(epochs):
        order = torch.randperm(run.n_envs, generator=run.minibatch_gen)
        for envs in torch.tensor_split(order, minibatches):
            envs = envs.to(run.device)
            mean, value = net.sequence(
                rollout.robots[:, envs],
                rollout.humans[:, envs],
                rollout.masks[:, envs],
                rollout.h0[envs],
                rollout.starts[:, envs],
            )
            loss = imitation_loss(
                mean, net.log_std, rollout.raws[:, envs], value, rollout.returns[:, envs], s.value_coef
            ) if rollout.imitation else ppo_loss(
                gaussian_log_prob(rollout.raws[:, envs], mean, net.log_std),
                rollout.logps[:, envs],
                rollout.advantages[:, envs],
                value,
                rollout.values[:, envs],
                rollout.returns[:, envs],
                gaussian_entropy(net.log_std).expand(value.shape),
                clip=s.clip,
                value_clip=s.value_clip or None,
                value_coef=s.value_coef,
                entropy_coef=s.entropy_coef,
                normalize_advantages=s.normalize_advantages,
            )
            total = float(loss.total.detach())
            if not math.isfinite(total):
                raise TrainingDiverged(
                    f"PPO loss became {total} at update {state.update}; "
                    f"{run.last_path} keeps the last good state"
                )
            optimizer.zero_grad(set_to_none=True)
            loss.total.backward()
            if s.max_grad_norm > 0:
                torch.nn.utils.clip_grad_norm_(net.parameters(), s.max_grad_norm)
            optimizer.step()
            terms = (loss.total, loss.policy, loss.value, loss.entropy, loss.approx_kl, loss.clip_fraction)
            for k, term in zip(LOSS_TERMS, terms, strict=True):
                sums[k] += float(term.detach())
            n_steps += 1
    if s.normalize_obs:
        net.update_obs_stats(
            rollout.robots.flatten(0, 1), rollout.humans.flatten(0, 1), rollout.masks.flatten(0, 1)
        )
    state.update_time += time.perf_counter() - t0
    state.update += 1
    state.updates_this_call += 1
    for k, total_k in sums.items():
        state.losses[k] = state.losses.get(k, 0.0) + total_k / n_steps
    state.losses["n"] = state.losses.get("n", 0) + 1

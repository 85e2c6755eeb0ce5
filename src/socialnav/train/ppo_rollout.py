"""The rollout phase of a PPO update: T lockstep steps of every environment, then GAE.

Actions: the Gaussian's sample is the log-probability's argument; the world receives it squashed
(holonomic: scaled onto the v_pref disc; unicycle: clipped), see ``squash_actions``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import torch

from socialnav.train.ppo_objective import gae, gaussian_log_prob
from socialnav.train.ppo_run import PPORun
from socialnav.train.ppo_state import PPOState
from socialnav.train.ppo_worlds import goal_distance, step_worlds


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


def collect_rollout(run: PPORun, state: PPOState) -> Rollout:
    """Steps every environment ``rollout_steps`` times with the stochastic policy, then computes GAE.

    Rewards get CrowdNav++'s potential term (``goal_shaping`` × metres gained towards the goal) and,
    with ``bootstrap_timeouts``, γ·V(final state) on a timeout.

    Args:
        run: the run.
        state: its state (GRU states, observation, episodes in flight and the curves' window
            advance; ``env_steps`` and ``collect_time`` too).

    Returns:
        The rollout.
    """
    from socialnav.policies.learned.attn_graph import ROBOT_FEATURES, observation_tensors, squash_actions

    s, net, device, n_envs, n_slots = run.settings, run.net, run.device, run.n_envs, run.n_slots
    walls = run.obstacle_encoding
    dt, kinematics = run.preset.world.dt, run.preset.world.kinematics
    rotation_limit, success_reward = run.preset.world.rotation_limit, run.preset.world.reward.success_reward
    T, steps_ahead = s.rollout_steps, net.prediction_steps
    t0 = time.perf_counter()
    net.eval()
    h0, starts = state.h.clone(), torch.zeros(T, n_envs, dtype=torch.bool, device=device)
    robots = torch.zeros(T, n_envs, ROBOT_FEATURES, device=device)
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
            rf, hf, mk = observation_tensors(obs, dt, steps_ahead, device, walls)
            robots[t], humans[t], masks[t], starts[t] = rf, hf, mk, state.start
            mean, value, state.h = net.step(rf, hf, mk, state.h, state.start)
            raw = mean + torch.randn(mean.shape, generator=run.action_gen).to(device) * net.log_std.exp()
            raws[t], values[t] = raw, value
            logps[t] = gaussian_log_prob(raw, mean, net.log_std)
            action = squash_actions(raw.double().cpu().numpy(), kinematics, obs.robot[:, 7], rotation_limit)
            goal_before = goal_distance(obs.robot)
            reward, term, trunc, final, state.obs = step_worlds(run.world, action)
            done = term | trunc
            # CrowdNav++'s potential term: goal_shaping x (metres gained towards the goal this step)
            shaped = reward + s.goal_shaping * (goal_before - goal_distance(final.robot))
            r = torch.as_tensor(shaped, dtype=torch.float32, device=device)
            if s.bootstrap_timeouts and trunc.any():
                rows = np.flatnonzero(trunc)
                frf, fhf, fmk = observation_tensors(final.take(rows), dt, steps_ahead, device, walls)
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
        rf, hf, mk = observation_tensors(state.obs, dt, steps_ahead, device, walls)
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
    )

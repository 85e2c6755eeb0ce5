"""The update phase of PPO: epochs of clipped-objective minibatch steps.

Minibatches are sets of whole environment sequences: the GRU replays each sequence from its stored
initial state.

The objective is in train/ppo_objective.py (Schulman et al., "Proximal Policy Optimization
Algorithms", 2017); docs/ppo.md explains the choices.
"""

from __future__ import annotations

import math
import time

import torch

from socialnav.train.ppo_objective import gaussian_entropy, gaussian_log_prob, ppo_loss
from socialnav.train.ppo_rollout import Rollout
from socialnav.train.ppo_run import PPORun
from socialnav.train.ppo_state import PPOState
from socialnav.train.rl import TrainingDiverged

#: The losses and diagnostics averaged over an update's minibatch steps (curves columns).
LOSS_TERMS = ("loss", "policy_loss", "value_loss", "entropy", "approx_kl", "clip_fraction")


def set_learning_rate(run: PPORun, state: PPOState) -> float:
    """Sets the coming update's learning rate (linearly annealed to 0 with ``anneal_lr``).

    Args:
        run: the run.
        state: its state (``update``: the updates done).

    Returns:
        The learning rate.
    """
    s = run.settings
    frac = 1.0 - state.update / run.n_updates
    lr_now = s.lr * frac if s.anneal_lr else s.lr
    for group in run.optimizer.param_groups:
        group["lr"] = lr_now
    return lr_now


def ppo_update(run: PPORun, state: PPOState, rollout: Rollout) -> None:
    """``epochs`` passes over the rollout in ``minibatches`` random sets of environments each.

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
    for _ in range(s.epochs):
        order = torch.randperm(run.n_envs, generator=run.minibatch_gen)
        for envs in torch.tensor_split(order, s.minibatches):
            envs = envs.to(run.device)
            mean, value = net.sequence(
                rollout.robots[:, envs],
                rollout.humans[:, envs],
                rollout.masks[:, envs],
                rollout.h0[envs],
                rollout.starts[:, envs],
            )
            loss = ppo_loss(
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

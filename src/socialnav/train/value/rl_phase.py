"""The RL phase of a value-based training run (CrowdNav/RGL schedule).

Lockstep ε-greedy collection into the replay memory, gradient steps at the replay ratio,
target-network updates, validations, curves rows and ``last.pt`` checkpoints, each due at its own
episode counts (:class:`TrainState`).
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from socialnav._progress import progress_bar
from socialnav.train.curves import validation_columns, window_columns
from socialnav.train.episodes import better, validate
from socialnav.train.optim import AdamSteps, TrainingDiverged
from socialnav.train.value.fused_step import FusedTDStep
from socialnav.train.value.memory import ReplayMemory
from socialnav.train.value.rl import (
    RGLRepoEpisodes,
    encoded_step,
    epsilon_at,
    push_step,
    replay_td_loss,
)
from socialnav.train.value.run import RL_STREAM_OFFSET, ValueRun
from socialnav.train.value.state import CurveWindow, TrainState, resume_record
from socialnav.train.worlds import MultiWorld

#: ``on_validation(episode, validation, wall_time) -> stop``.
OnValidation = Callable[[int, dict[str, Any], float], bool]


@dataclass(frozen=True)
class Learner:
    """The RL phase's collection and update machinery.

    Attributes:
        world: the training worlds (stream after the imitation episodes).
        memory: the replay memory (not saved with ``last.pt``).
        loss_at: the TD loss of memory slots (used unless ``fused_step`` is set).
        fused_step: the whole gradient step as one compiled graph (setting ``compile``), or None.
        adam: the RL optimizer's steps without its per-call Python.
        predictor_adam: the same for the state predictor's optimizer, or None.
        rgl_repo_episodes: per-slot episode buffers of the RGL repository's storage rule, or None.
    """

    world: MultiWorld
    memory: ReplayMemory
    loss_at: Callable[[torch.Tensor], torch.Tensor]
    fused_step: FusedTDStep | None
    adam: AdamSteps
    predictor_adam: AdamSteps | None
    rgl_repo_episodes: RGLRepoEpisodes | None


def build_learner(run: ValueRun, state: TrainState, stack: contextlib.ExitStack) -> Learner:
    """Freezes the target network and builds the learner.

    The training worlds restart at the saved stream positions; the replay memory starts empty.

    Args:
        run: the run (networks and optimizers already restored on resumption).
        state: its state.
        stack: closes the training worlds when the call ends.

    Returns:
        The learner.
    """
    settings, rl = run.settings, run.settings.rl
    run.target.eval()
    for p in run.target.parameters():
        p.requires_grad_(False)
    start = run.seeds["scenario_start"] + RL_STREAM_OFFSET
    world = MultiWorld(run.preset, run.n_humans, settings.collection_batch, "train", start)
    stack.callback(world.close)
    world.reset(state.stream_positions)
    encoding = run.policy.obstacle_encoding
    slots = world.n_human_slots + (0 if encoding is None else encoding.count)
    memory = ReplayMemory(rl.capacity, slots, device=run.device)
    fixed_targets = rl.td_targets == "rgl_repo"
    dt = run.preset.world.dt
    # compile: the whole gradient step as one compiled graph where the network traces into one
    # (train/value/fused_step.py), else the loss alone compiled
    fused_step = None
    if settings.compile:
        fused_step, refusal = FusedTDStep.build(
            run.policy, run.target, memory, run.optimizer, rl.gamma, dt, rl.batch_size, fixed_targets
        )
        if fused_step is None:
            run.say(f"compile: {run.policy_name}'s gradient step does not trace into one graph ({refusal}); "
                    "its loss is compiled instead")
    loss_at = replay_td_loss(
        run.policy, run.target, memory, rl.gamma, dt, fixed_targets,
        compiled=settings.compile and fused_step is None,
    )
    return Learner(
        world=world,
        memory=memory,
        loss_at=loss_at,
        fused_step=fused_step,
        # optimizer.step() without its per-call Python, bit-identical (train/optim.py: AdamSteps)
        adam=AdamSteps(run.optimizer),
        predictor_adam=None if run.predictor_optimizer is None else AdamSteps(run.predictor_optimizer),
        rgl_repo_episodes=None
        if rl.td_targets == "recomputed"
        else RGLRepoEpisodes(world.batch_size, fixed=fixed_targets),
    )


def save_last(run: ValueRun, state: TrainState, learner: Learner) -> None:
    """Writes ``last.pt``: the network and the whole training state (see :func:`resume_record`).

    Args:
        run: the run.
        state: its state.
        learner: its learner (the worlds' stream positions are saved).
    """
    record = resume_record(run, state, learner.world.stream_positions())
    run.save(run.last_path, {"phase": "rl", "resume": record})


def collect_step(
    run: ValueRun, state: TrainState, learner: Learner, window: CurveWindow, obs, eps: float
) -> int:
    """One lockstep ε-greedy step of every training episode, its transitions stored.

    Training stops at exactly ``rl.episodes``: when more episodes end in the last lockstep step than
    are still needed (untrained policies often time out together), only the first ones (in slot
    order) count; the others' transitions stay in the memory but are not counted.

    Args:
        run: the run.
        state: its state (``transitions`` and ``episode`` advance).
        learner: the worlds and the memory.
        window: the curves' window (the counted episodes' outcomes are added).
        obs: the encoded observation the policy acts on.
        eps: the exploration rate.

    Returns:
        The episodes counted in this step.
    """
    rl, policy = run.settings.rl, run.policy
    _, actions = policy.act(
        obs, epsilon=eps, generator=run.explore_gen, next_humans=obs.next_humans if run.oracle else None
    )
    res = encoded_step(policy, learner.world.step(np.asarray(actions, dtype=np.float64)))
    if learner.rgl_repo_episodes is not None:
        learner.rgl_repo_episodes.add_step(obs, res)
        learner.rgl_repo_episodes.finish(
            learner.memory, res, policy, run.target, rl.gamma, run.preset.world.dt
        )
    else:
        push_step(learner.memory, obs, res)
    state.transitions += int(obs.active.sum())
    counted = res.terminated | res.truncated
    need = rl.episodes - int(state.episode)
    if int(counted.sum()) > need:
        counted[np.flatnonzero(counted)[need:]] = False
    finished = int(counted.sum())
    window.stats.add(
        res.terminated & counted, res.truncated & counted, res.reward, res.final_time, run.success_reward
    )
    state.episode += finished
    return finished


def _check_loss(run: ValueRun, state: TrainState, value: float, gradient_step: int) -> None:
    if not math.isfinite(value):
        raise TrainingDiverged(
            f"RL loss became {value} at episode {state.episode} (gradient step {gradient_step}); "
            f"training stopped; {run.last_path} and {run.best_path} keep the last good state"
        )


def gradient_steps(
    run: ValueRun, state: TrainState, learner: Learner, window: CurveWindow, finished: int
) -> None:
    """The gradient steps owed for ``finished`` episodes at the replay ratio.

    None before the memory holds a minibatch and the warm-up; the state predictor, if any, takes
    one step on each step's minibatch.

    Args:
        run: the run.
        state: its state (``credit`` and ``gradient_steps`` advance).
        learner: the memory, the loss and the optimizer steps.
        window: the curves' window (losses are added).
        finished: episodes counted in the last collection step.

    Raises:
        TrainingDiverged: a loss became NaN or infinite.
    """
    rl, memory, net, predictor = run.settings.rl, learner.memory, run.net, run.predictor
    if len(memory) < max(rl.batch_size, rl.warmup_transitions):
        return
    state.credit += rl.gradient_steps_per_episode * finished
    n_steps = int(state.credit)
    if not n_steps:
        return
    state.credit -= n_steps
    net.train()
    fused_losses = []  # checked once per burst: no synchronisation per step
    for _ in range(n_steps):
        idx = memory.sample_indices(rl.batch_size, run.sample_gen)
        if learner.fused_step is not None:
            fused_losses.append(learner.fused_step(idx))
        else:
            loss = learner.loss_at(idx)
            lv = float(loss.detach())
            _check_loss(run, state, lv, state.gradient_steps)
            learner.adam.zero_grad()
            loss.backward()
            learner.adam.step()
            window.loss += lv
        if predictor is not None and learner.predictor_adam is not None:
            predictor.train()
            batch = memory.take(idx)
            pl = predictor.loss(
                batch.robot, batch.humans, batch.mask, batch.next_humans, batch.next_mask, run.preset.world.dt
            )
            learner.predictor_adam.zero_grad()
            pl.backward()
            learner.predictor_adam.step()
            predictor.eval()
            window.predictor_loss += float(pl.detach())
        state.gradient_steps += 1
        window.steps += 1
    if fused_losses:
        first = state.gradient_steps - len(fused_losses)
        for j, lv in enumerate(torch.stack(fused_losses).tolist()):
            _check_loss(run, state, lv, first + j)
            window.loss += lv
    net.eval()


def sync_target_if_due(run: ValueRun, state: TrainState) -> None:
    """Copies the network into the target network every ``rl.target_update_every`` episodes."""
    if state.episode >= state.next_target:
        run.target.load_state_dict(run.net.state_dict())
        while state.next_target <= state.episode:
            state.next_target += run.settings.rl.target_update_every


def validate_if_due(run: ValueRun, state: TrainState) -> dict[str, Any] | None:
    """The validation due every ``rl.validate_every`` episodes and at the end; best.pt on a better one.

    Args:
        run: the run.
        state: its state (``last_val``, ``best_val`` and ``next_val`` advance).

    Returns:
        The validation (with its ``episode``), or None when none was due.
    """
    rl, ep = run.settings.rl, state.episode
    if not (ep >= state.next_val or ep >= rl.episodes):
        return None
    val = validate(run.policy, run.val_world, run.oracle, run.success_reward)
    val["episode"] = ep
    state.last_val = val
    while state.next_val <= ep:
        state.next_val += rl.validate_every
    if better(val, state.best_val):
        state.best_val = val
        run.save(run.best_path, {"episode": ep, "val": val})
    run.say(
        f"episode {ep}: validation success {val['success']:.3f} collision {val['collision']:.3f} "
        f"timeout {val['timeout']:.3f} nav_time {val['nav_time']:.2f} "
        f"(best {state.best_val['success']:.3f} at {state.best_val['episode']})"
    )
    return val


def write_row_if_due(
    run: ValueRun, state: TrainState, window: CurveWindow, eps: float, val: dict[str, Any] | None, bar
) -> None:
    """A curves row every ``log_every`` episodes, after a validation and at the end; clears the window.

    Args:
        run: the run.
        state: its state (``next_log`` advances).
        window: the window the row closes.
        eps: the exploration rate of the last step.
        val: the validation just made, if any.
        bar: the progress bar (its postfix shows the row).
    """
    ep = state.episode
    if not (ep >= state.next_log or val is not None or ep >= run.settings.rl.episodes):
        return
    rates = window.stats.rates()
    row = {
        "phase": "rl",
        "episode": ep,
        "epsilon": eps,
        **window_columns(rates, window.stats.total),
        "loss": window.mean_loss(),
        "predictor_loss": window.mean_predictor_loss(run.predictor is not None),
        "gradient_steps": state.gradient_steps,
        "transitions": state.transitions,
        "wall_time": state.wall(run),
    }
    row.update(validation_columns(val))
    run.curves.write(row)
    bar.set_postfix(eps=f"{eps:.2f}", succ=f"{rates['success']:.2f}", loss=f"{row['loss']:.3g}",
                    refresh=False)
    window.clear()
    while state.next_log <= ep:
        state.next_log += run.settings.log_every


def run_rl(
    run: ValueRun,
    state: TrainState,
    learner: Learner,
    *,
    stop_after: int | None,
    on_validation: OnValidation | None,
) -> bool:
    """Steps until ``rl.episodes`` are counted, or a stop: the RL phase's loop.

    Args:
        run: the run.
        state: its state.
        learner: its learner.
        stop_after: stop after this many episodes in this call, without a final checkpoint.
        on_validation: called after every validation; True stops there (``last.pt`` written first).

    Returns:
        Whether training stopped before ``rl.episodes``.

    Raises:
        TrainingDiverged: a loss became NaN or infinite.
    """
    rl, policy = run.settings.rl, run.policy
    window = CurveWindow()
    bar = progress_bar(rl.episodes, int(state.episode), desc=f"{run.policy_name} RL", enabled=run.progress)
    episodes_this_call = 0
    obs = policy.encode(learner.world.observe(oracle=run.oracle))  # obstacle points appended, if any
    run.net.eval()
    try:
        while state.episode < rl.episodes:
            eps = epsilon_at(int(state.episode), rl)
            finished = collect_step(run, state, learner, window, obs, eps)
            episodes_this_call += finished
            bar.update(finished)
            gradient_steps(run, state, learner, window, finished)
            sync_target_if_due(run, state)
            val = validate_if_due(run, state)
            write_row_if_due(run, state, window, eps, val, bar)
            ep = state.episode
            if ep >= state.next_ckpt or ep >= rl.episodes:
                save_last(run, state, learner)
                while state.next_ckpt <= ep:
                    state.next_ckpt += run.settings.checkpoint_every
            if val is not None and on_validation is not None and ep < rl.episodes and on_validation(
                ep, val, state.wall(run)
            ):
                save_last(run, state, learner)
                return True
            if stop_after is not None and episodes_this_call >= stop_after and ep < rl.episodes:
                return True
            obs = policy.encode(learner.world.observe(oracle=run.oracle))
    finally:
        bar.close()
    return False

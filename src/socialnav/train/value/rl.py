"""Value-based RL (CrowdNav/RGL style) with the bookkeeping defects fixed.

- Episodes are collected from the batched world in lockstep with the ε-greedy lookahead policy
  (explicit ``torch.Generator``); every transition (s, r, s', done) is stored, the terminal one
  included.
- TD targets are computed at training time, under ``torch.no_grad()``, from a target network:
  y = r + γ^(dt·v_pref) · V_target(s') · (1 − done); ``done`` is 1 only for success/collision, a
  timeout bootstraps (truncation).
- The ratio of gradient steps to collected episodes is ``rl.gradient_steps_per_episode``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np
import torch

from socialnav.train.optim import compile_loss
from socialnav.train.value.memory import ReplayMemory, Transitions
from socialnav.train.value.settings import RLSettings


def epsilon_at(episode: int, rl: RLSettings) -> float:
    """Linear decay from epsilon_start to epsilon_end over the first epsilon_decay_episodes."""
    if rl.epsilon_decay_episodes <= 0 or episode >= rl.epsilon_decay_episodes:
        return float(rl.epsilon_end)
    frac = episode / rl.epsilon_decay_episodes
    return float(rl.epsilon_start + (rl.epsilon_end - rl.epsilon_start) * frac)


def td_targets(
    reward: torch.Tensor,
    done: torch.Tensor,
    next_value: torch.Tensor,
    gamma: float,
    dt: float,
    v_pref: torch.Tensor,
) -> torch.Tensor:
    """TD targets y = r + γ^(dt·v_pref) · V(s') · (1 − done).

    ``done`` is 1 for terminal steps only: truncations bootstrap.

    Args:
        reward: (M,) rewards.
        done: (M,) bool, terminal.
        next_value: (M,) V(s').
        gamma: discount per second of travel at v_pref.
        dt: time step [s].
        v_pref: (M,) preferred speed [m/s].

    Returns:
        (M,) the targets.
    """
    disc = torch.pow(
        torch.as_tensor(gamma, dtype=reward.dtype, device=reward.device), dt * v_pref.to(reward.dtype)
    )
    return reward + disc * next_value.to(reward.dtype) * (~done).to(reward.dtype)


def state_values(
    policy, network: torch.nn.Module, robot: torch.Tensor, humans: torch.Tensor, mask: torch.Tensor
) -> torch.Tensor:
    """V(s) of raw observed states through the policy's agent-centric transform."""
    return network.value(policy.transform(robot, humans, mask), mask)


def td_loss(
    policy,
    target_net: torch.nn.Module,
    batch: Transitions,
    gamma: float,
    dt: float,
    fixed_targets: bool = False,
) -> torch.Tensor:
    """MSE between V(s) and the TD target.

    The target is computed now with the target network, or, with ``fixed_targets``
    (rl.td_targets: rgl_repo), the one stored with the transition.

    Args:
        policy: the ValuePolicy (agent-centric transform, network).
        target_net: the target network.
        batch: the transitions.
        gamma: discount factor.
        dt: time step [s].
        fixed_targets: use the stored targets.

    Returns:
        The 0-d loss.
    """
    if fixed_targets:
        y = batch.target
    else:
        with torch.no_grad():
            next_v = state_values(policy, target_net, batch.next_robot, batch.next_humans, batch.next_mask)
            y = td_targets(batch.reward, batch.done, next_v, gamma, dt, batch.robot[:, 7])
    v = state_values(policy, policy.network, batch.robot, batch.humans, batch.mask)
    return torch.nn.functional.mse_loss(v, y.to(v.dtype))


def replay_td_loss(
    policy,
    target_net: torch.nn.Module,
    memory: ReplayMemory,
    gamma: float,
    dt: float,
    fixed_targets: bool = False,
    compiled: bool = False,
) -> Callable[[torch.Tensor], torch.Tensor]:
    """``loss(idx)``: :func:`td_loss` of the transitions in memory slots ``idx``.

    ``compiled`` wraps the whole of it, the gather from the memory included, in ``torch.compile``
    (rl ``compile: true``): the agent-centric transforms, the target network's forward pass and the
    online forward pass become one graph, and AOTAutograd compiles the backward pass too. A gradient
    step of these small networks is mostly the Python and dispatch cost of ≈ 1 500 small operators
    (docs/training_speed.md); compiled, most of it goes. The first call compiles (seconds); later
    calls reuse the graph as long as the batch size stays the same (``dynamic=False``: one static
    graph). The
    memory's tensors are preallocated, so a push never invalidates the graph. Policies whose value
    has a data-dependent branch (CADRL's crowd-less rows, LSTM-RL's packed sequences) compile into
    several graphs around it and still train.
    """

    def loss_at(idx: torch.Tensor) -> torch.Tensor:
        return td_loss(policy, target_net, memory.take(idx), gamma, dt, fixed_targets)

    return compile_loss(loss_at, memory.device) if compiled else loss_at


def encoded_step(policy, res):
    """``res`` (a MultiStep) with the policy's obstacle points appended to the states after the step.

    To ``final_humans``/``final_mask``: each episode's own map, also where the slot was refilled.
    """
    if getattr(policy, "obstacle_encoding", None) is None:
        return res
    humans, mask = policy.encode_arrays(res.final_robot, res.final_humans, res.final_mask, res.final_maps)
    return dataclasses.replace(res, final_humans=humans, final_mask=mask)


def push_step(memory: ReplayMemory, obs, res) -> None:
    """Stores the transitions of one lockstep step (every active slot)."""
    a = np.flatnonzero(obs.active)
    if a.size == 0:
        return
    memory.push(
        obs.robot[a],
        obs.humans[a],
        obs.human_mask[a],
        res.reward[a],
        res.final_robot[a],
        res.final_humans[a],
        res.final_mask[a],
        res.terminated[a],
    )


class RGLRepoEpisodes:
    """The RGL repository's storage rule for lockstep collection.

    ``rl.td_targets: rgl_repo`` and ``rgl_repo_final``.

    Its explorer (``crowd_nav/utils/explorer.py``, Chen et al., "Relational Graph Learning for Crowd
    Navigation", IROS 2020) keeps an episode's transitions until it ends, stores nothing of an episode
    that timed out and drops the last transition of the others (its loop runs over ``states[:-1]``, so
    the success or collision reward never enters a target). As first published (``rgl_repo``) it
    stores each remaining transition with the value target r + γ̄·V_target(s') computed at that moment,
    which later gradient steps reuse as is (``fixed``); its final version (``rgl_repo_final``) stores
    the reward and next state and computes r + γ̄·V_target(s') at each gradient step (every stored
    transition is then non-terminal). Here every slot of the lockstep batch keeps its episode's rows
    until the episode ends.
    """

    def __init__(self, n_slots: int, fixed: bool = True) -> None:
        """Empty episode buffers.

        Args:
            n_slots: lockstep slots.
            fixed: store targets computed now (``rgl_repo``), else rewards (``rgl_repo_final``).
        """
        self.rows: list[list[tuple]] = [[] for _ in range(int(n_slots))]
        self.fixed = fixed

    def add_step(self, obs, res) -> None:
        """Keeps the transitions of one lockstep step (every active slot)."""
        for b in np.flatnonzero(obs.active):
            self.rows[b].append(
                (
                    obs.robot[b],
                    obs.humans[b],
                    obs.human_mask[b],
                    res.reward[b],
                    res.final_robot[b],
                    res.final_humans[b],
                    res.final_mask[b],
                )
            )

    def finish(self, memory: ReplayMemory, res, policy, target_net, gamma: float, dt: float) -> int:
        """Stores the episodes that ended in this step by the rule above; returns transitions stored."""
        stored = 0
        for b in np.flatnonzero(res.terminated | res.truncated):
            rows, self.rows[b] = self.rows[b], []
            if res.truncated[b] or len(rows) < 2:
                continue
            robot, humans, mask, reward, next_robot, next_humans, next_mask = (
                torch.as_tensor(np.stack(col)).to(memory.device) for col in zip(*rows[:-1], strict=True)
            )
            dtype = memory.robot.dtype
            y = None
            if self.fixed:
                with torch.no_grad():
                    next_v = state_values(
                        policy, target_net, next_robot.to(dtype), next_humans.to(dtype), next_mask
                    )
                    y = td_targets(
                        reward.to(dtype),
                        torch.zeros(len(reward), dtype=torch.bool, device=memory.device),
                        next_v,
                        gamma,
                        dt,
                        robot[:, 7].to(dtype),
                    )
            memory.push(
                robot,
                humans,
                mask,
                reward,
                next_robot,
                next_humans,
                next_mask,
                torch.zeros(len(reward), dtype=torch.bool),
                target=y,
            )
            stored += len(reward)
        return stored

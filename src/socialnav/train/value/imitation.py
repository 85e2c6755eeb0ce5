"""Imitation learning: ORCA demonstrations, discounted Monte-Carlo value targets, MSE regression.

As CrowdNav: the teacher is ORCA driving the (invisible) robot with a safety space of 0.15 m; each
visited state s_i of an episode that ended in success or collision gets the target

    V(s_i) = Σ_{t ≥ i} γ^((t − i)·dt·v_pref) · r_t

where r_t is the reward of the step taken from s_t. Timed-out episodes are dropped (their return
is truncated), as CrowdNav does.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch

from socialnav.policies.native import NativePolicy
from socialnav.train.optim import AdamSteps, compile_loss
from socialnav.train.worlds import MultiWorld


def mc_returns(rewards: np.ndarray | list[float], gamma: float, dt: float, v_pref: float) -> np.ndarray:
    """Discounted returns of one episode: out[i] = Σ_{t≥i} γ^((t−i)·dt·v_pref) · r_t."""
    r = np.asarray(rewards, dtype=np.float64)
    disc = gamma ** (dt * v_pref)
    out = np.zeros_like(r)
    acc = 0.0
    for t in range(len(r) - 1, -1, -1):
        acc = r[t] + disc * acc
        out[t] = acc
    return out


@dataclass
class Demonstrations:
    """Visited states with their value targets (NumPy)."""

    robot: np.ndarray  # (M, 9)
    humans: np.ndarray  # (M, N, 5)
    mask: np.ndarray  # (M, N)
    value: np.ndarray  # (M,)
    episodes: int  # episodes collected (all outcomes)
    outcomes: dict[str, int]
    next_humans: np.ndarray | None = None  # (M, N, 5) the humans after each step (state predictor)
    next_mask: np.ndarray | None = None  # (M, N)

    def __len__(self) -> int:
        """States M."""
        return len(self.value)


def collect_demonstrations(
    world: MultiWorld,
    teacher: NativePolicy,
    episodes: int,
    gamma: float,
    success_reward: float,
    progress: Callable[[int], None] | None = None,
    policy=None,
) -> Demonstrations:
    """Runs the teacher until ``episodes`` episodes have finished; keeps successes and collisions.

    ``policy``: the value policy being trained; its obstacle encoding (if any) is applied to the
    stored states (the teacher itself sees the raw observation and its obstacles).
    """
    from socialnav.train.value.rl import encoded_step

    obs = world.observe()
    B = world.batch_size
    traj: list[list[tuple[np.ndarray, ...]]] = [[] for _ in range(B)]
    robots, humans, masks, values, next_humans, next_masks = [], [], [], [], [], []
    outcomes = {"success": 0, "collision": 0, "timeout": 0}
    done_count = 0
    while done_count < episodes:
        actions = teacher.act(obs)
        seen = obs if policy is None else policy.encode(obs)
        res = world.step(actions)
        if policy is not None:
            res = encoded_step(policy, res)
        for b in range(B):
            traj[b].append(
                (
                    seen.robot[b],
                    seen.humans[b],
                    seen.human_mask[b],
                    float(res.reward[b]),
                    res.final_humans[b],
                    res.final_mask[b],
                )
            )
        finished = np.flatnonzero(res.terminated | res.truncated)
        for b in finished:
            steps = traj[b]
            traj[b] = []
            if done_count >= episodes:
                continue
            done_count += 1
            if res.truncated[b]:
                outcomes["timeout"] += 1
                continue
            outcomes["success" if math.isclose(res.reward[b], success_reward) else "collision"] += 1
            v_pref = float(steps[0][0][7])
            ret = mc_returns([s[3] for s in steps], gamma, world.dt, v_pref)
            robots.append(np.stack([s[0] for s in steps]))
            humans.append(np.stack([s[1] for s in steps]))
            masks.append(np.stack([s[2] for s in steps]))
            next_humans.append(np.stack([s[4] for s in steps]))
            next_masks.append(np.stack([s[5] for s in steps]))
            values.append(ret)
            if progress is not None:
                progress(1)
        if progress is not None:
            progress(0)
        obs = world.observe()
    encoding = None if policy is None else policy.obstacle_encoding
    n = world.n_human_slots + (0 if encoding is None else encoding.count)
    if not values:
        return Demonstrations(
            np.zeros((0, 9)), np.zeros((0, n, 5)), np.zeros((0, n), bool), np.zeros(0), done_count, outcomes
        )
    return Demonstrations(
        np.concatenate(robots),
        np.concatenate(humans),
        np.concatenate(masks),
        np.concatenate(values),
        done_count,
        outcomes,
        np.concatenate(next_humans),
        np.concatenate(next_masks),
    )


def save_demonstrations(path, demos: Demonstrations, config_json: str) -> None:
    """Writes the demonstrations atomically with the run's config.

    Float32, as the regression uses them; a resumed imitation reuses them instead of collecting
    again.

    Args:
        path: the ``.npz`` file.
        demos: the demonstrations.
        config_json: the run's config as JSON (checked on reuse).
    """
    from socialnav._io import atomic_write

    def write(tmp: str) -> None:
        with open(tmp, "wb") as f:
            np.savez(
                f,
                robot=demos.robot.astype(np.float32),
                humans=demos.humans.astype(np.float32),
                mask=demos.mask.astype(bool),
                value=demos.value.astype(np.float32),
                episodes=np.int64(demos.episodes),
                outcomes=np.array([demos.outcomes[k] for k in OUTCOMES], dtype=np.int64),
                config=np.array(config_json),
            )

    atomic_write(path, write)


def load_demonstrations(path) -> tuple[Demonstrations, str]:
    """The demonstrations and the config JSON they were collected under."""
    with np.load(path, allow_pickle=False) as z:
        demos = Demonstrations(
            z["robot"], z["humans"], z["mask"], z["value"], int(z["episodes"]),
            dict(zip(OUTCOMES, (int(v) for v in z["outcomes"]), strict=True)),
        )
        return demos, str(z["config"])


OUTCOMES = ("success", "collision", "timeout")


def fit_values(
    policy,
    demos: Demonstrations,
    epochs: int,
    batch_size: int,
    generator: torch.Generator,
    optimizer: torch.optim.Optimizer,
    on_epoch: Callable[[int, float], None] | None = None,
    start_epoch: int = 0,
    compiled: bool = False,
) -> list[float]:
    """Supervised regression (MSE) of the policy's network onto the demonstrations' values.

    Epochs ``start_epoch .. epochs-1`` are run; ``on_epoch(epoch, loss)`` is called after each one
    (the trainer saves the network, ``optimizer`` and ``generator`` there, so that an interrupted
    imitation resumes at the next epoch with the same result as an uninterrupted one). ``compiled``
    (training setting ``compile``) compiles the minibatch loss with ``torch.compile``, as the RL
    loss (``train/value/rl.py: replay_td_loss``): one graph per minibatch size (the full one and an
    epoch's last, shorter one).

    Returns:
        Mean loss per epoch run.
    """
    net = policy.network
    dev = policy.device
    if len(demos) == 0 or epochs <= start_epoch:
        return []
    robot = torch.as_tensor(demos.robot, dtype=torch.float32, device=dev)
    humans = torch.as_tensor(demos.humans, dtype=torch.float32, device=dev)
    mask = torch.as_tensor(demos.mask, dtype=torch.bool, device=dev)
    value = torch.as_tensor(demos.value, dtype=torch.float32, device=dev)
    with torch.no_grad():
        joint = policy.transform(robot, humans, mask)  # the transform does not depend on the weights
    net.train()

    def batch_loss(idx: torch.Tensor) -> torch.Tensor:
        return torch.nn.functional.mse_loss(net.value(joint[idx], mask[idx]), value[idx])

    if compiled:
        batch_loss = compile_loss(batch_loss, joint.device)
    try:
        return _epochs(
            len(value),
            range(start_epoch, epochs),
            batch_size,
            generator,
            dev,
            optimizer,
            batch_loss,
            "imitation",
            on_epoch,
        )
    finally:
        net.eval()


def fit_predictor(
    predictor: torch.nn.Module,
    optimizer: torch.optim.Optimizer,
    demos: Demonstrations,
    epochs: int,
    batch_size: int,
    dt: float,
    generator: torch.Generator,
    device: torch.device | str = "cpu",
) -> list[float]:
    """Supervised training (position MSE) of the state predictor on the demonstrations.

    On the demonstrations' human transitions (s → s'), as RGL trains its state predictor during
    imitation learning.

    Args:
        predictor: the state predictor.
        optimizer: its optimizer.
        demos: the demonstrations (with ``next_humans``).
        epochs: passes over them.
        batch_size: minibatch size.
        dt: time step [s].
        generator: the minibatch orders.
        device: where the predictor lives.

    Returns:
        Mean loss per epoch [m²].
    """
    if len(demos) == 0 or epochs == 0 or demos.next_humans is None or demos.next_mask is None:
        return []
    dev = torch.device(device)
    robot = torch.as_tensor(demos.robot, dtype=torch.float32, device=dev)
    humans = torch.as_tensor(demos.humans, dtype=torch.float32, device=dev)
    mask = torch.as_tensor(demos.mask, dtype=torch.bool, device=dev)
    nxt = torch.as_tensor(demos.next_humans, dtype=torch.float32, device=dev)
    nmask = torch.as_tensor(demos.next_mask, dtype=torch.bool, device=dev)
    predictor.train()
    try:
        return _epochs(
            len(robot),
            range(epochs),
            batch_size,
            generator,
            dev,
            optimizer,
            lambda idx: predictor.loss(robot[idx], humans[idx], mask[idx], nxt[idx], nmask[idx], dt),
            "state-predictor",
        )
    finally:
        predictor.eval()


def _epochs(
    m: int,
    epochs: range,
    batch_size: int,
    generator: torch.Generator,
    device: torch.device | str,
    optimizer: torch.optim.Optimizer,
    batch_loss: Callable[[torch.Tensor], torch.Tensor],
    what: str,
    on_epoch: Callable[[int, float], None] | None = None,
) -> list[float]:
    """Minibatch epochs over ``m`` samples in a fresh permutation each (from ``generator``).

    One optimizer step per ``batch_loss(indices)``; returns the mean loss per epoch. A non-finite
    loss raises FloatingPointError naming ``what`` and the epoch.
    """
    losses = []
    adam = AdamSteps(optimizer)  # optimizer.step() without its per-call Python, bit-identical
    for epoch in epochs:
        perm = torch.randperm(m, generator=generator).to(device)
        total, count = 0.0, 0
        for s in range(0, m, batch_size):
            idx = perm[s : s + batch_size]
            loss = batch_loss(idx)
            if not torch.isfinite(loss):
                raise FloatingPointError(f"{what} loss became {loss.item()} in epoch {epoch}")
            adam.zero_grad()
            loss.backward()
            adam.step()
            total += float(loss.detach()) * len(idx)
            count += len(idx)
        losses.append(total / count)
        if on_epoch is not None:
            on_epoch(epoch, losses[-1])
    return losses

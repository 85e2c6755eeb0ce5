"""Replay memory: a preallocated ring buffer of raw transitions (s, r, s', done).

States are stored as the observation arrays (robot (9,), humans (N, 5), mask (N,)), not as network
inputs, so the agent-centric transform (and OM-SARL's occupancy maps) is applied at training time
and the memory does not depend on the network. ``done`` marks TERMINAL transitions only (success or
collision); a timeout is a truncation and is stored with ``done = False`` so that its target
bootstraps from the next state.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from socialnav.sim.observation import HUMAN_DIM, ROBOT_DIM


@dataclass(frozen=True)
class Transitions:
    """A batch of transitions (torch tensors on the memory's device)."""

    robot: torch.Tensor  # (M, 9)
    humans: torch.Tensor  # (M, N, 5)
    mask: torch.Tensor  # (M, N) bool
    reward: torch.Tensor  # (M,)
    next_robot: torch.Tensor  # (M, 9)
    next_humans: torch.Tensor  # (M, N, 5)
    next_mask: torch.Tensor  # (M, N) bool
    done: torch.Tensor  # (M,) bool, terminal (success/collision) only
    target: torch.Tensor | None = (
        None  # (M,) value target fixed when stored (rl.td_targets: rgl_repo), else NaN
    )


class ReplayMemory:
    """Fixed-capacity ring buffer; the oldest transitions are overwritten first.

    Args:
        capacity: maximum number of transitions.
        n_humans: human slots N per state (padded; the mask says which are real).
        device: where the tensors live (sampling returns tensors there).
        dtype: float dtype of the stored states and rewards.
    """

    def __init__(
        self,
        capacity: int,
        n_humans: int,
        device: str | torch.device = "cpu",
        dtype: torch.dtype = torch.float32,
    ) -> None:
        """Preallocates the tensors (see the class's arguments)."""
        if capacity < 1:
            raise ValueError(f"capacity must be >= 1, got {capacity}")
        self.capacity = int(capacity)
        self.n_humans = int(n_humans)
        self.device = torch.device(device)
        c, n = self.capacity, self.n_humans
        kw = {"device": self.device}
        self.robot = torch.zeros(c, ROBOT_DIM, dtype=dtype, **kw)
        self.humans = torch.zeros(c, n, HUMAN_DIM, dtype=dtype, **kw)
        self.mask = torch.zeros(c, n, dtype=torch.bool, **kw)
        self.reward = torch.zeros(c, dtype=dtype, **kw)
        self.next_robot = torch.zeros(c, ROBOT_DIM, dtype=dtype, **kw)
        self.next_humans = torch.zeros(c, n, HUMAN_DIM, dtype=dtype, **kw)
        self.next_mask = torch.zeros(c, n, dtype=torch.bool, **kw)
        self.done = torch.zeros(c, dtype=torch.bool, **kw)
        self.target = torch.full((c,), float("nan"), dtype=dtype, **kw)
        self.position = 0  # next slot written
        self.size = 0
        self.pushed = 0  # transitions ever pushed

    def __len__(self) -> int:
        """Transitions held."""
        return self.size

    def push(
        self, robot, humans, mask, reward, next_robot, next_humans, next_mask, done, target=None
    ) -> None:
        """Appends k transitions (arrays with a leading dimension k; NumPy or torch).

        ``target``: value targets fixed now (the RGL repository's rule), or None (computed at each
        gradient step). The other arguments are the fields of :class:`Transitions`.
        """
        if target is None:
            target = torch.full((int(np.shape(reward)[0]),), float("nan"))
        arrays = [
            torch.as_tensor(np.asarray(x) if not torch.is_tensor(x) else x)
            for x in (robot, humans, mask, reward, next_robot, next_humans, next_mask, done, target)
        ]
        k = int(arrays[0].shape[0])
        if any(int(a.shape[0]) != k for a in arrays):
            raise ValueError(
                f"all transition arrays need the same leading size, got {[tuple(a.shape) for a in arrays]}"
            )
        if k == 0:
            return
        if arrays[1].shape[1:] != (self.n_humans, HUMAN_DIM):
            raise ValueError(
                f"humans must have shape (k, {self.n_humans}, {HUMAN_DIM}), got {tuple(arrays[1].shape)}"
            )
        self.pushed += k
        if k > self.capacity:  # only the newest `capacity` survive
            arrays = [a[k - self.capacity :] for a in arrays]
            self.position = (self.position + k - self.capacity) % self.capacity
            k = self.capacity
        idx = (self.position + torch.arange(k)) % self.capacity
        idx = idx.to(self.device)
        for dst, src in zip(
            (
                self.robot,
                self.humans,
                self.mask,
                self.reward,
                self.next_robot,
                self.next_humans,
                self.next_mask,
                self.done,
                self.target,
            ),
            arrays,
            strict=True,
        ):
            dst[idx] = src.to(device=self.device, dtype=dst.dtype)
        self.position = (self.position + k) % self.capacity
        self.size = min(self.size + k, self.capacity)

    def sample(self, batch_size: int, generator: torch.Generator) -> Transitions:
        """``batch_size`` transitions drawn uniformly with replacement using ``generator`` (CPU)."""
        return self.take(self.sample_indices(batch_size, generator))

    def sample_indices(self, batch_size: int, generator: torch.Generator) -> torch.Tensor:
        """The slots :meth:`sample` would take (on the memory's device).

        The same draw, so that a caller may gather the transitions itself (e.g. inside a compiled
        loss).

        Args:
            batch_size: slots drawn (uniformly, with replacement).
            generator: the CPU generator drawn from.

        Returns:
            (batch_size,) int64 slots.

        Raises:
            ValueError: the memory is empty.
        """
        if self.size == 0:
            raise ValueError("cannot sample from an empty replay memory")
        if generator is None:
            raise ValueError("sampling needs an explicit torch.Generator")
        idx = torch.randint(0, self.size, (int(batch_size),), generator=generator)
        if self.device.type == "cuda":  # from pinned memory: the copy does not wait for the GPU's queue
            return idx.pin_memory().to(self.device, non_blocking=True)
        return idx.to(self.device)

    def take(self, idx: torch.Tensor) -> Transitions:
        """The transitions in slots ``idx``."""
        return Transitions(
            self.robot[idx],
            self.humans[idx],
            self.mask[idx],
            self.reward[idx],
            self.next_robot[idx],
            self.next_humans[idx],
            self.next_mask[idx],
            self.done[idx],
            self.target[idx],
        )

"""What every trainer counts and validates.

Outcomes of training episodes, greedy validation over the ``val`` split's worlds, and which
validation is better (what ``best.pt`` keeps).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from socialnav.train.worlds import MultiWorld


def collisions(terminated: np.ndarray, reward: np.ndarray, success_reward: float) -> np.ndarray:
    """Which of a step's ended episodes ended in a collision (with a person or a wall).

    Args:
        terminated: (B,) bool, ended by success or collision.
        reward: (B,) the step's rewards (success is the one equal to ``success_reward``).
        success_reward: the preset's success reward.

    Returns:
        (B,) bool.
    """
    return terminated & ~np.isclose(reward, success_reward)


@dataclass
class EpisodeStats:
    """Outcomes of finished episodes (success, collision, timeout) and success times."""

    success: int = 0
    collision: int = 0
    timeout: int = 0
    success_time: float = 0.0

    @property
    def total(self) -> int:
        """Episodes counted."""
        return self.success + self.collision + self.timeout

    def rates(self) -> dict[str, float]:
        """Success, collision and timeout rates, and the mean time of successes (NaN without one)."""
        n = max(self.total, 1)
        return {
            "success": self.success / n,
            "collision": self.collision / n,
            "timeout": self.timeout / n,
            "nav_time": self.success_time / self.success if self.success else math.nan,
        }

    def add(
        self,
        terminated: np.ndarray,
        truncated: np.ndarray,
        reward: np.ndarray,
        time: np.ndarray,
        success_reward: float,
    ) -> None:
        """Counts the episodes that ended in a step.

        Args:
            terminated: (B,) bool, ended by success or collision.
            truncated: (B,) bool, ended by the time limit.
            reward: (B,) the step's rewards (success is the one equal to ``success_reward``).
            time: (B,) episode time at the end [s].
            success_reward: the preset's success reward.
        """
        collided = collisions(terminated, reward, success_reward)
        succ = terminated & ~collided
        self.success += int(succ.sum())
        self.collision += int(collided.sum())
        self.timeout += int(truncated.sum())
        self.success_time += float(time[succ].sum())


def validate(policy, world: MultiWorld, oracle: bool, success_reward: float) -> dict[str, float]:
    """Greedy rollouts of every episode of ``world`` (a finite val stream).

    Args:
        policy: anything with ``act(obs, next_humans=...) -> (_, actions)``.
        world: the validation worlds.
        oracle: show the policy the humans' true next states.
        success_reward: the preset's success reward.

    Returns:
        Success, collision and timeout rates, the mean navigation time of successes, episodes.
    """
    world.reset()
    stats = EpisodeStats()
    encode = getattr(policy, "encode", None)  # a value policy's obstacle points (the PPO actor adds its own)
    while world.busy:
        obs = world.observe(oracle=oracle)
        obs = obs if encode is None else encode(obs)
        _, actions = policy.act(obs, next_humans=obs.next_humans if oracle else None)
        actions = np.asarray(actions, dtype=np.float64)
        actions[~obs.active] = 0.0
        res = world.step(actions)
        active = obs.active
        stats.add(res.terminated & active, res.truncated & active, res.reward, res.final_time, success_reward)
    out = stats.rates()
    out["episodes"] = stats.total
    return out


def better(a: dict[str, Any], b: dict[str, Any] | None) -> bool:
    """Validation a better than b: higher success, then fewer collisions, then faster.

    Args:
        a: a validation.
        b: the best so far, or None.

    Returns:
        Whether a is better.
    """
    if b is None:
        return True

    def key(m: dict[str, Any]) -> tuple:
        nt = m.get("nav_time")
        return (m["success"], -m["collision"], -(nt if nt is not None and not math.isnan(nt) else 1e9))

    return key(a) > key(b)


class GreedyActor:
    """An actor as :func:`validate` calls a policy: ``act(obs, next_humans) -> (_, actions)``.

    Args:
        policy: anything with ``act(obs) -> actions`` (a RecurrentActorPolicy: its mean actions).
    """

    def __init__(self, policy) -> None:
        """Wraps ``policy`` (a RecurrentActorPolicy)."""
        self.policy = policy

    def act(self, obs, next_humans=None):
        """``(None, actions)``: the deterministic actions of ``obs`` (``next_humans`` unused)."""
        return None, self.policy.act(obs)

"""r̂: the reward the value policy's lookahead expects of each candidate action.

Two rules (``reward_rule``): ``end`` is CrowdNav's and RGL's one-step estimate, from the clearances
at the end positions only (:func:`~socialnav.policies.learned.state.reward`); ``swept`` is the world's
rule, swept collision and discomfort over the step (:func:`~socialnav.policies.learned.state.swept_reward`).

Obstacle points (the trailing ``static`` slots, :mod:`~socialnav.policies.learned.lookahead_inputs`)
count for collisions only: the world's reward has no discomfort term for walls.
"""

from __future__ import annotations

import torch

from socialnav.policies.learned.state import RewardParams, reward, swept_reward

__all__ = ["REWARD_RULES", "lookahead_reward"]

REWARD_RULES: tuple[str, ...] = ("end", "swept")


def lookahead_reward(
    robot: torch.Tensor,
    robot_next: torch.Tensor,
    humans: torch.Tensor,
    humans_next: torch.Tensor,
    mask: torch.Tensor,
    static: int,
    rule: str,
    params: RewardParams,
) -> torch.Tensor:
    """r̂ (B, K) of every candidate action.

    Args:
        robot: (B, 9) robot states now.
        robot_next: (B, K, 9) robot states after each candidate action.
        humans: (B, N, 5) human states now, the last ``static`` slots obstacle points.
        humans_next: (B, N, 5) predicted human states after the step (the points unmoved).
        mask: (B, N) real humans and points.
        static: How many trailing slots are obstacle points.
        rule: "end" or "swept" (see the module docstring).
        params: The reward constants.

    Returns:
        (B, K) rewards; the collision penalty where the robot would touch an obstacle point.
    """
    n = humans.shape[1] - static
    h, hn, m = humans[:, :n], humans_next[:, :n], mask[:, :n]
    if rule == "swept":
        r = swept_reward(robot, robot_next, h, hn, m, params)
    else:
        r = reward(robot_next, hn.unsqueeze(1), m.unsqueeze(1), params)  # (B, K)
    if not static:
        return r
    points, point_mask = humans[:, n:], mask[:, n:]  # (B, P, 5), (B, P)
    end = robot_next[..., None, :2]  # (B, K, 1, 2)
    p = points[:, None, :, :2]  # (B, 1, P, 2)
    if rule == "swept":  # the points stand still: distance to the swept segment
        start = robot[:, None, None, :2]
        seg = end - start
        t = ((p - start) * seg).sum(-1) / (seg * seg).sum(-1).clamp_min(1e-300)
        closest = start + t.clamp(0.0, 1.0).unsqueeze(-1) * seg
        d = torch.linalg.vector_norm(p - closest, dim=-1)
    else:
        d = torch.linalg.vector_norm(p - end, dim=-1)  # (B, K, P)
    clearance = d - robot_next[..., 4:5] - points[:, None, :, 4]
    hit = ((clearance < 0) & point_mask[:, None, :]).any(dim=-1)
    return torch.where(hit, torch.full_like(r, params.collision_penalty), r)

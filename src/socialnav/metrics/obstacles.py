"""Obstacle metrics: the robot's clearance to walls and collisions with them (worlds with walls).

They score the robot against the trajectory's :attr:`~socialnav.trajectory.Trajectory.static_map`
and are undefined (NaN) on an open floor, so that the tables of the original protocol are unchanged:
a NaN never enters a mean. The human metrics (Wang et al., M_I–M_VI) concern humans only and ignore
the walls. Clearance is measured at samples k = 1..K like every other per-sample metric here.
"""

from __future__ import annotations

import numpy as np

from socialnav.metrics.basic import DISTANCE_TOL, indicator_outputs, robot_human_distance
from socialnav.metrics.registry import register_metric
from socialnav.trajectory import Trajectory

__all__ = [
    "COLLISION_KIND_KEY",
    "min_obstacle_clearance",
    "obstacle_clearance",
    "obstacle_proximity",
    "wall_collision",
]

COLLISION_KIND_KEY = "collision_kind"
"""``Trajectory.settings`` key naming what a collision episode hit: ``"human"`` or ``"obstacle"``."""

_CLEARANCE_REF = ("Clearance to static obstacles as in Francis et al., 'Principles and Guidelines for "
                  "Evaluating Social Robot Navigation Algorithms' (arXiv 2306.16740), Sec. on metrics "
                  "('minimum distance to obstacles'); threshold after CrowdNav's discomfort distance")


def obstacle_clearance(traj: Trajectory) -> np.ndarray | None:
    """Robot–obstacle clearance at samples k = 1..K [m], shape (K,), or None without a map.

    Clearance is the distance from the robot's centre to the nearest obstacle edge minus the robot's
    radius: negative when the robot's disc overlaps a wall. A centre inside a solid polygon counts as
    distance 0 (clearance −r), since the penetration depth is not a quantity any metric needs.
    """
    smap = traj.static_map
    if smap is None:
        return None
    return traj.derived("obstacle_clearance",
                        lambda: smap.distance(traj.positions[1:, 0]) - traj.radii[0])


@register_metric("min_obstacle_clearance", unit="m", direction="higher", outputs={"value": "m"},
                 reference=_CLEARANCE_REF)
def min_obstacle_clearance(traj: Trajectory) -> dict[str, float]:
    """Minimum robot–obstacle clearance (distance to the nearest obstacle − robot radius) [m].

    Over samples k = 1..K; NaN without a static map or without steps. Negative values mean the robot
    overlapped an obstacle (a wall collision).
    """
    c = obstacle_clearance(traj)
    if c is None or c.size == 0:
        return {"value": float("nan")}
    return {"value": float(c.min())}


@register_metric("obstacle_proximity", unit="s", direction="lower",
                 outputs={"duration_s": "s", "count": "samples", "fraction": "1"},
                 parameters={"threshold": 0.2}, reference=_CLEARANCE_REF)
def obstacle_proximity(traj: Trajectory, threshold: float = 0.2) -> dict[str, float]:
    """Time the robot spends with its obstacle clearance below ``threshold`` [m].

    ``duration_s`` = count·dt [s], ``count`` [samples k = 1..K], ``fraction`` = count/K; NaN without a
    static map. The default 0.2 m is the protocol's discomfort distance (CrowdNav, and M_I's ε).
    """
    if not np.isfinite(threshold):
        raise ValueError(f"obstacle_proximity: threshold must be finite, got {threshold!r}")
    c = obstacle_clearance(traj)
    if c is None:
        return {"duration_s": float("nan"), "count": float("nan"), "fraction": float("nan")}
    return indicator_outputs(c < threshold - DISTANCE_TOL, traj.dt)


@register_metric("wall_collision", unit="1", direction="lower", outputs={"value": "1"},
                 reference="Francis et al. (arXiv 2306.16740): collisions with obstacles reported apart "
                 "from collisions with people", population="known_outcome")
def wall_collision(traj: Trajectory) -> dict[str, float]:
    """Wall-collision indicator: 1 when the episode ended in a collision with an obstacle, else 0.

    The cause is ``settings["collision_kind"]`` (``"obstacle"`` or ``"human"``, recorded by the
    simulator); a collision episode without it counts as an obstacle collision when the robot's
    clearance to the map went below zero before (not at the same sample as) it overlapped a person.
    NaN when the outcome is unknown, and on an open floor (no map, and no log saying the robot hit an
    obstacle), where the rate would be a meaningless 0: the simulator records ``collision_kind`` in
    every world, walls or not. The ``collision`` rate keeps
    counting every collision; this one is the part of it caused by walls.
    """
    kind = traj.settings.get(COLLISION_KIND_KEY)
    if traj.outcome == "unknown" or (traj.static_map is None and kind != "obstacle"):
        return {"value": float("nan")}
    if traj.outcome != "collision":
        return {"value": 0.0}
    if kind is not None:
        if kind not in ("human", "obstacle"):
            raise ValueError(f"settings['{COLLISION_KIND_KEY}'] must be 'human' or 'obstacle', got {kind!r}")
        return {"value": float(kind == "obstacle")}
    c = obstacle_clearance(traj)
    if c is None or c.size == 0 or not bool(c.min() < 0.0):
        return {"value": 0.0}
    # The first overlap is the collision, a person's where both come at one sample (the simulator
    # reports a step that hit both as a human collision).
    first_wall = int(np.argmax(c < 0.0))  # samples 1..K, as robot_human_distance's
    hit_person = (robot_human_distance(traj, "clearance") < 0.0).any(axis=1)
    return {"value": 0.0 if hit_person[: first_wall + 1].any() else 1.0}

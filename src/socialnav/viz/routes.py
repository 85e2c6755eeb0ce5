"""The routes drawn with an episode among walls: each routed agent's shortest route from its start.

Where the humans followed routes (the world setting ``human_routes: shortest``, recorded in the
trajectory's settings with its ``route_clearance``) and where the robot's policy is ``orca_route`` or
``social_force_route``, the plots, animations and the viewer draw the route each of them planned at
the episode's start: the route layer's own answer (cpp/routes.hpp, ``_core.plan_route``) from the
agent's sample-0 position to its goal, with the radius and clearance the agent planned with:

- a human: its radius and the trajectory's ``route_clearance``; exactly the plan the world made at the
  episode's first step.
- the robot under ``orca_route``: its radius inflated as its ORCA inflates it (the world's ORCA
  ``radius_margin`` plus the policy's ``safety_space``) and the policy's ``route_clearance``; under
  ``social_force_route``: its radius and ``route_clearance``. The robot re-plans every step, around the
  walls and around the people standing still when it plans (its global planner's obstacle layer); what
  is drawn is its route around the walls alone from its start, the part of its plan the episode's map
  fixes. A result directory's manifest records the policy's parameters and the world, so that route is
  the robot's own; a bare trajectory file records only the policy's label, read as the policy's name
  with its default parameters (and the default ``radius_margin``).

A route is drawn only where the episode has walls and the route bends (more than one point to pass: a
route of the goal alone is the straight line the path shows anyway); no route is drawn where none was
found. Routes are (n, 2) polylines in metres: the start, then the points to pass, the goal last.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from socialnav.maps.static_map import StaticMap
from socialnav.trajectory import Trajectory

#: The native robot policies that follow routes, and whether their route radius takes ORCA's inflation.
ROUTE_POLICIES = {"orca_route": True, "social_force_route": False}

#: What ``routes=`` of the drawing functions takes: True (the routes the trajectory records enough to
#: plan, :func:`episode_routes`), False (none), or routes already planned ({agent: (n, 2) polyline}).
Routes = bool | Mapping[int, np.ndarray]


def plan(
    start: np.ndarray, goal: np.ndarray, radius: float, clearance: float, static_map: StaticMap
) -> np.ndarray | None:
    """The shortest route around ``static_map``'s walls as a polyline, or None where none was found.

    Args:
        start: (2,) where the agent starts [m].
        goal: (2,) its goal [m].
        radius: The radius it plans with [m], > 0.
        clearance: The distance it keeps from walls beyond its radius where the passage allows [m].
        static_map: The episode's :class:`~socialnav.maps.static_map.StaticMap`.

    Returns:
        (n + 1, 2): ``start``, then the n points of the route (the goal last).
    """
    from socialnav import _core

    vertices, offsets = static_map.to_flat()
    points, found, _ = _core.plan_route(
        np.array(start, dtype=np.float64), np.array(goal, dtype=np.float64), float(radius), float(clearance),
        np.array(vertices, dtype=np.float64), np.array(offsets, dtype=np.int64),
    )
    if not found:
        return None
    return np.concatenate([np.asarray(start, dtype=np.float64)[None], np.asarray(points, dtype=np.float64)])


def robot_route_parameters(
    traj: Trajectory, run: Mapping[str, Any] | None = None
) -> tuple[float, float] | None:
    """(radius, clearance) [m] the robot plans its routes with, or None when its policy follows none.

    Args:
        traj: The episode.
        run: The manifest of the result directory it comes from (its ``policy`` record and preset), if
            any; without it the trajectory's ``settings["policy"]`` is read as the policy's name with
            that policy's default parameters.
    """
    from socialnav.sim.settings import OrcaSettings

    record: Mapping[str, Any] = {}
    world: Mapping[str, Any] = {}
    if run is not None and isinstance(run.get("policy"), Mapping):
        record = run["policy"]
        name = record.get("policy")
        preset = run.get("preset")
        if isinstance(preset, Mapping) and isinstance(preset.get("world"), Mapping):
            world = preset["world"]
    else:
        name = traj.settings.get("policy")
    if name not in ROUTE_POLICIES:
        return None
    from socialnav.policies.registry import get_policy_entry

    defaults = get_policy_entry(str(name)).parameters
    clearance = float(record.get("route_clearance", defaults["route_clearance"]))
    radius = float(traj.radii[0])
    if ROUTE_POLICIES[str(name)]:  # ORCA inflates the robot's radius, and its route's with it
        orca = world.get("orca")
        margin = orca.get("radius_margin") if isinstance(orca, Mapping) else None
        radius += float(OrcaSettings().radius_margin if margin is None else margin)
        radius += float(record.get("safety_space", defaults["safety_space"]))
    return radius, clearance


def route_parameters(
    traj: Trajectory, run: Mapping[str, Any] | None = None
) -> dict[int, tuple[float, float]]:
    """{agent: (radius, clearance) [m]} of every agent that followed routes in ``traj``.

    Args:
        traj: The episode.
        run: The manifest of its result directory, if any (see :func:`robot_route_parameters`).
    """
    from socialnav.sim.settings import WorldSettings

    out: dict[int, tuple[float, float]] = {}
    robot = robot_route_parameters(traj, run)
    if robot is not None:
        out[0] = robot
    if traj.settings.get("human_routes") == "shortest":
        clearance = float(traj.settings.get("route_clearance", WorldSettings().route_clearance))
        for a in range(1, traj.n_agents):
            out[a] = (float(traj.radii[a]), clearance)
    return out


def episode_routes(traj: Trajectory, run: Mapping[str, Any] | None = None) -> dict[int, np.ndarray]:
    """{agent: (n + 1, 2) polyline} of the routes drawn with ``traj`` (the module docstring says which).

    Args:
        traj: The episode.
        run: The manifest of its result directory, if any: the robot's policy parameters.

    Returns:
        The routes by agent index (0: the robot); empty on an open floor and where no agent was routed.
    """
    if not traj.static_map:
        return {}
    out: dict[int, np.ndarray] = {}
    for a, (radius, clearance) in route_parameters(traj, run).items():
        start, goal = traj.positions[0, a], traj.goals[a]
        if not (radius > 0 and clearance >= 0 and np.isfinite(start).all() and np.isfinite(goal).all()):
            continue
        line = plan(start, goal, radius, clearance, traj.static_map)
        if line is not None and line.shape[0] > 2:  # a bend: more than the goal alone to pass
            out[a] = line
    return out


def resolve_routes(traj: Trajectory, routes: Routes) -> dict[int, np.ndarray]:
    """The routes to draw: ``routes`` itself, those of :func:`episode_routes` (True) or none (False)."""
    if routes is True:
        return episode_routes(traj)
    if routes is False:
        return {}
    return {int(a): np.asarray(line, dtype=np.float64) for a, line in routes.items()}

"""Routes around a static map's walls: the core's route layer from Python (docs/routes.md).

The native world plans the routes of its humans itself (``WorldSettings.human_routes``); these functions
give the same routes and distances to the tools that draw them, the metrics that measure progress along
them and to users, for one map at a time::

    from socialnav.maps import StaticMap
    from socialnav.maps.routes import plan_route

    door = StaticMap(([[-5.0, 0.0], [-0.6, 0.0]], [[0.6, 0.0], [5.0, 0.0]]))
    route = plan_route(door, start=(3.0, -3.0), goal=(3.0, 3.0), radius=0.3)
    route.points  # the points to pass, the goal last: through the door

The planner is a visibility graph over the walls' corners offset by the agent's radius plus a clearance
(Lozano-Pérez & Wesley 1979), shortest routes by A* (Hart, Nilsson & Raphael 1968); see ``cpp/routes.hpp``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from socialnav import _core
from socialnav.maps.static_map import MAX_COORDINATE, StaticMap

__all__ = ["DEFAULT_CLEARANCE", "ROBOT_CLEARANCE", "Route", "plan_route", "route_distances", "route_goals"]

#: The clearance [m] beyond their radius that routed humans keep from walls (WorldSettings.route_clearance).
DEFAULT_CLEARANCE = 0.2
#: The clearance [m] beyond its radius that a robot's route keeps from walls (orca_route's default).
ROBOT_CLEARANCE = 0.1


@dataclass(frozen=True)
class Route:
    """A planned route.

    Attributes:
        points: (K, 2) the points to pass [m], the goal last.
        found: False where no route reaches the goal at any inflation (points is then the goal alone).
        inflation: The distance [m] the route keeps from the walls: radius + clearance, or the radius
            alone where a passage is narrower than that.
    """

    points: np.ndarray
    found: bool
    inflation: float

    @property
    def length(self) -> float:
        """Length [m] of the route from its start (not stored: add the first leg yourself) over its points."""
        return float(np.linalg.norm(np.diff(self.points, axis=0), axis=1).sum())


def _flat(static_map: StaticMap | None) -> tuple[np.ndarray, np.ndarray]:
    if static_map is None:
        return np.zeros((0, 2)), np.zeros(1, dtype=np.int64)
    if not isinstance(static_map, StaticMap):
        raise TypeError(f"static_map must be a StaticMap or None, got {type(static_map).__name__}")
    return static_map.to_flat()


def _point(value: object, name: str) -> np.ndarray:
    p = np.asarray(value, dtype=np.float64).reshape(-1)
    if p.shape != (2,) or not np.all(np.isfinite(p)):
        raise ValueError(f"{name} must be a finite (x, y) point, got {value!r}")
    _within_bounds(p[None], name)
    return p


def _within_bounds(points: np.ndarray, name: str) -> None:
    # the bound of every map coordinate: the geometry's tolerances are sized for it
    far = np.flatnonzero(~(np.abs(points) <= MAX_COORDINATE).all(axis=1))
    if far.size:
        raise ValueError(f"{name} {points[far[0]].tolist()} is not finite or farther than the maps' bound "
                         f"(|x|, |y| <= {MAX_COORDINATE:,.0f} m)")


def plan_route(static_map: StaticMap | None, start: object, goal: object, radius: float,
               clearance: float = DEFAULT_CLEARANCE) -> Route:
    """The shortest route of a disc from ``start`` to ``goal`` around the map's walls.

    Args:
        static_map: The walls (None: an open floor, where the route is the goal itself).
        start: (x, y) [m].
        goal: (x, y) [m].
        radius: The agent's radius [m], > 0.
        clearance: Distance [m] kept from the walls beyond the radius where the passage allows.

    Returns:
        The route (its points exclude the start).

    Raises:
        ValueError: A point that is not a finite (x, y) within the maps' coordinate bound, a radius <= 0
            or a clearance < 0.
    """
    vertices, offsets = _flat(static_map)
    points, found, inflation = _core.plan_route(_point(start, "start"), _point(goal, "goal"), float(radius),
                                                float(clearance), vertices, offsets)
    return Route(np.array(points, dtype=np.float64).reshape(-1, 2), bool(found), float(inflation))


def route_distances(static_map: StaticMap | None, points: np.ndarray, goal: object,
                    radius: float) -> np.ndarray:
    """Free-space distances [m] of a disc from each point to the goal around the walls.

    The visibility graph inflated by the radius alone (no clearance): the length of the shortest path the
    disc could walk. Euclidean on an open floor.

    Args:
        static_map: The walls (None: an open floor).
        points: (n, 2) positions [m].
        goal: (x, y) [m].
        radius: The disc's radius [m], > 0.

    Returns:
        (n,) distances, inf where the goal cannot be reached.

    Raises:
        ValueError: A point or the goal not finite or beyond the maps' coordinate bound, or a radius <= 0.
    """
    pts = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 2)
    _within_bounds(pts, "point")
    vertices, offsets = _flat(static_map)
    out = np.empty(len(pts))
    _core.route_distances(pts, _point(goal, "goal"), float(radius), vertices, offsets, out)
    return out


def route_goals(robot: np.ndarray, obstacles: object, clearance: float = ROBOT_CLEARANCE) -> np.ndarray:
    """Where each robot's shortest route around its episode's walls heads, for B episodes at once.

    The route is planned from where the robot stands for its radius plus ``clearance`` (on the map's
    cached graphs: about 0.6 µs per robot on a door map), and the point returned is the one a routed
    human hands its preferred-velocity law: on the line to the route's first point, as far from the
    robot as the route is long (so that its distance is the distance still to walk); the goal itself on
    an open floor or with the goal in sight.
    ``orca_route`` heads the same way (around the people standing still too).

    Args:
        robot: (B, 9) robot rows of an :class:`~socialnav.sim.observation.Observation` (position,
            radius and goal are read).
        obstacles: the episodes' maps prepared for the core (``ObstacleArrays.native``), or None (open
            floors).
        clearance: distance [m] kept from the walls beyond the radius where the passage allows, >= 0.

    Returns:
        (B, 2) the points [m], world frame.
    """
    robot = np.ascontiguousarray(robot, dtype=np.float64)
    out = np.empty((robot.shape[0], 2))
    _core.robot_route_goals(robot, obstacles, float(clearance), out)
    return out

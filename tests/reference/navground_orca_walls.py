"""RVO2's ORCA with wall segments, computed by navground's ``ORCABehavior`` (navground 0.7).

navground hands its ``line_obstacles`` (``navground.core.LineSegment``) to RVO2 as 2-vertex
obstacles p1 -> p2 -> p1, both vertices convex: RVO2's own representation of a segment (what
``RVOSimulator::addObstacle`` builds for two vertices). It selects the obstacle edges like RVO2's
obstacle query: an edge is a neighbour when the agent is strictly on its right and its distance
is below ``static_time_horizon * maxSpeed + radius``; then RVO2's ``computeNewVelocity`` runs
unchanged. It does not build RVO2's obstacle kd-tree, which splits every edge crossing the line of
the edge chosen at a node (the split point gets legs of its own) and orders equally distant edges by
its query: where walls cross each other's lines, navground departs from RVO2 (RVO2 itself:
rvo2_pyrvo.py). Otherwise navground is RVO2, with the caveats of navground_orca.py:

- navground uses ``maxSpeed = |pref_velocity|``: the cases drawn here have ``|pref| == max_speed``;
- it pushes overlapping *agents* apart: the layouts keep agents >= 1 cm apart (walls are never
  pushed, so agents touching a wall exercise RVO2's collision branches unchanged);
- it is built in float32 (tolerances in tests/sim/test_orca_walls_reference.py).

What navground cannot express: solid polygons of k >= 3 vertices with arbitrary shape, and so
non-convex vertices. Its only polygon is the axis-aligned square it makes of a disc obstacle with
``treat_obstacles_as_agents = False``, and for those it inserts every edge, also the ones facing away
from the agent, which RVO2's query never selects: not RVO2's semantics. Polygons are therefore tested
by hand-built cases and invariants instead (tests/sim/test_orca_walls.py).
"""

from __future__ import annotations

import math

import numpy as np

from tests.reference.navground_orca import max_violation


def _navground_query(position, velocity, radius, pref_velocity, neighbor_positions, neighbor_velocities,
                     neighbor_radii, walls, *, time_horizon=5.0, time_horizon_obst=5.0, time_step=0.25,
                     neighbor_dist=10.0, max_neighbors=10):
    """navground's ORCA behaviour after one query: (new velocity, half-planes, |pref|)."""
    import navground.core as core
    from navground.core.behaviors import ORCABehavior
    from navground.core.kinematics import OmnidirectionalKinematics

    pref = np.asarray(pref_velocity, dtype=float)
    b = ORCABehavior(kinematics=OmnidirectionalKinematics(max_speed=float(np.hypot(*pref)) + 1.0),
                     radius=float(radius))
    b.safety_margin = 0.0
    b.time_horizon = float(time_horizon)
    b.static_time_horizon = float(time_horizon_obst)
    b.max_number_of_neighbors = int(max_neighbors)
    b.horizon = 0.5 * float(neighbor_dist)
    b.position = np.asarray(position, dtype=float)
    b.velocity = np.asarray(velocity, dtype=float)
    b.social_margin.set(0.0)
    b.environment_state.neighbors = [
        core.Neighbor(np.asarray(neighbor_positions[i], float), float(neighbor_radii[i]),
                      np.asarray(neighbor_velocities[i], float), i)
        for i in range(len(neighbor_radii))]
    b.environment_state.line_obstacles = [
        core.LineSegment(np.asarray(w[0], float), np.asarray(w[1], float)) for w in walls]
    u = np.array(b.desired_velocity_towards_velocity(pref, float(time_step)), dtype=float)
    lines = [(np.array(ln.point, float), np.array(ln.direction, float)) for ln in b.lines]
    return u, lines, float(np.hypot(*pref))


def navground_wall_velocity(*args, **kwargs):
    """navground's new velocity (RVO2 with ``maxSpeed = |pref|``) and whether its 2-D LP was
    feasible. Arguments: position, velocity, radius, pref_velocity, neighbor_positions,
    neighbor_velocities, neighbor_radii, walls ((W, 2, 2) segment end points), then the ORCA
    parameters as keywords."""
    u, lines, speed = _navground_query(*args, **kwargs)
    return u, max_violation(u, lines) <= 1e-6 * max(1.0, speed)


def random_wall_layout(rng: np.random.Generator, n_walls: int, n_agents: int) -> dict:
    """Agents among random wall segments in a 10 m box: |pref| == max_speed for every agent,
    agents >= 1 cm apart, some agents touching or overlapping a wall (RVO2's collision branches)."""
    walls = np.zeros((n_walls, 2, 2))
    for w in range(n_walls):
        centre = rng.uniform(-4.0, 4.0, size=2)
        angle = rng.uniform(-math.pi, math.pi)
        half = rng.uniform(0.3, 3.0)
        d = half * np.array([math.cos(angle), math.sin(angle)])
        walls[w] = (centre - d, centre + d)
    radii = rng.uniform(0.3, 0.5, size=n_agents)
    positions = np.zeros((n_agents, 2))
    for i in range(n_agents):
        near_wall = rng.uniform() < 0.4  # within two radii of a wall point: contacts and legs
        for _ in range(1000):
            if near_wall:
                w = walls[int(rng.integers(n_walls))]
                on = w[0] + rng.uniform(-0.1, 1.1) * (w[1] - w[0])
                a = rng.uniform(-math.pi, math.pi)
                p = on + rng.uniform(0.0, 2.0 * radii[i]) * np.array([math.cos(a), math.sin(a)])
            else:
                p = rng.uniform(-5.0, 5.0, size=2)
            if all(np.hypot(*(p - positions[j])) > radii[i] + radii[j] + 0.01 for j in range(i)):
                break
        positions[i] = p
    max_speeds = rng.uniform(0.5, 1.5, size=n_agents)
    heading = rng.uniform(-math.pi, math.pi, size=n_agents)
    pref = max_speeds[:, None] * np.stack([np.cos(heading), np.sin(heading)], axis=1)
    vangle = rng.uniform(-math.pi, math.pi, size=n_agents)
    speed = rng.uniform(0.0, 1.0, size=n_agents) * max_speeds
    velocities = speed[:, None] * np.stack([np.cos(vangle), np.sin(vangle)], axis=1)
    return dict(positions=positions, velocities=velocities, pref_velocities=pref, radii=radii,
                max_speeds=max_speeds, walls=walls)


def solve_with_hard_lines(lines, n_hard: int, max_speed: float, pref_velocity) -> np.ndarray:
    """RVO2's linear programs in float64 on given half-planes, the first ``n_hard`` (obstacles)
    kept in every sub-problem of the 3-D fallback (python_orca's programs otherwise)."""
    from tests.reference.python_orca import _det, _lp2, _normalize, _scale, _sub

    lines = [((float(p[0]), float(p[1])), (float(d[0]), float(d[1]))) for p, d in lines]
    opt = (float(pref_velocity[0]), float(pref_velocity[1]))
    fail, result = _lp2(lines, float(max_speed), opt, False)
    if fail == len(lines):
        return np.array(result)
    distance = 0.0
    for i in range(fail, len(lines)):
        p_i, d_i = lines[i]
        if _det(d_i, _sub(p_i, result)) <= distance:
            continue
        proj = list(lines[:n_hard])
        for j in range(n_hard, i):
            p_j, d_j = lines[j]
            determinant = _det(d_i, d_j)
            if abs(determinant) <= 1e-5:
                if d_i[0] * d_j[0] + d_i[1] * d_j[1] > 0.0:
                    continue
                point = _scale((p_i[0] + p_j[0], p_i[1] + p_j[1]), 0.5)
            else:
                t = _det(d_j, _sub(p_i, p_j)) / determinant
                point = (p_i[0] + t * d_i[0], p_i[1] + t * d_i[1])
            proj.append((point, _normalize(_sub(d_j, d_i))))
        k, new = _lp2(proj, float(max_speed), (-d_i[1], d_i[0]), True)
        if k >= len(proj):
            result = new
        distance = _det(d_i, _sub(p_i, result))
    return np.array(result)


def navground_lines(*args, **kwargs):
    """The half-planes navground built for the same query (obstacle lines first)."""
    return _navground_query(*args, **kwargs)[1]

"""Plain-Python (float64) reference of RVO2's ORCA for ONE agent, agents only.

Written from the description in J. van den Berg, S. J. Guy, M. Lin, D. Manocha,
"Reciprocal n-body collision avoidance" (ISRR 2011) and the semantics of the
RVO2 library's ``Agent::computeNewVelocity``:

1. Neighbour selection: neighbours with ``dist^2 < neighbor_dist^2``; the
   ``max_neighbors`` closest are kept, ordered by increasing distance (ties keep
   the input order, like RVO2's insertion sort).
2. One ORCA half-plane per neighbour, with combined radius ``R = r_a + r_b``,
   ``relPos = p_b - p_a``, ``relVel = v_a - v_b``:

   * not colliding (``|relPos|^2 > R^2``), ``w = relVel - relPos / tau``:
     - projection on the cut-off circle when ``w . relPos < 0`` and
       ``(w . relPos)^2 > R^2 |w|^2``;
     - otherwise projection on the left leg (``det(relPos, w) > 0``) or on the
       right leg of the truncated cone;
   * colliding (``|relPos|^2 <= R^2``): cut-off circle for the time step,
     ``w = relVel - relPos / time_step``.

   ``u`` is the smallest change of relative velocity that leaves the velocity
   obstacle; the half-plane passes through ``v_a + u / 2`` (reciprocity).
3. Incremental 2-D linear program (lines processed in neighbour order, no
   shuffling) that finds the velocity closest to the preferred velocity
   inside the intersection of the half-planes and the max-speed disc.  The
   preferred velocity is NOT clipped beforehand: only the starting point is
   projected on the disc (exactly like RVO2).
4. When that program is infeasible, the 3-D linear program fallback that
   minimises the maximal penetration into the half-planes (still inside the
   max-speed disc).

``RVO_EPSILON = 1e-5`` is used for parallel-line tests, as in RVO2.
All arithmetic is float64 Python scalars (no vectorisation: this is meant to
be obviously correct, not fast).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

RVO_EPSILON = 1e-5

Vec = tuple[float, float]
Line = tuple[Vec, Vec]  # (point, unit direction); feasible side is on the LEFT


def _det(a: Vec, b: Vec) -> float:
    return a[0] * b[1] - a[1] * b[0]


def _dot(a: Vec, b: Vec) -> float:
    return a[0] * b[0] + a[1] * b[1]


def _sub(a: Vec, b: Vec) -> Vec:
    return (a[0] - b[0], a[1] - b[1])


def _add(a: Vec, b: Vec) -> Vec:
    return (a[0] + b[0], a[1] + b[1])


def _scale(a: Vec, s: float) -> Vec:
    return (a[0] * s, a[1] * s)


def _norm(a: Vec) -> float:
    return math.sqrt(_dot(a, a))


def _normalize(a: Vec) -> Vec:
    n = _norm(a)
    return (a[0] / n, a[1] / n)


def orca_lines(position, velocity, radius, neighbor_positions, neighbor_velocities,
               neighbor_radii, time_horizon, time_step, neighbor_dist,
               max_neighbors) -> list[Line]:
    """ORCA half-planes of the agent, in RVO2 neighbour order."""
    p = (float(position[0]), float(position[1]))
    v = (float(velocity[0]), float(velocity[1]))
    nps = np.asarray(neighbor_positions, dtype=float).reshape(-1, 2)
    nvs = np.asarray(neighbor_velocities, dtype=float).reshape(-1, 2)
    nrs = np.asarray(neighbor_radii, dtype=float).reshape(-1)

    # --- neighbour selection (strict range, k nearest, stable for ties)
    range_sq = float(neighbor_dist) ** 2
    candidates = []
    for i in range(len(nrs)):
        rel = (float(nps[i, 0]) - p[0], float(nps[i, 1]) - p[1])
        d2 = _dot(rel, rel)
        if d2 < range_sq:
            candidates.append((d2, i))
    candidates.sort(key=lambda x: x[0])  # Python sort is stable
    selected = [i for _, i in candidates[: max(0, int(max_neighbors))]]

    inv_tau = 1.0 / float(time_horizon)
    lines: list[Line] = []
    for i in selected:
        rel_pos = (float(nps[i, 0]) - p[0], float(nps[i, 1]) - p[1])
        rel_vel = (v[0] - float(nvs[i, 0]), v[1] - float(nvs[i, 1]))
        dist_sq = _dot(rel_pos, rel_pos)
        comb_r = float(radius) + float(nrs[i])
        comb_r_sq = comb_r * comb_r
        if dist_sq > comb_r_sq:
            # velocity obstacle truncated at tau
            w = _sub(rel_vel, _scale(rel_pos, inv_tau))
            w_len_sq = _dot(w, w)
            dot1 = _dot(w, rel_pos)
            if dot1 < 0.0 and dot1 * dot1 > comb_r_sq * w_len_sq:
                # closest boundary point lies on the cut-off circle
                w_len = math.sqrt(w_len_sq)
                unit_w = _scale(w, 1.0 / w_len)
                direction = (unit_w[1], -unit_w[0])
                u = _scale(unit_w, comb_r * inv_tau - w_len)
            else:
                # closest boundary point lies on one of the legs
                leg = math.sqrt(dist_sq - comb_r_sq)
                if _det(rel_pos, w) > 0.0:  # left leg
                    direction = ((rel_pos[0] * leg - rel_pos[1] * comb_r) / dist_sq,
                                 (rel_pos[0] * comb_r + rel_pos[1] * leg) / dist_sq)
                else:  # right leg (direction reversed so feasible side is left)
                    direction = (-(rel_pos[0] * leg + rel_pos[1] * comb_r) / dist_sq,
                                 -(-rel_pos[0] * comb_r + rel_pos[1] * leg) / dist_sq)
                dot2 = _dot(rel_vel, direction)
                u = _sub(_scale(direction, dot2), rel_vel)
        else:
            # already overlapping: cut-off circle of the time step
            inv_dt = 1.0 / float(time_step)
            w = _sub(rel_vel, _scale(rel_pos, inv_dt))
            w_len = _norm(w)
            unit_w = _scale(w, 1.0 / w_len)
            direction = (unit_w[1], -unit_w[0])
            u = _scale(unit_w, comb_r * inv_dt - w_len)
        point = _add(v, _scale(u, 0.5))
        lines.append((point, direction))
    return lines


def _lp1(lines: Sequence[Line], line_no: int, radius: float, opt: Vec,
         direction_opt: bool):
    """Optimise on line ``line_no`` subject to previous lines and the disc.

    Returns the new result or None when infeasible."""
    point, direction = lines[line_no]
    dotp = _dot(point, direction)
    disc = dotp * dotp + radius * radius - _dot(point, point)
    if disc < 0.0:
        return None  # the disc does not reach this line
    sq = math.sqrt(disc)
    t_left = -dotp - sq
    t_right = -dotp + sq
    for i in range(line_no):
        p_i, d_i = lines[i]
        denom = _det(direction, d_i)
        numer = _det(d_i, _sub(point, p_i))
        if abs(denom) <= RVO_EPSILON:
            # (almost) parallel
            if numer < 0.0:
                return None
            continue
        t = numer / denom
        if denom >= 0.0:
            t_right = min(t_right, t)  # line i bounds on the right
        else:
            t_left = max(t_left, t)
        if t_left > t_right:
            return None
    if direction_opt:
        if _dot(opt, direction) > 0.0:
            return _add(point, _scale(direction, t_right))
        return _add(point, _scale(direction, t_left))
    t = _dot(direction, _sub(opt, point))
    if t < t_left:
        return _add(point, _scale(direction, t_left))
    if t > t_right:
        return _add(point, _scale(direction, t_right))
    return _add(point, _scale(direction, t))


def _lp2(lines: Sequence[Line], radius: float, opt: Vec, direction_opt: bool):
    """Returns (index of the first failing line or len(lines), result)."""
    if direction_opt:
        result = _scale(opt, radius)  # opt is a unit vector
    elif _dot(opt, opt) > radius * radius:
        result = _scale(_normalize(opt), radius)
    else:
        result = opt
    for i, (p_i, d_i) in enumerate(lines):
        if _det(d_i, _sub(p_i, result)) > 0.0:  # result violates line i
            new = _lp1(lines, i, radius, opt, direction_opt)
            if new is None:
                return i, result
            result = new
    return len(lines), result


def _lp3(lines: Sequence[Line], begin: int, radius: float, result: Vec) -> Vec:
    """Minimise the maximal penetration (no obstacle lines here)."""
    distance = 0.0
    for i in range(begin, len(lines)):
        p_i, d_i = lines[i]
        if _det(d_i, _sub(p_i, result)) > distance:
            proj: list[Line] = []
            for j in range(i):
                p_j, d_j = lines[j]
                determinant = _det(d_i, d_j)
                if abs(determinant) <= RVO_EPSILON:
                    if _dot(d_i, d_j) > 0.0:
                        continue  # same direction
                    point = _scale(_add(p_i, p_j), 0.5)
                else:
                    point = _add(p_i, _scale(d_i, _det(d_j, _sub(p_i, p_j)) / determinant))
                proj.append((point, _normalize(_sub(d_j, d_i))))
            fail, new = _lp2(proj, radius, (-d_i[1], d_i[0]), True)
            if fail >= len(proj):
                result = new
            # else: keep the previous result (RVO2 restores it; this "should
            # not happen" in exact arithmetic)
            distance = _det(d_i, _sub(p_i, result))
    return result


def solve_orca_lp(lines: Sequence[Line], max_speed: float, pref_velocity) -> np.ndarray:
    opt = (float(pref_velocity[0]), float(pref_velocity[1]))
    fail, result = _lp2(lines, float(max_speed), opt, False)
    if fail < len(lines):
        result = _lp3(lines, fail, float(max_speed), result)
    return np.array(result, dtype=float)


def python_orca_velocity(position, velocity, radius, max_speed, pref_velocity,
                         neighbor_positions, neighbor_velocities, neighbor_radii,
                         time_horizon=5.0, time_step=0.25, neighbor_dist=10.0,
                         max_neighbors=10) -> np.ndarray:
    """New velocity (shape ``(2,)``, float64) computed by ORCA / RVO2 semantics."""
    lines = orca_lines(position, velocity, radius, neighbor_positions,
                       neighbor_velocities, neighbor_radii, time_horizon,
                       time_step, neighbor_dist, max_neighbors)
    return solve_orca_lp(lines, max_speed, pref_velocity)


__all__ = ["RVO_EPSILON", "orca_lines", "solve_orca_lp", "python_orca_velocity"]

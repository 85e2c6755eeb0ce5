"""Comfort metrics M_I (personal space), M_II (projected path) and M_III (aggregated time).

Wang et al., "Metrics for Evaluating Social Conformity of Crowd Navigation Algorithms", ARSO 2022
(arXiv 2202.01045): the definitions of M_I–M_III in its metrics section, values in its Table II.
M_II's velocity rectangle follows the speed-dependent social zone of Jin et al., ICRA 2020.
Indicator metrics flag samples k = 1..K and report count, fraction = count/K and duration_s = count·dt
(see ``docs/metrics.md``).
"""

from __future__ import annotations

import numpy as np

from socialnav.metrics.basic import DISTANCE_TOL, indicator_outputs, min_over_humans, robot_human_distance
from socialnav.metrics.registry import JIN2020, WANG2022, register_metric
from socialnav.trajectory import Trajectory

__all__ = [
    "aggregated_time",
    "personal_space",
    "personal_space_flags",
    "projected_path",
    "projected_path_flags",
    "rectangles_intersect",
    "velocity_rectangles",
]

STOPPED_SPEED = 1e-6
"""Speed [m/s] at or below which an agent has no velocity rectangle (M_II)."""
TOUCH_TOL = 1e-9
"""Slack [m] of the separating-axis test, so that touching rectangles count as intersecting."""

_INDICATOR = {"count": "samples", "fraction": "1", "duration_s": "s"}


# ----------------------------------------------------------------------------------------- M_I
def personal_space_flags(traj: Trajectory, eps: float = 0.2, distance: str = "clearance") -> np.ndarray:
    """Samples k = 1..K whose robot–human distance d_k is below ``eps``.

    Wang et al., ARSO 2022 (arXiv 2202.01045), definition of M_I: d_k = min_h |p^h_k − p^r_k| − r_h − r_r
    (``distance="clearance"``) or the centre distance (``"centre"``); flag d_k < ε (less a rounding's
    slack, :data:`~socialnav.metrics.basic.DISTANCE_TOL`).

    Returns:
        Flags, shape (K,) bool.
    """
    return min_over_humans(robot_human_distance(traj, distance)) < eps - DISTANCE_TOL


@register_metric(
    "m1_personal_space", unit="s", direction="lower", outputs=_INDICATOR,
    parameters={"eps": 0.2, "distance": "clearance"}, variants=({"eps": 0.2}, {"eps": 1.2}),
    social=True, reference=WANG2022 + ", definition of M_I, Table II",
)
def personal_space(traj: Trajectory, eps: float = 0.2, distance: str = "clearance") -> dict[str, float]:
    """M_I personal-space violation: samples with robot–human distance below ε.

    Wang et al., ARSO 2022 (arXiv 2202.01045), definition of M_I. ε = 0.2 m reproduces the paper's
    table (CrowdSim's discomfort distance); ε = 1.2 m (Hall's personal distance) is the recommended
    general setting.

    Args:
        traj: The episode.
        eps: Threshold ε [m].
        distance: "clearance" (surface to surface) or "centre".

    Returns:
        ``count`` [samples], ``fraction`` [1], ``duration_s`` [s].
    """
    return indicator_outputs(personal_space_flags(traj, eps, distance), traj.dt)


# ----------------------------------------------------------------------------------------- M_II
def velocity_rectangles(
    positions: np.ndarray, velocities: np.ndarray, radii: np.ndarray, tau: float, anchor: str = "rear"
) -> tuple[np.ndarray, np.ndarray]:
    """Velocity rectangles of agents (Jin et al., ICRA 2020; Wang et al., ARSO 2022, definition of M_II).

    The rectangle has width 2·radius and length τ·|v| along v. With ``anchor="rear"`` its rear edge
    is centred on the agent's position; with ``"front"`` on the front of the body, p + r·v/|v|.

    Args:
        positions: [m], shape (..., 2).
        velocities: [m/s], shape (..., 2).
        radii: [m], broadcastable to positions.shape[:-1].
        tau: Time horizon τ [s].
        anchor: "rear" or "front".

    Returns:
        Corners [m], shape (..., 4, 2), in order around the rectangle, and a validity mask (...,)
        that is False for stopped agents (|v| ≤ 1e-6 m/s), which have no rectangle.
    """
    if anchor not in ("rear", "front"):
        raise ValueError(f"anchor must be 'rear' or 'front', got {anchor!r}")
    speed = np.linalg.norm(velocities, axis=-1)
    valid = speed > STOPPED_SPEED
    u = velocities / np.where(valid, speed, 1.0)[..., None]
    n = np.stack([-u[..., 1], u[..., 0]], axis=-1)
    r = np.broadcast_to(radii, speed.shape)[..., None]
    base = positions + (r * u if anchor == "front" else 0.0)
    tip = base + tau * velocities
    corners = np.stack([base + r * n, base - r * n, tip - r * n, tip + r * n], axis=-2)
    return corners, valid


def _edge_axes(corners: np.ndarray) -> np.ndarray:
    """Unit normals of two adjacent edges of rectangles (..., 4, 2) -> (..., 2, 2)."""
    edges = np.stack([corners[..., 1, :] - corners[..., 0, :], corners[..., 2, :] - corners[..., 1, :]], -2)
    length = np.linalg.norm(edges, axis=-1, keepdims=True)
    return edges / np.where(length > 0, length, 1.0)


def rectangles_intersect(a: np.ndarray, b: np.ndarray, tol: float = TOUCH_TOL) -> np.ndarray:
    """Closed overlap test of convex quadrilaterals by the separating-axis theorem.

    Two convex polygons are disjoint iff their projections onto some edge normal are disjoint;
    touching (gap ≤ ``tol``) counts as intersecting, as the spec requires.

    Args:
        a: Corners [m], shape (..., 4, 2).
        b: Corners [m], shape broadcastable with ``a``.
        tol: Slack [m].

    Returns:
        Shape (...,) bool.
    """
    a, b = np.broadcast_arrays(a, b)
    axes = np.concatenate([_edge_axes(a), _edge_axes(b)], axis=-2)  # (..., 4, 2)
    pa = np.einsum("...ad,...cd->...ac", axes, a)  # projections (..., axis, corner)
    pb = np.einsum("...ad,...cd->...ac", axes, b)
    separated = (pa.max(-1) < pb.min(-1) - tol) | (pb.max(-1) < pa.min(-1) - tol)
    return ~separated.any(-1)


def rectangle_overlap_flags(pos_a: np.ndarray, vel_a: np.ndarray, r_a: np.ndarray, pos_b: np.ndarray,
                            vel_b: np.ndarray, r_b: np.ndarray, tau: float, anchor: str = "rear",
                            tol: float = TOUCH_TOL) -> np.ndarray:
    """Closed overlap of velocity rectangles, by the separating-axis theorem in closed form.

    Same answer as building the corners with :func:`velocity_rectangles` and testing them with
    :func:`rectangles_intersect` (a test checks this), but for rectangles the projection of B onto an
    axis e is its centre's projection ± ((L_b/2)|u_b·e| + r_b|n_b·e|), so the four axes cost a few
    products instead of corner arrays. Stopped agents (|v| ≤ 1e-6 m/s) have no rectangle: False.

    Args:
        pos_a: (..., 2) positions [m] of the first agents.
        vel_a: (..., 2) velocities [m/s] of the first agents.
        r_a: (...) radii [m] (broadcastable).
        pos_b: (..., 2) positions [m] of the second agents, broadcastable with the first.
        vel_b: (..., 2) velocities [m/s] of the second agents.
        r_b: (...) radii [m] of the second agents.
        tau: Time horizon τ [s]; the rectangle's length is τ·|v|.
        anchor: "rear" (rear edge on the centre) or "front" (rear edge at p + r·v/|v|).
        tol: Touching slack [m]: a gap ≤ tol counts as intersecting.

    Returns:
        (...) bool.
    """
    if anchor not in ("rear", "front"):
        raise ValueError(f"anchor must be 'rear' or 'front', got {anchor!r}")
    return _frames_overlap(_motion_frame(pos_a, vel_a), np.asarray(r_a, dtype=float),
                           _motion_frame(pos_b, vel_b), np.asarray(r_b, dtype=float), tau, anchor, tol)


def _motion_frame(p: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, ...]:
    """(x, y, u_x, u_y, |v|, moving) of agents: what a velocity rectangle needs besides τ and r."""
    speed = np.sqrt(v[..., 0] ** 2 + v[..., 1] ** 2)
    valid = speed > STOPPED_SPEED
    safe = np.where(valid, speed, 1.0)
    return p[..., 0], p[..., 1], v[..., 0] / safe, v[..., 1] / safe, speed, valid


def _frames_overlap(fa: tuple[np.ndarray, ...], ra: np.ndarray, fb: tuple[np.ndarray, ...], rb: np.ndarray,
                    tau: float, anchor: str, tol: float) -> np.ndarray:
    """The separating-axis test of :func:`rectangle_overlap_flags` on precomputed motion frames."""
    def centre(f, r):
        px, py, ux, uy, speed, _ = f
        half = 0.5 * tau * speed
        offset = half + (r if anchor == "front" else 0.0)  # rear edge -> centre along u
        return px + offset * ux, py + offset * uy, half

    ax, ay, ah = centre(fa, ra)
    bx, by, bh = centre(fb, rb)
    aux, auy, a_ok = fa[2], fa[3], fa[5]
    bux, buy, b_ok = fb[2], fb[3], fb[5]
    dx, dy = bx - ax, by - ay
    c = np.abs(aux * bux + auy * buy)  # |u_a·u_b| = |n_a·n_b|
    s = np.abs(aux * buy - auy * bux)  # |u_a·n_b| = |n_a·u_b|
    # Axis u_a, n_a, u_b, n_b (n = u rotated by +90°).
    sep = np.abs(dx * aux + dy * auy) > ah + bh * c + rb * s + tol
    sep |= np.abs(-dx * auy + dy * aux) > ra + bh * s + rb * c + tol
    sep |= np.abs(dx * bux + dy * buy) > bh + ah * c + ra * s + tol
    sep |= np.abs(-dx * buy + dy * bux) > rb + ah * s + ra * c + tol
    return ~sep & a_ok & b_ok


def projected_path_flags(traj: Trajectory, tau: float = 1.0, anchor: str = "rear") -> np.ndarray:
    """Samples k = 1..K where the robot's velocity rectangle intersects any human's.

    Velocities are the executed ones, v_k = (p_k − p_{k−1})/dt (Wang et al., ARSO 2022,
    arXiv 2202.01045, definition of M_II; rectangle after Jin et al., ICRA 2020).

    Returns:
        Flags, shape (K,) bool.
    """
    if traj.n_humans == 0:
        return np.zeros(traj.n_steps, dtype=bool)
    if anchor not in ("rear", "front"):
        raise ValueError(f"anchor must be 'rear' or 'front', got {anchor!r}")
    # The frames do not depend on tau: computed once for the three default settings.
    px, py, ux, uy, speed, valid = traj.derived(
        "m2_motion_frame", lambda: np.stack(_motion_frame(traj.positions[1:], traj.executed_velocities())))
    robot = (px[:, :1], py[:, :1], ux[:, :1], uy[:, :1], speed[:, :1], valid[:, :1] > 0)
    humans = (px[:, 1:], py[:, 1:], ux[:, 1:], uy[:, 1:], speed[:, 1:], valid[:, 1:] > 0)
    hit = _frames_overlap(robot, traj.radii[0], humans, traj.radii[1:], tau, anchor, TOUCH_TOL)  # (K, H)
    return hit.any(axis=1)


@register_metric(
    "m2_projected_path", unit="s", direction="lower", outputs=_INDICATOR,
    parameters={"tau": 1.0, "anchor": "rear"}, variants=({"tau": 0.5}, {"tau": 1.0}, {"tau": 2.0}),
    social=True, reference=WANG2022 + ", definition of M_II, Table II; " + JIN2020,
    positive_parameters=("tau",),
)
def projected_path(traj: Trajectory, tau: float = 1.0, anchor: str = "rear") -> dict[str, float]:
    """M_II projected-path intrusion: robot and human velocity rectangles overlap.

    Wang et al., ARSO 2022 (arXiv 2202.01045), definition of M_II; the rectangle of length τ·|v|
    follows the speed-dependent social zone of Jin et al., ICRA 2020. τ = 1 s by default, reported at
    0.5, 1 and 2 s as a sensitivity check.

    Args:
        traj: The episode.
        tau: Horizon τ [s].
        anchor: "rear" (rear edge at the agent's centre, default) or "front" (at the body's front).

    Returns:
        ``count`` [samples], ``fraction`` [1], ``duration_s`` [s].
    """
    return indicator_outputs(projected_path_flags(traj, tau, anchor), traj.dt)


# ----------------------------------------------------------------------------------------- M_III
def first_arrival_steps(traj: Trajectory) -> np.ndarray:
    """First sample index at which each agent is within its radius of its reset goal.

    Searches the episode's samples 0..K, then the continuation samples K+1..K+M. Arrival is
    |p − g| < r, as CrowdSim's ``reached_destination``.

    Returns:
        Step indices, shape (A,) float; NaN for agents that never arrive in the data.
    """
    pos = traj.positions
    if traj.continuation is not None:
        pos = np.concatenate([pos, traj.continuation])
    inside = np.linalg.norm(pos - traj.goals, axis=-1) < traj.radii  # (K+M+1, A)
    first = np.argmax(inside, axis=0).astype(float)
    first[~inside.any(axis=0)] = np.nan
    return first


def entry_steps(traj: Trajectory) -> np.ndarray:
    """First sample at which each agent is present, shape (A,) float (0 without a mask; NaN if never)."""
    if traj.present is None:
        return np.zeros(traj.n_agents)
    first = np.argmax(traj.present, axis=0).astype(float)
    first[~traj.present.any(axis=0)] = np.nan
    return first


@register_metric(
    "m3_aggregated_time", unit="s", direction="lower",
    outputs={"time_s": "s", "steps": "steps", "censored": "count", "unresolved": "count"},
    parameters={"cap_s": 100.0}, social=True, reference=WANG2022 + ", definition of M_III, Table II",
    positive_parameters=("cap_s",),
)
def aggregated_time(traj: Trajectory, cap_s: float = 100.0) -> dict[str, float]:
    """M_III aggregated time: robot's navigation time plus each human's first arrival at its goal.

    Wang et al., ARSO 2022 (arXiv 2202.01045), definition of M_III, measured with a visible robot.
    The robot contributes T = K·dt; each human its first arrival (within its radius) at the goal it had
    at reset, searched through the episode and the ``continuation`` (robot parked where it reached its
    goal). Known arrival times (``traj.arrival_times``, finite entries) replace the detection, for the
    robot too. A human that enters the scene late (presence mask) contributes its arrival minus its entry, the
    time it took. Times above ``cap_s`` count as the cap and are ``censored`` (the robot's too); a
    human that has not arrived when the data reach the cap is censored (counted as the cap). A human
    that has not arrived when the data end *before* the cap is ``unresolved`` and makes the sums NaN,
    since its time is unknown.

    Args:
        traj: A successful episode.
        cap_s: Cap [s].

    Returns:
        ``time_s`` [s], ``steps`` (the same sum in steps; the paper's values read as steps),
        ``censored`` (robot and humans) and ``unresolved`` human counts.
    """
    cap_steps = cap_s / traj.dt
    first = first_arrival_steps(traj)
    first[0] = traj.n_steps  # the robot's time is its episode, successful by contract
    entry = entry_steps(traj)
    known = np.full(traj.n_agents, np.nan) if traj.arrival_times is None else traj.arrival_times / traj.dt
    # Known arrivals are times since sample 0, as detected ones are samples: both less the entry.
    early = np.isfinite(known) & (known < entry - 1e-9)
    if early.any():
        a = int(np.flatnonzero(early)[0])
        raise ValueError(f"M_III: agent {a} arrives at {known[a] * traj.dt:g} s, before it enters the "
                         f"data at {entry[a] * traj.dt:g} s (arrival times are seconds since sample 0)")
    took = np.where(np.isfinite(known), known, first) - entry  # steps from entry to arrival
    last_step = traj.n_steps + (0 if traj.continuation is None else traj.continuation.shape[0])
    arrived = ~np.isnan(took)
    late = arrived & (took > cap_steps + 1e-9)
    observed = last_step - np.nan_to_num(entry, nan=last_step)  # steps of data after each entry
    ghost = np.isnan(entry)  # never present in the data: not part of the scene
    never = ~arrived & ~ghost & (observed * traj.dt >= cap_s - 1e-9 * traj.dt)
    unresolved = ~arrived & ~never & ~ghost
    steps = np.where(arrived & ~late, took, np.where(ghost, 0.0, cap_steps))
    n_unresolved = int(unresolved.sum())
    total = float("nan") if n_unresolved else float(steps.sum())
    return {
        "time_s": total * traj.dt,
        "steps": total,
        "censored": float(np.count_nonzero(late | never)),
        "unresolved": float(n_unresolved),
    }

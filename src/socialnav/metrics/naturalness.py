"""Naturalness metrics M_IV (squared jerk) and M_V (walking speed).

Wang et al., "Metrics for Evaluating Social Conformity of Crowd Navigation Algorithms", ARSO 2022
(arXiv 2202.01045): the definitions of M_IV and M_V in its metrics section, values in its Table II.
Both are computed from the robot's positions only, so logs without velocities are scored alike.
"""

from __future__ import annotations

import numpy as np

from socialnav.metrics.basic import indicator_outputs
from socialnav.metrics.registry import WANG2022, register_metric
from socialnav.trajectory import Trajectory

__all__ = [
    "SPEED_TOL",
    "WalkingSpeedWarning",
    "JERK_DIFFERENCES",
    "jerk",
    "jerk_variant",
    "squared_jerk",
    "walking_speed",
    "walking_speed_flags",
    "walking_speed_note",
]

SPEED_TOL = 1e-6
"""Tolerance [m/s] around v_th: speeds computed from positions at exactly v_th land a rounding step
above or below it depending on the heading, so comparisons are made against v_th ± SPEED_TOL."""


class WalkingSpeedWarning(UserWarning):
    """The robot cannot exceed the walking-speed threshold, so M_V is zero by construction.

    Not issued per episode (a protocol would repeat it thousands of times): the protocol's tables state
    it once in their notes, and :func:`socialnav.logs.score_trajectories` warns once per call.
    """


def walking_speed_note(v_pref: float, v_th: float = 1.5) -> str | None:
    """The M_V caveat for a robot with preferred speed ``v_pref``, or None when it does not apply.

    A robot that respects v_pref ≤ v_th never moves strictly faster than v_th, so M_V is 0 by
    construction and M_V≥ (``*_ge`` outputs) is the informative column (spec: warn in that case).
    NaN (unknown v_pref) gives None.
    """
    if not v_pref <= v_th:
        return None
    return (f"robot v_pref {v_pref:g} m/s <= v_th {v_th:g} m/s: M_V (strictly above v_th) is 0 for a robot "
            "that respects v_pref; compare M_V≥ (m5_walking_speed.*_ge) instead")


def jerk(positions: np.ndarray, dt: float) -> np.ndarray:
    """Third finite difference j_k = (p_{k+3} − 3p_{k+2} + 3p_{k+1} − p_k)/dt³, k = 0..N−3.

    Args:
        positions: [m], shape (N+1, 2).
        dt: Step [s].

    Returns:
        Jerk [m/s³], shape (max(N−2, 0), 2).
    """
    p = np.asarray(positions, dtype=np.float64)
    if p.shape[0] < 4:
        return np.zeros((0, 2))
    return (p[3:] - 3.0 * p[2:-1] + 3.0 * p[1:-2] - p[:-3]) / dt**3


JERK_DIFFERENCES = ("forward", "central", "commanded")
"""How M_IV's jerk is discretised (the paper says only that it "is computed in discrete time"):

- ``forward`` (default): third forward differences of the positions, j_k = Δ³p_k / dt^q, k = 0..N−3;
- ``central``: ``np.gradient`` (central differences, first-order one-sided at both ends) applied three
  times to the positions, one value per sample, times dt^(3−q);
- ``commanded``: second forward differences of the commanded velocities u_0..u_N (u_0 the initial
  velocity), j_k = Δ²u_k / dt^(q−1), k = 0..N−2.

q is the ``dt_power`` parameter: 3 is the dimensionally correct jerk [m/s³]; 2 is the variant with one
power of dt fewer that a reader of the paper could also have used (values dt² times the q = 3 M_IV)."""


def jerk_variant(positions: np.ndarray, velocities: np.ndarray | None, dt: float,
                 difference: str = "forward", dt_power: int = 3) -> np.ndarray:
    """Jerk samples of one agent under one discretisation (see :data:`JERK_DIFFERENCES`).

    Args:
        positions: [m], shape (N+1, 2).
        velocities: Commanded velocities u_0..u_N [m/s], shape (N+1, 2); only read by ``commanded``.
        dt: Step [s].
        difference: One of :data:`JERK_DIFFERENCES`.
        dt_power: 3 (jerk in m/s³) or 2.

    Returns:
        Shape (M, 2): M = N−2 (forward), N+1 (central), N−1 (commanded); (0, 2) when N < 3.

    Raises:
        ValueError: Unknown ``difference`` or ``dt_power`` not 2 or 3.
    """
    if difference not in JERK_DIFFERENCES:
        raise ValueError(f"m4_jerk: difference must be one of {JERK_DIFFERENCES}, got {difference!r}")
    if dt_power not in (2, 3) or isinstance(dt_power, bool):
        raise ValueError(f"m4_jerk: dt_power must be 2 or 3, got {dt_power!r}")
    p = np.asarray(positions, dtype=np.float64)
    if p.shape[0] < 4:
        return np.zeros((0, 2))
    scale = dt ** (3 - dt_power)  # 1 for dt³; dt for dt² (one power of dt fewer in the denominator)
    if difference == "forward":
        return jerk(p, dt) * scale
    if difference == "central":
        j = np.gradient(np.gradient(np.gradient(p, dt, axis=0), dt, axis=0), dt, axis=0)
        return j * scale
    if velocities is None:
        raise ValueError("m4_jerk: difference='commanded' needs the commanded velocities")
    u = np.asarray(velocities, dtype=np.float64)
    return (u[2:] - 2.0 * u[1:-1] + u[:-2]) / dt**2 * scale


@register_metric(
    "m4_jerk", unit="(m/s^3)^2", direction="lower",
    outputs={"mean_sq": "(m/s^3)^2", "integral": "m^2/s^5"}, social=True,
    parameters={"difference": "forward", "dt_power": 3}, quiet_parameters=("difference", "dt_power"),
    reference=WANG2022 + ", definition of M_IV, Table II",
)
def squared_jerk(traj: Trajectory, difference: str = "forward", dt_power: int = 3) -> dict[str, float]:
    """M_IV squared jerk of the robot's path.

    Wang et al., ARSO 2022 (arXiv 2202.01045), definition of M_IV: the mean of |j_k|² over the
    jerk samples of the robot (by default the third forward differences of its positions, k = 0..N−3;
    :data:`JERK_DIFFERENCES` lists the other discretisations, chosen with ``difference`` and
    ``dt_power``). Also reports the integral Σ|j_k|²·dt. Both NaN when N < 3.

    Returns:
        ``mean_sq`` [(m/s³)²] and ``integral`` [(m/s³)²·s] (other units when ``dt_power`` is 2).
    """
    if traj.n_steps < 3:
        return {"mean_sq": float("nan"), "integral": float("nan")}
    commanded = traj.velocities[:, 0] if difference == "commanded" else None
    sq = np.sum(jerk_variant(traj.positions[:, 0], commanded, traj.dt, difference, dt_power) ** 2, axis=-1)
    return {"mean_sq": float(sq.mean()), "integral": float(sq.sum() * traj.dt)}


def walking_speed_flags(traj: Trajectory, v_th: float = 1.5) -> tuple[np.ndarray, np.ndarray]:
    """Samples k = 1..K where the robot's executed speed exceeds (reaches) v_th.

    Wang et al., ARSO 2022 (arXiv 2202.01045), definition of M_V, with the rounding tolerance of
    ``docs/metrics.md``.

    Returns:
        (above, at_or_above), each shape (K,) bool: |v_k| > v_th + 1e-6 and |v_k| ≥ v_th − 1e-6.
    """
    speed = np.linalg.norm(traj.executed_velocities()[:, 0], axis=-1)
    return speed > v_th + SPEED_TOL, speed >= v_th - SPEED_TOL


@register_metric(
    "m5_walking_speed", unit="s", direction="lower",
    outputs={"count": "samples", "fraction": "1", "duration_s": "s",
             "count_ge": "samples", "fraction_ge": "1", "duration_s_ge": "s"},
    parameters={"v_th": 1.5}, social=True, reference=WANG2022 + ", definition of M_V, Table II",
)
def walking_speed(traj: Trajectory, v_th: float = 1.5) -> dict[str, float]:
    """M_V: time the robot moves faster than human walking speed v_th.

    Wang et al., ARSO 2022 (arXiv 2202.01045), definition of M_V. ``count``/``fraction``/
    ``duration_s`` flag |v_k| > v_th + 1e-6 (strictly above); the ``*_ge`` outputs flag
    |v_k| ≥ v_th − 1e-6 (``M_V≥``, at or above), the column comparable with the paper's values for
    a robot whose v_pref equals v_th.

    When the robot's v_pref ≤ v_th the strict M_V is 0 by construction; that caveat is stated once
    per table or scoring call (:func:`walking_speed_note`), not per episode.

    Returns:
        Indicator outputs for both comparisons [samples, 1, s].
    """
    above, at_or_above = walking_speed_flags(traj, v_th)
    out = indicator_outputs(above, traj.dt)
    out.update({f"{k}_ge": v for k, v in indicator_outputs(at_or_above, traj.dt).items()})
    return out

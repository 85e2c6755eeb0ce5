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
    "jerk",
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


@register_metric(
    "m4_jerk", unit="(m/s^3)^2", direction="lower",
    outputs={"mean_sq": "(m/s^3)^2", "integral": "m^2/s^5"}, social=True,
    reference=WANG2022 + ", definition of M_IV, Table II",
)
def squared_jerk(traj: Trajectory) -> dict[str, float]:
    """M_IV squared jerk of the robot's path.

    Wang et al., ARSO 2022 (arXiv 2202.01045), definition of M_IV: the mean of |j_k|² over
    k = 0..N−3 with j_k the third finite difference of the robot's positions (see :func:`jerk`).
    Also reports the integral Σ|j_k|²·dt. Both NaN when N < 3.

    Returns:
        ``mean_sq`` [(m/s³)²] and ``integral`` [(m/s³)²·s].
    """
    if traj.n_steps < 3:
        return {"mean_sq": float("nan"), "integral": float("nan")}
    sq = np.sum(jerk(traj.positions[:, 0], traj.dt) ** 2, axis=-1)
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

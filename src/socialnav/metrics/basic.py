"""Basic navigation metrics: outcome indicators, time, path length, clearance, discomfort, overlaps.

These are the CrowdNav-style numbers reported beside the social metrics (Wang et al., ARSO 2022,
arXiv 2202.01045, basic metrics and Tables I/II: success, collision and timeout rates and navigation time).
They are computed on every episode; rates come from averaging the 0/1 indicators over episodes.

Geometry helpers used by the other metric modules live here too.
"""

from __future__ import annotations

import numpy as np

from socialnav.metrics.registry import WANG2022, register_metric
from socialnav.trajectory import Trajectory

DISTANCE_TOL = 1e-9
"""Slack [m] below a distance threshold before a sample is flagged (M_I, discomfort): a clearance of
exactly ε is not a violation, also when its floating-point value lands a rounding below ε
(1.2 − 0.5 − 0.5 is 0.19999999999999996)."""

__all__ = [
    "collision",
    "discomfort",
    "human_overlaps",
    "indicator_outputs",
    "min_clearance",
    "min_over_humans",
    "n_humans",
    "navigation_time",
    "path_length",
    "robot_human_distance",
    "success",
    "timeout",
]

_OUTCOME_REF = WANG2022 + ", basic metrics, Tables I and II (success, collision, timeout rates)"


def robot_human_distance(traj: Trajectory, distance: str = "clearance") -> np.ndarray:
    """Robot–human distance at samples k = 1..K (+inf where the human is absent).

    Args:
        traj: The episode.
        distance: "clearance" (|p^h − p^r| − r_h − r_r) or "centre" (|p^h − p^r|).

    Returns:
        [m], shape (K, H) with H = number of humans (H = 0 gives shape (K, 0)); read-only, computed
        once per trajectory and setting.
    """
    if distance not in ("clearance", "centre"):
        raise ValueError(f"distance must be 'clearance' or 'centre', got {distance!r}")
    return traj.derived(f"robot_human_distance:{distance}", lambda: _robot_human_distance(traj, distance))


def _robot_human_distance(traj: Trajectory, distance: str) -> np.ndarray:
    pos = traj.positions[1:]
    d = np.linalg.norm(pos[:, 1:] - pos[:, :1], axis=-1)
    if distance == "clearance":
        d = d - traj.radii[1:] - traj.radii[0]
    if traj.present is not None:
        d = np.where(traj.present[1:, 1:], d, np.inf)  # an absent human is infinitely far
    return d


def min_over_humans(d: np.ndarray) -> np.ndarray:
    """Minimum over the human axis of a (K, H) array; +inf where there are no humans [same unit]."""
    if d.shape[1] == 0:
        return np.full(d.shape[0], np.inf)
    return d.min(axis=1)


def _outcome_indicator(traj: Trajectory, outcome: str) -> dict[str, float]:
    if traj.outcome == "unknown":
        return {"value": float("nan")}  # a log without outcome must not count as a failure
    return {"value": float(traj.outcome == outcome)}


@register_metric("success", unit="1", direction="higher", outputs={"value": "1"}, reference=_OUTCOME_REF,
                 population="known_outcome")
def success(traj: Trajectory) -> dict[str, float]:
    """Success indicator: 1 when the robot reached its goal, 0 otherwise, NaN when unknown.

    Wang et al., ARSO 2022 (arXiv 2202.01045), Table I/II "Success %": the mean over episodes × 100.
    """
    return _outcome_indicator(traj, "success")


@register_metric("collision", unit="1", direction="lower", outputs={"value": "1"}, reference=_OUTCOME_REF,
                 population="known_outcome")
def collision(traj: Trajectory) -> dict[str, float]:
    """Collision indicator: 1 when the episode ended in a collision, 0 otherwise, NaN when unknown.

    Wang et al., ARSO 2022 (arXiv 2202.01045), Table I/II "Collision %".
    """
    return _outcome_indicator(traj, "collision")


@register_metric("timeout", unit="1", direction="lower", outputs={"value": "1"}, reference=_OUTCOME_REF,
                 population="known_outcome")
def timeout(traj: Trajectory) -> dict[str, float]:
    """Timeout indicator: 1 when the episode hit the time limit, 0 otherwise, NaN when unknown.

    Wang et al., ARSO 2022 (arXiv 2202.01045), Table I/II "Timeout %".
    """
    return _outcome_indicator(traj, "timeout")


@register_metric("navigation_time", unit="s", direction="lower", outputs={"value": "s"},
                 reference=WANG2022 + ", Table I/II 'Nav. time' (successful episodes)", population="success")
def navigation_time(traj: Trajectory) -> dict[str, float]:
    """Navigation time T = K·dt [s] of a successful episode; NaN unless the outcome is success.

    Wang et al., ARSO 2022 (arXiv 2202.01045), Table I/II "Nav. time (s)", averaged over successes.
    """
    return {"value": traj.duration if traj.outcome == "success" else float("nan")}


@register_metric("path_length", unit="m", direction="lower", outputs={"value": "m"},
                 reference="Common extra; not in " + WANG2022)
def path_length(traj: Trajectory) -> dict[str, float]:
    """Robot path length Σ_k |p_k − p_{k−1}| [m] over k = 1..K.

    Not one of Wang et al.'s (ARSO 2022, arXiv 2202.01045) metrics; recorded as a cheap, widely used
    efficiency measure (spec "Basic: also recorded").
    """
    steps = np.diff(traj.positions[:, 0], axis=0)
    return {"value": float(np.linalg.norm(steps, axis=-1).sum())}


def _clearance_per_step(traj: Trajectory) -> np.ndarray:
    """Robot's clearance per step k = 1..K [m], shape (K,): the simulator's swept value if given."""
    sampled = min_over_humans(robot_human_distance(traj, "clearance"))
    if traj.min_clearance is not None:
        # the swept minimum inside a step can only be smaller than the end-of-step sample
        return np.minimum(traj.min_clearance, sampled)
    return sampled


@register_metric("min_clearance", unit="m", direction="higher", outputs={"value": "m"},
                 reference="CrowdNav (Chen et al., ICRA 2019) 'min dist'; used beside " + WANG2022)
def min_clearance(traj: Trajectory) -> dict[str, float]:
    """Minimum robot–human clearance |p^h − p^r| − r_h − r_r [m] over steps 1..K.

    Uses the simulator's swept per-step minimum when the trajectory carries it, otherwise the
    samples. NaN without humans or steps. Companion of Wang et al., ARSO 2022 (arXiv 2202.01045),
    definition of M_I, which thresholds the same clearance.
    """
    c = _clearance_per_step(traj)
    if c.size == 0 or not np.isfinite(c).any():
        return {"value": float("nan")}
    return {"value": float(c.min())}


@register_metric("discomfort", unit="1/step", direction="lower",
                 outputs={"count": "steps", "per_step": "1/step", "per_s": "1/s"},
                 parameters={"threshold": 0.2},
                 reference="CrowdNav discomfort frequency (Chen et al., ICRA 2019); cf. " + WANG2022
                 + ", definition of M_I")
def discomfort(traj: Trajectory, threshold: float = 0.2) -> dict[str, float]:
    """Discomfort frequency: steps whose clearance is below ``threshold`` [m].

    Returns ``count`` [steps], ``per_step`` = count/K and ``per_s`` = count/T [1/s]. Uses the swept
    per-step clearance when available (CrowdSim's definition), else the samples. Related to M_I of
    Wang et al., ARSO 2022 (arXiv 2202.01045), definition of M_I, which uses samples only.
    """
    c = _clearance_per_step(traj)
    count = float(np.count_nonzero(c < threshold - DISTANCE_TOL))
    k = traj.n_steps
    if k == 0:
        return {"count": 0.0, "per_step": float("nan"), "per_s": float("nan")}
    return {"count": count, "per_step": count / k, "per_s": count / traj.duration}


def count_human_overlaps(traj: Trajectory) -> int:
    """Number of (sample k = 1..K, human pair) with centre distance < r_i + r_j (both present)."""
    h = traj.positions[1:, 1:]
    if h.shape[1] < 2:
        return 0
    d = np.linalg.norm(h[:, :, None] - h[:, None, :], axis=-1)
    r = traj.radii[1:]
    overlap = d < r[:, None] + r[None, :]
    iu = np.triu_indices(h.shape[1], k=1)
    return int(np.count_nonzero(overlap[:, iu[0], iu[1]]))


@register_metric("human_overlaps", unit="count", direction="none", outputs={"value": "count"},
                 reference="Simulator sanity check; not in " + WANG2022)
def human_overlaps(traj: Trajectory) -> dict[str, float]:
    """Human–human overlap count: the simulator's value if recorded, else counted from samples.

    The fallback counts (sample k = 1..K, pair) with centre distance < r_i + r_j. A sanity check of
    the human model rather than a robot metric (not in Wang et al., ARSO 2022, arXiv 2202.01045).
    """
    if traj.human_overlaps is not None:
        return {"value": float(traj.human_overlaps)}
    return {"value": float(count_human_overlaps(traj))}


@register_metric("n_humans", unit="count", direction="none", outputs={"value": "count"},
                 reference="Scene description; not in " + WANG2022)
def n_humans(traj: Trajectory) -> dict[str, float]:
    """Number of humans in the episode (present at one sample at least).

    Recorded on every episode so that summaries can tell single-human episodes (M_VI) from others
    without the outcome gating of the social metrics.
    """
    if traj.present is None:
        return {"value": float(traj.n_humans)}
    return {"value": float(np.count_nonzero(traj.present[:, 1:].any(axis=0)))}


def indicator_outputs(flags: np.ndarray, dt: float) -> dict[str, float]:
    """Summarise per-sample flags of an indicator metric (M_I, M_II, M_V).

    Args:
        flags: Flags for samples k = 1..K, shape (K,) bool.
        dt: Step [s].

    Returns:
        ``count`` [samples], ``fraction`` = count/K (Wang et al.'s 1/T·Σ, NaN when K = 0) and
        ``duration_s`` = count·dt [s].
    """
    count = float(np.count_nonzero(flags))
    n = flags.shape[0]
    return {"count": count, "fraction": count / n if n else float("nan"), "duration_s": count * dt}

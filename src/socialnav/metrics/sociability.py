"""Sociability metric M_VI: the side on which the robot passes a single human.

Wang et al., "Metrics for Evaluating Social Conformity of Crowd Navigation Algorithms", ARSO 2022
(arXiv 2202.01045): the definition of M_VI in its metrics section, values in its Table III.

With Δx = p^h_x − p^r_x and Δy = p^r_y − p^h_y (robot travelling +y), the case is labelled at the
first sample where the robot has come level with the human, Δy ≥ −(r_h + r_r), by the sign of Δx
there: Δx > 0 means the robot passes the human on the robot's own left, Δx < 0 on its right. The paper
prints this trigger with the inequality reversed (it would hold from t = 0); we follow the corrected
spec. If the robot jumps the whole band |Δy| ≤ r_h + r_r in one step, Δx is interpolated linearly to
Δy = 0 between the two samples.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

import numpy as np

from socialnav.metrics.registry import WANG2022, register_metric
from socialnav.trajectory import Trajectory

__all__ = ["SIDE_WORDING", "side_preference", "side_preference_sign", "summarize_side_preference"]

SIDE_WORDING: dict[str, dict[str, str]] = {"crossing": {"left": "behind", "right": "front"}}
"""Scenario-specific wording: in ``crossing`` passing on the left means passing behind the human."""


def _travel_frame(traj: Trajectory, frame: str) -> np.ndarray:
    """Positions [m], shape (K+1, A, 2), rotated so that the robot travels +y."""
    if frame == "world":
        return traj.positions
    if frame != "goal":
        raise ValueError(f"frame must be 'world' or 'goal', got {frame!r}")
    heading = traj.goals[0] - traj.positions[0, 0]
    norm = np.linalg.norm(heading)
    if norm == 0.0:
        raise ValueError("frame='goal' needs a robot goal different from its start")
    uy = heading / norm  # new +y axis
    ux = np.array([uy[1], -uy[0]])  # new +x axis, right-handed with uy
    return np.stack([traj.positions @ ux, traj.positions @ uy], axis=-1)


def side_preference(traj: Trajectory, human: int = 1, frame: str = "world") -> str | None:
    """M_VI side label of one episode: "left", "right" or None (never level, or Δx = 0 exactly).

    Wang et al., ARSO 2022 (arXiv 2202.01045), definition of M_VI (trigger inequality corrected, see
    the module docstring). In a collision-free episode the sign of Δx cannot change while
    |Δy| < r_h + r_r, so the label does not depend on where in the band it is read.

    Args:
        traj: The episode (normally a successful single-human one).
        human: Agent index of the human (default the first human).
        frame: "world" (the robot travels +y, as in the paper's scenarios) or "goal" (rotate so that
            the robot's start→goal direction is +y, for logs).

    Returns:
        "left" (Δx > 0), "right" (Δx < 0) or None.
    """
    if not 1 <= human < traj.n_agents:
        raise ValueError(f"human index {human} out of range 1..{traj.n_agents - 1}")
    pos = _travel_frame(traj, frame)
    band = traj.radii[human] + traj.radii[0]
    dx = pos[:, human, 0] - pos[:, 0, 0]
    dy = pos[:, 0, 1] - pos[:, human, 1]
    level = np.flatnonzero(dy >= -band)
    if level.size == 0:
        return None
    k = int(level[0])
    x = dx[k]
    if k > 0 and dy[k] > band:
        # the band was jumped in one step: read Δx where the segment crosses Δy = 0
        s = -dy[k - 1] / (dy[k] - dy[k - 1])
        x = dx[k - 1] + s * (dx[k] - dx[k - 1])
    if x > 0:
        return "left"
    if x < 0:
        return "right"
    return None


@register_metric(
    "m6_side_preference", unit="1", direction="none", outputs={"sign": "1"},
    parameters={"frame": "world"}, social=True, reference=WANG2022 + ", definition of M_VI, Table III",
)
def side_preference_sign(traj: Trajectory, frame: str = "world") -> dict[str, float]:
    """M_VI as a number: +1 left, −1 right, 0 unlabelled; NaN unless exactly one human.

    Wang et al., ARSO 2022 (arXiv 2202.01045), definition of M_VI; see :func:`side_preference`.
    Summarise a list of these with :func:`summarize_side_preference`.
    """
    if traj.n_humans != 1:
        return {"sign": float("nan")}
    label = side_preference(traj, 1, frame)
    return {"sign": {"left": 1.0, "right": -1.0, None: 0.0}[label]}


def _normalise(label: Any) -> str:
    if label is None or label == "unlabelled":
        return "unlabelled"
    if isinstance(label, str):
        if label in ("left", "right", "failed"):
            return label
        raise ValueError(f"unknown side label {label!r}")
    value = float(label)
    if math.isnan(value):
        return "failed"
    return "left" if value > 0 else "right" if value < 0 else "unlabelled"


def summarize_side_preference(labels: Iterable[Any], scenario: str | None = None) -> dict[str, float]:
    """Summarise M_VI over the cases of one scenario (Wang et al., ARSO 2022, Table III).

    Args:
        labels: Per case: "left", "right", None/"unlabelled", or "failed" (unsuccessful episode);
            the numeric form of :func:`side_preference_sign` (+1, −1, 0, NaN) is accepted too.
        scenario: Scenario name; for ``crossing`` the behind/front wording is added.

    Returns:
        ``left_pct`` and ``right_pct`` (percent of labelled cases, NaN when none), ``n_labelled``,
        ``n_unlabelled``, ``n_failed``; for crossing also ``behind_pct`` (= left) and ``front_pct``
        (= right).
    """
    names = [_normalise(x) for x in labels]
    n_left, n_right = names.count("left"), names.count("right")
    n_labelled = n_left + n_right
    out = {
        "left_pct": 100.0 * n_left / n_labelled if n_labelled else float("nan"),
        "right_pct": 100.0 * n_right / n_labelled if n_labelled else float("nan"),
        "n_labelled": float(n_labelled),
        "n_unlabelled": float(names.count("unlabelled")),
        "n_failed": float(names.count("failed")),
    }
    for side, word in SIDE_WORDING.get(scenario or "", {}).items():
        out[f"{word}_pct"] = out[f"{side}_pct"]
    return out

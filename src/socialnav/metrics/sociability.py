"""Sociability metric M_VI: the side on which the robot passes a single human.

Wang et al., "Metrics for Evaluating Social Conformity of Crowd Navigation Algorithms", ARSO 2022
(arXiv 2202.01045): the definition of M_VI in its metrics section, values in its Table III.

With Δx = p^h_x − p^r_x and Δy = p^r_y − p^h_y (robot travelling +y), the case is labelled at the
first sample where the robot has come level with the human, Δy ≥ −(r_h + r_r), by the sign of Δx
there: Δx > 0 means the robot passes the human on the robot's own left, Δx < 0 on its right. The paper
prints this trigger with the inequality reversed (it would hold from t = 0); we follow the corrected
spec. If the robot jumps the whole band |Δy| ≤ r_h + r_r in one step, Δx is interpolated linearly to
Δy = 0 between the two samples. A robot already beyond the band (Δy ≥ r_h + r_r) at the first sample
is not labelled: that pass happened before the data, if at all.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np

from socialnav.metrics.registry import WANG2022, register_metric
from socialnav.trajectory import Trajectory

__all__ = [
    "SIDE_CASES",
    "SIDE_WORDING",
    "side_case",
    "side_case_of_row",
    "side_preference",
    "side_preference_sign",
    "summarize_side_preference",
]

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


SIDE_CASES: tuple[str, ...] = ("left", "right", "undetermined", "never_level", "started_past")
"""Outcomes of the M_VI reading of one episode (see :func:`side_case`)."""


def side_case(traj: Trajectory, human: int = 1, frame: str = "world") -> str:
    """M_VI reading of one episode, one of :data:`SIDE_CASES`.

    Wang et al., ARSO 2022 (arXiv 2202.01045), definition of M_VI (trigger inequality corrected, see
    the module docstring). In a collision-free episode the sign of Δx cannot change while
    |Δy| < r_h + r_r, so the label does not depend on where in the band it is read.

    - ``left`` / ``right``: Δx > 0 / Δx < 0 at the first sample with Δy ≥ −(r_h + r_r);
    - ``undetermined``: Δx is exactly 0 there;
    - ``never_level``: no sample has Δy ≥ −(r_h + r_r);
    - ``started_past``: at the first sample where both are present the robot is already beyond the
      band (Δy ≥ r_h + r_r): the pass, if any, happened before the data, so it is not labelled.

    Args:
        traj: The episode (normally a successful single-human one).
        human: Agent index of the human (default the first human).
        frame: "world" (the robot travels +y, as in the paper's scenarios) or "goal" (rotate so that
            the robot's start→goal direction is +y, for logs).
    """
    if not 1 <= human < traj.n_agents:
        raise ValueError(f"human index {human} out of range 1..{traj.n_agents - 1}")
    pos = _travel_frame(traj, frame)
    band = traj.radii[human] + traj.radii[0]
    dx = pos[:, human, 0] - pos[:, 0, 0]
    dy = pos[:, 0, 1] - pos[:, human, 1]
    seen = np.flatnonzero(traj.presence[:, human])
    if seen.size == 0:
        return "never_level"
    if dy[seen[0]] >= band:
        return "started_past"
    with np.errstate(invalid="ignore"):
        level = np.flatnonzero(dy >= -band)  # NaN (human absent) compares False
    if level.size == 0:
        return "never_level"
    k = int(level[0])
    x = dx[k]
    if k > 0 and dy[k] > band and np.isfinite(dy[k - 1]):
        # the band was jumped in one step: read Δx where the segment crosses Δy = 0
        s = -dy[k - 1] / (dy[k] - dy[k - 1])
        x = dx[k - 1] + s * (dx[k] - dx[k - 1])
    if x > 0:
        return "left"
    if x < 0:
        return "right"
    return "undetermined"


def side_preference(traj: Trajectory, human: int = 1, frame: str = "world") -> str | None:
    """M_VI side label of one episode: "left", "right" or None (no label; see :func:`side_case`)."""
    case = side_case(traj, human, frame)
    return case if case in ("left", "right") else None


_LEVEL_CODE = {"left": 1.0, "right": 1.0, "undetermined": 1.0, "never_level": 0.0, "started_past": -1.0}


@register_metric(
    "m6_side_preference", unit="1", direction="none", outputs={"sign": "1", "level": "1"},
    parameters={"frame": "world"}, social=True, reference=WANG2022 + ", definition of M_VI, Table III",
)
def side_preference_sign(traj: Trajectory, frame: str = "world") -> dict[str, float]:
    """M_VI as numbers: ``sign`` +1 left, −1 right, 0 undetermined (Δx = 0), NaN without a reading.

    ``level`` tells the readings apart: 1 the robot came level with the human (``sign`` is set),
    0 it never did, −1 it started already past the human; both NaN unless exactly one human.
    Wang et al., ARSO 2022 (arXiv 2202.01045), definition of M_VI; see :func:`side_case`.
    Summarise score rows with :func:`summarize_side_preference`.
    """
    # the one human present at some sample (an agent absent throughout changes no metric)
    seen = np.flatnonzero(traj.presence[:, 1:].any(axis=0)) + 1
    if seen.size != 1:
        return {"sign": float("nan"), "level": float("nan")}
    case = side_case(traj, int(seen[0]), frame)
    sign = {"left": 1.0, "right": -1.0, "undetermined": 0.0}.get(case, float("nan"))
    return {"sign": sign, "level": _LEVEL_CODE[case]}


_BUCKETS = ("left", "right", "undetermined", "never_level", "started_past", "failed", "not_applicable",
            "unlabelled")
# "unlabelled" is accepted for result files written before undetermined and never_level were split


def side_case_of_row(row: Mapping[str, Any], frame: str = "world") -> str:
    """The M_VI case of a score row: a :data:`SIDE_CASES` label, ``failed`` or ``not_applicable``."""
    from socialnav.metrics.registry import metric_key

    n_humans = row.get("n_humans")
    if n_humans is not None and float(n_humans) != 1.0:
        return "not_applicable"
    success = row.get("success")
    level = row.get(metric_key("m6_side_preference", "level", {"frame": frame}))
    sign = row.get(metric_key("m6_side_preference", "sign", {"frame": frame}))
    if level is None or sign is None:
        raise KeyError(f"score row has no m6_side_preference keys for frame={frame!r}")
    level, sign = float(level), float(sign)
    if math.isnan(level):
        if success is not None and float(success) == 1.0:
            return "not_applicable"  # a successful episode has a reading unless it has no single human
        return "failed"
    if level == 0.0:
        return "never_level"
    if level < 0.0:
        return "started_past"
    return "left" if sign > 0 else "right" if sign < 0 else "undetermined"


def _normalise(item: Any, frame: str) -> str:
    if isinstance(item, Mapping):
        return side_case_of_row(item, frame)
    if isinstance(item, str):
        if item in _BUCKETS:
            return item
        raise ValueError(f"unknown side label {item!r}; valid: {list(_BUCKETS)}")
    if item is None:
        raise ValueError("side label None is ambiguous (undetermined or never level?); pass side_case() "
                         "labels or score rows")
    value = float(item)
    if math.isnan(value):
        raise ValueError("a NaN M_VI sign is ambiguous (failed episode, no reading, or not exactly one "
                         "human); pass the score rows from score_episode (dicts) or side_case() labels")
    return "left" if value > 0 else "right" if value < 0 else "undetermined"


def summarize_side_preference(
    items: Iterable[Any], scenario: str | None = None, *, frame: str = "world"
) -> dict[str, float]:
    """Summarise M_VI over the cases of one scenario (Wang et al., ARSO 2022, Table III).

    Args:
        items: Per episode one of: a score row (the dict from ``score_episode``; its ``success``,
            ``n_humans`` and ``m6_side_preference`` keys decide the case), a label from
            :data:`SIDE_CASES`, ``"failed"`` (unsuccessful episode) or ``"not_applicable"`` (not a
            single-human episode; excluded), or a finite sign (+1, −1, 0). A NaN sign or None is
            rejected: it cannot tell a failed episode from one without a reading.
        scenario: Scenario name; for ``crossing`` the behind/front wording is added.
        frame: The M_VI frame whose keys are read from score rows.

    Returns:
        ``left_pct`` and ``right_pct`` (percent of labelled cases, NaN when none) and the counts
        ``n_left``, ``n_right``, ``n_labelled`` (= left + right), ``n_undetermined`` (Δx = 0),
        ``n_never_level``, ``n_started_past``, ``n_unlabelled`` (the sum of the three),
        ``n_failed`` and ``n_not_applicable``; for crossing also ``behind_pct`` (= left) and
        ``front_pct`` (= right).
    """
    names = [_normalise(x, frame) for x in items]
    counts = {b: names.count(b) for b in _BUCKETS}
    n_labelled = counts["left"] + counts["right"]
    out = {
        "left_pct": 100.0 * counts["left"] / n_labelled if n_labelled else float("nan"),
        "right_pct": 100.0 * counts["right"] / n_labelled if n_labelled else float("nan"),
        "n_left": float(counts["left"]),
        "n_right": float(counts["right"]),
        "n_labelled": float(n_labelled),
        "n_undetermined": float(counts["undetermined"]),
        "n_never_level": float(counts["never_level"]),
        "n_started_past": float(counts["started_past"]),
        "n_unlabelled": float(counts["undetermined"] + counts["never_level"] + counts["started_past"]
                              + counts["unlabelled"]),
        "n_failed": float(counts["failed"]),
        "n_not_applicable": float(counts["not_applicable"]),
    }
    for side, word in SIDE_WORDING.get(scenario or "", {}).items():
        out[f"{word}_pct"] = out[f"{side}_pct"]
    return out

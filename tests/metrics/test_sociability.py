"""M_VI side preference: labels, mirror symmetry, band interpolation and summaries."""

from __future__ import annotations

import math

import numpy as np
import pytest

from socialnav.metrics import score_episode
from socialnav.metrics.sociability import (
    side_case,
    side_preference,
    side_preference_sign,
    summarize_side_preference,
)
from socialnav.trajectory import Trajectory


def _pair(robot: np.ndarray, human: np.ndarray, **kwargs) -> Trajectory:
    pos = np.stack([robot, human], 1)
    return Trajectory.from_positions(pos, 0.25, radii=0.3, **{"goals": pos[-1], **kwargs})


def _passing(human_x: float) -> Trajectory:
    k = np.arange(41)
    robot = np.stack([0 * k, -5 + 0.25 * k], 1)  # +y at 1 m/s
    human = np.stack([human_x + 0 * k, 5 - 0.25 * k], 1)  # −y at 1 m/s, meeting at y = 0
    return _pair(robot, human, outcome="success")


def test_mirrored_passing_gives_opposite_labels() -> None:
    assert side_preference(_passing(+0.8)) == "left"  # Δx > 0: the robot passes on its own left
    assert side_preference(_passing(-0.8)) == "right"
    assert side_preference_sign(_passing(-0.8)) == {"sign": -1.0, "level": 1.0}


def test_label_read_at_first_level_sample() -> None:
    # robot swerves after coming level; the label is fixed where Δy first reaches −(r_h + r_r)
    robot = np.array([[0, -3.0], [0, -1.0], [0, -0.5], [2, 0.0], [2, 1.0]])
    human = np.array([[0.7, 0.0]] * 5)
    assert side_preference(_pair(robot, human)) == "left"


def test_jumped_band_is_interpolated() -> None:
    # band r_h + r_r = 0.6; the robot jumps from Δy = −1 to Δy = 3. At Δy = 0 (s = 1/4):
    # Δx = −1.5 + 0.25·(0.5 − (−1.5)) = −1.0 -> right, although Δx = +0.5 after the jump
    robot = np.array([[1.5, -4.0], [1.5, -1.0], [-0.5, 3.0]])
    human = np.zeros((3, 2))
    assert side_preference(_pair(robot, human)) == "right"
    assert side_preference(_pair(robot * [-1, 1], human)) == "left"  # mirrored x -> −x


def test_never_level_is_unlabelled() -> None:
    k = np.arange(9)
    robot = np.stack([0 * k, -5 + 0.25 * k], 1)  # stops at y = −3
    human = np.tile([0.5, 0.0], (9, 1))
    traj = _pair(robot, human)
    assert side_preference(traj) is None and side_case(traj) == "never_level"
    out = side_preference_sign(traj)
    assert math.isnan(out["sign"]) and out["level"] == 0.0


def test_robot_starting_past_the_human_is_unlabelled() -> None:
    # band r_h + r_r = 0.6; the robot starts at Δy = +1 (already past) and moves away: no pass happened
    k = np.arange(9)
    robot = np.stack([0 * k, 1.0 + 0.25 * k], 1)
    human = np.tile([0.5, 0.0], (9, 1))
    traj = _pair(robot, human)
    assert side_case(traj) == "started_past" and side_preference(traj) is None
    out = side_preference_sign(traj)
    assert math.isnan(out["sign"]) and out["level"] == -1.0
    # exactly at the band edge (Δy = b) counts as past too; just inside (Δy < b) is read there
    assert side_case(_pair(robot - [0, 0.4], human)) == "started_past"
    assert side_case(_pair(robot - [0, 0.41], human)) == "left"


def test_undetermined_when_dx_is_zero() -> None:
    k = np.arange(9)
    robot = np.stack([0 * k, -2.0 + 0.25 * k], 1)
    human = np.tile([0.0, 0.0], (9, 1))  # head-on, Δx = 0 (a collision course; geometry only)
    traj = _pair(robot, human)
    assert side_case(traj) == "undetermined"
    assert side_preference_sign(traj) == {"sign": 0.0, "level": 1.0}


def test_goal_frame_for_logs() -> None:
    k = np.arange(41)
    robot = np.stack([-5 + 0.25 * k, 0 * k], 1)  # travelling +x
    human = np.stack([5 - 0.25 * k, 0 * k + 0.8], 1)  # on the robot's left (+y)
    traj = _pair(robot, human, goals=[[5, 0], [-5, 0.8]])
    assert side_preference(traj, frame="goal") == "right"


def test_sign_nan_without_exactly_one_human() -> None:
    pos = np.zeros((3, 3, 2))
    pos[:, 2, 0] = 5
    traj = Trajectory.from_positions(pos, 0.25, radii=0.3, goals=pos[-1])
    assert math.isnan(side_preference_sign(traj)["sign"])
    with pytest.raises(ValueError, match="human index"):
        side_preference(traj, human=3)


def test_summary_counts_and_crossing_wording() -> None:
    labels = ["left", "right", "right", "never_level", "failed", 1.0, "started_past", 0.0, "not_applicable"]
    out = summarize_side_preference(labels)
    assert out == {"left_pct": 50.0, "right_pct": 50.0, "n_left": 2.0, "n_right": 2.0, "n_labelled": 4.0,
                   "n_undetermined": 1.0, "n_never_level": 1.0, "n_started_past": 1.0, "n_unlabelled": 3.0,
                   "n_failed": 1.0, "n_not_applicable": 1.0}
    with pytest.raises(ValueError, match="ambiguous"):
        summarize_side_preference([1.0, float("nan")])
    with pytest.raises(ValueError, match="ambiguous"):
        summarize_side_preference([None])
    crossing = summarize_side_preference(["left", "right", "right", "right"], scenario="crossing")
    assert crossing["behind_pct"] == crossing["left_pct"] == 25.0
    assert crossing["front_pct"] == crossing["right_pct"] == 75.0
    empty = summarize_side_preference(["failed"])
    assert math.isnan(empty["left_pct"]) and empty["n_failed"] == 1.0
    with pytest.raises(ValueError, match="up"):
        summarize_side_preference(["up"])


def test_summary_from_score_rows_separates_failures_and_multi_human() -> None:
    # the docs' usage: score rows of a mixed log. A multi-human success is not applicable (was: failed)
    left = _passing(+0.8)
    failed = _pair(left.positions[:, 0], left.positions[:, 1], outcome="collision")
    three = np.concatenate([left.positions, left.positions[:, 1:] + [3.0, 0.0]], axis=1)
    multi = Trajectory.from_positions(three, 0.25, radii=0.3, goals=three[-1], outcome="success")
    never = _pair(left.positions[:9, 0], left.positions[:9, 1], outcome="success")
    rows = [score_episode(t) for t in (left, failed, multi, never, _passing(-0.8))]
    out = summarize_side_preference(rows)
    assert (out["n_left"], out["n_right"], out["n_failed"]) == (1.0, 1.0, 1.0)
    assert (out["n_not_applicable"], out["n_never_level"], out["n_undetermined"]) == (1.0, 1.0, 0.0)
    assert out["left_pct"] == 50.0


def test_a_human_absent_throughout_leaves_m6_unchanged() -> None:
    one = _passing(-0.8)
    pos = np.concatenate([one.positions, np.full((one.positions.shape[0], 1, 2), 9.0)], axis=1)
    present = np.ones(pos.shape[:2], dtype=bool)
    present[:, 2] = False  # a second human slot, never present (e.g. a padded log)
    two = Trajectory.from_positions(pos, 0.25, radii=0.3, goals=pos[-1], outcome="success", present=present)
    assert side_preference_sign(two) == side_preference_sign(one) == {"sign": -1.0, "level": 1.0}
    assert score_episode(two)["n_humans"] == 1

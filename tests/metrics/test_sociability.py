"""M_VI side preference: labels, mirror symmetry, band interpolation and summaries."""

from __future__ import annotations

import math

import numpy as np
import pytest

from socialnav.metrics.sociability import side_preference, side_preference_sign, summarize_side_preference
from socialnav.trajectory import Trajectory


def _pair(robot: np.ndarray, human: np.ndarray, **kwargs) -> Trajectory:
    return Trajectory.from_positions(np.stack([robot, human], 1), 0.25, radii=0.3, **kwargs)


def _passing(human_x: float) -> Trajectory:
    k = np.arange(41)
    robot = np.stack([0 * k, -5 + 0.25 * k], 1)  # +y at 1 m/s
    human = np.stack([human_x + 0 * k, 5 - 0.25 * k], 1)  # −y at 1 m/s, meeting at y = 0
    return _pair(robot, human, outcome="success")


def test_mirrored_passing_gives_opposite_labels() -> None:
    assert side_preference(_passing(+0.8)) == "left"  # Δx > 0: the robot passes on its own left
    assert side_preference(_passing(-0.8)) == "right"
    assert side_preference_sign(_passing(-0.8)) == {"sign": -1.0}


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
    assert side_preference(traj) is None
    assert side_preference_sign(traj) == {"sign": 0.0}


def test_goal_frame_for_logs() -> None:
    k = np.arange(41)
    robot = np.stack([-5 + 0.25 * k, 0 * k], 1)  # travelling +x
    human = np.stack([5 - 0.25 * k, 0 * k + 0.8], 1)  # on the robot's left (+y)
    traj = _pair(robot, human, goals=[[5, 0], [-5, 0.8]])
    assert side_preference(traj, frame="goal") == "right"


def test_sign_nan_without_exactly_one_human() -> None:
    pos = np.zeros((3, 3, 2))
    pos[:, 2, 0] = 5
    traj = Trajectory.from_positions(pos, 0.25)
    assert math.isnan(side_preference_sign(traj)["sign"])
    with pytest.raises(ValueError, match="human index"):
        side_preference(traj, human=3)


def test_summary_counts_and_crossing_wording() -> None:
    labels = ["left", "right", "right", None, "failed", 1.0, float("nan"), 0.0]
    out = summarize_side_preference(labels)
    assert out == {"left_pct": 50.0, "right_pct": 50.0, "n_labelled": 4.0, "n_unlabelled": 2.0,
                   "n_failed": 2.0}
    crossing = summarize_side_preference(["left", "right", "right", "right"], scenario="crossing")
    assert crossing["behind_pct"] == crossing["left_pct"] == 25.0
    assert crossing["front_pct"] == crossing["right_pct"] == 75.0
    empty = summarize_side_preference(["failed"])
    assert math.isnan(empty["left_pct"]) and empty["n_failed"] == 1.0
    with pytest.raises(ValueError, match="up"):
        summarize_side_preference(["up"])

"""Basic metrics on hand-built episodes with answers computed by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from socialnav.metrics import basic
from socialnav.trajectory import Trajectory


def _traj(robot: list, humans: list | None = None, dt: float = 0.25, **kwargs) -> Trajectory:
    """Robot path (K+1, 2) and humans (H, K+1, 2) -> Trajectory with radii 0.3."""
    agents = [np.asarray(robot, float)] + [np.asarray(h, float) for h in humans or []]
    pos = np.stack(agents, axis=1)
    return Trajectory.from_positions(pos, dt, radii=0.3, **{"goals": pos[-1], **kwargs})


@pytest.mark.parametrize(
    ("outcome", "expected"),
    [("success", (1, 0, 0)), ("collision", (0, 1, 0)), ("timeout", (0, 0, 1))],
)
def test_outcome_indicators(outcome: str, expected: tuple[int, int, int]) -> None:
    traj = _traj([[0, 0], [1, 0]], outcome=outcome)
    got = (basic.success(traj)["value"], basic.collision(traj)["value"], basic.timeout(traj)["value"])
    assert got == expected


def test_unknown_outcome_gives_nan_indicators() -> None:
    traj = _traj([[0, 0], [1, 0]])
    assert math.isnan(basic.success(traj)["value"]) and math.isnan(basic.collision(traj)["value"])


def test_navigation_time_only_on_success() -> None:
    path = [[0, 0.5 * k] for k in range(9)]  # K = 8, dt = 0.25 -> T = 2 s
    assert basic.navigation_time(_traj(path, outcome="success"))["value"] == 2.0
    assert math.isnan(basic.navigation_time(_traj(path, outcome="timeout"))["value"])


def test_path_length() -> None:
    assert basic.path_length(_traj([[0, 0], [3, 0], [3, 4]]))["value"] == 7.0


def test_min_clearance_samples_and_swept() -> None:
    robot = [[0, 0]] * 3
    human = [[0.61, 0], [0.8, 0], [2.0, 0]]  # sample 0 (clearance 0.01) is the initial state: ignored
    assert basic.min_clearance(_traj(robot, [human]))["value"] == pytest.approx(0.2)
    swept = _traj(robot, [human], min_clearance=[0.1, 1.5])
    assert basic.min_clearance(swept)["value"] == pytest.approx(0.1)
    assert math.isnan(basic.min_clearance(_traj(robot))["value"])


def test_discomfort_count_per_step_per_second() -> None:
    # clearance = centre distance - 0.6; below 0.2 m when the centre distance is 0.7 (k = 2, 5, 6)
    centre = [2.0, 2.0, 0.7, 2.0, 2.0, 0.7, 0.7, 2.0]
    traj = _traj([[0, 0]] * 8, [[[d, 0] for d in centre]], dt=0.5)
    out = basic.discomfort(traj)
    assert out == {"count": 3.0, "per_step": 3 / 7, "per_s": 3 / 3.5}
    assert basic.discomfort(traj, threshold=1.5)["count"] == 7.0


def test_human_overlaps_field_and_fallback() -> None:
    robot = [[0, 0]] * 3
    h1 = [[5, 0]] * 3
    h2 = [[5.5, 0], [5.5, 0], [9, 0]]  # overlaps h1 (0.5 < 0.6) at samples 0 and 1; sample 0 ignored
    h3 = [[5, 0.59]] * 3  # overlaps h1 at samples 1 and 2; never h2 (|(0.5, 0.59)| = 0.77 > 0.6)
    traj = _traj(robot, [h1, h2, h3])
    assert basic.count_human_overlaps(traj) == 1 + 2
    assert basic.human_overlaps(traj)["value"] == 3.0
    assert basic.human_overlaps(_traj(robot, [h1, h2], human_overlaps=7))["value"] == 7.0


def test_indicator_outputs() -> None:
    flags = np.array([True, False, True, True])
    assert basic.indicator_outputs(flags, 0.25) == {"count": 3.0, "fraction": 0.75, "duration_s": 0.75}
    out = basic.indicator_outputs(np.zeros(0, bool), 0.25)
    assert out["count"] == 0.0 and math.isnan(out["fraction"])

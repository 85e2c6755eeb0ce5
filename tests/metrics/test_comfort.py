"""M_I, M_II and M_III on hand-built episodes with answers computed by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from socialnav.metrics import comfort
from socialnav.trajectory import Trajectory


def _traj(agents: list, dt: float = 0.25, radii: float | list = 0.3, **kwargs) -> Trajectory:
    pos = np.stack([np.asarray(a, float) for a in agents], 1)
    return Trajectory.from_positions(pos, dt, radii=radii, **{"goals": pos[-1], **kwargs})


def _square(x0: float, y0: float, side: float = 1.0) -> np.ndarray:
    return np.array([[x0, y0], [x0 + side, y0], [x0 + side, y0 + side], [x0, y0 + side]])


# ----------------------------------------------------------------------------------------- M_I
def test_m1_counts_exactly_k_samples() -> None:
    # clearance = centre distance − 0.6: below ε = 0.2 at the 3 samples k = 3, 4, 5 (K = 10)
    centre = [0.7, 2, 2, 0.7, 0.7, 0.7, 2, 2, 2, 2, 2]  # sample 0 is the initial state: not counted
    traj = _traj([[[0, 0]] * 11, [[d, 0] for d in centre]])
    assert comfort.personal_space(traj, eps=0.2) == {"count": 3.0, "fraction": 0.3, "duration_s": 0.75}
    assert comfort.personal_space(traj, eps=1.2)["count"] == 3.0  # 2 − 0.6 = 1.4 ≥ 1.2
    assert comfort.personal_space(traj, eps=1.5)["count"] == 10.0
    assert comfort.personal_space(traj, eps=0.2, distance="centre")["count"] == 0.0
    assert comfort.personal_space(traj, eps=0.8, distance="centre")["count"] == 3.0


def test_m1_uses_nearest_human_and_strict_threshold() -> None:
    robot = [[0, 0]] * 3
    far = [[5, 0]] * 3
    near = [[0, 0.8], [0, 0.8], [0, 0.79]]  # clearance exactly 0.2 (not flagged), then 0.19
    flags = comfort.personal_space_flags(_traj([robot, far, near]), eps=0.2)
    np.testing.assert_array_equal(flags, [False, True])
    with pytest.raises(ValueError, match="distance"):
        comfort.personal_space_flags(_traj([robot, far]), distance="surface")


def test_a_clearance_of_exactly_eps_is_not_flagged_whatever_its_rounding() -> None:
    from socialnav.metrics.basic import discomfort

    # 1.2 − 0.5 − 0.5 is 0.19999999999999996 and 0.8 − 0.3 − 0.3 is 0.20000000000000007: both are ε
    for centre, radius in ((1.2, 0.5), (0.8, 0.3), (0.7, 0.25), (1.0, 0.4)):
        traj = _traj([[[0, 0]] * 3, [[centre, 0]] * 3], radii=radius)
        assert comfort.personal_space(traj, eps=0.2)["count"] == 0.0, (centre, radius)
        assert discomfort(traj, threshold=0.2)["count"] == 0.0, (centre, radius)
        closer = _traj([[[0, 0]] * 3, [[centre - 1e-6, 0]] * 3], radii=radius)  # a micrometre in: flagged
        assert comfort.personal_space(closer, eps=0.2)["count"] == 2.0, (centre, radius)
        assert discomfort(closer, threshold=0.2)["count"] == 2.0, (centre, radius)


# ----------------------------------------------------------------------------------------- M_II
def test_rectangles_touching_intersect_separated_do_not() -> None:
    a = _square(0, 0)
    assert comfort.rectangles_intersect(a, _square(1, 0))  # shared edge
    assert comfort.rectangles_intersect(a, _square(1, 1))  # shared corner
    assert comfort.rectangles_intersect(a, _square(0.5, 0.5))  # overlap
    assert not comfort.rectangles_intersect(a, _square(1.01, 0))
    assert not comfort.rectangles_intersect(a, _square(0, -1.001))
    # a diamond whose bounding box overlaps the square but which is separated along the diagonal
    diamond = np.array([[1.3, 0.8], [1.8, 1.3], [1.3, 1.8], [0.8, 1.3]])  # near edge: x + y = 2.1
    assert not comfort.rectangles_intersect(a, diamond)
    assert comfort.rectangles_intersect(a, diamond - 0.05)  # x + y = 2 touches the corner (1, 1)
    # batched
    got = comfort.rectangles_intersect(np.stack([a, a]), np.stack([_square(1, 0), _square(2, 0)]))
    np.testing.assert_array_equal(got, [True, False])


def test_velocity_rectangle_corners_rear_and_front() -> None:
    rect, valid = comfort.velocity_rectangles(np.array([0.0, 0.0]), np.array([1.0, 0.0]), 0.5, tau=2.0)
    assert valid
    np.testing.assert_allclose(rect, [[0, 0.5], [0, -0.5], [2, -0.5], [2, 0.5]])
    rect, _ = comfort.velocity_rectangles(np.array([0.0, 0.0]), np.array([1.0, 0.0]), 0.5, tau=2.0,
                                          anchor="front")
    np.testing.assert_allclose(rect, [[0.5, 0.5], [0.5, -0.5], [2.5, -0.5], [2.5, 0.5]])
    _, valid = comfort.velocity_rectangles(np.zeros((2, 2)), np.array([[0.0, 0.0], [1e-7, 0.0]]), 0.3, 1.0)
    np.testing.assert_array_equal(valid, [False, False])


def _crossing_scene(k_max: int = 8) -> Trajectory:
    # dt = 0.5: robot along +x at 1 m/s on y = 0; human along +y at 1 m/s on x = 3, from y = −2
    k = np.arange(k_max + 1)
    robot = np.stack([k * 0.5, 0 * k], 1)
    human = np.stack([3.0 + 0 * k, -2.0 + k * 0.5], 1)
    return _traj([robot, human], dt=0.5)


def test_m2_crossing_counts_by_hand() -> None:
    traj = _crossing_scene()
    # τ = 1: robot [k/2, k/2+1]×[−.3, .3], human [2.7, 3.3]×[−2+k/2, −1+k/2] overlap only at k = 4
    assert comfort.projected_path(traj, tau=1.0) == {"count": 1.0, "fraction": 1 / 8, "duration_s": 0.5}
    np.testing.assert_array_equal(np.flatnonzero(comfort.projected_path_flags(traj, 1.0)) + 1, [4])
    # τ = 2: x overlap for 1.4 ≤ k ≤ 6.6, y overlap for k ≤ 4.6 -> k = 2, 3, 4
    np.testing.assert_array_equal(np.flatnonzero(comfort.projected_path_flags(traj, 2.0)) + 1, [2, 3, 4])
    # front anchored, τ = 1: robot [k/2+.3, k/2+1.3], human y [−1.7+k/2, −.7+k/2] -> k = 3, 4
    flags = comfort.projected_path_flags(traj, 1.0, anchor="front")
    np.testing.assert_array_equal(np.flatnonzero(flags) + 1, [3, 4])


def test_m2_stopped_agents_have_no_rectangle() -> None:
    robot = [[0, 0], [0.5, 0], [1.0, 0]]
    human = [[1.2, 0]] * 3  # standing right in front of the robot: bodies overlap, no rectangle
    assert comfort.projected_path(_traj([robot, human]), tau=2.0)["count"] == 0.0
    stopped_robot = [[0, 0]] * 3
    walking = [[1.2, 0], [0.9, 0], [0.6, 0]]
    assert comfort.projected_path(_traj([stopped_robot, walking]), tau=2.0)["count"] == 0.0
    assert comfort.projected_path(_traj([robot]), tau=2.0)["count"] == 0.0  # no humans


# ----------------------------------------------------------------------------------------- M_III
def _m3_scene() -> Trajectory:
    """dt = 0.25, robot K = 8 (2 s); human 1 arrives at sample 4, human 2 in continuation sample 11,
    human 3 never; continuation M = 4 (data up to sample 12 = 3 s)."""
    k = np.arange(9)
    robot = np.stack([0 * k, k * 0.5], 1)
    h1 = np.stack([5.0 + 0 * k, 5.0 - 0.5 * np.maximum(4 - k, 0)], 1)  # |p − g| = 0 from k = 4
    h2 = np.tile([-5.0, -3.0], (9, 1))
    h3 = np.tile([9.0, 9.0], (9, 1))
    goals = [[0, 4], [5, 5], [-5, -5], [-9, -9]]
    cont = np.array([
        [[0, 4], [5, 5], [-5, -4.0], [9, 9]],
        [[0, 4], [5, 5], [-5, -4.65], [9, 9]],  # 0.35 m from the goal: not within radius 0.3
        [[0, 4], [5, 5], [-5, -4.71], [9, 9]],  # 0.29 m: arrived at sample K + 3 = 11
        [[0, 4], [5, 5], [-5, -5.0], [9, 9]],
    ])
    return _traj([robot, h1, h2, h3], goals=goals, continuation=cont, outcome="success")


def test_m3_first_arrivals() -> None:
    np.testing.assert_array_equal(comfort.first_arrival_steps(_m3_scene()), [8, 4, 11, np.nan])


def test_m3_sums_and_censoring_by_hand() -> None:
    traj = _m3_scene()
    # cap 3 s = 12 steps, reached by the data: human 3 censored at 12 -> 8 + 4 + 11 + 12 = 35 steps
    assert comfort.aggregated_time(traj, cap_s=3.0) == {
        "time_s": 8.75, "steps": 35.0, "censored": 1.0, "unresolved": 0.0}
    # cap 2.5 s = 10 steps: human 2 (11) is late and counts as 10 -> 8 + 4 + 10 + 10 = 32
    assert comfort.aggregated_time(traj, cap_s=2.5) == {
        "time_s": 8.0, "steps": 32.0, "censored": 2.0, "unresolved": 0.0}
    # cap 100 s: the data end at 3 s without human 3 arriving -> unknown
    out = comfort.aggregated_time(traj, cap_s=100.0)
    assert math.isnan(out["time_s"]) and math.isnan(out["steps"]) and out["unresolved"] == 1.0


def test_m3_all_arrive_without_continuation() -> None:
    k = np.arange(5)
    robot = np.stack([0 * k, 0.5 * k], 1)
    human = np.tile([3.0, 3.0], (5, 1))  # starts at its goal: arrival at sample 0
    traj = _traj([robot, human], goals=[[0, 2], [3, 3]], outcome="success")
    assert comfort.aggregated_time(traj) == {"time_s": 1.0, "steps": 4.0, "censored": 0.0, "unresolved": 0.0}

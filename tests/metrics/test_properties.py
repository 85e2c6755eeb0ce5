"""Hypothesis property tests: ranges, duration = count·dt, rigid-motion invariance, mirror symmetry."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from socialnav.metrics import comfort, naturalness, sociability
from socialnav.metrics.basic import min_over_humans, robot_human_distance
from socialnav.trajectory import Trajectory

coords = st.floats(-6.0, 6.0, allow_nan=False, allow_infinity=False)
dts = st.sampled_from([0.1, 0.25, 0.5])


@st.composite
def scenes(draw: st.DrawFn, min_humans: int = 1, max_humans: int = 4) -> Trajectory:
    k = draw(st.integers(1, 12))
    a = 1 + draw(st.integers(min_humans, max_humans))
    pos = draw(arrays(np.float64, (k + 1, a, 2), elements=coords))
    radii = draw(arrays(np.float64, (a,), elements=st.floats(0.1, 0.5)))
    return Trajectory.from_positions(pos, draw(dts), radii=radii, v_pref=2.0, goals=pos[-1],
                                     outcome="success")


def _transformed(traj: Trajectory, angle: float, shift: tuple[float, float]) -> Trajectory:
    c, s = math.cos(angle), math.sin(angle)
    rot = np.array([[c, -s], [s, c]])
    return Trajectory.from_positions(traj.positions @ rot.T + shift, traj.dt, radii=traj.radii,
                                     v_pref=traj.v_pref, goals=traj.goals @ rot.T + shift,
                                     outcome=traj.outcome)


def _check_indicator(out: dict[str, float], dt: float) -> None:
    assert 0.0 <= out["fraction"] <= 1.0
    assert math.isclose(out["duration_s"], out["count"] * dt)


@given(scenes(), st.floats(0.0, 2.0), st.floats(0.1, 3.0))
@settings(max_examples=60, deadline=None)
def test_indicator_ranges(traj: Trajectory, eps: float, tau: float) -> None:
    _check_indicator(comfort.personal_space(traj, eps=eps), traj.dt)
    _check_indicator(comfort.projected_path(traj, tau=tau), traj.dt)
    speed = naturalness.walking_speed(traj, v_th=1.5)
    _check_indicator(speed, traj.dt)
    ge = {k[:-3]: v for k, v in speed.items() if k.endswith("_ge")}
    _check_indicator(ge, traj.dt)
    assert speed["count"] <= ge["count"]  # strictly above implies at or above


@given(scenes(), st.floats(0.0, 2 * math.pi), coords, coords, st.sampled_from([0.2, 1.2]))
@settings(max_examples=60, deadline=None)
def test_m1_invariant_under_rigid_motion(traj: Trajectory, angle: float, dx: float, dy: float,
                                         eps: float) -> None:
    d = min_over_humans(robot_human_distance(traj))
    assume(np.all(np.abs(d - eps) > 1e-7))  # rounding can legitimately flip a sample at d ≈ ε
    moved = _transformed(traj, angle, (dx, dy))
    np.testing.assert_array_equal(comfort.personal_space_flags(moved, eps),
                                  comfort.personal_space_flags(traj, eps))


def _flags_with_touch_tolerance(traj: Trajectory, tau: float, anchor: str, tol: float) -> np.ndarray:
    saved = comfort.TOUCH_TOL
    comfort.TOUCH_TOL = tol
    try:
        return comfort.projected_path_flags(traj, tau, anchor)
    finally:
        comfort.TOUCH_TOL = saved


@given(scenes(), st.floats(0.0, 2 * math.pi), coords, coords, st.sampled_from([0.5, 1.0, 2.0]),
       st.sampled_from(["rear", "front"]))
@settings(max_examples=60, deadline=None)
def test_m2_invariant_under_rigid_motion(traj: Trajectory, angle: float, dx: float, dy: float,
                                         tau: float, anchor: str) -> None:
    speeds = np.linalg.norm(traj.executed_velocities(), axis=-1)
    assume(np.all(np.abs(speeds - comfort.STOPPED_SPEED) > 1e-9))
    # rounding can legitimately flip rectangles that just touch (corner on corner, a gap at the touch
    # tolerance): only cases whose flags do not depend on the tolerance between 0 and 1 µm are compared
    assume(np.array_equal(_flags_with_touch_tolerance(traj, tau, anchor, 0.0),
                          _flags_with_touch_tolerance(traj, tau, anchor, 1e-6)))
    moved = _transformed(traj, angle, (dx, dy))
    np.testing.assert_array_equal(comfort.projected_path_flags(moved, tau, anchor),
                                  comfort.projected_path_flags(traj, tau, anchor))


@given(scenes(min_humans=1, max_humans=1))
@settings(max_examples=100, deadline=None)
def test_m6_label_flips_under_mirror(traj: Trajectory) -> None:
    mirrored = Trajectory.from_positions(traj.positions * [-1.0, 1.0], traj.dt, radii=traj.radii,
                                         goals=traj.goals * [-1.0, 1.0])
    label, flipped = sociability.side_preference(traj), sociability.side_preference(mirrored)
    assert flipped == {"left": "right", "right": "left", None: None}[label]


@given(arrays(np.float64, st.integers(0, 60), elements=st.floats(-1e3, 1e3) | st.just(float("nan"))))
@settings(max_examples=60, deadline=None)
def test_summary_bounds(values: np.ndarray) -> None:
    from socialnav.metrics.aggregate import summarize

    out = summarize(values, n_boot=200)
    finite = values[~np.isnan(values)]
    assert out["n"] == finite.size
    if finite.size:
        lo, hi = finite.min(), finite.max()
        assert lo - 1e-9 <= out["ci_low"] <= out["ci_high"] <= hi + 1e-9
        assert lo - 1e-9 <= out["mean"] <= hi + 1e-9

"""M_IV (squared jerk) and M_V (walking speed) with hand-computed answers."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from socialnav.metrics import naturalness
from socialnav.metrics.naturalness import WalkingSpeedWarning
from socialnav.trajectory import Trajectory


def _robot(path: np.ndarray, dt: float, v_pref: float = 2.0) -> Trajectory:
    pos = np.asarray(path, float)[:, None]
    return Trajectory.from_positions(pos, dt, radii=0.3, v_pref=v_pref, goals=pos[-1])


# ----------------------------------------------------------------------------------------- M_IV
def test_constant_velocity_has_zero_jerk() -> None:
    t = np.arange(11) * 0.25
    out = naturalness.squared_jerk(_robot(np.stack([1.2 * t, -0.5 * t + 3], 1), 0.25))
    assert out["mean_sq"] == pytest.approx(0.0, abs=1e-18)
    assert out["integral"] == pytest.approx(0.0, abs=1e-18)


def test_constant_acceleration_has_zero_jerk() -> None:
    t = np.arange(8) * 0.5
    assert naturalness.squared_jerk(_robot(np.stack([t**2, 0 * t], 1), 0.5))["mean_sq"] == pytest.approx(0)


def test_cubic_path_known_jerk() -> None:
    # p(t) = (a t³, b t³): third derivative (6a, 6b); the third difference of a cubic is exact
    a, b, dt, n = 2.0, -1.0, 0.5, 6
    t = np.arange(n + 1) * dt
    out = naturalness.squared_jerk(_robot(np.stack([a * t**3, b * t**3], 1), dt))
    expected = 36 * (a**2 + b**2)  # 180 (m/s³)²
    assert out["mean_sq"] == pytest.approx(expected)
    assert out["integral"] == pytest.approx(expected * (n - 2) * dt)  # 4 jerk samples × dt
    np.testing.assert_allclose(naturalness.jerk(np.stack([a * t**3, b * t**3], 1), dt), [[6 * a, 6 * b]] * 4)


def test_jerk_nan_for_short_paths() -> None:
    out = naturalness.squared_jerk(_robot(np.zeros((3, 2)), 0.25))  # N = 2 < 3
    assert math.isnan(out["mean_sq"]) and math.isnan(out["integral"])
    assert naturalness.squared_jerk(_robot(np.zeros((4, 2)), 0.25))["mean_sq"] == 0.0  # N = 3: one jerk


# ----------------------------------------------------------------------------------------- M_V
def _speeds_path(speeds: list[float], headings: list[float], dt: float) -> np.ndarray:
    steps = [[s * dt * math.cos(h), s * dt * math.sin(h)] for s, h in zip(speeds, headings, strict=True)]
    return np.concatenate([[[0.0, 0.0]], np.cumsum(steps, axis=0)])


def test_walking_speed_strict_and_at_or_above() -> None:
    dt = 0.25
    speeds = [1.0, 1.5, 1.6, 1.5 + 1e-7, 1.5 - 1e-7, 1.4]
    traj = _robot(_speeds_path(speeds, [0.3] * 6, dt), dt)
    out = naturalness.walking_speed(traj, v_th=1.5)
    assert (out["count"], out["fraction"], out["duration_s"]) == (1.0, 1 / 6, 0.25)
    assert (out["count_ge"], out["fraction_ge"], out["duration_s_ge"]) == (4.0, 4 / 6, 1.0)


def test_walking_speed_robust_to_heading_rounding() -> None:
    # exactly 1.5 m/s in 72 headings: rounding lands on both sides of 1.5, the tolerance absorbs it
    headings = list(np.linspace(0, 2 * np.pi, 72, endpoint=False))
    traj = _robot(_speeds_path([1.5] * 72, headings, 0.25), 0.25)
    speeds = np.linalg.norm(traj.executed_velocities()[:, 0], axis=1)
    assert np.any(speeds > 1.5) and np.any(speeds < 1.5)  # the rounding the tolerance guards against
    out = naturalness.walking_speed(traj)
    assert out["count"] == 0.0 and out["count_ge"] == 72.0


def test_walking_speed_warns_when_robot_cannot_exceed_threshold() -> None:
    path = _speeds_path([1.0, 1.0], [0.0, 0.0], 0.25)
    # stated once per table/scoring call, not per episode: the metric itself stays silent
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        naturalness.walking_speed(_robot(path, 0.25, v_pref=1.5))
    assert "M_V≥" in naturalness.walking_speed_note(1.5) and "1.5" in naturalness.walking_speed_note(1.2)
    assert naturalness.walking_speed_note(1.6) is None
    assert naturalness.walking_speed_note(float("nan")) is None
    assert issubclass(WalkingSpeedWarning, UserWarning)

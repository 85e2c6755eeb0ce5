"""M_IV's discretisations (``difference``, ``dt_power``) against hand-computed trajectories."""

from __future__ import annotations

import numpy as np
import pytest

from socialnav.metrics import naturalness, score_episode
from socialnav.metrics.registry import metric_key
from socialnav.trajectory import Trajectory

CUBE = np.array([[0.0, 0.0], [1.0, 0.0], [8.0, 0.0], [27.0, 0.0]])  # p(t) = t³ at t = 0..3, dt = 1


def _robot(path: np.ndarray, dt: float, velocities: np.ndarray | None = None) -> Trajectory:
    pos = np.asarray(path, float)[:, None]
    traj = Trajectory.from_positions(pos, dt, radii=0.3, v_pref=2.0, goals=pos[-1], outcome="success")
    if velocities is None:
        return traj
    return Trajectory(dt=dt, positions=pos, velocities=np.asarray(velocities, float)[:, None],
                      radii=traj.radii, v_pref=traj.v_pref, goals=traj.goals, roles=traj.roles,
                      outcome="success")


def test_forward_default_is_todays_m4() -> None:
    # Δ³p = 27 − 3·8 + 3·1 − 0 = 6 → one sample, |j|² = 36
    out = naturalness.squared_jerk(_robot(CUBE, 1.0))
    assert out["mean_sq"] == pytest.approx(36.0)
    assert naturalness.squared_jerk(_robot(CUBE, 1.0), difference="forward", dt_power=3) == out


def test_central_differences_by_hand() -> None:
    # np.gradient of [0, 1, 8, 27]: edges 1 and 19, interior 8/2 = 4 and 26/2 = 13 → [1, 4, 13, 19];
    # again: [3, 6, 7.5, 6]; again: [3, 2.25, 0, −1.5]; mean of squares (9 + 5.0625 + 0 + 2.25)/4
    out = naturalness.squared_jerk(_robot(CUBE, 1.0), difference="central")
    assert out["mean_sq"] == pytest.approx(16.3125 / 4)
    assert out["integral"] == pytest.approx(16.3125)


def test_commanded_velocities_by_hand() -> None:
    # u = [0, 1, 3, 6] with dt = 0.5: Δ²u = [3 − 2 + 0, 6 − 6 + 1] = [1, 1], ÷ dt² = 4 → |j|² = 16
    u = np.array([[0.0, 0.0], [1.0, 0.0], [3.0, 0.0], [6.0, 0.0]])
    out = naturalness.squared_jerk(_robot(CUBE, 0.5, velocities=u), difference="commanded")
    assert out["mean_sq"] == pytest.approx(16.0)
    # dt² instead of dt³: one power of dt fewer in the denominator, |j|² × dt²
    out2 = naturalness.squared_jerk(_robot(CUBE, 0.5, velocities=u), difference="commanded", dt_power=2)
    assert out2["mean_sq"] == pytest.approx(16.0 * 0.25)


@pytest.mark.parametrize("difference", ["forward", "central"])
def test_dt_power_two_scales_by_dt_squared(difference: str) -> None:
    dt = 0.25
    path = np.stack([np.sin(np.arange(12) * 0.7), np.arange(12) * 0.3], 1)
    base = naturalness.squared_jerk(_robot(path, dt), difference=difference)["mean_sq"]
    two = naturalness.squared_jerk(_robot(path, dt), difference=difference, dt_power=2)["mean_sq"]
    assert two == pytest.approx(base * dt**2)


def test_keys_of_the_default_stay_published_and_variants_are_named() -> None:
    assert metric_key("m4_jerk", "mean_sq") == "m4_jerk.mean_sq"
    assert metric_key("m4_jerk", "mean_sq", {"dt_power": 3, "difference": "forward"}) == "m4_jerk.mean_sq"
    assert metric_key("m4_jerk", "mean_sq", {"dt_power": 2}) == "m4_jerk.mean_sq@dt_power=2"
    assert (metric_key("m4_jerk", "mean_sq", {"difference": "central", "dt_power": 2})
            == "m4_jerk.mean_sq@difference=central,dt_power=2")


def test_score_episode_reports_several_discretisations_side_by_side() -> None:
    traj = _robot(CUBE, 1.0)
    row = score_episode(traj, {"m4_jerk": [{}, {"difference": "central"}, {"dt_power": 2}]})
    assert row["m4_jerk.mean_sq"] == pytest.approx(36.0)
    assert row["m4_jerk.mean_sq@difference=central"] == pytest.approx(16.3125 / 4)
    assert row["m4_jerk.mean_sq@dt_power=2"] == pytest.approx(36.0)  # dt = 1: same number, other key


@pytest.mark.parametrize(("params", "message"), [
    ({"difference": "backward"}, "difference must be one of"),
    ({"dt_power": 4}, "dt_power must be 2 or 3"),
])
def test_bad_discretisation_is_named(params: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        naturalness.squared_jerk(_robot(CUBE, 1.0), **params)

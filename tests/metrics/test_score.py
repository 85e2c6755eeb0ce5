"""score_episode: flat keys, success gating, parameter overrides."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from socialnav.metrics import score_episode, score_keys
from socialnav.trajectory import Trajectory


def _episode(outcome: str) -> Trajectory:
    k = np.arange(21)
    robot = np.stack([0 * k, -4 + 0.4 * k], 1)  # 1.6 m/s, above v_pref: no speed warning needed
    human = np.tile([0.5, 0.0], (21, 1))
    return Trajectory.from_positions(np.stack([robot, human], 1), 0.25, radii=0.3, v_pref=[2.0, 1.0],
                                     goals=[robot[-1], human[-1]], outcome=outcome)


def test_keys_are_stable_and_documented_form() -> None:
    ok, bad = score_episode(_episode("success")), score_episode(_episode("collision"))
    assert list(ok) == list(bad) == score_keys()
    assert "m1_personal_space.duration_s@eps=0.2,distance=clearance" in ok
    assert "m1_personal_space.duration_s@eps=1.2,distance=clearance" in ok
    assert {f"m2_projected_path.fraction@tau={t},anchor=rear" for t in ("0.5", "1", "2")} <= set(ok)
    assert "m5_walking_speed.duration_s_ge@v_th=1.5" in ok and "m4_jerk.mean_sq" in ok
    assert all(isinstance(v, float) for v in ok.values())


def test_social_metrics_nan_unless_success() -> None:
    ok, bad = score_episode(_episode("success")), score_episode(_episode("collision"))
    assert ok["m1_personal_space.count@eps=0.2,distance=clearance"] == 3.0  # centre 0.4·k−4 within 0.8
    assert ok["m6_side_preference.sign@frame=world"] == 1.0
    for key, value in bad.items():
        if key.startswith("m") and not key.startswith("min_"):
            assert math.isnan(value), key
    assert bad["collision"] == 1.0 and bad["success"] == 0.0 and bad["path_length"] == pytest.approx(8.0)
    assert math.isnan(bad["navigation_time"]) and ok["navigation_time"] == 5.0


def test_unknown_outcome_scored_when_asked() -> None:
    row = score_episode(_episode("unknown"), require_success=False)
    assert row["m1_personal_space.count@eps=0.2,distance=clearance"] == 3.0
    assert math.isnan(row["success"])


def test_parameter_overrides() -> None:
    params = {"m1_personal_space": {"distance": "centre", "eps": 0.8},
              "m2_projected_path": [{"anchor": "front"}, {"tau": 2.0, "anchor": "front"}]}
    row = score_episode(_episode("success"), params)
    assert [k for k in row if k.startswith("m1")] == [
        "m1_personal_space.count@eps=0.8,distance=centre",
        "m1_personal_space.fraction@eps=0.8,distance=centre",
        "m1_personal_space.duration_s@eps=0.8,distance=centre",
    ]
    assert row["m1_personal_space.count@eps=0.8,distance=centre"] == 3.0
    m2_settings = {k.split("@")[1] for k in row if k.startswith("m2")}
    assert m2_settings == {"tau=1,anchor=front", "tau=2,anchor=front"}
    assert list(row) == score_keys(params)
    with pytest.raises(KeyError, match="m9"):
        score_episode(_episode("success"), {"m9": {}})
    with pytest.raises(KeyError, match="epsilon"):
        score_episode(_episode("success"), {"m1_personal_space": {"epsilon": 1.0}})


def test_failed_episode_does_not_warn() -> None:
    traj = Trajectory.from_positions(np.zeros((3, 1, 2)), 0.25, radii=0.3, v_pref=1.0, goals=[[0, 0]],
                                     outcome="timeout")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        score_episode(traj)


def test_unknown_outcome_warns_that_social_metrics_are_nan() -> None:
    from socialnav.metrics import UnknownOutcomeWarning

    traj = Trajectory.from_positions(np.zeros((3, 2, 2)) + [[0, 0], [3, 0]], 0.25, radii=0.3,
                                     goals=[[0, 0], [3, 0]])
    with pytest.warns(UnknownOutcomeWarning, match="require_success=False"):
        row = score_episode(traj)
    assert math.isnan(row["m4_jerk.mean_sq"]) and math.isnan(row["success"])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert not math.isnan(score_episode(traj, require_success=False)["m1_personal_space.count@eps=0.2,"
                                                                          "distance=clearance"])

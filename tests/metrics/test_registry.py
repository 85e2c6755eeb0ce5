"""Registry: records, look-up errors, key naming, and the citation contract of every metric."""

from __future__ import annotations

import subprocess
import sys

import pytest

import socialnav.metrics as sm
from socialnav.metrics.registry import get_metric, list_metrics, metric_key, parse_key, register_metric
from socialnav.metrics.score import score_keys


def test_all_metrics_registered_with_records() -> None:
    names = [m.name for m in list_metrics()]
    assert names == [
        "success", "collision", "timeout", "navigation_time", "path_length", "min_clearance",
        "discomfort", "human_overlaps", "n_humans", "m1_personal_space", "m2_projected_path",
        "m3_aggregated_time", "m4_jerk", "m5_walking_speed", "m6_side_preference",
        "min_obstacle_clearance", "obstacle_proximity", "wall_collision",
        "human_arrival", "humans_stuck", "robot_stuck_time",
    ]
    obstacle_metrics = ("min_obstacle_clearance", "obstacle_proximity", "wall_collision")
    progress_metrics = ("human_arrival", "humans_stuck", "robot_stuck_time")
    for m in list_metrics():
        assert m.direction in ("lower", "higher", "none")
        assert m.unit and m.outputs and m.description and m.reference
        assert m.map_only == (m.name in progress_metrics)
        if m.name in obstacle_metrics:
            assert "2306.16740" in m.reference  # Francis et al.
            continue
        if m.name in progress_metrics:
            assert "docs/metrics.md" in m.reference and "Lozano-Pérez" in m.reference  # the route distance
            continue
        assert "2202.01045" in (m.fn.__doc__ or "") or m.name in ("path_length", "human_overlaps", "n_humans")
    assert "Jin" in get_metric("m2_projected_path").fn.__doc__
    assert "Jin" in get_metric("m2_projected_path").reference


def test_social_flag_exact() -> None:
    social = {m.name for m in list_metrics() if m.social}
    assert social == {f"m{i}_{n}" for i, n in enumerate(
        ["personal_space", "projected_path", "aggregated_time", "jerk", "walking_speed",
         "side_preference"], start=1)}


def test_get_metric_unknown_lists_valid_names() -> None:
    with pytest.raises(KeyError) as err:
        get_metric("m7_gaze")
    assert "m1_personal_space" in str(err.value) and "success" in str(err.value)


def test_unknown_parameter_rejected() -> None:
    with pytest.raises(KeyError, match="epsilon"):
        get_metric("m1_personal_space").resolve({"epsilon": 0.3})


def test_duplicate_and_bad_direction_rejected() -> None:
    with pytest.raises(ValueError, match="already registered"):
        register_metric("success", unit="1", direction="higher", outputs={"value": "1"}, reference="x")(
            lambda traj: {"value": 1.0}
        )
    with pytest.raises(ValueError, match="direction"):
        register_metric("new_metric", unit="1", direction="up", outputs={"value": "1"}, reference="x")  # type: ignore[arg-type]


def test_key_naming_and_parse_round_trip() -> None:
    assert metric_key("success", "value") == "success"
    assert metric_key("m4_jerk", "mean_sq") == "m4_jerk.mean_sq"
    key = metric_key("m1_personal_space", "duration_s", {"eps": 0.2, "distance": "clearance"})
    assert key == "m1_personal_space.duration_s@eps=0.2,distance=clearance"
    assert metric_key("m2_projected_path", "count", {"tau": 1.0, "anchor": "rear"}) == (
        "m2_projected_path.count@tau=1,anchor=rear"
    )
    # omitted parameters take their defaults, so the key is the row's key
    key2 = metric_key("m2_projected_path", "count", {"tau": 1.0})
    assert key2 == "m2_projected_path.count@tau=1,anchor=rear"
    assert metric_key("m2_projected_path", "count", {"tau": 1.0}) in score_keys()
    assert metric_key("m3_aggregated_time", "steps") == "m3_aggregated_time.steps@cap_s=100"
    with pytest.raises(KeyError, match="no output"):
        metric_key("m2_projected_path", "counts")
    with pytest.raises(KeyError, match="unknown parameter"):
        metric_key("m2_projected_path", "count", {"taus": 1.0})
    with pytest.raises(KeyError, match="unknown metric"):
        metric_key("m9_nonsense", "value")
    assert parse_key(key) == ("m1_personal_space", "duration_s", {"eps": "0.2", "distance": "clearance"})
    assert parse_key("success") == ("success", "value", {})


def test_import_is_numpy_only() -> None:
    code = (
        "import sys, socialnav.metrics, socialnav.trajectory; "
        "bad = [m for m in sys.modules if m.split('.')[0] in ('torch', 'pyarrow', 'pandas')]; "
        "sys.exit(1 if bad else 0)"
    )
    flags = ["-S"] if sys.flags.no_site else []
    assert subprocess.run([sys.executable, *flags, "-c", code]).returncode == 0
    assert sm.score_episode is not None


@pytest.mark.parametrize(("params", "error", "message"), [
    ({"m3_aggregated_time": {"cap_s": -5}}, ValueError, "parameter cap_s must be a finite number >= 0"),
    ({"m1_personal_space": {"eps": True}}, ValueError, "parameter eps must be a finite number >= 0, got Tr"),
    ({"m2_projected_path": {"tau": float("nan")}}, ValueError, "parameter tau must be a finite number >= 0"),
    ({"m3_aggregated_time": {"cap_s": 0}}, ValueError, "parameter cap_s must be > 0, got 0"),
    ({"m2_projected_path": {"tau": 0.0}}, ValueError, "parameter tau must be > 0, got 0.0"),
    ({"m1_personal_space": {"eps": "big"}}, ValueError, "parameter eps must be a finite number >= 0"),
    ({"m1_personal_space": []}, TypeError, r"params\['m1_personal_space'\] must be a dict of parameters or a "
                                           "non-empty list"),
    ([{}, {}], TypeError, "params must map metric names to parameter dicts"),
])
def test_metric_parameters_are_checked(params, error, message):
    import numpy as np

    from socialnav.metrics import score_episode
    from socialnav.trajectory import Trajectory

    k = np.arange(11)
    pos = np.stack([np.stack([0 * k, 0.25 * k], 1), np.stack([1 + 0 * k, 5 - 0.25 * k], 1)], 1)
    traj = Trajectory.from_positions(pos, 0.25, radii=0.3, goals=pos[-1], outcome="success")
    with pytest.raises(error, match=message):
        score_episode(traj, params)

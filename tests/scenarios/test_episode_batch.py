"""EpisodeBatch helpers, episode seeds, and validation of scenario settings."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np
import pytest

from socialnav.scenarios import (
    SPLIT_BASES,
    EpisodeBatch,
    ScenarioGenerationError,
    episode_seeds,
    make_scenario,
    scenario_from_settings,
)


def test_episode_seeds() -> None:
    assert SPLIT_BASES == {"val": 0, "test": 1000, "train": 2000}
    np.testing.assert_array_equal(episode_seeds("test", [0, 1, 499]), [1000, 1001, 1499])
    np.testing.assert_array_equal(episode_seeds("val", np.arange(3)), [0, 1, 2])
    np.testing.assert_array_equal(episode_seeds("train", [5]), [2005])
    assert episode_seeds("train", [10**6])[0] == 2000 + 10**6  # train is unbounded
    assert episode_seeds("test", 3).tolist() == [1003]
    assert episode_seeds("test", []).shape == (0,)
    assert episode_seeds("val", [1]).dtype == np.int64


def test_episode_seeds_errors() -> None:
    with pytest.raises(ValueError, match="'val', 'test', 'train'"):
        episode_seeds("testing", [0])
    with pytest.raises(ValueError, match=">= 0"):
        episode_seeds("test", [-1])
    with pytest.raises(ValueError, match="overlap"):
        episode_seeds("val", [1000])
    with pytest.raises(TypeError, match="integers"):
        episode_seeds("val", [0.5])


def _batch(n_humans: int, b: int = 4) -> EpisodeBatch:
    return make_scenario("circle_crossing", n_humans=n_humans).episodes("test", range(b))


def test_batch_shapes_and_robot() -> None:
    bt = _batch(5, b=3)
    assert bt.batch_size == len(bt) == 3 and bt.max_humans == 5
    np.testing.assert_array_equal(bt.n_humans, [5, 5, 5])
    np.testing.assert_array_equal(bt.robot_start, [[0.0, -4.0]] * 3)
    np.testing.assert_array_equal(bt.robot_goal, [[0.0, 4.0]] * 3)
    np.testing.assert_array_equal(bt.robot_theta, np.full(3, np.pi / 2))
    np.testing.assert_array_equal(bt.robot_radius, 0.3)
    np.testing.assert_array_equal(bt.robot_v_pref, 1.0)
    np.testing.assert_array_equal(bt.seeds, [1000, 1001, 1002])
    np.testing.assert_array_equal(bt.indices, [0, 1, 2])
    assert bt.human_mask.dtype == bool and bt.human_mask.all()


def test_take_and_concat() -> None:
    a, b = _batch(5, b=4), _batch(2, b=3)
    sub = a.take([2, 0])
    np.testing.assert_array_equal(sub.human_start, a.human_start[[2, 0]])
    np.testing.assert_array_equal(a.take(1).seeds, a.seeds[[1]])
    np.testing.assert_array_equal(a.take(slice(1, 3)).indices, [1, 2])
    cat = EpisodeBatch.concat([a, b]).validate()
    assert cat.batch_size == 7 and cat.max_humans == 5
    np.testing.assert_array_equal(cat.n_humans, [5] * 4 + [2] * 3)
    np.testing.assert_array_equal(cat.human_start[4:, :2], b.human_start)
    assert np.all(cat.human_start[4:, 2:] == 0) and not cat.human_mask[4:, 2:].any()
    with pytest.raises(ValueError, match="at least one"):
        EpisodeBatch.concat([])


def test_zero_humans() -> None:
    bt = _batch(0)
    assert bt.human_start.shape == (4, 0, 2) and bt.human_mask.shape == (4, 0)


@pytest.mark.parametrize(
    ("field", "value", "match"),
    [
        ("human_start", lambda a: a[:, :, :1], "human_start must have shape"),
        ("seeds", lambda a: a.astype(np.int32), "seeds must be int64"),
        ("human_mask", lambda a: a.astype(np.int8), "human_mask must be bool"),
        ("robot_radius", lambda a: -a, "robot_radius must be > 0"),
        ("human_goal", lambda a: np.where(True, np.nan, a), "human_goal contains non-finite"),
        ("human_radius", lambda a: 0 * a, "human_radius must be > 0"),
    ],
)
def test_validate_names_field(field: str, value: Callable, match: str) -> None:
    bt = _batch(3)
    bad = dataclasses.replace(bt, **{field: value(getattr(bt, field))})
    with pytest.raises(ValueError, match=match):
        bad.validate()


def test_validate_padding() -> None:
    bt = EpisodeBatch.concat([_batch(3), _batch(1)])
    start = bt.human_start.copy()
    start[-1, -1] = 1.0
    with pytest.raises(ValueError, match="padded"):
        dataclasses.replace(bt, human_start=start).validate()


@pytest.mark.parametrize(
    ("params", "exc", "match"),
    [
        ({"human_radius": -0.3}, ValueError, r"human_radius must be > 0, got -0.3"),
        ({"robot_radius": 0}, ValueError, r"robot_radius must be > 0"),
        ({"n_humans": -1}, ValueError, r"n_humans must be >= 0, got -1"),
        ({"n_humans": 2.5}, TypeError, r"n_humans must be an int"),
        ({"circle_radius": float("nan")}, ValueError, r"circle_radius must be finite"),
        ({"robot_v_pref": float("inf")}, ValueError, r"robot_v_pref must be finite"),
        ({"discomfort_dist": -0.1}, ValueError, r"discomfort_dist must be >= 0"),
        ({"robot_v_pref": "fast"}, TypeError, r"robot_v_pref must be a number"),
        ({"robot_v_pref": True}, TypeError, r"robot_v_pref must be a number"),
        ({"randomize_attributes": 1}, TypeError, r"randomize_attributes must be a bool"),
        ({"random_radius_range": (0.5, 0.3)}, ValueError, r"random_radius_range must satisfy"),
        ({"random_radius_range": (0.5,)}, TypeError, r"random_radius_range must be a sequence"),
        ({"max_attempts": 0}, ValueError, r"max_attempts must be > 0"),
    ],
)
def test_bad_settings_name_field_and_value(params: dict, exc: type, match: str) -> None:
    with pytest.raises(exc, match=match):
        make_scenario("circle_crossing", **params)


def test_settings_normalised_and_recorded() -> None:
    sc = make_scenario("random", circle_radius=4, random_radius_range=[0.3, 0.4])
    assert isinstance(sc.circle_radius, float) and sc.random_radius_range == (0.3, 0.4)
    rec = sc.settings()
    assert rec["type"] == "random" and rec["square_width"] == 12.0
    assert scenario_from_settings(rec) == sc
    with pytest.raises(dataclasses.FrozenInstanceError):
        sc.n_humans = 3  # type: ignore[misc]


def test_generate_input_errors() -> None:
    sc = make_scenario("circle_crossing")
    with pytest.raises(ValueError, match="same shape"):
        sc.generate([0, 1], [1000])
    with pytest.raises(ValueError, match=">= 0"):
        sc.generate([-1], [5])
    with pytest.raises(TypeError, match="integers"):
        sc.generate([0.0], [1000])


def test_impossible_scene_raises() -> None:
    sc = make_scenario("random", n_humans=30, square_width=2.0, max_attempts=50)
    with pytest.raises(ScenarioGenerationError, match=r"random: start of human \d+.*50 attempts"):
        sc.episodes("test", range(4))


def test_validate_names_the_episode() -> None:
    bt = _batch(3)
    goal = bt.human_goal.copy()
    goal[2, 1, 0] = np.nan
    bad = dataclasses.replace(bt, human_goal=goal)
    row = rf"episode {int(bt.indices[2])} \(seed {int(bt.seeds[2])}, row 2 of the batch\) has"
    with pytest.raises(ValueError, match=rf"human_goal contains non-finite values: {row}"):
        bad.validate()
    robot_goal, theta = bt.robot_goal.copy(), bt.robot_theta.copy()
    robot_goal[0, 0] = theta[0] = np.nan  # a NaN goal, and the heading a scenario derives from it
    with pytest.raises(ValueError, match=r"robot_goal contains non-finite values"):  # the cause, not theta
        dataclasses.replace(bt, robot_goal=robot_goal, robot_theta=theta).validate()
    radius = bt.human_radius.copy()
    radius[1, 0] = 0.0
    with pytest.raises(ValueError, match=r"human_radius must be > 0 for real humans: episode .*row 1 of the "
                       r"batch\), human 0 has 0.0"):
        dataclasses.replace(bt, human_radius=radius).validate()


def test_validate_refuses_agents_that_start_overlapping() -> None:
    # a scenario of one's own that stacks people, or puts one on the robot: the episode would open with a
    # collision nobody caused
    bt = _batch(3)
    start = bt.human_start.copy()
    start[1, 2] = start[1, 0] + np.array([0.5, 0.0])  # 0.5 m apart, radii 0.3 + 0.3
    with pytest.raises(ValueError, match=r"episode 1 \(seed 1001, row 1 of the batch\): humans 0 and 2 start "
                                         r"overlapping \(centres 0.5 m apart, radii 0.3 \+ 0.3 m\)"):
        dataclasses.replace(bt, human_start=start).validate()
    start = bt.human_start.copy()
    start[0, 1] = bt.robot_start[0] + np.array([0.0, 0.2])
    with pytest.raises(ValueError, match=r"human 1 starts overlapping the robot \(centres 0.2 m apart"):
        dataclasses.replace(bt, human_start=start).validate()
    start = bt.human_start.copy()
    start[1, 2] = start[1, 0] + np.array([0.6, 0.0])  # touching: allowed
    dataclasses.replace(bt, human_start=start).validate()

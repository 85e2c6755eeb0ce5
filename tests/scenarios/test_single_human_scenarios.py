"""Single-human scenarios (passing, overtaking, crossing): offset grid, repeats and jitter."""

from __future__ import annotations

import numpy as np
import pytest

from socialnav.scenarios import EpisodeBatch, make_scenario

SINGLE = ["passing", "overtaking", "crossing"]
GRID = -0.6 + np.arange(20) * 1.2 / 19  # the spec's o_i


def _offset(name: str, bt: EpisodeBatch) -> np.ndarray:
    """Lateral offset read from the goal (the goal is not moved by the start jitter)."""
    return bt.human_goal[:, 0, 1 if name == "crossing" else 0]


@pytest.mark.parametrize("name", SINGLE)
def test_exact_grid(name: str) -> None:
    bt = make_scenario(name).episodes("test", range(20))
    assert bt.human_start.shape == (20, 1, 2) and bt.human_mask.all()
    off = _offset(name, bt)
    np.testing.assert_allclose(off, GRID, rtol=0, atol=1e-15)
    assert off[0] == -0.6 and off[-1] == 0.6
    np.testing.assert_array_equal(bt.human_radius, 0.3)


def test_passing_geometry() -> None:
    bt = make_scenario("passing").episodes("test", range(20))
    np.testing.assert_allclose(bt.human_start[:, 0], np.stack([GRID, np.full(20, 4.0)], 1))
    np.testing.assert_allclose(bt.human_goal[:, 0], np.stack([GRID, np.full(20, -4.0)], 1))
    np.testing.assert_array_equal(bt.human_v_pref, 1.0)


def test_overtaking_geometry() -> None:
    bt = make_scenario("overtaking").episodes("test", range(20))
    np.testing.assert_allclose(bt.human_start[:, 0], np.stack([GRID, np.full(20, -2.0)], 1))
    np.testing.assert_allclose(bt.human_goal[:, 0], np.stack([GRID, np.full(20, 6.0)], 1))
    np.testing.assert_array_equal(bt.human_v_pref, 0.5)
    fast = make_scenario("overtaking", robot_v_pref=1.5).episodes("test", [0])
    assert fast.human_v_pref[0, 0] == 0.75
    # a robot driving straight at full speed catches the human at the origin
    t = (fast.human_start[0, 0, 1] - fast.robot_start[0, 1]) / (1.5 - 0.75)
    assert fast.robot_start[0, 1] + 1.5 * t == pytest.approx(0.0)
    custom = make_scenario("overtaking", gap=3.0, speed_ratio=0.25).episodes("test", [0])
    assert custom.human_start[0, 0, 1] == -1.0 and custom.human_v_pref[0, 0] == 0.25


def test_crossing_geometry() -> None:
    bt = make_scenario("crossing").episodes("test", range(20))
    np.testing.assert_allclose(bt.human_start[:, 0], np.stack([np.full(20, -4.0), GRID], 1))
    np.testing.assert_allclose(bt.human_goal[:, 0], np.stack([np.full(20, 4.0), GRID], 1))


def test_offsets_derive_from_radii() -> None:
    sc = make_scenario("passing", human_radius=0.5, robot_radius=0.4)
    off = _offset("passing", sc.episodes("test", range(20)))
    np.testing.assert_allclose(off[[0, -1]], [-0.9, 0.9])
    sc = make_scenario("passing", offset_span=1.0, n_offsets=5)
    np.testing.assert_allclose(
        _offset("passing", sc.episodes("test", range(5))), [-1.0, -0.5, 0.0, 0.5, 1.0]
    )


@pytest.mark.parametrize("name", SINGLE)
def test_repeats_and_jitter(name: str) -> None:
    sc = make_scenario(name, repeats=10)
    assert sc.n_episodes == 200
    bt = sc.episodes("test", range(200))
    off = _offset(name, bt)
    np.testing.assert_allclose(off[:20], GRID, rtol=0, atol=1e-15)
    dev = off - np.tile(GRID, 10)
    half_spacing = 0.6 / 19
    assert np.all(np.abs(dev[20:]) <= half_spacing) and np.all(dev[20:] != 0)
    assert np.abs(dev[20:]).max() > 0.5 * half_spacing
    # start moved by at most 0.1 m per axis from its offset line position
    nominal = make_scenario(name).episodes("test", np.arange(200) % 20)
    shift = bt.human_start[:, 0] - nominal.human_start[:, 0]
    lateral = 1 if name == "crossing" else 0
    shift[:, lateral] -= dev
    np.testing.assert_allclose(shift[:20], 0.0, rtol=0, atol=1e-15)
    assert np.all(np.abs(shift[20:]) <= 0.1 + 1e-12) and np.abs(shift[20:]).max() > 0.05
    # 600 single-human cases: 3 scenarios x 20 offsets x 10 repeats
    assert 3 * sc.n_episodes == 600


@pytest.mark.parametrize("name", SINGLE)
def test_single_batch_independence_and_splits(name: str) -> None:
    sc = make_scenario(name, repeats=5)
    full = sc.episodes("test", range(100))
    one = EpisodeBatch.concat([sc.episodes("test", [i]) for i in range(100)])
    for k, v in full.arrays().items():
        np.testing.assert_array_equal(one.arrays()[k], v, err_msg=k)
    val = sc.episodes("val", range(100))
    np.testing.assert_array_equal(val.human_start[:20], full.human_start[:20])  # exact grid
    assert np.all(np.any(val.human_start[20:] != full.human_start[20:], axis=(1, 2)))


@pytest.mark.parametrize("name", SINGLE)
def test_single_bad_input(name: str) -> None:
    with pytest.raises(ValueError, match=r"has 20 episodes.*got index 20"):
        make_scenario(name).episodes("test", [20])
    with pytest.raises(ValueError, match=r"n_humans must be 1.*got 5"):
        make_scenario(name, n_humans=5)
    with pytest.raises(ValueError, match="randomize_attributes must be False"):
        make_scenario(name, randomize_attributes=True)
    with pytest.raises(ValueError, match=r"repeats must be >= 1, got 0"):
        make_scenario(name, repeats=0)
    with pytest.raises(ValueError, match=r"n_offsets must be >= 2"):
        make_scenario(name, n_offsets=1)
    with pytest.raises(ValueError, match=r"offset_span must be > 0"):
        make_scenario(name, offset_span=-0.1)


@pytest.mark.parametrize("name, params, message", [
    ("overtaking", {"gap": 0.1}, r"Overtaking: the human can start 0.105 m from the robot's centre, within "
                                 r"their radii \(0.6 m\)"),
    ("crossing", {"circle_radius": 0.3}, r"Crossing: the human can start 0.3 m from the robot's centre"),
    ("passing", {"circle_radius": 0.5, "repeats": 2, "start_jitter": 0.3}, r"Passing: the human can start"),
    ("overtaking", {"speed_ratio": 1.0}, r"speed_ratio must be < 1"),
])
def test_settings_that_start_the_human_on_the_robot_are_refused(name, params, message):
    with pytest.raises(ValueError, match=message):
        make_scenario(name, **params)


def test_the_protocols_single_human_scenarios_start_clear():
    for name in ("passing", "overtaking", "crossing"):
        make_scenario(name, repeats=10, robot_v_pref=1.5)  # wang2022's, jittered repeats included

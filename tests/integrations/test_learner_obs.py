"""Learner observations (socialnav.sim.learner_obs and its wrappers): hand-computed layouts, padding and
nearest-human selection, scales, robot-frame actions, and the same conversion in the single env, the
native vector env and Gymnasium's sync vector env."""

import math

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import socialnav  # noqa: F401  (registers the ids)
from socialnav.envs.learner_wrappers import LearnerObservation, LearnerObservationVector
from socialnav.envs.vector import SocialNavVectorEnv
from socialnav.settings import ConfigError
from socialnav.sim.learner_obs import ObservationSettings, ObservationTransform

# robot at (1, 1) heading +y, velocity (0, 0.5), radius 0.3, goal (1, 4), v_pref 1.5
ROBOT = np.array([[1.0, 1.0, 0.0, 0.5, 0.3, 1.0, 4.0, 1.5, math.pi / 2]])
HUMANS = np.array([[[0.0, 0.0, 0.0, 0.0, 0.0], [2.0, 1.0, 1.0, 0.0, 0.4], [1.0, 3.0, 0.0, -1.0, 0.3]]])
MASK = np.array([[False, True, True]])


def test_robot_frame_layout_by_hand():
    t = ObservationTransform(ObservationSettings(frame="robot", max_humans=4), 3, "unicycle")
    out = t(ROBOT, HUMANS, MASK)
    # rot = pi/2: x' points along +y (towards the goal), y' along -x
    np.testing.assert_allclose(out["robot"][0], [3.0, 1.5, 0.0, 0.3, 0.5, 0.0], atol=1e-6)
    # human (2, 1): 1 m to the robot's right -> (0, -1); velocity (1, 0) -> (0, -1); da 1; radius sum 0.7
    np.testing.assert_allclose(out["humans"][0, 0], [0.0, -1.0, 0.0, -1.0, 0.4, 1.0, 0.7], atol=1e-6)
    # human (1, 3): 2 m ahead -> (2, 0); velocity (0, -1) -> (-1, 0)
    np.testing.assert_allclose(out["humans"][0, 1], [2.0, 0.0, -1.0, 0.0, 0.3, 2.0, 0.6], atol=1e-6)
    np.testing.assert_array_equal(out["humans"][0, 2:], 0.0)  # padding
    np.testing.assert_array_equal(out["human_mask"][0], [1, 1, 0, 0])
    assert out["robot"].dtype == np.float32 and out["human_mask"].dtype == np.int8
    assert t.single_space().contains({k: v[0] for k, v in out.items()})
    # holonomic robots carry no heading in the robot frame
    holo = ObservationTransform(ObservationSettings(frame="robot"), 3, "holonomic")(ROBOT, HUMANS, MASK)
    assert holo["robot"][0, 2] == 0.0 and holo["humans"].shape == (1, 3, 7)


def test_world_frame_scales_and_nearest_humans():
    s = ObservationSettings(max_humans=1, length_scale=2.0, speed_scale=0.5, dtype="float64")
    out = ObservationTransform(s, 3, "holonomic")(ROBOT, HUMANS, MASK)
    np.testing.assert_allclose(out["robot"][0], [0.5, 0.5, 0.0, 1.0, 0.15, 0.5, 2.0, 3.0, math.pi / 2])
    # two real humans, one slot: the nearer (2, 1) at 1 m beats (1, 3) at 2 m
    np.testing.assert_allclose(out["humans"][0, 0], [1.0, 0.5, 2.0, 0.0, 0.2])
    assert out["humans"].dtype == np.float64


def test_fixed_count_keeps_the_nearest_in_slot_order():
    humans = np.zeros((1, 4, 5))
    humans[0, :, 0] = [5.0, 1.0, 3.0, 2.0]  # distances from (0, 0)
    robot = np.zeros((1, 9))
    robot[0, 5] = 1.0
    out = ObservationTransform(ObservationSettings(max_humans=2, dtype="float64"), 4, "holonomic")(
        robot, humans, np.ones((1, 4), bool)
    )
    np.testing.assert_array_equal(out["humans"][0, :, 0], [1.0, 2.0])  # slots 1 and 3, in slot order


def test_bad_settings_are_named():
    with pytest.raises(ConfigError, match="observation.frame"):
        ObservationSettings(frame="goal")
    with pytest.raises(ConfigError, match="observation.max_humans"):
        ObservationSettings(max_humans=0)
    with pytest.raises(ConfigError, match="observation.length_scale"):
        ObservationSettings(length_scale=float("nan"))
    with pytest.raises(ValueError, match="discrete holonomic"):
        ObservationTransform(ObservationSettings(frame="robot"), 5, "holonomic", "discrete")


scene = st.floats(-5, 5, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(st.lists(scene, min_size=12, max_size=12), st.floats(-math.pi, math.pi), scene, scene)
def test_robot_frame_is_invariant_to_moving_the_whole_scene(values, angle, shift_x, shift_y):
    robot = np.array([[values[0], values[1], values[2], values[3], 0.3, values[4], values[5], 1.0, 0.0]])
    humans = np.array(
        [[[values[6], values[7], values[8], values[9], 0.3], [values[10], values[11], 0.0, 0.0, 0.4]]]
    )
    if math.hypot(values[4] - values[0], values[5] - values[1]) < 1e-3:
        return  # the goal direction is undefined at the goal
    c, s = math.cos(angle), math.sin(angle)
    rot = np.array([[c, -s], [s, c]])
    moved_r, moved_h = robot.copy(), humans.copy()
    for cols in ((0, 1), (5, 6)):
        moved_r[0, list(cols)] = rot @ robot[0, list(cols)] + [shift_x, shift_y]
    moved_r[0, 2:4] = rot @ robot[0, 2:4]
    moved_h[0, :, 0:2] = humans[0, :, 0:2] @ rot.T + [shift_x, shift_y]
    moved_h[0, :, 2:4] = humans[0, :, 2:4] @ rot.T
    t = ObservationTransform(ObservationSettings(frame="robot", dtype="float64"), 2, "holonomic")
    mask = np.ones((1, 2), bool)
    a, b = t(robot, humans, mask), t(moved_r, moved_h, mask)
    np.testing.assert_allclose(a["robot"], b["robot"], atol=1e-9)
    np.testing.assert_allclose(a["humans"], b["humans"], atol=1e-9)
    # an action straight ahead in the robot frame points at the goal in the world
    world = t.actions_to_world(np.array([[1.0, 0.0]]), moved_r)[0]
    to_goal = moved_r[0, 5:7] - moved_r[0, 0:2]
    np.testing.assert_allclose(world, to_goal / np.linalg.norm(to_goal), atol=1e-9)
    back = t.actions_from_world(np.array([[0.3, -0.7]]), moved_r)
    np.testing.assert_allclose(t.actions_to_world(back, moved_r), [[0.3, -0.7]], atol=1e-12)


def test_robot_frame_equals_the_value_networks_rotate():
    torch = pytest.importorskip("torch", reason="torch (the learn extra) is not installed")
    from socialnav.policies.learned.state import rotate

    joint = rotate(torch.tensor(ROBOT), torch.tensor(HUMANS[:, 1:]), "unicycle").numpy()[0]
    out = ObservationTransform(ObservationSettings(frame="robot", dtype="float64"), 2, "unicycle")(
        ROBOT, HUMANS[:, 1:], MASK[:, 1:]
    )
    np.testing.assert_allclose(out["robot"][0], joint[0, :6], atol=1e-12)
    np.testing.assert_allclose(out["humans"][0], joint[:, 6:], atol=1e-12)


def test_single_vector_and_sync_envs_convert_alike():
    settings = ObservationSettings(frame="robot", max_humans=5)
    single = LearnerObservation(gym.make("socialnav/Passing-v0"), settings)
    native = LearnerObservationVector(SocialNavVectorEnv(3, scenario="passing"), settings)
    copies = gym.make_vec("socialnav/Passing-v0", num_envs=2, vectorization_mode="sync")
    sync = LearnerObservationVector(copies, settings)
    assert single.observation_space == native.single_observation_space == sync.single_observation_space
    first, _ = single.reset(seed=4)
    obs, _ = native.reset(seed=4)
    sync_obs, _ = sync.reset(seed=4)  # copy 0 is seeded 4
    for key in first:
        np.testing.assert_array_equal(obs[key][0], first[key])
        np.testing.assert_array_equal(sync_obs[key][0], first[key])
    np.testing.assert_array_equal(first["human_mask"], [1, 0, 0, 0, 0])  # one human, four padded slots
    ahead = np.array([1.5, 0.0])  # robot frame: straight at the goal
    for _ in range(200):
        o, _, terminated, truncated, info = single.step(ahead)
        vo, _, vterm, vtrunc, vinfo = native.step(np.tile(ahead, (3, 1)))
        if terminated or truncated:
            break
        np.testing.assert_array_equal(vo["robot"][0], o["robot"])
    assert vterm[0] or vtrunc[0]
    for key in o:  # the terminal observation, converted alike
        np.testing.assert_array_equal(vinfo["final_obs"][0][key], o[key])
    single.close(), native.close(), sync.close()


def test_robot_frame_actions_reach_the_goal_without_humans():
    env = LearnerObservation(gym.make("socialnav/CircleCrossing-v0", scenario_params={"n_humans": 0}),
                             ObservationSettings(frame="robot"))
    assert env.observation_space["humans"].shape == (1, 7)  # one padded slot: networks need an input
    obs, _ = env.reset(seed=0)
    assert obs["human_mask"].tolist() == [0]
    for _ in range(100):
        obs, reward, terminated, truncated, info = env.step(np.array([1.0, 0.0]))
        if terminated or truncated:
            break
    assert info["outcome"] == "success" and reward == 1.0


def test_gym_make_human_render_mode_without_display_is_socialnav_error(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(RuntimeError, match="render_mode='human' needs a display"):
        gym.make("socialnav/CircleCrossing-v0", render_mode="human")

"""Learner observations among walls: the ``obstacle_points`` key by hand in both frames, its space,
the default layout without it, and the wrapped envs (single, vector, SB3's checker) with a map."""

import gymnasium as gym
import numpy as np
import pytest

import socialnav  # noqa: F401  (registers the ids)
from socialnav.envs.learner_wrappers import LearnerObservation, LearnerObservationVector
from socialnav.envs.vector import SocialNavVectorEnv
from socialnav.maps.static_map import StaticMap
from socialnav.settings import ConfigError
from socialnav.sim.learner_obs import ObservationSettings, ObservationTransform

WALL = StaticMap(([[-1.0, 1.0], [1.0, 1.0]],))  # points every 0.5 m: x = -1, -0.5, 0, 0.5, 1 at y = 1
MAP = {"polygons": [[[-2.0, 0.5], [2.0, 0.5]], [[-0.4, -2.4], [0.4, -2.4], [0.4, -1.6], [-0.4, -1.6]]]}


def _robot(x, y, gx, gy):
    r = np.zeros((1, 9))
    r[0, :2], r[0, 4], r[0, 5:7], r[0, 7] = (x, y), 0.3, (gx, gy), 1.0
    return r


def _call(settings, robot, static_map=WALL):
    t = ObservationTransform(settings, 1, "holonomic", static_map=static_map)
    return t, t(robot, np.zeros((1, 1, 5)), np.zeros((1, 1), bool))


def test_world_frame_points_by_hand():
    t, out = _call(ObservationSettings(obstacle_points=3, length_scale=2.0), _robot(0.2, 0.0, 0.0, 5.0))
    # nearest to (0.2, 0): (0, 1) 1.020, (0.5, 1) 1.044, (-0.5, 1) 1.221; halved by length_scale
    np.testing.assert_allclose(out["obstacle_points"][0], [[0.0, 0.5], [0.25, 0.5], [-0.25, 0.5]], atol=1e-7)
    assert out["obstacle_point_mask"].tolist() == [[1, 1, 1]]
    assert out["obstacle_points"].dtype == np.float32
    assert t.single_space()["obstacle_points"].shape == (3, 2)


def test_robot_frame_points_by_hand_and_padding():
    # goal straight ahead in +y: the robot frame's x-axis is world +y, its y-axis world -x
    settings = ObservationSettings(frame="robot", obstacle_points=4, obstacle_range=1.2, dtype="float64")
    t, out = _call(settings, _robot(0.0, 0.0, 0.0, 5.0))
    d = np.hypot(0.5, 1.0)
    np.testing.assert_allclose(
        out["obstacle_points"][0],
        [[1.0, 0.0, 1.0], [1.0, 0.5, d], [1.0, -0.5, d], [0.0, 0.0, 0.0]],  # tie: (-0.5, 1) comes first
        atol=1e-12,
    )
    assert out["obstacle_point_mask"].tolist() == [[1, 1, 1, 0]]  # (±1, 1) are beyond 1.2 m
    assert t.single_space()["obstacle_points"].shape == (4, 3)


def test_no_obstacle_keys_by_default_and_an_open_floor_is_padding():
    _, out = _call(ObservationSettings(), _robot(0.0, 0.0, 0.0, 5.0))
    assert set(out) == {"robot", "humans", "human_mask"}
    _, out = _call(ObservationSettings(obstacle_points=2), _robot(0.0, 0.0, 0.0, 5.0), static_map=None)
    assert out["obstacle_point_mask"].tolist() == [[0, 0]] and np.all(out["obstacle_points"] == 0)


def test_bad_obstacle_settings_are_named():
    with pytest.raises(ConfigError, match="observation.obstacle_points"):
        ObservationSettings(obstacle_points=-1)
    with pytest.raises(ConfigError, match="observation.obstacle_spacing"):
        ObservationSettings(obstacle_spacing=0.0)
    with pytest.raises(ConfigError, match="observation.obstacle_range"):
        ObservationSettings.from_dict({"obstacle_range": float("inf")})


@pytest.mark.parametrize("frame", ["world", "robot"])
def test_wrapped_envs_with_walls_stay_in_their_spaces(frame):
    settings = ObservationSettings(frame=frame, obstacle_points=8)
    env = LearnerObservation(gym.make("socialnav/CircleCrossing-v0", static_map=MAP), settings)
    venv = LearnerObservationVector(SocialNavVectorEnv(3, static_map=MAP), settings)
    obs, _ = env.reset(seed=0)
    vobs, _ = venv.reset(seed=0)
    rng = np.random.default_rng(0)
    for _ in range(20):
        assert env.observation_space.contains(obs)
        space = venv.single_observation_space
        assert all(space.contains({k: v[b] for k, v in vobs.items()}) for b in range(3))
        assert obs["obstacle_point_mask"].sum() > 0
        obs, *_ = env.step(rng.uniform(-1, 1, 2))
        vobs, *_ = venv.step(rng.uniform(-1, 1, (3, 2)))
    env.close()
    venv.close()


def test_sb3_checker_accepts_the_wrapped_env_with_walls():
    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.env_checker import check_env

    from socialnav.integrations.sb3 import SocialNavVecEnv

    settings = ObservationSettings(frame="robot", obstacle_points=8)
    env = LearnerObservation(gym.make("socialnav/CircleCrossing-v0", static_map=MAP), settings)
    check_env(env, warn=True)
    adapter = SocialNavVecEnv("socialnav/CircleCrossing-v0", 2, observation=settings, static_map=MAP)
    obs = adapter.reset()
    assert obs["obstacle_points"].shape == (2, 8, 3) and obs["obstacle_point_mask"].shape == (2, 8)
    adapter.close()


def _on_outline(points: np.ndarray, static_map: StaticMap) -> bool:
    """Every encoded point lies on the map's outline (distance 0 to its edges, to float32)."""
    return bool(np.all(static_map.distance(points) < 1e-5))  # float32 observations


@pytest.mark.parametrize("scenario", ["narrow_doorway", "circle_crossing_obstacles"])
def test_the_wrappers_and_the_sb3_adapter_encode_each_episodes_own_walls(scenario):
    # A scenario's walls (not only a static_map given to the env) reach the learner's observation, each
    # episode's own (circle_crossing_obstacles draws pillars per episode), in final_obs too: what the
    # SB3 policy is given at evaluation (integrations/sb3_policy.py)
    from socialnav.scenarios import make_scenario

    settings = ObservationSettings(obstacle_points=16)
    sc = make_scenario(scenario)
    env = LearnerObservation(gym.make("socialnav/CircleCrossing-v0", scenario=scenario, split="test"),
                             settings)
    obs, info = env.reset(options={"index": 3})
    own = sc.episodes("test", [3]).static_map(0)
    points = obs["obstacle_points"][obs["obstacle_point_mask"].astype(bool)]
    assert len(points) > 0 and _on_outline(points, own)
    venv = LearnerObservationVector(SocialNavVectorEnv(4, scenario=scenario, split="test"), settings)
    vobs, vinfo = venv.reset(options={"index": 0})
    rng = np.random.default_rng(1)
    finals = seen = 0
    for _ in range(200):
        for b in range(4):
            episode_map = sc.episodes("test", [int(vinfo["episode_index"][b])]).static_map(0)
            kept = vobs["obstacle_point_mask"][b].astype(bool)  # none where every wall is out of range
            assert _on_outline(vobs["obstacle_points"][b][kept], episode_map)
            seen += int(kept.sum())
        vobs, _, _, _, vinfo_step = venv.step(rng.uniform(-1, 1, (4, 2)))
        for b in np.flatnonzero(vinfo_step.get("_final_obs", np.zeros(4, bool))):
            final, index = vinfo_step["final_obs"][b], int(vinfo_step["final_info"]["episode_index"][b])
            kept = final["obstacle_point_mask"].astype(bool)
            assert _on_outline(final["obstacle_points"][kept], sc.episodes("test", [index]).static_map(0))
            finals += 1
        vinfo = vinfo_step
    assert finals > 0 and seen > 0
    env.close()
    venv.close()
    pytest.importorskip("stable_baselines3")
    from socialnav.integrations.sb3 import SocialNavVecEnv

    adapter = SocialNavVecEnv(scenario, 2, observation=settings, split="test")
    adapter.seed(0)
    sobs = adapter.reset()
    for b in range(2):
        episode_map = sc.episodes("test", [adapter.reset_infos[b]["episode_index"]]).static_map(0)
        kept = sobs["obstacle_point_mask"][b].astype(bool)
        assert _on_outline(sobs["obstacle_points"][b][kept], episode_map)
    assert sobs["obstacle_point_mask"].any()
    adapter.close()

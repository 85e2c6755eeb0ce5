"""The Gymnasium envs in worlds with walls: obstacles in the observation, collision_kind in info."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from tests.sim._walls import pillars_and_walls

from socialnav.envs.single import SocialNavEnv
from socialnav.envs.vector import SocialNavVectorEnv
from socialnav.maps.static_map import StaticMap
from socialnav.scenarios import make_scenario
from socialnav.sim.settings import WorldSettings
from socialnav.sim.world import World

ACROSS = StaticMap(([[-2.0, 0.0], [2.0, 0.0]],))  # across the robot's straight route (0, -4) -> (0, 4)


def test_env_checker_passes_with_obstacles():
    check_env(SocialNavEnv(static_map=pillars_and_walls()), skip_render_check=True)
    check_env(gym.make("socialnav/CircleCrossing-v0", static_map=ACROSS.to_dict()).unwrapped,
              skip_render_check=True)


def test_observation_carries_the_padded_obstacle_edges():
    static_map = pillars_and_walls()  # a square (4 edges), an L block (6) and two walls (1 each)
    env = SocialNavEnv(static_map=static_map, max_obstacle_edges=16)
    obs, _ = env.reset(seed=3)
    assert obs["obstacles"].shape == (16, 4) and env.observation_space.contains(obs)
    start, end = static_map.edges()
    np.testing.assert_array_equal(obs["obstacles"][:12], np.hstack([start, end]))
    np.testing.assert_array_equal(obs["obstacle_mask"], [1] * 12 + [0] * 4)
    assert not obs["obstacles"][12:].any()
    open_floor = SocialNavEnv()
    assert "obstacles" not in open_floor.reset(seed=3)[0]


def test_a_map_larger_than_the_bound_is_refused():
    with pytest.raises(ValueError, match="12 edges, more than max_obstacle_edges = 4"):
        SocialNavEnv(static_map=pillars_and_walls(), max_obstacle_edges=4)
    with pytest.raises(ValueError, match="max_obstacle_edges must be an integer >= 0"):
        SocialNavEnv(max_obstacle_edges=-1)
    padded = SocialNavEnv(max_obstacle_edges=8)  # room for maps, none given: all padding
    obs, _ = padded.reset(seed=0)
    assert obs["obstacles"].shape == (8, 4) and not obs["obstacle_mask"].any()


def test_collision_with_a_wall_is_reported_in_info():
    env = SocialNavEnv(static_map=ACROSS, scenario_params={"n_humans": 1})
    env.reset(seed=0)
    info = {"outcome": "running"}
    while info["outcome"] == "running":
        _, reward, terminated, _, info = env.step(np.array([0.0, 1.0]))
    assert terminated and info["outcome"] == "collision" and info["collision_kind"] == "obstacle"
    assert reward == -0.25


def test_vector_env_carries_obstacles_in_observations_and_final_observations():
    env = SocialNavVectorEnv(num_envs=3, static_map=ACROSS, scenario_params={"n_humans": 1})
    obs, info = env.reset(seed=0)
    assert obs["obstacles"].shape == (3, 1, 4) and obs["obstacle_mask"].all()
    assert env.observation_space.contains(obs)
    for _ in range(40):
        obs, _, term, trunc, info = env.step(np.tile([0.0, 1.0], (3, 1)))
        if (term | trunc).any():
            break
    done = np.flatnonzero(term | trunc)
    assert len(done)
    for b in done:
        assert info["final_info"]["collision_kind"][b] == "obstacle"
        np.testing.assert_array_equal(info["final_obs"][b]["obstacles"], [[-2.0, 0.0, 2.0, 0.0]])


@pytest.mark.parametrize("scenario, edges", [("narrow_hallway", None), ("circle_crossing_obstacles", 12)])
def test_a_scenario_with_walls_shows_them_by_default(scenario, edges):
    from socialnav.scenarios import make_scenario

    own = make_scenario(scenario)
    expected = len(own.layout.edges()[0]) if edges is None else edges  # the layout's, or 3 pillars x 4
    assert own.max_obstacle_edges == expected > 0
    env = gym.make("socialnav/CircleCrossing-v0", scenario=scenario, preset="francis2023").unwrapped
    check_env(env, skip_render_check=True)
    for seed in range(3):
        obs, _ = env.reset(seed=seed)
        assert obs["obstacles"].shape == (expected, 4)
        assert obs["obstacle_mask"].sum() == expected  # every edge of the episode's map, no padding
        smap = env._world.static_maps[0]
        np.testing.assert_array_equal(obs["obstacles"], np.hstack(smap.edges()))
    with pytest.raises(ValueError, match=rf"scenario '{scenario}'\'s maps have up to {expected} edges, more "
                                         r"than max_obstacle_edges = 2"):
        SocialNavEnv(scenario=scenario, max_obstacle_edges=2)


def test_a_learner_observation_blind_to_the_walls_warns():
    from socialnav.sim import LearnerObservation, ObservationSettings

    with pytest.warns(UserWarning, match=r"scenario 'narrow_hallway' has walls, but none of the learner's "
                                         r"observation parts \['robot', 'humans', 'obstacle_points'\] shows "
                                         r"them \(obstacle_points = 0\)"):
        LearnerObservation(gym.make("socialnav/CircleCrossing-v0", scenario="narrow_hallway"))
    with pytest.warns(UserWarning, match=r"obstacle_points = 0\)"):
        LearnerObservation(gym.make("socialnav/CircleCrossing-v0", static_map=ACROSS.to_dict()))
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        LearnerObservation(gym.make("socialnav/CircleCrossing-v0", scenario="narrow_hallway"),
                           ObservationSettings(obstacle_points=16))
        # a lidar sees the walls without reading the maps
        LearnerObservation(gym.make("socialnav/CircleCrossing-v0", scenario="narrow_hallway",
                                    world={"sensing": {"lidar_beams": 8}}),
                           ObservationSettings(parts=("robot", "humans", "lidar")))
        LearnerObservation(gym.make("socialnav/CircleCrossing-v0"))  # an open floor: nothing to see


def test_every_francis2023_scenario_makes_an_env_with_the_evaluations_crowd():
    from socialnav.evaluate.plan import cell_scenario, plan_cells
    from socialnav.presets import load_preset

    preset = load_preset("francis2023")
    cells = [c for c in plan_cells(preset) if c.visibility == "invisible"]
    assert len(cells) == 9
    for cell in cells:
        env = gym.make("socialnav/CircleCrossing-v0", scenario=cell.scenario, preset=preset,
                       split="test").unwrapped
        evaluated = cell_scenario(preset, cell)
        assert env._cfg.scenario == evaluated, cell.scenario  # the same crowd, robot and geometry
        obs, _ = env.reset(seed=0)
        assert obs["human_mask"].sum() == evaluated.n_humans and obs["obstacle_mask"].any()


def test_static_map_may_be_a_map_file(tmp_path):
    from socialnav.maps.files import save_map

    path = tmp_path / "across.yaml"
    save_map(path, ACROSS)
    for given in (path, str(path)):
        env = SocialNavEnv(static_map=given)
        assert env._cfg.static_map == ACROSS
        obs, _ = env.reset(seed=0)
        np.testing.assert_array_equal(obs["obstacles"], [[-2.0, 0.0, 2.0, 0.0]])
    with pytest.raises(ValueError, match=r"missing\.yaml: no such map file"):
        SocialNavEnv(static_map=tmp_path / "missing.yaml")


def test_a_static_map_beside_a_walled_scenario_is_said_to_be_unused():
    with pytest.warns(UserWarning, match="scenario 'narrow_hallway' has walls of its own, which win over "
                      "static_map: the given map is not used") as said:
        env = SocialNavEnv(scenario="narrow_hallway", static_map=pillars_and_walls())
    assert len([w for w in said if "walls of its own" in str(w.message)]) == 1  # the env's World is not told
    # a World built directly says it too, and its episodes keep the scenario's walls
    scenario = make_scenario("narrow_hallway")
    with pytest.warns(UserWarning, match="scenario 'narrow_hallway' has walls of its own"):
        world = World(WorldSettings(), scenario, 2, split="test", record=False,
                      static_map=pillars_and_walls())
    world.reset()
    batch = scenario.episodes("test", range(2))
    for slot in range(2):
        np.testing.assert_array_equal(world.static_maps[slot].edges()[0], batch.static_map(slot).edges()[0])
    own = SocialNavEnv(scenario="narrow_hallway")
    assert env.observation_space["obstacles"].shape == own.observation_space["obstacles"].shape

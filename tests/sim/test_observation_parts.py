"""Named observation parts: a part registered from outside the package is found everywhere.

``goal_distance`` (the robot's distance to its goal, shape (1,)) is defined and registered here, as a user's
package would: ``socialnav list`` lists it, the Gymnasium envs (single, vector) and the learner wrappers give
its key with the declared space (Gymnasium's and SB3's checkers pass), the SB3 adapter exposes it, a tiny
SB3 PPO run consumes it and the saved model is evaluated with it. An agent set registered the same way is
read by the networks' input builders. The entry point group ``socialnav.observations`` registers a part too.
"""

from __future__ import annotations

import importlib.metadata
import json

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import socialnav  # noqa: F401  (registers the ids)
from socialnav.envs import (
    RAW_PARTS,
    LearnerObservation,
    LearnerObservationVector,
    SocialNavEnv,
    SocialNavVectorEnv,
)
from socialnav.sim import ObservationSettings, register_observation_part
from socialnav.sim.observation import ROBOT_GX, ROBOT_GY, ROBOT_PX, ROBOT_PY
from socialnav.sim.parts import (
    ObservationComposition,
    ObservationPart,
    PartContext,
    PartInput,
    UnknownObservationPartError,
    get_observation_part,
    list_observation_parts,
    unregister_observation_part,
)
from socialnav.sim.parts import registry as parts_registry

PARTS = (*RAW_PARTS, "goal_distance")
LEARNER_PARTS = ("robot", "humans", "obstacle_points", "goal_distance")


class GoalDistance(ObservationPart):
    """The robot's distance to its goal."""

    name = "goal_distance"
    description = "the robot's distance to its goal"
    columns = {"goal_distance": {"world": ("distance",), "robot": ("distance",)}}

    def compute(self, data, ctx):
        r = np.asarray(data.robot, dtype=np.float64)
        d = np.hypot(r[:, ROBOT_GX] - r[:, ROBOT_PX], r[:, ROBOT_GY] - r[:, ROBOT_PY]) / ctx.length_scale
        return {"goal_distance": d[:, None].astype(ctx.np_dtype)}


class GoalMarker(ObservationPart):
    """The robot's goal as one standing agent the networks read like a human."""

    name = "goal_marker"
    description = "the goal as a standing agent"
    columns = {"goal_marker": {"world": ("px", "py", "vx", "vy", "radius")}}
    static = True

    def compute(self, data, ctx):
        return {}

    def agents(self, data, ctx):
        rows = np.zeros((data.batch_size, 1, 5))
        rows[:, 0, :2] = np.asarray(data.robot)[:, [ROBOT_GX, ROBOT_GY]]
        rows[:, 0, 4] = 0.05
        return rows, np.ones((data.batch_size, 1), dtype=bool)


@pytest.fixture
def goal_distance():
    register_observation_part(GoalDistance)
    yield GoalDistance
    unregister_observation_part("goal_distance")


def _distance(robot: np.ndarray) -> np.ndarray:
    return np.hypot(robot[..., ROBOT_GX] - robot[..., ROBOT_PX], robot[..., ROBOT_GY] - robot[..., ROBOT_PY])


def test_the_built_in_parts_declare_their_widths_once():
    from socialnav.policies.learned.state import JOINT_DIM, SELF_DIM
    from socialnav.sim.learner_obs import HUMAN_COLUMNS, ROBOT_COLUMNS
    from socialnav.sim.observation import HUMAN_DIM, ROBOT_DIM

    robot, humans = get_observation_part("robot"), get_observation_part("humans")
    assert (robot.width("robot"), robot.width("robot", "robot")) == (ROBOT_DIM, SELF_DIM) == (9, 6)
    assert (humans.width("humans"), humans.width("humans", "robot")) == (HUMAN_DIM, 7)
    assert SELF_DIM + humans.width("humans", "robot") == JOINT_DIM == 13
    assert robot.columns["robot"] is ROBOT_COLUMNS and humans.columns["humans"] is HUMAN_COLUMNS
    names = [p.name for p in list_observation_parts()]
    assert names[:4] == ["robot", "humans", "obstacle_points", "obstacle_edges"]


def test_a_part_registered_from_outside_is_listed_by_socialnav_list(goal_distance, capsys):
    from socialnav.cli import main

    assert main(["list"]) == 0
    text = capsys.readouterr().out
    assert "Observation parts" in text and "goal_distance: the robot's distance to its goal" in text
    assert main(["list", "--json"]) == 0
    listed = {o["name"]: o for o in json.loads(capsys.readouterr().out)["observations"]}
    columns = {"goal_distance": {"world": ["distance"], "robot": ["distance"]}}
    assert listed["goal_distance"]["columns"] == columns
    assert {"robot", "humans", "obstacle_points", "obstacle_edges"} <= set(listed)


def test_the_raw_envs_compose_the_part_and_pass_the_checker(goal_distance):
    env = SocialNavEnv(scenario_params={"n_humans": 3}, observation_parts=PARTS)
    check_env(env, skip_render_check=True)
    assert env.observation_space["goal_distance"].shape == (1,)
    obs, _ = env.reset(seed=3)
    assert list(obs) == ["robot", "humans", "human_mask", "goal_distance"]
    np.testing.assert_allclose(obs["goal_distance"], [_distance(obs["robot"])])
    obs, *_ = env.step(env.action_space.sample())
    assert env.observation_space.contains(obs)
    env.close()
    made = gym.make("socialnav/CircleCrossing-v0", observation_parts=list(PARTS))
    assert "goal_distance" in made.observation_space.spaces
    made.close()

    venv = SocialNavVectorEnv(4, scenario_params={"n_humans": 3}, observation_parts=PARTS)
    assert venv.single_observation_space["goal_distance"].shape == (1,)
    obs, _ = venv.reset(seed=0)
    assert venv.observation_space.contains(obs)
    np.testing.assert_allclose(obs["goal_distance"][:, 0], _distance(obs["robot"]))
    for _ in range(40):
        obs, _, terminated, truncated, info = venv.step(venv.action_space.sample())
        assert venv.observation_space.contains(obs)
        if "final_obs" in info:
            for b in np.flatnonzero(info["_final_obs"]):
                final = info["final_obs"][b]
                np.testing.assert_allclose(final["goal_distance"], [_distance(final["robot"])])
    venv.close()


def test_the_default_raw_layout_is_unchanged_by_the_composition():
    plain = SocialNavEnv(scenario_params={"n_humans": 2})
    named = SocialNavEnv(scenario_params={"n_humans": 2}, observation_parts=RAW_PARTS)
    assert plain.observation_space == named.observation_space
    a, _ = plain.reset(seed=5)
    b, _ = named.reset(seed=5)
    assert list(a) == ["robot", "humans", "human_mask"]
    for key in a:
        assert a[key].dtype == b[key].dtype and a[key].tobytes() == b[key].tobytes()
    with pytest.raises(ValueError, match="lacks humans"):
        SocialNavEnv(observation_parts=("robot",))
    with pytest.raises(UnknownObservationPartError, match="unknown observation part 'no_such_part'"):
        SocialNavEnv(observation_parts=(*RAW_PARTS, "no_such_part"))


@pytest.mark.parametrize("frame", ["world", "robot"])
def test_the_learner_wrappers_give_the_part_in_their_units(goal_distance, frame):
    settings = ObservationSettings(frame=frame, length_scale=2.0, parts=LEARNER_PARTS)
    raw_env = gym.make("socialnav/CircleCrossing-v0", scenario_params={"n_humans": 2})
    env = LearnerObservation(raw_env, settings)
    check_env(env, skip_render_check=True)
    raw = env.unwrapped
    obs, _ = env.reset(seed=1)
    assert env.observation_space["goal_distance"].dtype == np.float32
    expected = _distance(raw._world.observe().robot[0]) / 2.0
    np.testing.assert_allclose(obs["goal_distance"], [expected], rtol=1e-6)
    env.close()
    venv = LearnerObservationVector(SocialNavVectorEnv(3, scenario_params={"n_humans": 2}), settings)
    obs, _ = venv.reset(seed=0)
    assert venv.observation_space.contains(obs) and obs["goal_distance"].shape == (3, 1)
    venv.close()


def test_settings_name_registered_parts_and_keep_old_records(goal_distance):
    assert "parts" not in ObservationSettings().to_dict()  # models saved before parts existed: same record
    s = ObservationSettings.from_dict({"parts": list(LEARNER_PARTS)})
    assert s.parts == LEARNER_PARTS and s.to_dict()["parts"] == list(LEARNER_PARTS)
    from socialnav.settings import ConfigError

    with pytest.raises(ConfigError, match="observation.parts.*unknown observation part 'nope'"):
        ObservationSettings(parts=("robot", "nope"))
    with pytest.raises(ConfigError, match="observation.parts.*once"):
        ObservationSettings(parts=("robot", "robot"))


def test_the_sb3_adapter_exposes_the_part_and_a_tiny_ppo_run_consumes_it(goal_distance, tmp_path):
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    from socialnav.integrations.sb3 import SocialNavVecEnv, save_model
    from socialnav.integrations.sb3_policy import load_sb3_policy
    from socialnav.presets import load_preset
    from socialnav.sim import World

    settings = ObservationSettings(max_humans=5, parts=LEARNER_PARTS)
    sb3_check_env(LearnerObservation(SocialNavEnv(scenario_params={"n_humans": 5}), settings), warn=False)
    venv = SocialNavVecEnv("circle_crossing", 4, observation=settings, preset="wang2022")
    assert venv.observation_space["goal_distance"].shape == (1,)
    obs = venv.reset()
    np.testing.assert_allclose(obs["goal_distance"][:, 0], _distance(venv._robot), rtol=1e-6)
    model = PPO("MultiInputPolicy", venv, n_steps=16, batch_size=32, n_epochs=1, seed=0, device="cpu")
    assert "goal_distance" in model.policy.features_extractor.extractors
    model.learn(64)
    path = save_model(model, tmp_path / "goal.zip")
    venv.close()

    preset = load_preset("wang2022")
    policy = load_sb3_policy(f"sb3:{path}", preset)
    assert policy.describe()["observation"]["parts"] == list(LEARNER_PARTS)
    from socialnav.scenarios import make_scenario

    world = World(preset.world, make_scenario("circle_crossing", n_humans=5), batch_size=2)
    try:
        actions = policy.act(world.reset())
    finally:
        world.close()
    assert actions.shape == (2, 2) and np.isfinite(actions).all()


def test_the_networks_read_an_agent_set_part():
    torch = pytest.importorskip("torch")
    from socialnav.policies.learned import ValuePolicy
    from socialnav.policies.learned.attn_graph import observation_tensors
    from socialnav.policies.learned.sarl import SARL
    from socialnav.scenarios import make_scenario
    from socialnav.sim import World, WorldSettings

    register_observation_part(GoalMarker)
    try:
        world = World(WorldSettings(), make_scenario("circle_crossing", n_humans=3), batch_size=2)
        obs = world.reset()
        world.close()
        parts = ("robot", "humans", "goal_marker")
        policy = ValuePolicy(SARL(), observation_parts=parts)
        encoded = policy.encode(obs)
        assert encoded.humans.shape == (2, 4, 5) and encoded.static_slots == 1
        np.testing.assert_array_equal(encoded.humans[:, 3, :2], obs.robot[:, [ROBOT_GX, ROBOT_GY]])
        assert encoded.humans[:, :3].tobytes() == obs.humans.tobytes()
        idx, _ = policy.act(obs)
        assert idx.shape == (2,)
        _, hf, mask = observation_tensors(obs, 0.25, 2, parts=parts)
        assert hf.shape == (2, 4, 6) and bool(mask[:, 3].all())
        assert torch.is_tensor(hf)
        with pytest.raises(ValueError, match="not sets of agents"):
            register_observation_part(GoalDistance)
            ValuePolicy(SARL(), observation_parts=("robot", "humans", "goal_distance"))
    finally:
        unregister_observation_part("goal_marker")
        unregister_observation_part("goal_distance")


def test_compositions_refuse_what_they_cannot_lay_out():
    with pytest.raises(ValueError, match="no 'robot' frame"):
        ObservationComposition(("robot", "obstacle_edges"), PartContext(frame="robot"))
    with pytest.raises(ValueError, match="listed twice"):
        ObservationComposition(("robot", "robot"), PartContext())
    data = PartInput.from_arrays(np.zeros((1, 9)), np.zeros((1, 0, 5)), np.zeros((1, 0), bool))
    out = ObservationComposition(("robot", "humans"), PartContext(human_slots=2))(data)
    assert out["humans"].shape == (1, 2, 5) and out["human_mask"].tolist() == [[0, 0]]


class _FakeEntryPoint:
    def __init__(self, name, obj):
        self.name, self.value, self._obj = name, f"plugin:{name}", obj

    def load(self):
        return self._obj


def test_the_entry_point_group_registers_a_part(monkeypatch):
    class Heading(ObservationPart):
        description = "the robot's heading"
        columns = {"heading": {"world": ("theta",)}}

        def compute(self, data, ctx):
            return {"heading": np.asarray(data.robot)[:, 8:9].astype(ctx.np_dtype)}

    calls = []

    def fake_entry_points(group):
        calls.append(group)
        return [_FakeEntryPoint("heading", Heading)]

    monkeypatch.setattr(importlib.metadata, "entry_points", fake_entry_points)
    monkeypatch.setattr(parts_registry, "_plugins_loaded", False)
    try:
        part = get_observation_part("heading")
        assert calls == ["socialnav.observations"] and part.name == "heading"
        env = SocialNavEnv(observation_parts=(*RAW_PARTS, "heading"))
        obs, _ = env.reset(seed=0)
        assert obs["heading"].shape == (1,)
        env.close()
    finally:
        unregister_observation_part("heading")


def test_training_refuses_a_record_observing_other_parts(monkeypatch):
    import dataclasses

    from socialnav.policies import learned_catalog
    from socialnav.settings import ConfigError
    from socialnav.train.worlds import check_observation_parts

    sarl = learned_catalog.get_learned_spec("sarl")
    check_observation_parts("sarl")  # every shipped record observes NETWORK_PARTS
    other = dataclasses.replace(sarl, observation_parts=("robot", "humans", "goal_marker", "obstacle_points"))
    monkeypatch.setattr(learned_catalog, "get_learned_spec", lambda name: other)
    with pytest.raises(ConfigError, match="observes robot, humans, goal_marker, obstacle_points: training"):
        check_observation_parts("sarl")
    with pytest.raises(ValueError, match="holding 'robot'"):
        dataclasses.replace(sarl, observation_parts=("humans",))


class NearestVertex(ObservationPart):
    """A part that reads the walls: the distance to the nearest vertex of the episode's map (1e3 without)."""

    name = "nearest_vertex"
    description = "distance to the nearest wall vertex"
    columns = {"nearest_vertex": {"world": ("distance",), "robot": ("distance",)}}

    def compute(self, data, ctx):
        out = np.full((data.batch_size, 1), 1e3)
        for b, smap in enumerate(data.maps):
            if smap is not None and smap.polygons:
                v = np.concatenate(smap.polygons)
                out[b, 0] = np.min(np.hypot(v[:, 0] - data.robot[b, 0], v[:, 1] - data.robot[b, 1]))
        return {"nearest_vertex": out.astype(ctx.np_dtype)}


def test_a_part_that_reads_the_walls_gets_each_episodes_map_in_every_wrapper():
    # circle_crossing_obstacles draws a map per episode: no env-wide map stands in for it
    register_observation_part(NearestVertex)
    try:
        parts = ("robot", "humans", "nearest_vertex")
        walled = "circle_crossing_obstacles"
        raw = SocialNavEnv(scenario=walled, observation_parts=(*RAW_PARTS, "nearest_vertex"))
        expected, _ = raw.reset(seed=0)
        assert expected["nearest_vertex"][0] < 100
        env = LearnerObservation(SocialNavEnv(scenario=walled), ObservationSettings(parts=parts))
        got, _ = env.reset(seed=0)
        np.testing.assert_allclose(got["nearest_vertex"], expected["nearest_vertex"], rtol=1e-6)
        venv = SocialNavVectorEnv(2, scenario=walled, observation_parts=(*RAW_PARTS, "nearest_vertex"))
        raw_obs, _ = venv.reset(seed=0)
        venv.close()
        learner = LearnerObservationVector(SocialNavVectorEnv(2, scenario=walled),
                                           ObservationSettings(parts=parts))
        obs, _ = learner.reset(seed=0)
        np.testing.assert_allclose(obs["nearest_vertex"], raw_obs["nearest_vertex"], rtol=1e-6)
        assert (obs["nearest_vertex"] < 100).all()
        learner.close()
        env.close()
        raw.close()
        # the built-ins that never read the maps say so; the obstacle parts and outside parts read them
        never = ("robot", "humans", "lidar", "robot_twist")
        assert not any(get_observation_part(n).reads_maps for n in never)
        assert get_observation_part("obstacle_points").reads_maps and NearestVertex.reads_maps
    finally:
        unregister_observation_part("nearest_vertex")


def test_lidar_readings_stay_inside_the_declared_box():
    # a no-return beam reads float32(lidar_range), which rounds above lidar_range for e.g. 1.1 or 2.7
    from socialnav.sim.parts.builtin import LidarPart
    from socialnav.sim.settings import SensingSettings

    part, outside = LidarPart(), []
    for lidar_range in (1.1, 2.7, 3.3, 7.7, 10.0):
        for scale in (1.0, 1.5, 0.7):
            for dtype in ("float32", "float64"):
                ctx = PartContext(length_scale=scale, dtype=dtype,
                                  sensing=SensingSettings(lidar_beams=3, lidar_range=lidar_range))
                scan = np.full((1, 3), lidar_range, dtype=np.float32)  # what the world writes
                data = PartInput.from_arrays(np.zeros((1, 9)), np.zeros((1, 0, 5)), np.zeros((1, 0), bool),
                                             sensors={"lidar": scan})
                if not part.spaces(ctx)["lidar"].contains(part.compute(data, ctx)["lidar"][0]):
                    outside.append((lidar_range, scale, dtype))
    assert outside == []
    env = LearnerObservation(SocialNavEnv(world={"sensing": {"lidar_beams": 16, "lidar_range": 1.1}}),
                             ObservationSettings(dtype="float64", parts=("robot", "humans", "lidar")))
    check_env(env, skip_render_check=True)
    env.close()


def test_learner_layouts_refuse_parts_they_cannot_give_when_built():
    from socialnav.settings import ConfigError

    walls = {"scenario": "narrow_hallway"}
    with pytest.raises(ValueError, match="'obstacle_edges' is the raw env's"):
        LearnerObservation(SocialNavEnv(**walls),
                           ObservationSettings(parts=("robot", "humans", "obstacle_edges")))
    with pytest.raises(ConfigError, match=r"observation.obstacle_points asks for obstacle points, but "
                                          r"observation.parts \['robot', 'humans'\] lack the part"):
        ObservationSettings(obstacle_points=16, parts=("robot", "humans"))
    with pytest.raises(ConfigError, match="observation.parts must name at least one part"):
        ObservationSettings(parts=())
    with pytest.raises(ConfigError, match="observation.max_humans must be an integer"):
        ObservationSettings(max_humans=True)
    # the raw env given parts without its lidar: refused when the wrapper is built, not at reset
    lidar_env = SocialNavEnv(world={"sensing": {"lidar_beams": 8}}, observation_parts=("robot", "humans"))
    with pytest.raises(ValueError, match=r"read the raw env's key\(s\) lidar, which the env does not give: "
                                         r"its observation_parts \['robot', 'humans'\] lack 'lidar'"):
        LearnerObservation(lidar_env, ObservationSettings(parts=("robot", "humans", "lidar")))
    with pytest.raises(TypeError, match="observation_parts must be a list of part names, got the text"):
        SocialNavEnv(observation_parts="robot")


def test_networks_refuse_parts_they_cannot_read_when_built():
    pytest.importorskip("torch")
    from socialnav.policies.learned import ValuePolicy
    from socialnav.policies.learned.sarl import SARL
    from socialnav.sim.obstacle_points import ObstaclePoints

    with pytest.raises(ValueError, match="observation part.s. lidar of a network are not sets of agents"):
        ValuePolicy(SARL(), observation_parts=("robot", "humans", "lidar"))
    encoding = ObstaclePoints(8, 0.5, 4.0, 0.0).to_dict()
    with pytest.raises(ValueError, match="'humans' of a network moves and comes after the static "
                                         "'obstacle_points'"):
        ValuePolicy(SARL(), obstacle_encoding=encoding,
                    observation_parts=("robot", "obstacle_points", "humans"))


def test_the_same_part_class_defined_again_replaces_itself():
    # a notebook cell run twice defines a new class object of the same name and module
    def define():
        class Again(ObservationPart):
            name = "again"
            description = "a part defined twice"
            columns = {"again": {"world": ("x",)}}

            def compute(self, data, ctx):
                return {"again": np.zeros((data.batch_size, 1), dtype=ctx.np_dtype)}

        return Again

    first, second = define(), define()
    try:
        register_observation_part(first)
        register_observation_part(second)
        assert type(get_observation_part("again")) is second
        other = type("Again", (first,), {"__qualname__": "Other"})
        with pytest.raises(ValueError, match=r"already registered to .*Again \(pass replace=True"):
            register_observation_part(other)
    finally:
        unregister_observation_part("again")

"""The PPO baselines among walls: the obstacle points reach crowdnav_pp's and ppo_mlp's inputs after the
human slots (positions by hand, nearest first, masked where padded), a wall in front of the robot
changes a fixed network's action, an open floor changes nothing (up to float32 rounding), and the
checkpoint keeps the encoding; a checkpoint trained without walls is refused under a walled preset."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from socialnav.maps.static_map import StaticMap
from socialnav.policies.learned import save_checkpoint
from socialnav.policies.learned.attn_graph import AttnGraphNet, observation_tensors
from socialnav.policies.learned.checkpoint import CheckpointError
from socialnav.policies.learned.ppo_mlp import MLPActorCritic
from socialnav.policies.learned.ppo_policy import RecurrentActorPolicy
from socialnav.policies.learned_loading import PresetMismatchError, load_ppo_policy
from socialnav.presets import load_preset
from socialnav.sim.observation import Observation, ObstacleArrays
from socialnav.sim.obstacle_points import ObstaclePoints
from socialnav.train.worlds import ppo_policy_config

from .helpers import SMALL_ATTN_GRAPH as SMALL

#: a 2 m wall 1 m ahead of a robot at (1, 2) heading for (1, 6): its points at x = 0, 0.5, …, 2, y = 3
WALL = StaticMap.from_polygons([np.array([[0.0, 3.0], [2.0, 3.0]])])


def _obs(maps=None, time=0.0, b=1):
    """B copies of: the robot at (1, 2) going to (1, 6), one human at (2, 2) walking at (1, 0) m/s."""
    robot = np.tile([[1.0, 2.0, 0.0, 0.5, 0.3, 1.0, 6.0, 1.0, np.pi / 2]], (b, 1))
    humans = np.zeros((b, 2, 5))
    humans[:, 0] = [2.0, 2.0, 1.0, 0.0, 0.3]
    mask = np.tile([[True, False]], (b, 1))
    walls = None if maps is None else ObstacleArrays.from_maps(maps)
    return Observation(robot, humans, mask, np.ones(b, dtype=bool), np.full(b, time), 0.25, "holonomic",
                       obstacles=walls)


def _attn_graph(seed=0):
    torch.manual_seed(seed)
    return AttnGraphNet(prediction_steps=2, **SMALL).eval()


def _mlp(seed=0, obstacle_slots=16):
    torch.manual_seed(seed)
    return MLPActorCritic(prediction_steps=2, max_humans=2, hidden=16, obstacle_slots=obstacle_slots).eval()


DEFAULT = ObstaclePoints()


def _actor(net, encoding=DEFAULT, name="crowdnav_pp"):
    return RecurrentActorPolicy(name, net, kinematics="holonomic", rotation_limit=0.0, dt=0.25,
                                obstacle_encoding=encoding)


def test_the_points_follow_the_humans_nearest_first_and_stand_still():
    robot, humans, mask = observation_tensors(_obs([WALL]), 0.25, 2, obstacle_encoding=ObstaclePoints())
    assert humans.shape == (1, 2 + 16, 6) and mask.shape == (1, 18)
    # the human: (1, 0) from the robot, then 0.25 m further each predicted step
    torch.testing.assert_close(humans[0, 0], torch.tensor([1.0, 0.0, 1.25, 0.0, 1.5, 0.0]))
    assert mask[0].tolist() == [True, False] + [True] * 5 + [False] * 11
    # the points relative to the robot, nearest first (ties: outline order), the same at every step
    expected = [[0.0, 1.0], [-0.5, 1.0], [0.5, 1.0], [-1.0, 1.0], [1.0, 1.0]]
    torch.testing.assert_close(humans[0, 2:7], torch.tensor([p * 3 for p in expected]))
    assert not humans[0, 7:].any() and not humans[0, 1].any()
    # an observation that already carries its points is not encoded twice
    obs = _obs([WALL])
    h, m = (np.asarray(t) for t in ObstaclePoints().agents(obs.robot[:, :2], [WALL]))
    encoded = dataclasses.replace(obs, humans=np.concatenate([obs.humans, h], 1),
                                  human_mask=np.concatenate([obs.human_mask, m], 1), static_slots=16)
    again = observation_tensors(encoded, 0.25, 2, obstacle_encoding=ObstaclePoints())[1]
    torch.testing.assert_close(again, humans)


@settings(max_examples=30, deadline=None)
@given(
    seed=st.integers(0, 2**16),
    n_walls=st.integers(0, 4),
    steps=st.integers(0, 5),
    count=st.integers(1, 20),
)
def test_the_human_slots_are_unchanged_and_the_points_are_the_encodings(seed, n_walls, steps, count):
    """Any walls, any robot: the human slots are those without an encoding, and the point slots are the
    encoding's nearest points relative to the robot, the same at every predicted step."""
    g = np.random.default_rng(seed)
    # wall segments and squares in horizontal bands of their own (the map refuses crossing outlines)
    walls = []
    for i in range(n_walls):
        x, y, size = g.uniform(-4, 3), -5 + 2.5 * i + g.uniform(0, 1), g.uniform(0.2, 1.4)
        corners = [[x, y], [x + size, y], [x + size, y + size], [x, y + size]]
        walls.append(np.array(corners[:2] if g.random() < 0.5 else corners))
    static_map = StaticMap.from_polygons(walls) if walls else None
    b = 3
    obs = _obs([static_map] * b, b=b)
    robot = obs.robot.copy()
    robot[:, :2] = g.uniform(-4, 4, size=(b, 2))
    humans = obs.humans.copy()
    humans[:, :, :4] = g.normal(size=(b, 2, 4))
    obs = dataclasses.replace(obs, robot=robot, humans=humans)
    encoding = ObstaclePoints(count=count)
    plain = observation_tensors(obs, 0.25, steps)
    rf, hf, mk = observation_tensors(obs, 0.25, steps, obstacle_encoding=encoding)
    torch.testing.assert_close(rf, plain[0])
    torch.testing.assert_close(hf[:, :2], plain[1])
    assert torch.equal(mk[:, :2], plain[2])
    points, mask = encoding.nearest(robot[:, :2], [static_map] * b)
    assert mk[:, 2:].numpy().tolist() == mask.tolist()
    relative = (points - robot[:, None, :2]) * mask[..., None]
    expected = np.tile(relative, (1, 1, steps + 1))
    np.testing.assert_allclose(hf[:, 2:].numpy(), expected, rtol=1e-6, atol=1e-5)


def test_without_an_encoding_or_beyond_range_the_network_sees_no_points():
    _, humans, mask = observation_tensors(_obs([WALL]), 0.25, 2)
    assert humans.shape == (1, 2, 6) and mask.shape == (1, 2)
    far = StaticMap.from_polygons([np.array([[0.0, 6.5], [2.0, 6.5]])])  # 4.5 m away: out of range
    _, humans, mask = observation_tensors(_obs([far]), 0.25, 2, obstacle_encoding=ObstaclePoints())
    assert mask[0].tolist() == [True, False] + [False] * 16 and not humans[0, 2:].any()


@pytest.mark.parametrize("kind", ["crowdnav_pp", "ppo_mlp"])
def test_a_wall_in_front_of_the_robot_changes_the_action(kind):
    net = _attn_graph() if kind == "crowdnav_pp" else _mlp()
    open_floor = _actor(net, name=kind).act(_obs())
    walled = _actor(net, name=kind).act(_obs([WALL]))
    assert np.abs(walled - open_floor).max() > 1e-5
    # per episode: a batch of a walled and an open episode acts as each does alone
    both = _actor(net, name=kind).act(_obs([WALL, None], b=2))
    np.testing.assert_allclose(both, np.concatenate([walled, open_floor]), rtol=1e-5, atol=1e-6)


def test_crowdnav_pp_on_an_open_floor_acts_as_without_the_point_slots():
    """The K masked slots take no part in either attention; the sums run over more (zero) terms, so the
    actions agree to float32 rounding (about 1e-9 here), not bit for bit."""
    net = _attn_graph(seed=3)
    g = np.random.default_rng(0)
    b = 6
    obs = _obs(b=b)
    humans = obs.humans.copy()
    humans[:, :, :4] = g.normal(size=(b, 2, 4))
    mask = g.random((b, 2)) < 0.7
    obs = Observation(obs.robot, humans, mask, obs.active, obs.time, obs.dt, obs.kinematics)
    later = Observation(obs.robot, humans, mask, obs.active, obs.time + 0.25, obs.dt, obs.kinematics)
    with_points, without = _actor(net), _actor(net, encoding=None)
    for o in (obs, later):  # the GRU state carried from the first step to the second
        np.testing.assert_allclose(with_points.act(o), without.act(o), rtol=1e-6, atol=1e-7)


def test_ppo_mlp_on_an_open_floor_acts_as_the_network_without_point_inputs():
    """The padded point slots are zero inputs (flags 0): the walled MLP acts as an open-floor MLP whose
    first layers are its own without the point columns."""
    walled = _mlp(seed=2)
    plain = _mlp(obstacle_slots=0)
    state = walled.state_dict()
    width = plain.actor[0].in_features
    for head in ("actor", "critic"):
        state[f"{head}.0.weight"] = state[f"{head}.0.weight"][:, :width]
    plain.load_state_dict(state)
    obs = _obs(b=3)
    np.testing.assert_allclose(_actor(walled, name="ppo_mlp").act(obs),
                               _actor(plain, encoding=None, name="ppo_mlp").act(obs), rtol=1e-6, atol=1e-7)
    robot, humans, mask = observation_tensors(obs, 0.25, 2, obstacle_encoding=ObstaclePoints())
    assert not walled.flat_input(robot, humans, mask)[:, width:].any()


def test_ppo_mlp_keeps_its_human_slots_beside_a_wall():
    """The points have slots of their own: the nearest human stays in the input however close the wall."""
    net = _mlp()
    robot, humans, mask = observation_tensors(_obs([WALL]), 0.25, 2, obstacle_encoding=ObstaclePoints())
    x = net.flat_input(robot, humans, mask)
    f = net.input_dim + 1
    human_slot = x[0, 9 : 9 + f]
    assert human_slot[-1] == 1.0  # the flag of the real human, first of the max_humans = 2 slots
    points = x[0, 9 + 2 * f :].view(16, f)
    assert points[:, -1].tolist() == [1.0] * 5 + [0.0] * 11
    with pytest.raises(ValueError, match="16 point slots, the input has 2 slots"):
        net.flat_input(*observation_tensors(_obs([WALL]), 0.25, 2))


def _config(trained_on: str, encoding: bool):
    trained = load_preset(trained_on)
    vp = ppo_policy_config(load_preset("francis2023"))
    if not encoding:
        vp.pop("obstacle_encoding")
    return json.loads(json.dumps({"ppo_policy": vp, "preset": trained.to_dict(), "policy": "crowdnav_pp"},
                                 default=lambda v: list(v) if isinstance(v, tuple) else str(v)))


def test_the_checkpoint_keeps_the_encoding_and_acts_the_same(tmp_path):
    net = _attn_graph()
    config = _config("francis2023", encoding=True)
    assert config["ppo_policy"]["obstacle_encoding"] == ObstaclePoints().to_dict()
    path = save_checkpoint(tmp_path / "walls.pt", "crowdnav_pp", net, config=config)
    policy = load_ppo_policy("crowdnav_pp", path, preset=load_preset("francis2023"))
    assert policy.obstacle_encoding == ObstaclePoints() and policy.preset_mismatch == []
    assert policy.describe()["obstacle_encoding"] == ObstaclePoints().to_dict()
    np.testing.assert_array_equal(policy.act(_obs([WALL])), _actor(net).act(_obs([WALL])))


def test_an_old_checkpoint_without_the_key_reads_no_obstacles(tmp_path):
    net = _attn_graph()
    config = _config("crowdnav", encoding=False)
    path = save_checkpoint(tmp_path / "open.pt", "crowdnav_pp", net, config=config)
    policy = load_ppo_policy("crowdnav_pp", path, preset=load_preset("crowdnav"))
    assert policy.obstacle_encoding is None and "obstacle_encoding" not in policy.describe()
    np.testing.assert_array_equal(policy.act(_obs([WALL])), _actor(net, encoding=None).act(_obs()))


def test_a_checkpoint_trained_without_walls_is_refused_under_a_walled_preset(tmp_path):
    path = save_checkpoint(tmp_path / "open.pt", "crowdnav_pp", _attn_graph(),
                           config=_config("crowdnav", encoding=False))
    with pytest.raises(PresetMismatchError, match="walls: the checkpoint was trained without walls"):
        load_ppo_policy("crowdnav_pp", path, preset=load_preset("francis2023"))
    allowed = load_ppo_policy("crowdnav_pp", path, preset=load_preset("francis2023"),
                              allow_preset_mismatch=True)
    assert allowed.obstacle_encoding is None
    assert any(m.startswith("walls:") for m in allowed.describe()["preset_mismatch_allowed"])


def test_a_bad_encoding_or_one_the_mlp_does_not_read_is_refused(tmp_path):
    config = _config("francis2023", encoding=True)
    config["ppo_policy"]["obstacle_encoding"]["count"] = 0
    path = save_checkpoint(tmp_path / "bad.pt", "crowdnav_pp", _attn_graph(), config=config)
    with pytest.raises(CheckpointError, match=r"config.ppo_policy.obstacle_encoding is invalid.*count"):
        load_ppo_policy("crowdnav_pp", path)
    path = save_checkpoint(tmp_path / "mlp.pt", "ppo_mlp", _mlp(obstacle_slots=8),
                           config=_config("francis2023", encoding=True))
    with pytest.raises(CheckpointError, match="has 16 point slots, its network reads 8"):
        load_ppo_policy("ppo_mlp", path)
    config = _config("francis2023", encoding=True)
    config["ppo_policy"]["obstacles"] = 1
    path = save_checkpoint(tmp_path / "extra.pt", "crowdnav_pp", _attn_graph(), config=config)
    with pytest.raises(CheckpointError, match="optionally obstacle_encoding"):
        load_ppo_policy("crowdnav_pp", path)

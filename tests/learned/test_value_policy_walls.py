"""ValuePolicy among walls: the obstacle points reach the network as standing agents, the lookahead
counts them for collisions only (hand-computed cases, end and swept rules), an open floor changes
nothing, and a policy without an encoding ignores walls as before."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from socialnav.maps.static_map import StaticMap
from socialnav.policies.learned import ValuePolicy, build
from socialnav.sim.observation import Observation, ObstacleArrays
from socialnav.sim.obstacle_points import ObstaclePoints

from .helpers import NETWORKS, random_scene

ENCODING = ObstaclePoints().to_dict()  # 16 points, 0.5 m, 4 m, radius 0.1
WALL_AHEAD = StaticMap(([[-2.0, 0.5], [2.0, 0.5]],))  # points every 0.5 m, one at (0, 0.5)


def _obs(robot, humans, mask, maps=None, next_humans=None):
    b = robot.shape[0]
    walls = None if maps is None else ObstacleArrays.from_maps(maps)
    return Observation(robot, humans, mask, np.ones(b, bool), np.zeros(b), 0.25, "holonomic",
                       next_humans, walls)


def _policy(name="rgl", encoding=ENCODING, zero=False, **kw):
    torch.manual_seed(3)
    net = build(name).to(torch.float64)
    if zero:  # V = 0 everywhere: the lookahead value of an action is its reward r̂
        with torch.no_grad():
            for p in net.parameters():
                p.zero_()
    return ValuePolicy(net, obstacle_encoding=encoding, **kw)


def _robot_at_origin(v_pref=1.0):
    robot = np.zeros((1, 9))
    robot[0, 4], robot[0, 6], robot[0, 7] = 0.3, -5.0, v_pref  # goal far behind: no success term
    return robot


def _action(heading_k: int, speed_i: int) -> int:
    return 1 + 5 * heading_k + speed_i  # CrowdSim's order (docs/policies_learned.md)


def test_without_an_encoding_walls_are_ignored_as_before():
    pol = _policy(encoding=None)
    robot, humans, mask = random_scene(np.random.default_rng(1), 4, 3)
    plain = _obs(robot, humans, mask)
    walled = _obs(robot, humans, mask, [WALL_AHEAD] * 4)
    assert pol.encode(walled) is walled
    np.testing.assert_array_equal(pol.values(walled), pol.values(plain))


@pytest.mark.parametrize("name", NETWORKS)
def test_an_encoded_policy_on_an_open_floor_scores_as_without_the_encoding(name):
    """The K appended slots are all padding on an open floor: every network ignores them."""
    robot, humans, mask = random_scene(np.random.default_rng(2), 6, 4)
    obs = _obs(robot, humans, mask)
    with_enc, without = _policy(name), _policy(name, encoding=None)
    encoded = with_enc.encode(obs)
    assert encoded.humans.shape == (6, 4 + 16, 5) and encoded.static_slots == 16
    assert not encoded.human_mask[:, 4:].any()
    np.testing.assert_allclose(with_enc.values(obs), without.values(obs), rtol=0, atol=1e-12)


def test_encode_appends_the_points_once_and_extends_the_oracles_next_humans():
    pol = _policy()
    robot = _robot_at_origin()
    humans = np.array([[[3.0, 3.0, 0.5, 0.0, 0.3]]])
    nxt = humans.copy()
    nxt[..., 0] += 0.125
    obs = pol.encode(_obs(robot, humans, np.array([[True]]), [WALL_AHEAD], next_humans=nxt))
    assert obs.static_slots == 16 and pol.encode(obs) is obs
    # the nearest points of the wall y = 0.5 from the origin: (0, 0.5) first
    np.testing.assert_allclose(obs.humans[0, 1], [0.0, 0.5, 0.0, 0.0, 0.1])
    assert obs.human_mask[0].sum() == 1 + 9  # the 9 points of the 4 m wall, all within 4 m
    np.testing.assert_array_equal(obs.next_humans[0, 1:], obs.humans[0, 1:])  # points stand still
    np.testing.assert_array_equal(obs.next_humans[0, 0], nxt[0, 0])


def test_the_lookahead_counts_wall_points_for_collisions_only():
    """Robot at the origin (radius 0.3) below the wall y = 0.5 (points every 0.5 m, radius 0.1),
    V = 0 so that each action's value is its reward."""
    pol = _policy(zero=True)
    q = pol.values(_obs(_robot_at_origin(), np.zeros((1, 0, 5)), np.zeros((1, 0), bool), [WALL_AHEAD]))
    # +y at full speed: ends at (0, 0.25), 0.25 m from the point (0, 0.5) < 0.3 + 0.1: collision
    assert q[0, _action(4, 4)] == pytest.approx(-0.25)
    # +y at the second speed (0.286 m/s): ends at y = 0.0716, clearance 0.5 - 0.0716 - 0.4 = 0.028;
    # a human there would cost discomfort, a wall does not
    assert q[0, _action(4, 1)] == 0.0
    # away from the wall, and standing still: nothing
    assert q[0, _action(12, 4)] == 0.0 and q[0, 0] == 0.0


def test_a_human_still_costs_discomfort_beside_the_wall_points():
    pol = _policy(zero=True)
    humans = np.array([[[0.0, -0.75, 0.0, 0.0, 0.3]]])  # a standing human below the robot
    q = pol.values(_obs(_robot_at_origin(), humans, np.array([[True]]), [WALL_AHEAD]))
    # -y at the second speed: ends 0.0716 m lower, human clearance 0.75 - 0.0716 - 0.6 = 0.0784 < 0.2
    speed = (np.exp(0.4) - 1) / (np.e - 1)  # CrowdSim's second speed at v_pref 1
    expected = (0.75 - 0.25 * speed - 0.6 - 0.2) * 0.5 * 0.25
    assert q[0, _action(12, 1)] == pytest.approx(expected, abs=1e-12)


def test_the_swept_rule_catches_a_wall_crossed_within_one_step():
    """v_pref 4 m/s: a full-speed step of 1 m crosses the wall at y = 0.5 with both ends 0.5 m away
    from its points (more than 0.3 + 0.1): the end rule sees nothing, the swept rule a collision."""
    robot = _robot_at_origin(v_pref=4.0)
    args = (robot, np.zeros((1, 0, 5)), np.zeros((1, 0), bool), [WALL_AHEAD])
    end = _policy(zero=True).values(_obs(*args))
    swept = _policy(zero=True, reward_rule="swept").values(_obs(*args))
    assert end[0, _action(4, 4)] == 0.0
    assert swept[0, _action(4, 4)] == pytest.approx(-0.25)
    assert swept[0, _action(12, 4)] == 0.0


@pytest.mark.parametrize("information", ["constant_velocity", "learned"])
def test_points_do_not_move_under_prediction(information):
    from socialnav.policies.learned.predictor import StatePredictor

    torch.manual_seed(0)
    predictor = StatePredictor().to(torch.float64)
    with torch.no_grad():  # a predictor that moves everything it is given
        for p in predictor.parameters():
            p.normal_(0, 0.5)
    pol = _policy(information=information, predictor=predictor)
    robot, humans, mask = random_scene(np.random.default_rng(4), 2, 3)
    obs = pol.encode(_obs(robot, humans, mask, [WALL_AHEAD, WALL_AHEAD]))
    h = torch.as_tensor(obs.humans)
    m = torch.as_tensor(obs.human_mask)
    nxt = pol.predict_humans(torch.as_tensor(robot), h, m, 0.25, static=16)
    torch.testing.assert_close(nxt[:, 3:], h[:, 3:], rtol=0, atol=0)


@pytest.mark.parametrize("name", ["sarl", "om_sarl"])
def test_the_native_scorer_scores_wall_points_like_the_torch_module(name):
    from socialnav import _core

    if not _core.SarlScorer.supported():
        pytest.skip("CPU without AVX2/FMA")
    torch.manual_seed(5)
    net = build(name)
    robot, humans, mask = random_scene(np.random.default_rng(6), 5, 4)
    obs = _obs(robot, humans, mask, [WALL_AHEAD, None, WALL_AHEAD, WALL_AHEAD, None])
    native = ValuePolicy(net, obstacle_encoding=ENCODING, scorer="native")
    module = ValuePolicy(net, obstacle_encoding=ENCODING, scorer="torch")
    assert native.active_scorer == "native"
    np.testing.assert_allclose(native.values(obs), module.values(obs), rtol=1e-4, atol=1e-5)


def test_a_checkpoint_with_a_bad_obstacle_encoding_is_refused_by_name(tmp_path):
    from socialnav.policies.learned.checkpoint import CheckpointError, save_checkpoint
    from socialnav.policies.learned_loading import load_learned_policy

    good = {"kinematics": "holonomic", "obstacle_encoding": ObstaclePoints(count=4).to_dict()}
    save_checkpoint(tmp_path / "good.pt", "rgl", build("rgl"), config={"value_policy": good})
    assert load_learned_policy("rgl", tmp_path / "good.pt").value_policy.obstacle_encoding.count == 4
    bad = {"kinematics": "holonomic", "obstacle_encoding": {"kind": "outline_points", "count": 0}}
    save_checkpoint(tmp_path / "bad.pt", "rgl", build("rgl"), config={"value_policy": bad})
    with pytest.raises(CheckpointError, match=r"config.value_policy is invalid: obstacle_encoding.count"):
        load_learned_policy("rgl", tmp_path / "bad.pt")

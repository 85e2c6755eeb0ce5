"""Action set, propagation, agent-centric rotation, reward and occupancy maps on hand-built cases."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from socialnav.policies.learned.actions import discrete_actions, speed_fractions
from socialnav.policies.learned.state import (
    RewardParams,
    occupancy_map,
    propagate_humans_constant_velocity,
    propagate_robot,
    reward,
    rotate,
)

SPEEDS = np.array([(math.exp((i + 1) / 5) - 1) / (math.e - 1) for i in range(5)])


def test_speed_fractions_values():
    # (e^{(i+1)/5} - 1)/(e - 1), evaluated by hand to 6 decimals
    want = [0.128851, 0.286231, 0.478454, 0.713236, 1.0]
    np.testing.assert_allclose(speed_fractions().numpy(), want, atol=1e-6)


def test_holonomic_action_set():
    v_pref = torch.tensor([1.0, 0.5], dtype=torch.float64)
    a = discrete_actions("holonomic", v_pref).numpy()
    assert a.shape == (2, 81, 2)
    assert np.all(a[:, 0] == 0.0)  # stop first
    speed = np.linalg.norm(a[:, 1:], axis=-1).reshape(2, 16, 5)  # heading-major, speed-minor
    np.testing.assert_allclose(speed[0], np.tile(SPEEDS, (16, 1)), atol=1e-12)
    np.testing.assert_allclose(speed[1], 0.5 * np.tile(SPEEDS, (16, 1)), atol=1e-12)
    ang = np.arctan2(a[0, 1:, 1], a[0, 1:, 0]).reshape(16, 5)
    want = np.arange(16) * 2 * np.pi / 16
    np.testing.assert_allclose(np.mod(ang - want[:, None] + np.pi, 2 * np.pi) - np.pi, 0.0, atol=1e-12)
    # index 1 + k*5 + i: heading k, speed i
    np.testing.assert_allclose(a[0, 1 + 4 * 5 + 4], [0.0, 1.0], atol=1e-12)  # k=4: π/2, full speed


def test_unicycle_action_set_contains_straight():
    a = discrete_actions("unicycle", torch.tensor([2.0], dtype=torch.float64)).numpy()[0]
    assert a.shape == (81, 2) and np.all(a[0] == 0)
    rot = a[1:, 1].reshape(16, 5)
    assert np.all(rot == rot[:, :1])
    rots = rot[:, 0]
    assert rots[0] == pytest.approx(-math.pi / 4)
    assert np.any(rots == 0.0)  # straight ahead exists exactly
    np.testing.assert_allclose(np.diff(rots), math.pi / 32)
    assert np.all(np.abs(rots) <= math.pi / 4 + 1e-12)
    np.testing.assert_allclose(a[1:, 0].reshape(16, 5), 2.0 * np.tile(SPEEDS, (16, 1)), atol=1e-12)


def test_propagate_robot():
    robot = torch.tensor([[1.0, 2.0, 0.3, 0.4, 0.3, 5.0, 5.0, 1.0, 0.5]], dtype=torch.float64)
    acts = torch.tensor([[[1.0, -1.0], [0.0, 0.0]]], dtype=torch.float64)
    h = propagate_robot(robot, acts, "holonomic", 0.25)[0]
    np.testing.assert_allclose(h[0].numpy(), [1.25, 1.75, 1.0, -1.0, 0.3, 5, 5, 1, 0.5])
    np.testing.assert_allclose(h[1].numpy(), [1.0, 2.0, 0.0, 0.0, 0.3, 5, 5, 1, 0.5])
    acts_u = torch.tensor([[[1.0, math.pi / 4]]], dtype=torch.float64)
    robot_u = robot.clone()
    robot_u[0, 8] = math.pi / 4
    u = propagate_robot(robot_u, acts_u, "unicycle", 0.5)[0, 0].numpy()
    np.testing.assert_allclose(u, [1.0, 2.5, 0.0, 1.0, 0.3, 5, 5, 1, math.pi / 2], atol=1e-12)


def test_propagate_humans_constant_velocity():
    h = torch.tensor([[[1.0, 1.0, -2.0, 4.0, 0.3]]])
    np.testing.assert_allclose(
        propagate_humans_constant_velocity(h, 0.25)[0, 0].numpy(), [0.5, 2.0, -2, 4, 0.3]
    )


@pytest.mark.parametrize("kinematics", ["holonomic", "unicycle"])
def test_rotate_hand_computed(kinematics):
    # Robot at origin heading +y with goal (0, 4); human at (1, 0) moving -x.
    # rot = atan2(4, 0) = π/2: the frame's x-axis is world +y, its y-axis world -x.
    robot = torch.tensor([[0.0, 0.0, 0.0, 1.0, 0.3, 0.0, 4.0, 1.0, math.pi / 2]], dtype=torch.float64)
    humans = torch.tensor([[[1.0, 0.0, -1.0, 0.0, 0.4]]], dtype=torch.float64)
    j = rotate(robot, humans, kinematics)[0, 0].numpy()
    # dg, v_pref, theta, radius, vx, vy, px1, py1, vx1, vy1, radius1, da, radius_sum
    want = [4.0, 1.0, 0.0, 0.3, 1.0, 0.0, 0.0, -1.0, 0.0, 1.0, 0.4, 1.0, 0.7]
    np.testing.assert_allclose(j, want, atol=1e-12)


@pytest.mark.parametrize("kinematics", ["holonomic", "unicycle"])
def test_rotate_writes_each_column_once_in_the_asked_dtype(kinematics):
    # (B, K, 9) robots against (B, 1, N, 5) humans, as the lookahead calls it: the robot part is
    # broadcast over the humans, each row carries it, and asking for float32 is exactly .to(float32).
    g = torch.Generator().manual_seed(3)
    robot = torch.rand(4, 7, 9, generator=g, dtype=torch.float64) * 8 - 4
    humans = (torch.rand(4, 1, 5, 5, generator=g, dtype=torch.float64) * 8 - 4).expand(4, 7, 5, 5)
    ref = rotate(robot, humans, kinematics)
    assert ref.shape == (4, 7, 5, 13) and ref.dtype == torch.float64
    for h in range(5):
        assert torch.equal(ref[:, :, h, :6], ref[:, :, 0, :6])
        one = rotate(robot, humans[:, :, h : h + 1], kinematics)[:, :, 0]
        assert torch.equal(ref[:, :, h], one)
    got = rotate(robot, humans, kinematics, dtype=torch.float32)
    assert got.dtype == torch.float32 and torch.equal(got, ref.to(torch.float32))


def test_rotate_unicycle_heading_relative_to_goal_direction():
    robot = torch.tensor([[1.0, 1.0, 0.0, 0.0, 0.3, 2.0, 2.0, 1.0, 0.0]], dtype=torch.float64)
    humans = torch.tensor([[[1.0, 3.0, 0.0, 0.0, 0.3]]], dtype=torch.float64)
    j = rotate(robot, humans, "unicycle")[0, 0].numpy()
    assert j[0] == pytest.approx(math.sqrt(2))
    assert j[2] == pytest.approx(-math.pi / 4)  # theta - rot
    # human at (0, 2) relative, frame rotated by π/4: (2 sin π/4, 2 cos π/4) = (√2, √2)
    np.testing.assert_allclose(j[6:8], [math.sqrt(2), math.sqrt(2)], atol=1e-12)
    assert j[11] == pytest.approx(2.0)


def _robot_at(x, y, gx=5.0, gy=0.0):
    return torch.tensor([x, y, 0.0, 0.0, 0.3, gx, gy, 1.0, 0.0], dtype=torch.float64)


def _humans(*pos, r=0.3):
    return torch.tensor([[px, py, 0.0, 0.0, r] for px, py in pos], dtype=torch.float64)


def test_reward_cases():
    p = RewardParams()
    robots = torch.stack(
        [_robot_at(0, 0), _robot_at(0, 0), _robot_at(0, 0), _robot_at(4.9, 0), _robot_at(4.9, 0)]
    )
    humans = torch.stack(
        [
            _humans((0.5, 0.0), (3.0, 0.0)),  # clearance -0.1: collision
            _humans((0.0, 0.7), (3.0, 0.0)),  # clearance 0.1: discomfort
            _humans((2.0, 0.0), (3.0, 0.0)),  # nothing
            _humans((9.0, 0.0), (9.0, 9.0)),  # goal reached
            _humans((5.3, 0.0), (9.0, 9.0)),  # goal reached but colliding: collision wins
        ]
    )
    mask = torch.ones(5, 2, dtype=torch.bool)
    r = reward(robots, humans, mask, p).numpy()
    np.testing.assert_allclose(r, [-0.25, (0.1 - 0.2) * 0.5 * 0.25, 0.0, 1.0, -0.25], atol=1e-12)


def test_reward_ignores_padded_and_no_humans():
    robots = torch.stack([_robot_at(0, 0), _robot_at(0, 0)])
    humans = torch.stack([_humans((0.1, 0.0), (3.0, 0.0)), _humans((0.1, 0.0), (3.0, 0.0))])
    humans[1, 0, 0] = float("nan")  # garbage in a padded slot
    mask = torch.tensor([[False, True], [False, False]])
    np.testing.assert_array_equal(reward(robots, humans, mask).numpy(), [0.0, 0.0])
    assert reward(robots, humans[:, :0], mask[:, :0]).shape == (2,)


def test_reward_constants_are_settings():
    p = RewardParams(
        collision_penalty=-1.0, discomfort_dist=0.5, discomfort_penalty_factor=1.0, time_step=0.1
    )
    robots = torch.stack([_robot_at(0, 0), _robot_at(0, 0)])
    humans = torch.stack([_humans((0.5, 0.0)), _humans((0.9, 0.0))])
    r = reward(robots, humans, torch.ones(2, 1, dtype=torch.bool), p).numpy()
    np.testing.assert_allclose(r, [-1.0, (0.3 - 0.5) * 1.0 * 0.1], atol=1e-12)


def test_occupancy_map_hand_built():
    # human 0 at the origin walking +y (frame x = world +y, frame y = world -x)
    humans = torch.tensor(
        [
            [
                [0.0, 0.0, 0.0, 1.0, 0.3],
                [0.5, 1.5, 1.0, 0.0, 0.3],  # in 0's frame (1.5, -0.5): cell (3, 1) = 7, vel (0, -1)
                [-1.5, 0.2, 0.0, -1.0, 0.3],  # (0.2, 1.5): cell (2, 3) = 14, vel (-1, 0)
                [0.8, 1.2, 0.0, 1.0, 0.3],  # (1.2, -0.8): cell 7 too, vel (1, 0)
                [10.0, 10.0, 0.0, 0.0, 0.3],  # outside every map
                [0.1, 0.1, 5.0, 5.0, 0.3],  # padded
            ]
        ],
        dtype=torch.float64,
    )
    mask = torch.tensor([[True, True, True, True, True, False]])
    om = occupancy_map(humans, mask).numpy()[0]
    assert om.shape == (6, 48)
    m0 = om[0].reshape(16, 3)
    want0 = np.zeros((16, 3))
    want0[7] = [1.0, 0.5, -0.5]  # mean of (0, -1) and (1, 0)
    want0[14] = [1.0, -1.0, 0.0]
    np.testing.assert_allclose(m0, want0, atol=1e-12)
    # human 1 walks +x: its frame is the world frame
    m1 = om[1].reshape(16, 3)
    want1 = np.zeros((16, 3))
    want1[1] = [1.0, 0.0, 1.0]  # human 0 at (-0.5, -1.5): cell (1, 0)
    want1[6] = [1.0, 0.0, 1.0]  # human 3 at (0.3, -0.3): cell (2, 1)
    want1[0] = [1.0, 0.0, -1.0]  # human 2 at (-2.0, -1.3): cell (0, 0), on the map's edge
    np.testing.assert_allclose(m1, want1, atol=1e-12)
    np.testing.assert_array_equal(om[4], 0.0)  # nobody near human 4
    np.testing.assert_array_equal(om[5], 0.0)  # padded human has an empty map


def test_occupancy_map_channels():
    humans = torch.tensor([[[0.0, 0.0, 1.0, 0.0, 0.3], [0.5, 0.5, 0.0, 2.0, 0.3]]], dtype=torch.float64)
    mask = torch.ones(1, 2, dtype=torch.bool)
    om1 = occupancy_map(humans, mask, om_channel_size=1)[0, 0].numpy()
    om2 = occupancy_map(humans, mask, om_channel_size=2)[0, 0].numpy().reshape(16, 2)
    assert om1.shape == (16,) and om1[10] == 1 and om1.sum() == 1  # (0.5, 0.5) → cell (2, 2)
    np.testing.assert_allclose(om2[10], [0.0, 2.0])

"""The value policy's parts on their own: observation → tensors; r̂ with obstacle points, hand-computed."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from socialnav.policies.learned.lookahead_inputs import lookahead_inputs, static_slots
from socialnav.policies.learned.lookahead_reward import lookahead_reward
from socialnav.policies.learned.state import RewardParams

CPU = torch.device("cpu")


def robot_at(x: float, y: float) -> list[float]:
    """A robot state (radius 0.3, goal far away so that no success reward fires)."""
    return [x, y, 0.0, 0.0, 0.3, 10.0, 10.0, 1.0, 0.0]


def test_a_mapping_without_humans_gets_one_padded_slot_and_the_default_dt():
    obs = {"robot": np.array([robot_at(0, 0)]), "humans": np.zeros((1, 0, 5)),
           "human_mask": np.zeros((1, 0), bool)}
    x = lookahead_inputs(obs, None, CPU, default_dt=0.3)
    assert x.dt == 0.3 and x.as_numpy and x.static == 0 and x.next_humans is None
    assert x.robot.dtype == torch.float64 and x.robot.shape == (1, 9)
    assert x.humans.shape == (1, 1, 5) and not x.mask.any()


def test_the_oracles_next_humans_get_the_obstacle_points_where_they_are():
    humans = np.arange(15, dtype=float).reshape(1, 3, 5)  # one human, then two obstacle points
    obs = {"robot": np.array([robot_at(0, 0)]), "humans": humans, "human_mask": np.ones((1, 3), bool),
           "dt": 0.25, "static_slots": 2}
    nxt = np.full((1, 1, 5), -1.0)
    x = lookahead_inputs(obs, nxt, CPU, default_dt=0.3)
    assert x.dt == 0.25 and x.static == static_slots(obs) == 2
    assert x.next_humans is not None
    assert x.next_humans.tolist() == [[[-1.0] * 5, humans[0, 1].tolist(), humans[0, 2].tolist()]]


def test_a_float32_tensor_observation_stays_float32_and_torch():
    obs = {"robot": torch.tensor([robot_at(0, 0)], dtype=torch.float32),
           "humans": torch.zeros(1, 2, 5), "human_mask": torch.ones(1, 2, dtype=torch.bool)}
    x = lookahead_inputs(obs, None, CPU, default_dt=0.25)
    assert not x.as_numpy and x.robot.dtype == x.humans.dtype == torch.float32


@pytest.mark.parametrize(
    "rule, point_mask, expected",
    [
        # action 0 ends at (1, 0): 0.539 m from the point, clear; its segment passes 0.2 m from it, a hit
        # action 1 ends at (0, -1): 1.3 m away; its segment's nearest point, the start, is 0.539 m away
        ("end", True, [0.0, 0.0]),
        ("swept", True, [-0.25, 0.0]),
        ("swept", False, [0.0, 0.0]),  # a padded point slot is never hit
    ],
)
def test_an_obstacle_point_counts_for_collision_only(rule, point_mask, expected):
    robot = torch.tensor([robot_at(0, 0)], dtype=torch.float64)
    robot_next = torch.tensor([[robot_at(1, 0), robot_at(0, -1)]], dtype=torch.float64)
    point = torch.tensor([[[0.5, 0.2, 0.0, 0.0, 0.0]]], dtype=torch.float64)  # radius 0
    mask = torch.tensor([[point_mask]])
    r = lookahead_reward(robot, robot_next, point, point, mask, 1, rule, RewardParams())
    assert r.tolist() == [expected]


def test_a_point_within_the_discomfort_distance_costs_nothing():
    # 0.35 m from the end position: clearance 0.05 m < discomfort_dist 0.2 m, which a human would pay for
    robot = torch.tensor([robot_at(0, 0)], dtype=torch.float64)
    robot_next = torch.tensor([[robot_at(1, 0)]], dtype=torch.float64)
    point = torch.tensor([[[1.35, 0.0, 0.0, 0.0, 0.0]]], dtype=torch.float64)
    mask = torch.ones(1, 1, dtype=torch.bool)
    as_point = lookahead_reward(robot, robot_next, point, point, mask, 1, "end", RewardParams())
    assert as_point.tolist() == [[0.0]]
    as_human = lookahead_reward(robot, robot_next, point, point, mask, 0, "end", RewardParams())
    assert as_human.item() == pytest.approx((0.05 - 0.2) * 0.5 * 0.25)

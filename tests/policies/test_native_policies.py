"""The native robot policies (linear, ORCA, social force) take the world's settings, as its humans do."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from socialnav.policies.building import build_policy
from socialnav.policies.native import NativePolicy
from socialnav.presets import load_preset
from socialnav.scenarios import make_scenario
from socialnav.sim import World
from socialnav.sim.settings import OrcaSettings


def _preset(**world):
    preset = load_preset("wang2022")
    return dataclasses.replace(preset, world=dataclasses.replace(preset.world, **world))


def test_the_robot_orca_policy_uses_the_presets_orca_parameters():
    orca = OrcaSettings(time_horizon=2.0, neighbor_dist=3.0)
    preset = _preset(orca=orca)
    policy = build_policy("orca", preset)
    assert (policy._orca_settings.time_horizon, policy._orca_settings.neighbor_dist) == (2.0, 3.0)
    world = World(preset.world, make_scenario("circle_crossing", n_humans=5, robot_v_pref=1.5), 8,
                  split="test", count=8)
    world.reset()
    for _ in range(6):  # into the crossing, where the horizons decide
        world.step(np.zeros((8, 2)))
    obs = world.observe()
    action = policy.act(obs)
    by_hand = NativePolicy("orca", safety_space=policy.safety_space, orca=orca, threads=1).act(obs)
    np.testing.assert_array_equal(action, by_hand)  # what the humans use, not the defaults
    default = build_policy("orca", load_preset("wang2022")).act(obs)
    assert not np.array_equal(default, action)  # the horizons matter here: the test can tell


def test_native_policies_turn_by_the_worlds_rotation_limit():
    preset = _preset(kinematics="unicycle", rotation_limit=math.pi / 3)
    world = World(preset.world, make_scenario("circle_crossing", n_humans=0, robot_v_pref=1.5), 1,
                  split="test", count=1)
    world.reset()
    world.goal[0, 0] = world.position[0, 0] + (5.0, 0.0)  # straight to the right: a turn of pi/2 wanted
    obs = world.observe()
    for name in ("linear", "orca", "social_force"):
        action = build_policy(name, preset).act(obs)
        assert abs(action[0, 1]) == math.pi / 3, name


def test_a_non_finite_real_human_is_refused_not_dropped():
    world = World(load_preset("wang2022").world, make_scenario("circle_crossing", n_humans=2), 2,
                  split="test", count=2)
    world.reset()
    obs = world.observe()
    humans = obs.humans.copy()
    humans[1, 0, 2] = np.inf
    for name in ("linear", "orca", "social_force"):
        with pytest.raises(ValueError, match=r"observation humans\[1, 0\] \(a real human\) is not finite"):
            build_policy(name, load_preset("wang2022")).act(dataclasses.replace(obs, humans=humans))


def test_maps_prepared_for_another_batch_are_refused_by_name():
    from socialnav import _core
    from socialnav.maps.static_map import StaticMap
    from socialnav.sim.observation import ObstacleArrays

    walls = ObstacleArrays.from_maps([StaticMap(([[0.0, 0.0], [1.0, 0.0]],))] * 2).native
    with pytest.raises(ValueError, match="obstacles: prepared for 2 episodes, the observation has 3"):
        _core.robot_actions("orca", np.zeros((3, 9)), np.zeros((3, 1, 5)), np.zeros((3, 1), bool),
                            np.ones(3, bool), 0, 1.0, 0.25, None, 0.0, None, _core.ThreadPool(1),
                            np.zeros((3, 2)), walls)

"""A learned policy refuses an observation it would turn into a silently wrong action."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

pytest.importorskip("torch")

from socialnav.policies.building import build_policy  # noqa: E402
from socialnav.presets import load_preset  # noqa: E402
from socialnav.scenarios import make_scenario  # noqa: E402
from socialnav.sim import World, WorldSettings  # noqa: E402


@pytest.fixture(scope="module")
def sarl():
    return build_policy("sarl", load_preset("wang2022"))


def _observation(**world):
    settings = WorldSettings(threads=1, **world)
    w = World(settings, make_scenario("circle_crossing", n_humans=3, robot_v_pref=1.5), 4, split="test",
              count=4)
    w.reset()
    return w.observe()


def test_a_unicycle_robots_observation_is_refused_by_a_holonomic_network(sarl):
    with pytest.raises(ValueError, match=r"trained for a holonomic robot; the observation is of a .unicycle"):
        sarl.act(_observation(kinematics="unicycle"))


def test_non_finite_values_of_real_humans_and_robots_are_named(sarl):
    obs = _observation()
    assert sarl.act(obs).shape == (4, 2)
    humans = obs.humans.copy()
    humans[2, 1, 0] = np.nan
    with pytest.raises(ValueError, match=r"observation humans\[2, 1\] \(a real human\) is not finite"):
        sarl.act(dataclasses.replace(obs, humans=humans))
    masked = dataclasses.replace(obs, humans=humans, human_mask=obs.human_mask & ~np.eye(4, 3, -1, bool))
    assert not masked.human_mask[2, 1]
    sarl.act(masked)  # the NaN sits in an empty slot: nothing reads it
    robot = obs.robot.copy()
    robot[0, 5] = np.nan  # a NaN goal: the network would stop the robot without a word
    with pytest.raises(ValueError, match=r"observation robot row 0 is not finite"):
        sarl.act(dataclasses.replace(obs, robot=robot))
    with pytest.raises(ValueError, match=r"robot must be \(B, 9\) and humans \(B, N, 5\)"):
        sarl.act(dataclasses.replace(obs, humans=obs.humans[..., :4]))

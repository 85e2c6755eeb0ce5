"""The route-following robot policies (orca_route, social_force_route): a global planner over the walls
(cpp/routes.hpp) with ORCA or social force as the local one."""

import dataclasses

import numpy as np
import pytest

from socialnav.evaluate.multi import ROUTE_POLICIES, default_specs
from socialnav.maps import StaticMap
from socialnav.policies import list_policies, make_policy
from socialnav.scenarios import make_scenario
from socialnav.sim import World, WorldSettings


def _actions(policy_name, static_map, episodes=6, steps=30, **params):
    scenario = make_scenario("circle_crossing", n_humans=3)
    with World(WorldSettings(threads=1), scenario, episodes, count=episodes, static_map=static_map) as world:
        obs = world.reset()
        policy = make_policy(policy_name, threads=1, **params)
        out = []
        for _ in range(steps):
            a = policy.act(obs)
            out.append(a)
            obs = world.step(a, observe=True).observation
        return np.array(out)


@pytest.mark.parametrize(("routed", "plain"),
                         [("orca_route", "orca"), ("social_force_route", "social_force")])
def test_on_an_open_floor_they_are_their_plain_kinds(routed, plain):
    assert np.array_equal(_actions(routed, None), _actions(plain, None))


def _reaches_goal(policy_name):
    # A wall across the robot's way from (0, -4) to (0, 4), closed on the left by a side wall: straight
    # towards the goal the robot stops against it (a local minimum); round its open end it arrives.
    walls = StaticMap(([[-6.0, 0.0], [1.5, 0.0]], [[-6.0, 0.0], [-6.0, -6.0]]))
    scenario = make_scenario("circle_crossing", n_humans=1)
    settings = WorldSettings(threads=1, time_limit=40.0)
    with World(settings, scenario, 1, count=1, static_map=walls) as world:
        obs = world.reset()
        world.position[0, 1] = world.goal[0, 1] = (10.0, -10.0)  # the human out of the way
        policy = make_policy(policy_name, threads=1)
        while True:
            result = world.step(policy.act(obs), observe=True)
            if result.finished:
                return result.finished[0].outcome
            obs = result.observation


def test_the_route_takes_the_robot_round_a_wall_where_plain_orca_stops():
    assert _reaches_goal("orca") != "success"
    assert _reaches_goal("orca_route") == "success"


def test_listed_and_recorded():
    names = {p.name for p in list_policies()}
    assert set(ROUTE_POLICIES) <= names
    record = make_policy("orca_route", route_clearance=0.15).describe()
    assert record["policy"] == "orca_route" and record["route_clearance"] == 0.15
    assert "route_clearance" not in make_policy("orca").describe()
    with pytest.raises(ValueError, match="route_clearance"):
        make_policy("orca_route", route_clearance=-1.0)


def test_policy_all_adds_them_under_walls_only():
    open_floor = [s.name for s in default_specs("wang2022", learned=False)]
    walled = [s.name for s in default_specs("francis2023", learned=False, walls=True)]
    assert not set(ROUTE_POLICIES) & set(open_floor)
    assert set(ROUTE_POLICIES) <= set(walled)
    route_spec = next(s for s in default_specs("francis2023", False, True) if s.name == "orca_route")
    assert dataclasses.asdict(route_spec)["label"] == "ORCA + route"

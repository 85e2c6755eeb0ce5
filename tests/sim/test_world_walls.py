"""Worlds with static obstacles: per-slot maps, humans among walls, the robot's wall collisions."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from tests.sim._walls import human_clearances, pillars_and_walls, walled_world, with_map

from socialnav import _core
from socialnav.maps.static_map import StaticMap
from socialnav.policies import make_policy
from socialnav.scenarios import make_scenario
from socialnav.settings import ConfigError
from socialnav.sim.settings import WorldSettings
from socialnav.sim.world import World

WALL_X = StaticMap(([[0.0, -3.0], [0.0, 3.0]],))  # a thin wall across the robot's path


def _run(world, policy="orca", max_steps=None):
    pol = make_policy(policy, threads=1)
    world.reset()
    finished, steps, worst = [], 0, np.inf
    while world.busy and (max_steps is None or steps < max_steps):
        finished += world.step(pol.act(world.observe())).finished
        worst = min(worst, float(human_clearances(world).min()))
        steps += 1
    return finished, worst


# -- settings and maps --------------------------------------------------------------------------------
def test_max_obstacle_vertices_is_checked_with_the_setting_named():
    with pytest.raises(ConfigError, match="max_obstacle_vertices"):
        WorldSettings(max_obstacle_vertices=-1)
    big = StaticMap(tuple([[x, 0.0], [x, 1.0]] for x in range(10)))  # 20 vertices
    with pytest.raises(ValueError, match="max_obstacle_vertices = 16"):
        walled_world(big, max_obstacle_vertices=16)
    world = walled_world(None, max_obstacle_vertices=16)
    with pytest.raises(ValueError, match=r"slot 1 has 20 vertices, more than max_obstacle_vertices = 16"):
        world.set_static_map(1, big)
    assert world.static_maps == [None, None]  # a refused map changes nothing
    huge = StaticMap(tuple([[x, 0.0], [x, 1.0]] for x in range(10_000)))  # 20 000 vertices
    many = walled_world(None, batch=2048, count=1000, max_obstacle_vertices=20_000)  # the test split's 1000
    with pytest.raises(ValueError, match=r"in each of 2048 slots needs 12\.2 GiB"):  # 320 bytes a vertex
        many.set_static_map(0, huge)


def test_slots_have_their_own_maps_and_an_open_slot_is_unchanged():
    """Slot 0 gets walls, slot 1 none: slot 1 runs bit-identical to a world without any map."""
    open_world = walled_world(None, n_humans=5, batch=2, count=2)
    walled = walled_world(None, n_humans=5, batch=2, count=2)
    walled.reset()
    walled.set_static_map(0, pillars_and_walls())
    open_world.reset()
    pol = make_policy("orca", threads=1)
    for _ in range(40):
        a = pol.act(open_world.observe())
        open_world.step(a)
        walled.step(pol.act(walled.observe()))
    np.testing.assert_array_equal(walled.position[1], open_world.position[1])
    assert not np.array_equal(walled.position[0], open_world.position[0])
    assert walled.observe().obstacles.maps == (walled.static_maps[0], None)


def test_slots_sharing_a_map_run_as_with_their_own_copies():
    """Slots whose maps are equal share one prepared copy in the core (and in the robot policies'
    prepared batch): each slot still runs exactly as in a world of its own with that map, and a
    different map in between is not mixed up with its neighbours'."""
    other = StaticMap(([[-1.0, 0.5], [1.0, 0.5]],))
    equal_copy = StaticMap(tuple(np.array(p) for p in pillars_and_walls().polygons))
    maps = [pillars_and_walls(), equal_copy, other, pillars_and_walls(), None]
    batch = walled_world(None, batch=5, count=5)
    batch.reset()
    for b, m in enumerate(maps):
        batch.set_static_map(b, m)
    prepared = batch.observe().obstacles.native
    assert prepared.episodes == 5
    n_walls = pillars_and_walls().n_vertices
    assert prepared.prepared_vertices == n_walls + other.n_vertices + n_walls  # runs of equal maps share
    pol = make_policy("orca", threads=1)
    for _ in range(60):
        batch.step(pol.act(batch.observe()))
    for b, m in enumerate(maps):
        alone = walled_world(None, batch=5, count=5)
        alone.reset()
        alone.set_static_map(b, m)
        for _ in range(60):
            alone.step(pol.act(alone.observe()))
        np.testing.assert_array_equal(alone.position[b], batch.position[b], err_msg=f"slot {b}")


@pytest.mark.parametrize("through", ["world", "scenario"])
def test_episodes_carry_the_map_into_their_trajectories(through):
    """The map given to the World, or the scenario's ``static_map`` attribute, reaches every episode
    (refilled ones included) and its trajectory."""
    if through == "world":
        world = walled_world(pillars_and_walls(), n_humans=3, batch=2, count=4)
    else:
        scenario = with_map(make_scenario("circle_crossing", n_humans=3), pillars_and_walls())
        world = World(WorldSettings(threads=1), scenario, 2, split="test", count=4)
    trajectories, _ = _run(world)
    assert len(trajectories) == 4
    assert all(t.static_map == pillars_and_walls() for t in trajectories)


def test_a_slot_map_set_by_hand_lasts_for_the_current_episode_only():
    world = walled_world(None, n_humans=2, batch=1, count=3)
    world.reset()
    world.set_static_map(0, WALL_X)
    assert world.observe().obstacles.maps == (WALL_X,)
    pol = make_policy("orca", threads=1)
    finished = []
    while not finished:
        finished = world.step(pol.act(world.observe())).finished
    assert finished[0].static_map == WALL_X
    assert world.static_maps == [None] and world.observe().obstacles is None


# -- ORCA humans ------------------------------------------------------------------------------------
def test_orca_humans_never_enter_the_obstacles_over_long_runs():
    world = walled_world(pillars_and_walls(), n_humans=10, batch=4, count=60, continue_after_success=True)
    _, worst = _run(world, max_steps=1500)
    # ORCA keeps radius + CrowdSim's 1 cm margin; rounding only below that.
    assert worst >= 0.01 - 1e-9


def _random_map(draw) -> StaticMap:
    polygons = []
    for _ in range(draw(st.integers(1, 5))):
        cx, cy = draw(st.floats(-1.6, 1.6)), draw(st.floats(-1.6, 1.6))
        kind = draw(st.sampled_from(["wall", "convex", "l_shape"]))
        angle = draw(st.floats(-math.pi, math.pi))
        rot = np.array([[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]])
        if kind == "wall":
            half = draw(st.floats(0.2, 0.8))
            local = np.array([[-half, 0.0], [half, 0.0]])
        elif kind == "convex":
            k = draw(st.integers(3, 7))
            r = draw(st.floats(0.15, 0.6))
            a = 2 * math.pi * np.arange(k) / k
            local = r * np.stack([np.cos(a), np.sin(a)], axis=1)
        else:
            s = draw(st.floats(0.3, 0.7))
            local = s * np.array([[0, 0], [1, 0], [1, 0.4], [0.4, 0.4], [0.4, 1], [0, 1]], dtype=float)
        polygons.append(np.array([cx, cy]) + local @ rot.T)
    return StaticMap(tuple(polygons))


@settings(max_examples=12, deadline=None)
@given(data=st.data())
def test_property_orca_humans_stay_out_of_random_obstacles(data):
    """Random maps of walls, convex polygons and non-convex L blocks (overlapping and crossing ones
    included) within 2.4 m of the centre; humans start beyond 3.3 m and cross the room."""
    static_map = _random_map(data.draw)
    seed_start = data.draw(st.integers(0, 10_000))
    world = walled_world(static_map, n_humans=8, batch=2, count=2, continue_after_success=True)
    world.stream.next_index = seed_start
    _, worst = _run(world, max_steps=300)
    assert worst >= -1e-6


def test_human_heading_into_a_wall_stops_and_one_at_an_angle_slides():
    """One ORCA human walks at a wall 1.5 m ahead (head-on and at 45 degrees); the robot is far away."""
    wall = StaticMap(([[2.0, -10.0], [2.0, 10.0]],))
    for goal, slides in (((6.0, 0.0), False), ((6.0, 4.0), True)):
        world = walled_world(wall, n_humans=1, batch=1, count=1, time_limit=60.0)
        world.reset()
        world.position[0, 0], world.goal[0, 0] = (-8.0, -8.0), (-8.0, -7.0)
        world.position[0, 1], world.goal[0, 1], world.velocity[0, 1] = (0.5, 0.0), goal, (0.0, 0.0)
        ys = []
        for _ in range(200):
            world.step(np.zeros((1, 2)))
            ys.append(world.position[0, 1, 1])
            assert world.position[0, 1, 0] <= 2.0 - world.radius[0, 1] - 0.01 + 1e-9
        # It closes in on the wall (the gap shrinks by dt / tau_obst per step) and stops there ...
        assert world.position[0, 1, 0] == pytest.approx(2.0 - 0.31, abs=1e-3)
        assert np.hypot(*world.velocity[0, 1]) < 1e-3
        if slides:  # ... after sliding along it to the point closest to its goal,
            assert max(np.diff(ys)) > 0.1 and ys[-1] == pytest.approx(4.0, abs=0.05)
        else:  # ... or straight ahead.
            assert np.abs(ys).max() < 1e-9


def test_corridor_keeps_the_humans_inside():
    """Two long walls 2 m apart along x; humans in both directions inside never leave the corridor."""
    corridor = StaticMap(([[-20.0, -1.0], [20.0, -1.0]], [[-20.0, 1.0], [20.0, 1.0]]))
    world = walled_world(corridor, n_humans=6, batch=1, count=1, time_limit=40.0)
    world.reset()
    world.position[0, 0], world.goal[0, 0] = (0.0, -10.0), (0.0, -9.0)
    rng = np.random.default_rng(3)
    for i in range(1, 7):
        side = -1.0 if i % 2 else 1.0
        world.position[0, i] = (side * (4.0 + 1.3 * i), rng.uniform(-0.5, 0.5))
        world.goal[0, i] = (-side * 12.0, rng.uniform(-0.5, 0.5))
        world.radius[0, i] = 0.3
    for _ in range(120):
        world.step(np.zeros((1, 2)))
        ys = world.position[0, 1:, 1]
        assert np.all(np.abs(ys) <= 1.0 - 0.3 - 0.01 + 1e-9)
    sides = np.array([-1.0 if i % 2 else 1.0 for i in range(1, 7)])
    assert np.all(np.sign(world.position[0, 1:, 0]) == -sides)  # everyone got through


# -- the robot ------------------------------------------------------------------------------------
def _robot_world(static_map, **settings):
    """One slot, one human far away; the robot at (-0.31, 0) with goal (5, 0)."""
    world = walled_world(static_map, n_humans=1, batch=1, count=1, **settings)
    world.reset()
    world.position[0, 0], world.goal[0, 0], world.radius[0, 0] = (-0.31, 0.0), (5.0, 0.0), 0.3
    world.position[0, 1], world.goal[0, 1] = (-8.0, 8.0), (-8.0, 9.0)
    return world


def test_robot_crossing_a_thin_wall_within_one_step_collides_with_the_obstacle():
    # dt = 1 s at 1 m/s: the robot's disc starts 1 cm short of the wall and ends 39 cm past it.
    world = _robot_world(WALL_X, dt=1.0)
    result = world.step(np.array([[1.0, 0.0]]))
    assert list(result.outcome) == ["collision"]
    assert list(result.collision_kind) == ["obstacle"]
    assert result.reward[0] == WorldSettings().reward.collision_penalty
    (trajectory,) = result.finished
    assert trajectory.settings["collision_kind"] == "obstacle"
    assert trajectory.static_map == WALL_X


def test_obstacle_penalty_and_termination_are_settings():
    from socialnav.sim.settings import RewardSettings

    world = _robot_world(WALL_X, dt=1.0, obstacle_collision_ends=False,
                         reward=RewardSettings(obstacle_collision_penalty=-0.05))
    result = world.step(np.array([[1.0, 0.0]]))
    assert list(result.outcome) == [""] and result.reward[0] == -0.05
    assert world.position[0, 0, 0] == pytest.approx(0.69)  # walls do not stop the robot: they cost


def test_human_collisions_are_reported_as_human():
    world = _robot_world(WALL_X, dt=0.25)
    world.position[0, 1] = world.goal[0, 1] = (-0.31, 0.7)  # standing 0.7 m above the robot
    result = world.step(np.array([[0.0, 1.0]]))
    assert list(result.collision_kind) == ["human"]
    assert result.finished[0].settings["collision_kind"] == "human"


def test_robot_next_to_a_wall_but_not_touching_is_fine():
    world = _robot_world(WALL_X, dt=0.25)
    result = world.step(np.array([[0.0, 1.0]]))  # along the wall, 1 cm away
    assert list(result.outcome) == [""] and result.reward[0] == 0.0


@pytest.mark.parametrize("policy", ["orca", "social_force"])
def test_orca_and_social_force_robots_avoid_the_walls_the_linear_robot_hits(policy):
    """A slanted wall segment across the straight line to the goal: the linear robot runs into it, the
    ORCA and social-force robots slide along it and round its end (both see the observation's
    obstacles). (Head-on to a wall, ORCA stops in front of it: it is a local avoider, not a planner.)"""
    wall = StaticMap(([[-1.0, -0.5], [1.0, 0.5]],))
    results = {}
    for name in ("linear", policy):
        world = walled_world(wall, n_humans=1, batch=1, count=1, time_limit=40.0)
        world.reset()
        world.position[0, 1], world.goal[0, 1] = (-9.0, 9.0), (-9.0, 10.0)
        pol = make_policy(name, threads=1)
        kinds = []
        while world.busy:
            r = world.step(pol.act(world.observe()))
            kinds += [k for k in r.collision_kind if k]
            results[name] = (r.outcome[0], kinds)
    assert results["linear"] == ("collision", ["obstacle"])
    assert results[policy][0] == "success"


# -- social force ---------------------------------------------------------------------------------
def test_social_force_wall_repulsion_matches_helbing_molnar_by_hand():
    """U0 = 10 m^2/s^2, R = 0.2 m: |F| = U0/R exp(-d/R) along the normal from the closest point."""
    params = None  # the social_force behaviour's defaults
    walls = StaticMap(([[1.0, -5.0], [1.0, 5.0]], [[-3.0, 2.0], [-1.0, 2.0], [-1.0, 3.0], [-3.0, 3.0]]))
    vertices, offsets = walls.to_flat()
    p = np.array([0.4, 1.0])
    wall = 10.0 / 0.2 * math.exp(-0.6 / 0.2)  # 0.6 m from the wall at x = 1, pushing -x
    corner = np.array([0.4, 1.0]) - np.array([-1.0, 2.0])  # the box's closest point is its corner (-1, 2)
    d = np.hypot(*corner)
    box = 10.0 / 0.2 * math.exp(-d / 0.2) * corner / d
    expected = np.array([-wall, 0.0]) + box
    force = _core.social_force_wall_force(p, vertices, offsets, params)
    assert force == pytest.approx(tuple(expected), rel=1e-12)
    # Inside a solid polygon the force pushes out through the nearest edge at full strength.
    inside = _core.social_force_wall_force(np.array([-2.0, 2.1]), vertices, offsets, params)
    assert inside == pytest.approx((-50.0 * math.exp(-3.0 / 0.2), -50.0), rel=1e-12)


def test_social_force_human_takes_the_wall_force_in_its_euler_step():
    wall = StaticMap(([[1.0, -5.0], [1.0, 5.0]],))
    world = walled_world(wall, n_humans=1, batch=1, count=1, human_model="social_force")
    world.reset()
    world.position[0, 0], world.goal[0, 0] = (-8.0, -8.0), (-8.0, -7.0)
    world.position[0, 1], world.goal[0, 1], world.v_pref[0, 1] = (0.4, 0.0), (0.4, 3.0), 1.0
    world.step(np.zeros((1, 2)))
    desired = np.array([0.0, 1.0])  # 3 m away: full speed towards the goal
    force = desired / 0.5 + np.array([-10.0 / 0.2 * math.exp(-0.6 / 0.2), 0.0])  # robot: invisible
    v = 0.25 * force
    v *= min(1.0, 1.3 / np.hypot(*v))
    np.testing.assert_allclose(world.velocity[0, 1], v, rtol=1e-12)


# -- determinism ------------------------------------------------------------------------------------
def test_one_and_two_threads_give_bit_identical_trajectories_with_obstacles():
    runs = []
    for threads in (1, 2):
        world = walled_world(pillars_and_walls(), n_humans=8, batch=5, count=12, threads=threads,
                             continue_after_success=True)
        trajectories, _ = _run(world)
        runs.append({t.settings["index"]: t for t in trajectories})
    assert sorted(runs[0]) == sorted(runs[1]) == list(range(12))
    for k, a in runs[0].items():
        b = runs[1][k]
        assert a.outcome == b.outcome and a.settings.get("collision_kind") == b.settings.get("collision_kind")
        for name in ("positions", "velocities", "min_clearance", "continuation"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=f"{name} of {k}")

"""socialnav.sim.orca_step: the world's ORCA solver with obstacles, for one set of agents."""

import numpy as np
import pytest
from tests.sim._walls import pillars_and_walls, walled_world

from socialnav.maps.static_map import StaticMap
from socialnav.sim import orca_step


def test_orca_step_is_the_solver_of_the_worlds_orca_humans():
    """The humans' velocities after a world step equal orca_step on the state before it, with
    CrowdSim's inputs: radius + 1 cm, max speed v_pref, unit preferred velocity (the robot invisible)."""
    static_map = pillars_and_walls()
    world = walled_world(static_map, n_humans=8, batch=1, count=1)
    world.reset()
    for _ in range(12):  # let velocities build up near the obstacles
        world.step(np.zeros((1, 2)))
    p, v, g = world.position[0, 1:].copy(), world.velocity[0, 1:].copy(), world.goal[0, 1:]
    to_goal = g - p
    d = np.linalg.norm(to_goal, axis=1, keepdims=True)
    pref = np.where(d > 1.0, to_goal / d, to_goal)
    expected = orca_step(p, v, pref, world.radius[0, 1:] + 0.01, world.v_pref[0, 1:], static_map)
    world.step(np.zeros((1, 2)))
    np.testing.assert_array_equal(world.velocity[0, 1:], expected)


def test_a_wall_segment_blocks_from_both_sides_and_a_polygon_from_outside():
    wall = StaticMap(([[0.0, -5.0], [0.0, 5.0]],))
    # Two agents facing the wall from either side, 1 m away, preferring to walk through it (they
    # ignore each other: max_neighbors = 0). ORCA lets each close 1/tau_obst of the gap per second.
    v = orca_step([[-1.0, 0.0], [1.0, 0.5]], [[1.0, 0.0], [-1.0, 0.0]], [[1.0, 0.0], [-1.0, 0.0]],
                  [0.3, 0.3], [1.0, 1.0], wall, time_horizon_obst=5.0, max_neighbors=0)
    np.testing.assert_allclose(v, [[0.7 / 5.0, 0.0], [-0.7 / 5.0, 0.0]], atol=1e-12)
    box = StaticMap(([[1.0, -1.0], [3.0, -1.0], [3.0, 1.0], [1.0, 1.0]],))
    v = orca_step([[0.0, 0.0]], [[1.0, 0.0]], [[1.0, 0.0]], [0.3], [1.0], box, time_horizon_obst=2.0)
    np.testing.assert_allclose(v, [[0.7 / 2.0, 0.0]], atol=1e-12)
    # Without obstacles: the preferred velocity.
    free = orca_step([[0.0, 0.0]], [[0.0, 0.0]], [[0.6, 0.8]], [0.3], [1.0])
    np.testing.assert_array_equal(free, [[0.6, 0.8]])


def test_an_agent_touching_a_wall_may_not_move_further_in():
    wall = StaticMap(([[0.0, -5.0], [0.0, 5.0]],))
    v = orca_step([[-0.2, 0.0]], [[0.5, 0.0]], [[0.6, 0.8]], [0.3], [1.0], wall)
    assert v[0, 0] <= 1e-12 and v[0, 1] == pytest.approx(0.8)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"positions": [[0.0, 0.0, 0.0]]}, "positions must have shape"),
        ({"velocities": [[np.nan, 0.0]]}, "velocities contains a non-finite value"),
        ({"radii": [-0.1]}, "radii must be >= 0"),
        ({"max_speeds": [1.0, 2.0]}, r"max_speeds must have shape \(1,\)"),
        ({"time_horizon_obst": 0.0}, "time_horizon_obst must be a finite number > 0"),
        ({"max_neighbors": 65}, "max_neighbors must be an integer in"),
    ],
)
def test_orca_step_names_bad_arguments(kwargs, message):
    args = dict(positions=[[0.0, 0.0]], velocities=[[0.0, 0.0]], pref_velocities=[[1.0, 0.0]], radii=[0.3],
                max_speeds=[1.0])
    args.update(kwargs)
    with pytest.raises(ValueError, match=message):
        orca_step(**args)
    with pytest.raises(TypeError, match="static_map must be a StaticMap"):
        orca_step([[0.0, 0.0]], [[0.0, 0.0]], [[1.0, 0.0]], [0.3], [1.0], static_map=[[0, 0], [1, 1]])


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"max_neighbors": "a"}, "max_neighbors must be an integer in \\[0, 64\\], got 'a'"),
    ({"max_neighbors": None}, "max_neighbors must be an integer in \\[0, 64\\], got None"),
    ({"time_step": "x"}, "time_step must be a finite number > 0, got 'x'"),
    ({"time_horizon": None}, "time_horizon must be a finite number > 0, got None"),
])
def test_orca_step_names_an_argument_of_the_wrong_type(kwargs, message):
    from socialnav.sim import orca_step

    z = np.zeros((1, 2))
    with pytest.raises(ValueError, match=message):
        orca_step(z, z, z, np.full(1, 0.3), np.ones(1), **kwargs)


def test_discrete_actions_refuse_nonsense_speeds_and_limits():
    from socialnav.sim.actions import discrete_actions

    with pytest.raises(ValueError, match="v_pref must be a finite speed > 0"):
        discrete_actions("holonomic", -1.0)
    with pytest.raises(ValueError, match="rotation_limit must be a finite angle > 0"):
        discrete_actions("unicycle", 1.0, rotation_limit=0.0)

"""The differential drive (kinematics diff_drive): acceleration limits, exact arcs, reversing, its twist
in observations and snapshots, the native robots' command rule, and what refuses it (docs/kinematics.md)."""

import math

import numpy as np
import pytest
from _worldkit import hand_world, place

from socialnav import _core
from socialnav.sim.settings import DiffDriveSettings, WorldSettings


def diff_world(**limits) -> object:
    w = hand_world(human_model="linear", kinematics="diff_drive", diff_drive=DiffDriveSettings(**limits))
    place(w, 0, (0.0, 0.0), (0.0, 10.0), v_pref=1.0)
    place(w, 1, (5.0, 5.0), (5.0, 5.0))  # a human standing at its goal, out of the way
    w.theta[0] = math.pi / 2
    return w


def test_a_step_from_rest_with_both_acceleration_limits_active_by_hand():
    # dt 0.25 s, limits 2.5 m/s² and 3.2 rad/s²: from rest v can reach 0.625 m/s and ω 0.8 rad/s. The
    # command (1 m/s, dθ 0.5 rad → ω 2 rad/s) exceeds both, so v = 0.625, ω = 0.8. The arc of constant
    # (v, ω) over 0.25 s turns the heading by 0.2 rad; its chord has length
    # v·dt·sin(0.1)/0.1 = 0.15625 × 0.99833417 = 0.15598971 m along the mid-step heading π/2 + 0.1, i.e.
    # (−sin 0.1, cos 0.1) = (−0.09983342, 0.99500417): a displacement of (−0.01557299, 0.15521041) m.
    w = diff_world()
    w.step(np.array([[1.0, 0.5]]))
    assert w.theta[0] == pytest.approx(math.pi / 2 + 0.2, abs=1e-12)
    np.testing.assert_allclose(w.position[0, 0], (-0.01557299, 0.15521041), atol=1e-8)
    np.testing.assert_allclose(w.velocity[0, 0], np.array([-0.01557299, 0.15521041]) / 0.25, atol=1e-7)
    np.testing.assert_allclose(w.robot_twist(), [[0.625, 0.8]])
    # Braking to a stop and back to no turn: 0.625 m/s and 0.8 rad/s are exactly what one step removes.
    w.step(np.array([[0.0, -0.5]]))
    np.testing.assert_allclose(w.robot_twist(), [[0.0, 0.0]], atol=1e-15)
    np.testing.assert_allclose(w.position[0, 0], (-0.01557299, 0.15521041), atol=1e-8)
    assert w.theta[0] == pytest.approx(math.pi / 2 + 0.2, abs=1e-12)
    # Straight on at 0.625 m/s along π/2 + 0.2 = (−0.19866933, 0.98006658): (−0.03104208, 0.15313540) more.
    w.step(np.array([[1.0, 0.0]]))
    np.testing.assert_allclose(w.position[0, 0], (-0.04661507, 0.30834582), atol=1e-8)


def test_speed_and_turn_rate_bounds_apply_before_the_window():
    # A loose window (100 m/s², 100 rad/s²): v is bounded by v_pref 1 m/s, ω by rotation_limit / dt = π rad/s.
    w = diff_world(max_linear_acceleration=100.0, max_angular_acceleration=100.0)
    w.step(np.array([[5.0, 3.0]]))
    np.testing.assert_allclose(w.robot_twist(), [[1.0, math.pi]])
    assert w.theta[0] == pytest.approx(math.pi / 2 + math.pi / 4)


def test_the_arc_is_exact_whatever_the_step_is_cut_into():
    # Constant (v, ω) driven in one step or in ten steps of dt/10 ends at the same pose (the chord rule).
    ends = []
    for dt, steps in ((0.25, 1), (0.025, 10)):
        loose = DiffDriveSettings(max_linear_acceleration=1000.0, max_angular_acceleration=1000.0)
        w = hand_world(human_model="linear", kinematics="diff_drive", dt=dt,
                       rotation_limit=math.pi / 4 * dt / 0.25, diff_drive=loose)
        place(w, 0, (0.0, 0.0), (0.0, 10.0), v_pref=1.0)
        place(w, 1, (5.0, 5.0), (5.0, 5.0))
        w.theta[0] = 0.3
        for _ in range(steps):
            w.step(np.array([[0.8, 2.0 * dt]]))  # ω = 2 rad/s
        ends.append((w.position[0, 0].copy(), w.theta[0]))
    np.testing.assert_allclose(ends[0][0], ends[1][0], atol=1e-12)
    assert ends[0][1] == pytest.approx(ends[1][1], abs=1e-12)


def test_reversing_is_bounded_by_max_reverse_speed_and_off_by_default():
    w = diff_world()
    w.step(np.array([[-1.0, 0.0]]))
    np.testing.assert_allclose(w.robot_twist(), [[0.0, 0.0]])
    w = diff_world(max_linear_acceleration=100.0, max_reverse_speed=0.3)
    w.step(np.array([[-1.0, 0.0]]))
    np.testing.assert_allclose(w.robot_twist(), [[-0.3, 0.0]])
    np.testing.assert_allclose(w.position[0, 0], (0.0, -0.075), atol=1e-12)  # backwards along π/2


def test_every_episode_starts_at_rest_and_the_twist_is_restored():
    settings = WorldSettings(kinematics="diff_drive", threads=1)
    from socialnav.scenarios import make_scenario
    from socialnav.sim import World

    def world():
        return World(settings, make_scenario("circle_crossing", n_humans=3), 4, split="test", count=40)

    a, b = world(), world()
    obs = a.reset()
    np.testing.assert_array_equal(obs.robot_twist, np.zeros((4, 2)))
    b.reset()
    actions = np.tile([[1.0, 0.3]], (4, 1))
    for _ in range(3):
        a.step(actions)
    twist = a.robot_twist(new_at_rest=False)
    assert np.all(twist[:, 0] > 0)
    # b takes a's state arrays and twist: from there the two step identically
    for key in ("position", "velocity", "goal", "radius", "v_pref", "mask", "theta", "steps", "status"):
        np.copyto(getattr(b, key), getattr(a, key))
    b.set_robot_twist(twist)
    ra, rb = a.step(actions, observe=True), b.step(actions, observe=True)
    np.testing.assert_array_equal(a.position, b.position)
    np.testing.assert_array_equal(ra.observation.robot_twist, rb.observation.robot_twist)
    # A finished episode's final observation keeps its twist; the refilled slot starts at rest.
    short = World(WorldSettings(kinematics="diff_drive", threads=1, time_limit=1.0),
                  make_scenario("circle_crossing", n_humans=1), 1, split="test", count=2)
    short.reset()
    for _ in range(3):
        short.step(np.array([[1.0, 0.1]]))
    res = short.step(np.array([[1.0, 0.1]]), final_observation=True, observe=True)  # the 4th step: timeout
    assert res.truncated[0]
    np.testing.assert_allclose(res.final_observation.robot_twist, [[1.0, 0.4]])
    np.testing.assert_array_equal(res.observation.robot_twist, [[0.0, 0.0]])


def test_the_native_robots_drive_the_heading_projection_of_their_command():
    # The linear robot commands v_pref towards its goal; the diff drive turns towards it (at most
    # rotation_limit) and drives the command's component along its heading: |u| cos(error).
    robot = np.zeros((3, 9))
    robot[:, 4], robot[:, 7], robot[:, 8] = 0.3, 1.0, math.pi / 2  # radius, v_pref, facing +y
    robot[0, 5:7] = (10.0, 0.0)  # goal to the right: error -90°
    robot[1, 5:7] = (10 * math.cos(math.pi / 6), 10 * math.sin(math.pi / 6))  # error -60°
    robot[2, 5:7] = (0.0, -10.0)  # goal behind: error 180°
    humans, mask, active = np.zeros((3, 1, 5)), np.zeros((3, 1), bool), np.ones(3, bool)
    from socialnav.sim.pool import shared_pool

    def act(reverse: float) -> np.ndarray:
        out = np.zeros((3, 2))
        _core.robot_actions("linear", robot, humans, mask, active, _core.DIFF_DRIVE, math.pi / 4, 0.25, None,
                            0.0, None, shared_pool(1), out, None, 0.1, reverse)
        return out

    out = act(0.0)
    np.testing.assert_allclose(out[0], (0.0, -math.pi / 4), atol=1e-12)  # turns in place
    np.testing.assert_allclose(out[1], (0.5, -math.pi / 4), atol=1e-12)  # cos 60° of 1 m/s
    assert out[2, 0] == 0.0 and abs(out[2, 1]) == pytest.approx(math.pi / 4)  # turns (either way) at 180°
    # allowed to reverse, it backs towards the goal behind it without turning
    np.testing.assert_allclose(act(0.4)[2], (-0.4, 0.0), atol=1e-12)


def test_settings_record_the_limits_of_a_diff_drive_only():
    assert "diff_drive" not in WorldSettings().to_dict()
    assert "diff_drive" not in WorldSettings(kinematics="unicycle").to_dict()
    assert WorldSettings(kinematics="diff_drive").to_dict()["diff_drive"] == {
        "max_linear_acceleration": 2.5, "max_angular_acceleration": 3.2, "max_reverse_speed": 0.0}
    from socialnav.settings import ConfigError

    with pytest.raises((ConfigError, ValueError), match="max_linear_acceleration"):
        WorldSettings(diff_drive=DiffDriveSettings(max_linear_acceleration=0.0))


def test_the_env_passes_check_env_with_the_twist_and_bounds_reversing():
    import gymnasium as gym
    from gymnasium.utils.env_checker import check_env

    import socialnav.envs  # noqa: F401  (registers the envs)

    world = {"kinematics": "diff_drive", "diff_drive": {"max_reverse_speed": 0.2}}
    env = gym.make("socialnav/CircleCrossing-v0", world=world)
    check_env(env.unwrapped)
    obs, _ = env.reset(seed=0)
    np.testing.assert_array_equal(obs["robot_twist"], [0.0, 0.0])
    assert env.action_space.low[0] == -0.2
    obs, *_ = env.step(np.array([1.0, 0.0]))
    assert obs["robot_twist"][0] == pytest.approx(0.625)


def test_the_value_lookahead_moves_the_robot_as_the_world_does():
    torch = pytest.importorskip("torch")
    from socialnav.policies.learned.actions import discrete_actions
    from socialnav.policies.learned.sarl import SARL
    from socialnav.policies.learned.state import DiffDriveLimits, propagate_robot
    from socialnav.policies.learned.value_policy import ValuePolicy

    limits = DiffDriveSettings(max_reverse_speed=0.2)
    base = diff_world(max_reverse_speed=0.2)
    for action in ([1.0, 0.3], [0.4, -0.6]):  # a twist to start from
        base.step(np.array([action]))
    obs = base.observe()
    robot = torch.as_tensor(np.concatenate([obs.robot, obs.robot_twist], 1))
    actions = discrete_actions("diff_drive", robot[:, 7], math.pi / 4)  # (1, 81, 2)
    actions[0, 1] = torch.tensor([-1.0, 0.0])  # one candidate backs up
    predicted = propagate_robot(robot, actions, "diff_drive", 0.25,
                                DiffDriveLimits.of(limits.to_dict(), math.pi / 4))[0]
    for k in range(0, 81, 7):
        w = diff_world(max_reverse_speed=0.2)
        for key in ("position", "velocity", "theta", "steps"):
            np.copyto(getattr(w, key), getattr(base, key))
        w.set_robot_twist(obs.robot_twist)
        w.step(actions[0, k].numpy()[None])
        world_state = [*w.position[0, 0], *w.velocity[0, 0]]
        np.testing.assert_allclose(predicted[k, 0:4].numpy(), world_state, atol=1e-12)
        assert math.remainder(predicted[k, 8].item() - w.theta[0], 2 * math.pi) == pytest.approx(0, abs=1e-12)
        np.testing.assert_allclose(predicted[k, 9:].numpy(), w.robot_twist()[0], atol=1e-12)
    with pytest.raises(ValueError, match="diff_drive limits"):
        ValuePolicy(SARL(), kinematics="diff_drive")
    policy = ValuePolicy(SARL(), kinematics="diff_drive", diff_drive=limits.to_dict())
    _, chosen = policy.act(obs)
    assert chosen.shape == (1, 2)
    with pytest.raises(ValueError, match="robot_twist"):
        policy.act({"robot": obs.robot, "humans": obs.humans, "human_mask": obs.human_mask})


@pytest.mark.parametrize("preset", ["wang2022_unicycle", "wang2022_diffdrive"])
def test_the_kinematics_presets_find_their_shipped_crowdnav_pp(preset):
    pytest.importorskip("torch")
    from socialnav.policies.building import build_policy, shipped_checkpoint
    from socialnav.presets import load_preset

    path = shipped_checkpoint("crowdnav_pp", preset)
    assert path is not None and path.name == f"crowdnav_pp_{preset}.pt"
    policy = build_policy("crowdnav_pp", load_preset(preset))  # no --checkpoint
    assert policy.checkpoint == path and policy.kinematics == load_preset(preset).world.kinematics

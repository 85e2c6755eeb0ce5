"""Step semantics of the batched world on hand-built scenes with hand-computed answers."""

import math

import numpy as np
import pytest
from _worldkit import hand_world, place

from socialnav import _core
from socialnav.settings import ConfigError
from socialnav.sim.settings import WorldSettings


def test_linear_human_walks_at_v_pref_and_stops_at_goal():
    w = hand_world(human_model="linear")
    place(w, 0, (-5.0, -5.0), (-5.0, 5.0))
    place(w, 1, (0.0, 0.0), (0.6, 0.0), v_pref=1.0)
    w.step(np.zeros((1, 2)))
    np.testing.assert_allclose(w.position[0, 1], (0.25, 0.0))
    w.step(np.zeros((1, 2)))
    w.step(np.zeros((1, 2)))  # 0.5 -> 0.6: only the remaining 0.1 m, no overshoot
    np.testing.assert_allclose(w.position[0, 1], (0.6, 0.0))
    np.testing.assert_allclose(w.velocity[0, 1], (0.4, 0.0))


def test_swept_collision_is_detected_between_samples():
    # Robot at 4 m/s crosses 1 m in one step; a static human 0.55 m beside the path's midpoint:
    # clearance is 0.143 m at both ends of the step but -0.05 m in the middle.
    w = hand_world(human_model="linear")
    place(w, 0, (-1.0, 0.0), (10.0, 0.0), v_pref=4.0)
    place(w, 1, (-0.5, 0.55), (-0.5, 0.55))
    r = w.step(np.array([[4.0, 0.0]]))
    assert w.dmin[0] == pytest.approx(0.55 - 0.6)
    assert r.terminated[0] and not r.truncated[0]
    assert r.finished[0].outcome == "collision"
    assert r.reward[0] == pytest.approx(-0.25)


def test_discomfort_reward_matches_crowdsim_formula():
    w = hand_world(human_model="linear")
    place(w, 0, (0.0, 0.0), (0.0, 10.0))
    place(w, 1, (0.4, 0.6), (0.4, 0.6))
    w.step(np.array([[0.0, 0.0]]))
    d = math.hypot(0.4, 0.6) - 0.6  # 0.121 m < 0.2 m
    assert w.dmin[0] == pytest.approx(d)
    assert w.reward[0] == pytest.approx((d - 0.2) * 0.5 * 0.25)


def test_success_when_within_radius_of_goal():
    w = hand_world(human_model="linear")
    place(w, 0, (0.0, 0.0), (0.0, 0.5))
    place(w, 1, (5.0, 5.0), (5.0, 5.0))
    r = w.step(np.array([[0.0, 1.0]]))  # ends 0.25 m from the goal < radius 0.3
    assert r.terminated[0]
    assert r.reward[0] == 1.0
    assert r.outcome[0] == "success"
    traj = r.finished[0]
    assert traj.outcome == "success"
    assert traj.positions.shape == (2, 2, 2)
    np.testing.assert_allclose(traj.positions[1, 0], (0.0, 0.25))


def test_collision_takes_precedence_over_success():
    w = hand_world(human_model="linear")
    place(w, 0, (0.0, 0.0), (0.0, 0.25))
    place(w, 1, (0.0, 0.7), (0.0, 0.7))
    r = w.step(np.array([[0.0, 1.0]]))
    assert r.finished[0].outcome == "collision"


def test_timeout_at_time_limit_is_a_truncation():
    w = hand_world(human_model="linear", time_limit=1.0)
    place(w, 0, (0.0, 0.0), (0.0, 10.0))
    place(w, 1, (5.0, 5.0), (5.0, 5.0))
    for _ in range(3):
        r = w.step(np.zeros((1, 2)))
        assert not (r.terminated[0] or r.truncated[0])
    r = w.step(np.zeros((1, 2)))  # t = 1.0 >= limit
    assert r.truncated[0] and not r.terminated[0]
    assert r.finished[0].outcome == "timeout"
    assert r.reward[0] == 0.0


def test_crowdsim_compat_timeout_fires_one_second_early_and_wins():
    w = hand_world(human_model="linear", time_limit=2.0, crowdsim_compat=True)
    place(w, 0, (0.0, 0.0), (0.0, 10.0))
    place(w, 1, (5.0, 5.0), (5.0, 5.0))
    for _ in range(4):  # CrowdSim checks the clock before the step: t_before = 0, .25, .5, .75
        assert not w.step(np.zeros((1, 2))).truncated[0]
    w.position[0, 0] = (0.0, 9.9)  # would succeed in this step ...
    r = w.step(np.array([[0.0, 1.0]]))  # ... but t_before = 1.0 >= 2 - 1: timeout wins
    assert r.finished[0].outcome == "timeout"


def test_crowdsim_compat_sweeps_with_previous_human_velocity():
    # The human walks away fast; with its new velocity the sweep is clear, with its previous
    # (zero) velocity the robot's motion into the old position counts as a collision.
    for compat, expected in ((False, "running"), (True, "collision")):
        w = hand_world(human_model="linear", crowdsim_compat=compat)
        place(w, 0, (0.0, 0.0), (0.0, 10.0))
        place(w, 1, (0.0, 0.8), (0.0, 20.0), v_pref=2.0)
        r = w.step(np.array([[0.0, 1.0]]))
        outcome = r.finished[0].outcome if r.finished else "running"
        assert outcome == expected, compat


def test_human_overlaps_are_counted_unless_compat():
    for compat, expected in ((False, 1), (True, 0)):
        w = hand_world(n_humans=2, human_model="linear", crowdsim_compat=compat)
        place(w, 0, (-5.0, -5.0), (-5.0, 5.0))
        place(w, 1, (0.0, 0.0), (0.0, 0.0))
        place(w, 2, (0.5, 0.0), (0.5, 0.0))
        w.step(np.zeros((1, 2)))
        assert w.overlaps[0] == expected
        assert w.status[0] == _core.STATUS_RUNNING  # overlaps never end an episode


def test_visible_robot_is_avoided_invisible_is_not():
    # A human walks at a robot standing slightly off its path. Invisible: it walks through the
    # robot (the robot's own swept test ends the episode); visible: ORCA keeps it clear.
    closest = {}
    for visibility in ("invisible", "visible"):
        w = hand_world(visibility=visibility)
        place(w, 0, (0.0, 0.0), (10.0, -10.0))
        place(w, 1, (0.1, 3.0), (0.1, -3.0))
        gaps = []
        for _ in range(24):
            r = w.step(np.zeros((1, 2)))
            if r.finished:
                gaps.append(r.finished[0].min_clearance.min())
                break
            gaps.append(np.linalg.norm(w.position[0, 1] - w.position[0, 0]) - 0.6)
        closest[visibility] = min(gaps)
    assert closest["invisible"] < 0.0
    assert closest["visible"] > 0.0


def test_orca_modes_are_identical():
    """RVO2 computes an agent's new velocity from its neighbours' positions, velocities and radii only;
    the others' preferred velocities never enter it, so CrowdNav's decentralized mode (others prefer
    zero) and RGL's centralized mode give the same velocities."""
    outs = []
    for mode in ("centralized", "decentralized"):
        w = hand_world(n_humans=5, batch=8, orca_mode=mode)
        w.restart(0)
        trajs = []
        while w.busy:
            trajs += w.step(np.tile([0.0, 1.0], (8, 1))).finished
        outs.append(sorted(trajs, key=lambda t: t.settings["index"]))
    for a, b in zip(*outs, strict=True):
        np.testing.assert_array_equal(a.positions, b.positions)


def test_unicycle_turns_then_moves_along_new_heading():
    w = hand_world(human_model="linear", kinematics="unicycle")
    place(w, 0, (0.0, 0.0), (0.0, 10.0))
    place(w, 1, (5.0, 5.0), (5.0, 5.0))
    w.theta[0] = math.pi / 2
    w.step(np.array([[1.0, -math.pi / 4]]))
    assert w.theta[0] == pytest.approx(math.pi / 4)
    np.testing.assert_allclose(w.position[0, 0], (0.25 * math.cos(math.pi / 4), 0.25 * math.sin(math.pi / 4)))
    w.step(np.array([[1.0, 3.0]]))  # rotation clipped to the limit pi/4
    assert w.theta[0] == pytest.approx(math.pi / 2)


def test_holonomic_action_is_clipped_to_v_pref():
    w = hand_world(human_model="linear")
    place(w, 0, (0.0, 0.0), (0.0, 10.0), v_pref=1.0)
    place(w, 1, (5.0, 5.0), (5.0, 5.0))
    w.step(np.array([[0.0, 3.0]]))
    np.testing.assert_allclose(w.velocity[0, 0], (0.0, 1.0))
    w.step(np.array([[1e200, 0.0]]))  # |a|^2 overflows: still its direction at v_pref, not a stop
    np.testing.assert_allclose(w.velocity[0, 0], (1.0, 0.0))
    w.step(np.array([[-1e300, 1e300]]))
    np.testing.assert_allclose(w.velocity[0, 0], (-math.sqrt(0.5), math.sqrt(0.5)))


def test_continuation_after_success_records_humans_until_they_arrive():
    w = hand_world(human_model="linear", visibility="visible", continue_after_success=True)
    place(w, 0, (0.0, 0.0), (0.0, 0.25))
    place(w, 1, (3.0, 0.0), (3.0, 2.0))  # arrives (within 0.3 m) at t = 1.75 s
    r = w.step(np.array([[0.0, 1.0]]))
    assert not r.finished and w.status[0] == _core.STATUS_CONTINUING and w.end_step[0] == 1
    for _ in range(20):
        r = w.step(np.array([[0.0, 1.0]]))  # ignored: the robot is parked
        if r.finished:
            break
    traj = r.finished[0]
    assert traj.outcome == "success"
    assert traj.positions.shape[0] == 2  # the robot's episode: samples 0..1
    assert traj.continuation.shape[0] == 6  # samples 2..7 (t = 1.75 s is sample 7)
    np.testing.assert_allclose(traj.continuation[:, 0], np.tile([0.0, 0.25], (6, 1)))
    np.testing.assert_allclose(traj.continuation[-1, 1], (3.0, 1.75))


def test_human_overlaps_are_counted_over_the_robots_episode_only():
    # The robot reaches its goal at once; the two humans meet head-on during the M_III continuation.
    w = hand_world(n_humans=2, human_model="linear", visibility="visible", continue_after_success=True)
    place(w, 0, (0.0, 0.0), (0.0, 0.25))
    place(w, 1, (5.0, -2.0), (5.0, 2.0))
    place(w, 2, (5.0, 2.0), (5.0, -2.0))
    r = w.step(np.array([[0.0, 1.0]]))
    assert w.status[0] == _core.STATUS_CONTINUING
    while not r.finished:
        r = w.step(np.zeros((1, 2)))
    traj = r.finished[0]
    crossing = np.linalg.norm(traj.continuation[:, 1] - traj.continuation[:, 2], axis=1) < 0.6
    assert crossing.any()  # they did overlap, after the robot's episode
    assert traj.human_overlaps == 0  # as metrics.md defines it: samples k = 1..K of the robot's episode


def test_unicycle_heading_wraps_to_zero_two_pi_as_crowdsim():
    w = hand_world(human_model="linear", kinematics="unicycle")
    place(w, 0, (0.0, 0.0), (0.0, 50.0))
    place(w, 1, (9.0, 9.0), (9.0, 9.0))
    w.theta[0] = math.pi / 2
    for k in range(1, 21):  # a left turn of pi/4 per step, 5 whole turns
        w.step(np.array([[0.0, math.pi / 4]]))
        assert 0.0 <= w.theta[0] < 2 * math.pi
        assert w.theta[0] == pytest.approx((math.pi / 2 + k * math.pi / 4) % (2 * math.pi), abs=1e-12)
    w.theta[0] = 0.1
    w.step(np.array([[0.0, -math.pi / 4]]))  # below 0: wrapped up, as Python's % does
    assert w.theta[0] == pytest.approx(0.1 - math.pi / 4 + 2 * math.pi)


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_action_is_refused(bad):
    w = hand_world()
    with pytest.raises(ValueError, match="slot 0 is not finite"):
        w.step(np.array([[bad, 0.0]]))


def test_wrong_action_shape_is_refused():
    w = hand_world(batch=2)
    with pytest.raises(ValueError, match=r"actions must have shape \(2, 2\)"):
        w.step(np.zeros((3, 2)))


@pytest.mark.parametrize(("field", "value", "message"), [
    ("dt", 0.0, "dt must be"),
    ("dt", -0.25, "dt must be"),
    ("dt", float("nan"), "dt must be"),
    ("time_limit", -1.0, "time_limit must be"),
    ("human_model", "boids", "human_model must be one of 'orca', 'social_force', 'linear', got 'boids'"),
    ("visibility", "seen", "visibility must be one of"),
    ("kinematics", "car", "kinematics must be one of"),
])
def test_invalid_settings_name_the_field(field, value, message):
    with pytest.raises(ConfigError, match=message):
        WorldSettings(**{field: value})


def test_unknown_nested_setting_is_named():
    from socialnav.settings import from_dict
    with pytest.raises(ConfigError, match=r"orca\.horizon.*valid: max_neighbors, neighbor_dist"):
        from_dict(WorldSettings, {"orca": {"horizon": 3}})
    with pytest.raises(ConfigError, match=r"orca.max_neighbors must be in \[0, 64\]"):
        from_dict(WorldSettings, {"orca": {"max_neighbors": 100}})


def test_nan_in_scenario_state_is_refused():
    w = hand_world()
    import dataclasses

    from socialnav.sim.world import EpisodeStream
    ep = w.scenario.episodes("test", [0])
    bad = dataclasses.replace(ep, human_start=np.full_like(ep.human_start, np.nan))
    with pytest.raises(ValueError, match="non-finite human_start for episode index 0"):
        w._load(np.array([0]), bad)
    assert isinstance(w.stream, EpisodeStream)


@pytest.mark.parametrize("native", [True, False])
def test_idle_slots_once_the_stream_is_exhausted(native):
    from socialnav.sim.world import EpisodeStream

    w = hand_world(n_humans=2, batch=4)
    if not native:
        w._native_scenario = None  # the Python generator's path (custom scenarios)
    w.use_stream(EpisodeStream(w.scenario, "test", 0, 6))  # six episodes for four slots
    done = []
    for _ in range(200):
        done += w.step(np.zeros((4, 2))).finished
        if not w.busy:
            break
    assert sorted(t.settings["index"] for t in done) == list(range(6))
    assert (w.status == _core.STATUS_IDLE).all()


def test_oracle_preview_equals_the_next_step_and_changes_nothing():
    w = hand_world(n_humans=5, batch=4, visibility="visible")
    w.restart(0)
    for _ in range(3):
        w.step(np.tile([0.0, 1.0], (4, 1)))
    before = w.position.copy()
    obs = w.observe(oracle=True)
    np.testing.assert_array_equal(w.position, before)  # previewing does not move anyone
    w.step(np.tile([0.3, 0.5], (4, 1)))
    np.testing.assert_array_equal(obs.next_humans[..., :2], w.position[:, 1:])
    np.testing.assert_array_equal(obs.next_humans[..., 2:4], w.velocity[:, 1:])


def test_core_refuses_state_buffers_it_would_have_to_copy():
    w = hand_world()
    arrays = [w.position, w.velocity, w.goal, w.radius, w.v_pref, w.mask, w.theta, w.steps, w.status,
              w.reward, w.dmin, w.done, w.overlaps, w.arrival, w.end_step]
    config = w._core_config(1, w.n_agents, 0)
    _core.World(config, *arrays, None, None, None)  # the right dtypes are accepted
    bad = list(arrays)
    bad[0] = w.position.astype(np.float32)
    with pytest.raises(TypeError):
        _core.World(config, *bad, None, None, None)
    with pytest.raises(ValueError, match="position: expected 4 elements"):
        _core.World(config, np.zeros((1, 3, 2)), *arrays[1:], None, None, None)
    with pytest.raises(TypeError):
        w._core.preview_humans(np.zeros((1, 1, 5), dtype=np.float32))


def test_stream_over_a_finite_scenario_ends_with_it():
    from socialnav.scenarios import make_scenario
    from socialnav.sim.world import EpisodeStream

    stream = EpisodeStream(make_scenario("passing", n_humans=1), split="train", start=15)
    batch = stream.take(100)
    assert batch.indices.tolist() == [15, 16, 17, 18, 19]
    assert stream.take(1) is None


@pytest.mark.parametrize("scenario", ["circle_crossing", "passing"])
def test_native_observation_equals_the_python_reference(scenario):
    """World.observe is filled by the core; build_observation stays the reference, bit for bit, on
    running, finished, refilled and idle slots."""
    from socialnav.policies import make_policy
    from socialnav.scenarios import make_scenario
    from socialnav.sim.observation import build_observation
    from socialnav.sim.world import World

    w = World(WorldSettings(threads=2), make_scenario(scenario), 64, split="test", count=100, record=False)
    policy = make_policy("orca", threads=2)
    w.reset()
    steps = 0
    while w.busy:
        obs = w.observe()
        ref = build_observation(w.position, w.velocity, w.goal, w.radius, w.v_pref, w.mask, w.theta,
                                w.active, w.steps * w.settings.dt, w.settings.dt, w.settings.kinematics)
        for field in ("robot", "humans", "human_mask", "active", "time"):
            a, b = getattr(obs, field), getattr(ref, field)
            assert a.dtype == b.dtype and a.shape == b.shape, field
            assert np.array_equal(a.view(np.uint8), b.view(np.uint8)), field
        w.step(policy.act(obs))
        steps += 1
    assert steps > 20


def test_native_refill_refuses_bad_slots():
    from socialnav.scenarios import episode_seeds, make_scenario
    from socialnav.sim.world import World

    scenario = make_scenario("circle_crossing")
    w = World(WorldSettings(threads=2), scenario, 8, split="test", count=8, record=False)
    w.reset()
    seeds, failure = episode_seeds("test", np.arange(2)), np.zeros(2, dtype=np.int32)
    with pytest.raises(ValueError, match="slot 1 given twice"):
        w._core.load_generated(w._native_scenario, np.array([1, 1]), seeds, failure)
    with pytest.raises(ValueError, match="slot 9 out of range"):
        w._core.load_generated(w._native_scenario, np.array([1, 9]), seeds, failure)
    other = make_scenario("circle_crossing", n_humans=3)
    from socialnav.scenarios.native import native_config

    with pytest.raises(ValueError, match="does not match"):
        w._core.load_generated(native_config(other), np.array([1, 2]), seeds, failure)

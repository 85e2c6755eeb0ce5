"""The robot's perception (cpp/sensing.hpp, WorldSettings.sensing, the ``lidar`` part): a lidar against
hand-computed distances, occlusion cases by hand, and the world's detections (range, field of view,
noise, dropout, latency) against its exact state."""

import dataclasses
import math

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from tests.sim._walls import pillars_and_walls

import socialnav  # noqa: F401  (registers the Gymnasium ids)
from socialnav import _core
from socialnav.maps import StaticMap
from socialnav.scenarios import make_scenario
from socialnav.settings import ConfigError
from socialnav.sim import World, WorldSettings
from socialnav.sim.settings import SensingSettings

NO_DISCS = (np.zeros((0, 2)), np.zeros(0))


def flat(*polygons):
    return StaticMap(tuple(np.asarray(p, dtype=float) for p in polygons)).to_flat()


def scan(polygons=(), discs=NO_DISCS, beams=8, fov=2 * math.pi, heading=0.0, eye=(0.0, 0.0), range_=10.0):
    vertices, offsets = flat(*polygons) if polygons else (np.zeros((0, 2)), np.zeros(1, dtype=np.int64))
    positions, radii = (np.asarray(d, dtype=float) for d in discs)
    return np.array(_core.lidar_scan(np.asarray(eye, float), heading, beams, fov, range_,
                                     positions.reshape(-1, 2), radii, vertices, offsets))


def in_sight(centre, radius, polygons=(), others=NO_DISCS, eye=(0.0, 0.0)):
    vertices, offsets = flat(*polygons) if polygons else (np.zeros((0, 2)), np.zeros(1, dtype=np.int64))
    positions, radii = (np.asarray(d, dtype=float) for d in others)
    return _core.disc_in_sight(np.asarray(eye, float), np.asarray(centre, float), radius,
                               positions.reshape(-1, 2), radii, vertices, offsets)


# -- the lidar, by hand --------------------------------------------------------------------------------

def test_beam_layout_over_a_circle_and_a_sector():
    angles = np.degrees(_core.lidar_beam_angles(8, 2 * math.pi))
    assert np.allclose(angles, [-180, -135, -90, -45, 0, 45, 90, 135])
    assert np.allclose(_core.lidar_beam_angles(3, math.pi), [-math.pi / 2, 0.0, math.pi / 2])
    assert _core.lidar_beam_angles(1, math.pi) == [0.0]


def test_a_wall_at_an_angle_and_beams_that_graze_its_ends():
    # The wall x + y = 2 from (2, 0) to (0, 2): the 45 degree beam meets it at (1, 1); the beams at 0 and 90
    # degrees meet its two end points exactly.
    ranges = scan([[[2.0, 0.0], [0.0, 2.0]]])
    assert ranges[5] == pytest.approx(math.sqrt(2.0), abs=1e-12)
    assert ranges[4] == pytest.approx(2.0, abs=1e-12) and ranges[6] == pytest.approx(2.0, abs=1e-12)
    assert np.all(ranges[[0, 1, 2, 3, 7]] == 10.0)  # nothing else within range


def test_a_disc_at_the_beams_formula():
    ranges = scan(discs=([[3.0, 0.0]], [0.5]), beams=360)
    angles = np.asarray(_core.lidar_beam_angles(360, 2 * math.pi))
    assert ranges[180] == pytest.approx(2.5, abs=1e-12)  # straight ahead: 3 - 0.5
    d = angles[181]  # one degree off the centre line: t = 3 cos d - sqrt(r^2 - 9 sin^2 d)
    assert ranges[181] == pytest.approx(3 * math.cos(d) - math.sqrt(0.25 - 9 * math.sin(d) ** 2), abs=1e-12)
    half = math.asin(0.5 / 3.0)
    missed = np.abs(angles) > half + 1e-9
    assert np.all(ranges[missed] == 10.0) and np.all(ranges[~missed] < 3.0)


def test_max_range_a_heading_and_the_front_face_of_a_box():
    assert np.all(scan([[[12.0, -1.0], [12.0, 1.0]]], range_=10.0) == 10.0)  # beyond range: nothing
    # heading north: beam 0 (straight ahead) meets the wall y = 3
    assert scan([[[-1.0, 3.0], [1.0, 3.0]]], heading=math.pi / 2)[4] == pytest.approx(3.0)
    box = [[2.0, -1.0], [4.0, -1.0], [4.0, 1.0], [2.0, 1.0]]  # solid, counter-clockwise
    assert scan([box])[4] == pytest.approx(2.0)
    # a sector lidar sees only its sector: the wall behind is not returned
    assert np.all(scan([[[-2.0, -1.0], [-2.0, 1.0]]], beams=5, fov=math.pi / 2) == 10.0)


def _brute_force_scan(segments, discs, beams, fov, heading, range_):
    """Every beam against every segment and disc, in NumPy: what the native scan's beam ranges must equal."""
    angles = heading + np.asarray(_core.lidar_beam_angles(beams, fov))
    u = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    out = np.full(beams, range_)
    for a, b in segments:
        p, e = np.asarray(a, float), np.asarray(b, float) - np.asarray(a, float)
        denom = u[:, 0] * e[1] - u[:, 1] * e[0]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (p[0] * e[1] - p[1] * e[0]) / denom
            s = (p[0] * u[:, 1] - p[1] * u[:, 0]) / denom
        hit = (t >= 0) & (s >= 0) & (s <= 1)
        out = np.where(hit & (t < out), t, out)
    for c, r in zip(*discs, strict=True):
        b = u @ np.asarray(c, float)
        q = r * r - (np.dot(c, c) - b * b)
        t = b - np.sqrt(np.maximum(q, 0))
        out = np.where((b > 0) & (q >= 0) & (t < out), t, out)
    return out


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**31 - 1), st.sampled_from([1, 7, 90, 360, 1000]),
       st.sampled_from([2 * math.pi, math.pi, 0.5]))
def test_the_scan_equals_every_beam_against_every_occluder(seed, beams, fov):
    # The native scan tests only the beams an occluder's angular extent may cover: it must find the same.
    rng = np.random.default_rng(seed)
    segments = [tuple(map(tuple, rng.uniform(-6, 6, (2, 2)))) for _ in range(int(rng.integers(0, 6)))]
    segments = [(a, b) for a, b in segments if np.hypot(b[0] - a[0], b[1] - a[1]) > 1e-3
                and abs((b[0] - a[0]) * a[1] - (b[1] - a[1]) * a[0]) > 1e-9]  # none through the eye
    centres = rng.uniform(-6, 6, (int(rng.integers(0, 5)), 2))
    radii = rng.uniform(0.1, 0.5, len(centres))
    keep = np.hypot(centres[:, 0], centres[:, 1]) > radii + 1e-6
    discs = (centres[keep], radii[keep])
    heading = float(rng.uniform(-math.pi, math.pi))
    got = scan([list(map(list, s)) for s in segments], discs, beams=beams, fov=fov, heading=heading,
               range_=8.0)
    np.testing.assert_allclose(got, _brute_force_scan(segments, discs, beams, fov, heading, 8.0), atol=1e-9)


def test_a_disc_holding_the_eye_blinds_every_beam():
    assert np.all(scan(discs=([[0.1, 0.0]], [0.3])) == 0.0)


# -- occlusion, by hand --------------------------------------------------------------------------------

WALL = [[2.0, -1.0], [2.0, 1.0]]  # seen from the origin it hides the slopes |y / x| < 1/2


def test_a_human_behind_a_wall_is_hidden_and_one_partly_in_sight_is_not():
    assert not in_sight((4.0, 0.0), 0.3, [WALL])
    # centre ray blocked; the disc's upper edge at 0.4913 rad is past the wall's end at atan(1/2) = 0.4636
    assert in_sight((4.0, 1.8), 0.3, [WALL])
    # its upper edge at 0.4291 rad: hidden
    assert not in_sight((4.0, 1.5), 0.3, [WALL])
    assert in_sight((4.0, 2.0), 0.3, [WALL])  # half of it above the wall's end
    assert in_sight((1.5, 0.0), 0.3, [WALL])  # in front of the wall


def test_a_human_behind_a_corner_is_hidden():
    corner = [[0.0, 1.0], [3.0, 1.0], [3.0, 4.0], [2.0, 4.0], [2.0, 2.0], [0.0, 2.0]]  # solid L
    assert not in_sight((4.0, 5.0), 0.3, [corner], eye=(1.0, 0.0))
    assert in_sight((4.0, 0.5), 0.3, [corner], eye=(1.0, 0.0))


def test_humans_hide_humans_only_when_they_cover_the_whole_disc():
    occluder = ([[2.0, 0.0]], [0.3])
    assert not in_sight((4.0, 0.0), 0.3, others=occluder)
    assert in_sight((4.0, 0.5), 0.3, others=occluder)
    assert in_sight((4.0, 0.0), 0.3)


# -- the world's detections ----------------------------------------------------------------------------

def _run(settings, steps=40, batch=6, scenario="circle_crossing", n_humans=5):
    """The observations of `steps` steps of a straight-to-goal robot and the world's exact states."""
    world = World(settings, make_scenario(scenario, n_humans=n_humans), batch, count=batch, record=False)
    obs = world.reset()
    seen, exact = [obs], [(world.position.copy(), world.velocity.copy(), world.theta.copy())]
    for _ in range(steps):
        to_goal = obs.robot[:, 5:7] - obs.robot[:, :2]
        speed = np.linalg.norm(to_goal, axis=1, keepdims=True)
        obs = world.step(to_goal / np.maximum(speed, 1.0), observe=True).observation
        seen.append(obs)
        exact.append((world.position.copy(), world.velocity.copy(), world.theta.copy()))
    world.close()
    return seen, exact


def test_sensing_defaults_give_the_same_bytes_and_records():
    base = WorldSettings(threads=1)
    assert "sensing" not in base.to_dict()
    explicit = WorldSettings.from_dict({"threads": 1, "sensing": SensingSettings().to_dict()})
    lidar_only = dataclasses.replace(base, sensing=SensingSettings(lidar_beams=16))
    a, _ = _run(base)
    b, _ = _run(explicit)
    c, _ = _run(lidar_only)
    for x, y, z in zip(a, b, c, strict=True):
        for name in ("robot", "humans", "human_mask", "active", "time"):
            assert getattr(x, name).tobytes() == getattr(y, name).tobytes() == getattr(z, name).tobytes()
        assert x.lidar is None and z.lidar.shape == (6, 16) and z.lidar.dtype == np.float32
    assert lidar_only.to_dict()["sensing"]["lidar_beams"] == 16


def _bearing(rel, heading):
    """|angle| of each relative position (B, N, 2) off the heading (B,)."""
    angle = np.arctan2(rel[..., 1], rel[..., 0]) - heading[:, None]
    return np.abs(np.remainder(angle + np.pi, 2 * np.pi) - np.pi)


def test_range_and_field_of_view_keep_exactly_the_humans_inside():
    sensing = SensingSettings(range=3.0, fov=math.pi / 2)
    seen, exact = _run(WorldSettings(threads=1, kinematics="unicycle", sensing=sensing))
    kept = 0
    for obs, (pos, _, theta) in zip(seen, exact, strict=True):
        rel = pos[:, 1:] - pos[:, :1]
        bearing = _bearing(rel, theta)
        inside = (np.hypot(rel[..., 0], rel[..., 1]) <= 3.0) & (bearing <= np.pi / 4)
        assert np.array_equal(obs.human_mask, inside)
        assert np.array_equal(obs.humans[inside][:, :2], pos[:, 1:][inside])
        assert np.all(obs.humans[~inside] == 0.0)
        kept += int(inside.sum())
    assert 0 < kept < sum(o.human_mask.size for o in seen)  # the test saw both kinds


def test_a_holonomic_robot_looks_where_it_goes():
    sensing = SensingSettings(fov=math.pi / 2)
    seen, exact = _run(WorldSettings(threads=1, sensing=sensing), steps=10)
    for obs, (pos, vel, _) in zip(seen[1:], exact[1:], strict=True):
        heading = np.arctan2(vel[:, 0, 1], vel[:, 0, 0])
        rel = pos[:, 1:] - pos[:, :1]
        bearing = _bearing(rel, heading)
        assert np.array_equal(obs.human_mask, bearing <= np.pi / 4)


def test_latency_reports_the_world_as_it_was():
    seen, exact = _run(WorldSettings(threads=1, sensing=SensingSettings(latency=3)), steps=20)
    for step, obs in enumerate(seen):
        pos, vel, _ = exact[max(step - 3, 0)]
        live = obs.active
        assert np.array_equal(obs.humans[live][..., :2], pos[live][:, 1:])
        assert np.array_equal(obs.humans[live][..., 2:4], vel[live][:, 1:])
        assert np.array_equal(obs.robot[live][:, :2], exact[step][0][live][:, 0])  # its own state is now


def test_noise_and_dropout_are_drawn_per_seed_and_independent_of_threads():
    sensing = SensingSettings(position_noise=0.1, velocity_noise=0.05, dropout=0.25, lidar_beams=32,
                              lidar_noise=0.02)
    one, exact = _run(WorldSettings(threads=1, sensing=sensing), steps=30, batch=8)
    two, _ = _run(WorldSettings(threads=2, sensing=sensing), steps=30, batch=8)
    for a, b in zip(one, two, strict=True):
        assert a.humans.tobytes() == b.humans.tobytes() and a.lidar.tobytes() == b.lidar.tobytes()
    errors, detected, possible = [], 0, 0
    for obs, (pos, _, _) in zip(one, exact, strict=True):
        live = obs.active[:, None] & np.ones_like(obs.human_mask)
        detected += int((obs.human_mask & live).sum())
        possible += int(live.sum())
        errors.append((obs.humans[..., :2] - pos[:, 1:])[obs.human_mask & live])
    err = np.concatenate(errors)
    assert 0.09 < err.std() < 0.11 and abs(err.mean()) < 0.01  # N(0, 0.1^2) on each coordinate
    assert 0.72 < detected / possible < 0.78  # a quarter missed


def test_occlusion_in_the_world_matches_the_geometry():
    sensing = SensingSettings(occlusion_walls=True)
    settings = WorldSettings(threads=1, sensing=sensing)
    world = World(settings, make_scenario("narrow_doorway"), 4, count=4, record=False)
    obs = world.reset()
    hidden = 0
    for _ in range(30):
        for b in range(4):
            vertices, offsets = world.static_maps[b].to_flat()
            for i in range(world.n_agents - 1):
                if not world.mask[b, i + 1]:
                    continue
                expected = _core.disc_in_sight(world.position[b, 0], world.position[b, i + 1],
                                               world.radius[b, i + 1], np.zeros((0, 2)), np.zeros(0),
                                               vertices, offsets)
                assert obs.human_mask[b, i] == expected
                hidden += not expected
        obs = world.step(np.zeros((4, 2)), observe=True).observation
    world.close()
    assert hidden > 0


def test_the_world_lidar_is_the_scan_of_its_state_without_the_robot():
    sensing = SensingSettings(lidar_beams=72, lidar_range=6.0)
    world = World(WorldSettings(threads=1, sensing=sensing), make_scenario("narrow_doorway"), 3, count=3,
                  record=False)
    obs = world.reset()
    for _ in range(5):
        obs = world.step(np.zeros((3, 2)), observe=True).observation
    for b in range(3):
        vertices, offsets = world.static_maps[b].to_flat()
        real = world.mask[b, 1:].astype(bool)
        heading = math.atan2(world.goal[b, 0, 1] - world.position[b, 0, 1],
                             world.goal[b, 0, 0] - world.position[b, 0, 0])  # standing: towards its goal
        expected = _core.lidar_scan(world.position[b, 0], heading, 72, 2 * math.pi, 6.0,
                                    world.position[b, 1:][real], world.radius[b, 1:][real], vertices, offsets)
        assert np.array_equal(obs.lidar[b], np.float32(expected))
        assert np.all(obs.lidar[b] > 0.0)  # the robot's own disc returns nothing
    world.close()


def test_the_oracle_knows_the_next_states_of_detected_humans_only():
    world = World(WorldSettings(threads=1, sensing=SensingSettings(range=2.5)),
                  make_scenario("circle_crossing", n_humans=5), 4, count=4, record=False)
    world.reset()
    for _ in range(8):
        world.step(np.zeros((4, 2)))
    obs = world.observe(oracle=True)
    assert np.all(obs.next_humans[~obs.human_mask] == 0.0)
    assert np.all(obs.next_humans[obs.human_mask][:, 4] > 0.0)
    world.close()


def test_bad_sensing_settings_are_named():
    with pytest.raises(ConfigError, match="sensing.fov"):
        WorldSettings.from_dict({"sensing": {"fov": 7.0}})
    with pytest.raises(ConfigError, match="sensing.dropout"):
        WorldSettings.from_dict({"sensing": {"dropout": 1.5}})
    with pytest.raises(ConfigError, match="sensing.lidar_beams"):
        WorldSettings.from_dict({"sensing": {"lidar_beams": -1}})


# -- the envs ------------------------------------------------------------------------------------------

def test_the_envs_pass_check_env_with_the_lidar_key():
    from gymnasium.utils.env_checker import check_env

    world = {"sensing": {"lidar_beams": 60, "range": 5.0, "occlusion_walls": True}}
    env = gym.make("socialnav/CircleCrossing-v0", world=world, static_map=pillars_and_walls().to_dict())
    check_env(env.unwrapped)
    obs, _ = env.reset(seed=1)
    assert obs["lidar"].shape == (60,) and obs["lidar"].dtype == np.float32
    assert env.observation_space["lidar"].contains(obs["lidar"])
    assert obs["lidar"].min() < 5.0  # a wall in sight
    env.close()


def test_the_vector_env_and_the_sb3_adapter_carry_the_lidar():
    from socialnav.envs import SocialNavVectorEnv
    from socialnav.sim import ObservationSettings

    world = {"sensing": {"lidar_beams": 24, "lidar_range": 4.0}}
    venv = SocialNavVectorEnv(3, world=world)
    obs, _ = venv.reset(seed=0)
    assert obs["lidar"].shape == (3, 24) and np.all(obs["lidar"] <= 4.0)
    venv.close()
    pytest.importorskip("stable_baselines3")
    from socialnav.integrations.sb3 import SocialNavVecEnv

    settings = ObservationSettings(frame="robot", length_scale=2.0, parts=("robot", "humans", "lidar"))
    sb3_env = SocialNavVecEnv("socialnav/CircleCrossing-v0", 2, world=world, observation=settings)
    first = sb3_env.reset()
    assert first["lidar"].shape == (2, 24) and first["lidar"].dtype == np.float32
    assert np.all(first["lidar"] <= 2.0)  # 4 m in units of 2 m
    sb3_env.step_async(np.zeros((2, 2)))
    sb3_env.step_wait()
    sb3_env.close()
    assert sb3_env.training_record()["sensing"]["lidar_beams"] == 24


def test_a_policy_trained_with_other_detections_is_noted_not_refused(tmp_path, capsys):
    # a full-observation checkpoint under wang2022_partial: an experiment of its own, said once
    pytest.importorskip("torch")
    from socialnav.cli import main
    from socialnav.policies.building import shipped_checkpoint
    from socialnav.policies.learned_loading import perception_note
    from socialnav.presets import load_preset

    partial, full = load_preset("wang2022_partial"), load_preset("wang2022")
    assert perception_note("checkpoint c.pt", None, full) is None
    assert perception_note("checkpoint c.pt", {"lidar_beams": 90}, full) is None  # a lidar is brought
    assert perception_note("checkpoint c.pt", None, partial) == (
        "checkpoint c.pt was trained with other detections than preset 'wang2022_partial' gives (range None "
        "-> 5.0, training -> evaluation): it is evaluated with the preset's (docs/perception.md)")
    assert perception_note("model m.zip", {"range": 5.0}, partial) is None
    checkpoint = shipped_checkpoint("sarl", "wang2022")
    assert main(["evaluate", "--policy", "sarl", "--checkpoint", str(checkpoint), "--preset",
                 "wang2022_partial", "--scenario", "circle_crossing", "--episodes", "1", "--out",
                 str(tmp_path / "run"), "--no-progress"]) == 0
    err = capsys.readouterr().err
    assert err.count("was trained with other detections than preset 'wang2022_partial'") == 1

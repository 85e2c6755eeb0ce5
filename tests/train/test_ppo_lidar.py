"""The lidar PPO policy (``lidar_ppo``): it reads the robot's state and its lidar scan, brings its lidar
to the worlds it trains and acts in (the preset's own detections unchanged), trains and resumes as the
other PPO networks do, and is refused where its scan is missing or another lidar is fitted."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import torch

from socialnav.cli import main
from socialnav.policies.learned import load_checkpoint
from socialnav.policies.learned.lidar_net import LidarActorCritic
from socialnav.policies.learned.ppo_inputs import network_inputs, network_sensors, robot_width
from socialnav.policies.learned_catalog import learned_policy_names
from socialnav.scenarios import make_scenario
from socialnav.sim import SensingSettings, World, WorldSettings
from socialnav.train.ppo.algorithm import train_ppo
from tests.train.bit_identical_runs import run_digests
from tests.train.ppo_smoke import ppo_smoke
from tests.train.walled_preset import write_walled_preset

MIX = ["narrow_hallway", "circle_crossing_obstacles"]


def _smoke():
    return ppo_smoke(policy="lidar_ppo", lidar_beams=36)


@pytest.fixture()
def walls_preset(tmp_path):
    return write_walled_preset(tmp_path, "francis_lidar", MIX)


def _observation(beams, batch=3):
    settings = WorldSettings(threads=1, sensing=SensingSettings(lidar_beams=beams))
    with World(settings, make_scenario("circle_crossing", n_humans=5), batch, count=batch) as world:
        return world.reset()


def test_the_network_reads_the_state_then_the_scan():
    net = LidarActorCritic(lidar_beams=36, lidar_range=10.0)
    assert "lidar_ppo" in learned_policy_names("ppo")
    assert robot_width(net) == 9 + 36 and network_sensors(net) == {"lidar_beams": 36, "lidar_range": 10.0}
    obs = _observation(36)
    robot, humans, mask = network_inputs(net, obs, 0.25, "cpu")
    assert robot.shape == (3, 45)
    np.testing.assert_allclose(robot[:, 9:].numpy(), obs.lidar, rtol=0, atol=0)
    mean, value, h = net.step(robot, humans, mask, net.initial_state(3), torch.ones(3, dtype=torch.bool))
    means, values = net.sequence(robot[None], humans[None], mask[None], h, torch.ones(1, 3, dtype=torch.bool))
    torch.testing.assert_close(means[0], mean)
    torch.testing.assert_close(values[0], value)
    # the scan moves the action: the network is not blind to it
    farther = robot.clone()
    farther[:, 9:] = 10.0
    assert not torch.allclose(net.step(farther, humans, mask, h, torch.zeros(3, dtype=torch.bool))[0], mean)


def test_the_history_is_the_earlier_scans_and_sequence_replays_step():
    torch.manual_seed(0)
    net = LidarActorCritic(lidar_beams=36, lidar_history=3)
    assert net.model_kwargs()["lidar_history"] == 3 and net.gru_hidden == 2 * 36
    assert "lidar_history" not in LidarActorCritic(lidar_beams=36).model_kwargs()  # older checkpoints' layout
    b, t = 2, 5
    robot = torch.rand(t, b, 9 + 36) * 10.0
    humans, mask = torch.zeros(t, b, 1, 2), torch.zeros(t, b, 1, dtype=torch.bool)
    starts = torch.zeros(t, b, dtype=torch.bool)
    starts[0, :] = True
    starts[3, 1] = True  # episode 1 restarts at step 3
    h, means = net.initial_state(b), []
    for i in range(t):
        mean, _, h_next = net.step(robot[i], humans[i], mask[i], h, starts[i])
        means.append(mean)
        if i == 2:
            # the state holds this step's scan and the one before it, newest first
            torch.testing.assert_close(h_next.view(b, 2, 36)[:, 0], robot[2, :, 9:])
            torch.testing.assert_close(h_next.view(b, 2, 36)[:, 1], robot[1, :, 9:])
        h = h_next
    seq_means, _ = net.sequence(robot, humans, mask, net.initial_state(b), starts)
    torch.testing.assert_close(seq_means, torch.stack(means))
    # an episode's first step sees its own scan three times: the earlier state is ignored
    first, later = torch.ones(b, dtype=torch.bool), torch.zeros(b, dtype=torch.bool)
    fresh = net.step(robot[3], humans[3], mask[3], torch.full((b, 72), 5.0), first)[0]
    again = net.step(robot[3], humans[3], mask[3], torch.zeros(b, 72), first)[0]
    torch.testing.assert_close(fresh, again)
    # the earlier scans move the action: a person that moved is not a person that stood
    moved = net.step(robot[3], humans[3], mask[3], torch.full((b, 72), 5.0), later)[0]
    assert not torch.allclose(moved, fresh)


def test_a_single_scan_network_reads_as_before():
    torch.manual_seed(1)
    net = LidarActorCritic(lidar_beams=36)
    robot = torch.rand(4, 9 + 36) * 10.0
    expected_scan = net.encoder((robot[:, 9:] / 10.0).unsqueeze(1))
    features = net.features(robot, robot[:, 9:].unsqueeze(1))
    torch.testing.assert_close(features[:, 9:], expected_scan, rtol=0, atol=0)
    h = net.initial_state(4)
    assert h.shape == (4, 1)
    mean, _, h_next = net.step(robot, None, None, h, torch.zeros(4, dtype=torch.bool))
    assert h_next is h
    torch.testing.assert_close(mean, net.actor(features), rtol=0, atol=0)  # step reads the scan alone


def test_a_missing_or_other_lidar_is_named():
    net = LidarActorCritic(lidar_beams=36)
    with pytest.raises(ValueError, match="36-beam lidar, the observation has no lidar"):
        network_inputs(net, _observation(0), 0.25, "cpu")
    with pytest.raises(ValueError, match="36-beam lidar, the observation has a 18-beam lidar"):
        network_inputs(net, _observation(18), 0.25, "cpu")
    world = WorldSettings(sensing=SensingSettings(lidar_beams=18))
    with pytest.raises(ValueError, match="lidar_beams 18"):
        world.with_sensors({"lidar_beams": 36})
    added = WorldSettings(sensing=SensingSettings(range=5.0)).with_sensors({"lidar_beams": 36,
                                                                            "lidar_range": 8.0})
    assert added.sensing == SensingSettings(range=5.0, lidar_beams=36, lidar_range=8.0)
    assert WorldSettings().with_sensors({}) == WorldSettings()
    # a lidar field the world sets (with no beams yet) is the world's: a full-circle lidar clashes with it
    sector = WorldSettings(sensing=SensingSettings(lidar_fov=1.0))
    with pytest.raises(ValueError, match=r"lidar_fov 1.0 \(world\) vs 6.28"):
        sector.with_sensors({"lidar_beams": 36})
    assert sector.with_sensors({"lidar_beams": 36, "lidar_fov": 1.0}).sensing.lidar_beams == 36
    # the same beams with another sector, and the world's own noise kept
    noisy = WorldSettings(sensing=SensingSettings(lidar_beams=36, lidar_fov=3.0, lidar_noise=0.1))
    with pytest.raises(ValueError, match=r"lidar_fov 3.0 \(world\) vs 6.28"):
        noisy.with_sensors({"lidar_beams": 36})
    assert WorldSettings(sensing=SensingSettings(lidar_noise=0.1)).with_sensors(
        {"lidar_beams": 36}).sensing.lidar_noise == 0.1
    # the detections are the preset's: a policy cannot bring a longer detection range (or a misspelt key)
    for key in ("range", "lidr_beams"):
        with pytest.raises(ValueError, match=f"lidar settings only .*, not {key}: what the robot detects"):
            WorldSettings(sensing=SensingSettings(range=5.0)).with_sensors({key: 90})


def test_trained_among_walls_it_brings_its_lidar_to_the_evaluation(tmp_path, walls_preset, capsys):
    out = tmp_path / "run"
    summary = train_ppo(walls_preset, out, _smoke(), progress=False, log=lambda _: None)
    assert summary.updates == 4
    ck = load_checkpoint(out / "best.pt", "lidar_ppo", expected_input_dim=-1)
    assert ck.model.model_kwargs()["lidar_beams"] == 36
    assert "lidar_history" not in ck.model.model_kwargs()  # the default: the current scan alone
    assert ck.config["preset"]["world"]["sensing"]["lidar_beams"] == 36  # the worlds it trained in
    ev = tmp_path / "eval"
    rc = main(["evaluate", "--policy", "lidar_ppo", "--checkpoint", str(out / "best.pt"),
               "--preset", "francis2023", "--scenario", "narrow_hallway", "--episodes", "2",
               "--visibility", "invisible", "--out", str(ev), "--no-progress"])
    assert rc == 0, capsys.readouterr().err
    manifest = json.loads((ev / "manifest.json").read_text())
    assert manifest["policy"]["sensors"] == {"lidar_beams": 36, "lidar_range": 10.0}
    assert "sensing" not in manifest["preset"]["world"]  # the protocol's world is francis2023's own


@pytest.mark.parametrize("history", [1, 3])
def test_a_lidar_run_resumed_mid_episode_ends_as_an_uninterrupted_one(tmp_path, walls_preset, history):
    s = dataclasses.replace(_smoke(), lidar_history=history)  # 3: the scan history is the resumed state
    train_ppo(walls_preset, tmp_path / "whole", s, progress=False, log=lambda _: None)
    train_ppo(walls_preset, tmp_path / "split", s, progress=False, stop_after=2, log=lambda _: None)
    train_ppo(walls_preset, tmp_path / "split", s, progress=False, log=lambda _: None)
    assert run_digests(tmp_path / "split") == run_digests(tmp_path / "whole")
    net = load_checkpoint(tmp_path / "whole" / "best.pt", "lidar_ppo", expected_input_dim=-1).model
    assert net.lidar_history == history


def _door_observation(robot_xy, goal_xy):
    from socialnav.maps.static_map import StaticMap
    from socialnav.sim.observation import ObstacleArrays

    obs = _observation(36, batch=2)
    door = StaticMap(([[-20.0, 0.0], [-0.6, 0.0]], [[0.6, 0.0], [20.0, 0.0]]))
    robot = obs.robot.copy()
    robot[:, 0:2], robot[:, 5:7] = robot_xy, goal_xy
    return dataclasses.replace(obs, robot=robot, obstacles=ObstacleArrays.from_maps([door, None])), door


def test_route_goal_is_the_point_the_route_heads_for():
    from socialnav.maps.routes import ROBOT_CLEARANCE, plan_route, route_goals

    obs, door = _door_observation((3.0, -3.0), (3.0, 3.0))
    goals = route_goals(obs.robot, obs.obstacles.native)
    route = plan_route(door, (3.0, -3.0), (3.0, 3.0), radius=0.3, clearance=ROBOT_CLEARANCE)
    # through the door: towards the route's first corner, as far as the route is long
    first = route.points[0] - np.array([3.0, -3.0])
    length = np.linalg.norm(first) + route.length
    assert len(route.points) == 3 and abs(route.points[0][0]) < 0.6 and length > 6.0 + 1.0
    offset = goals[0] - np.array([3.0, -3.0])
    np.testing.assert_allclose(np.linalg.norm(offset), length, rtol=1e-12)
    np.testing.assert_allclose(offset / np.linalg.norm(offset), first / np.linalg.norm(first), rtol=1e-12)
    np.testing.assert_array_equal(goals[1], (3.0, 3.0))  # an open floor: the goal itself
    from socialnav.train.ppo.worlds import route_distance

    # the trainer's potential term of a route-goal network: the metres still to walk along the route
    np.testing.assert_allclose(route_distance(obs), [length, 6.0], rtol=1e-12)
    in_sight, _ = _door_observation((0.0, -3.0), (0.0, 3.0))  # straight through the door
    np.testing.assert_array_equal(route_goals(in_sight.robot, in_sight.obstacles.native)[0], (0.0, 3.0))
    with pytest.raises(ValueError, match="prepared for 2 episodes, the robot rows are 1"):
        route_goals(obs.robot[:1], obs.obstacles.native)


def test_a_route_goal_network_reads_the_route_goal_as_its_goal():
    obs, _ = _door_observation((3.0, -3.0), (3.0, 3.0))
    plain = LidarActorCritic(lidar_beams=36)
    routed = LidarActorCritic(lidar_beams=36, route_goal=True)
    assert routed.model_kwargs()["route_goal"] and "route_goal" not in plain.model_kwargs()
    a, _, _ = network_inputs(plain, obs, 0.25, "cpu")
    b, _, _ = network_inputs(routed, obs, 0.25, "cpu")
    from socialnav.maps.routes import route_goals

    goal = route_goals(obs.robot, obs.obstacles.native)
    offset = (goal - obs.robot[:, 0:2]).astype(np.float32)
    np.testing.assert_allclose(b[:, 0:2].numpy(), offset, rtol=0, atol=0)
    assert not torch.equal(a[0, :3], b[0, :3])  # behind the wall: another goal
    torch.testing.assert_close(a[1], b[1], rtol=0, atol=0)  # the open floor's episode: the goal itself
    torch.testing.assert_close(a[:, 3:], b[:, 3:], rtol=0, atol=0)  # the rest as it was
    assert obs.robot[0, 5] == 3.0 and obs.robot[0, 6] == 3.0  # the observation is not changed


def test_a_route_goal_run_trains_resumes_and_keeps_its_setting(tmp_path, walls_preset):
    s = dataclasses.replace(_smoke(), lidar_route_goal=True)
    train_ppo(walls_preset, tmp_path / "whole", s, progress=False, log=lambda _: None)
    train_ppo(walls_preset, tmp_path / "split", s, progress=False, stop_after=2, log=lambda _: None)
    train_ppo(walls_preset, tmp_path / "split", s, progress=False, log=lambda _: None)
    assert run_digests(tmp_path / "split") == run_digests(tmp_path / "whole")
    ck = load_checkpoint(tmp_path / "whole" / "best.pt", "lidar_ppo", expected_input_dim=-1)
    assert ck.model.route_goal and ck.config["train"]["lidar_route_goal"] is True
    assert _policy_record(tmp_path / "whole" / "best.pt")["route_goal"] is True  # in results manifests
    plain = run_digests(_train_plain(tmp_path, walls_preset))
    assert plain != run_digests(tmp_path / "whole")  # the setting reaches the network


def _policy_record(checkpoint):
    from socialnav.policies.registry import make_policy

    return make_policy("lidar_ppo", checkpoint=str(checkpoint)).describe()


def _train_plain(tmp_path, preset):
    train_ppo(preset, tmp_path / "plain", _smoke(), progress=False, log=lambda _: None)
    return tmp_path / "plain"


def test_latency_survives_a_resume_of_the_worlds():
    from socialnav.presets import load_preset
    from socialnav.train.ppo.worlds import restore_worlds, world_snapshot
    from socialnav.train.worlds import MultiWorld

    preset = load_preset("wang2022_partial")
    preset = dataclasses.replace(preset, world=dataclasses.replace(
        preset.world, sensing=SensingSettings(range=5.0, latency=2, position_noise=0.05)))
    a = MultiWorld(preset, 5, 4, "train", 0)
    b = MultiWorld(preset, 5, 4, "train", 0)
    try:
        a.reset()
        b.reset()
        for _ in range(7):
            a.step(np.zeros((4, 2)))
        restore_worlds(b, world_snapshot(a))
        assert np.array_equal(a.observe().humans, b.observe().humans)
        for _ in range(5):  # the delayed detections come from the restored record of past states
            a.step(np.zeros((4, 2)))
            b.step(np.zeros((4, 2)))
            assert np.array_equal(a.observe().humans, b.observe().humans)
    finally:
        a.close()
        b.close()

"""PPO training among walls: a training mix with walls gives the network the default obstacle encoding
(recorded in the checkpoint), the rollout stores the points after the human slots, the worlds' maps
come back on resumption, and `socialnav train` → `socialnav evaluate` runs end to end under
francis2023 for crowdnav_pp and ppo_mlp. Open floors are unchanged (no key, no slots)."""

from __future__ import annotations

import contextlib
import dataclasses
import json

import numpy as np
import pytest
import torch

import socialnav.policies.learned_catalog as catalog
from socialnav.cli import main
from socialnav.policies.learned import load_checkpoint
from socialnav.policies.learned.attn_graph import observation_tensors
from socialnav.presets import load_preset
from socialnav.settings import ConfigError
from socialnav.sim.obstacle_points import ObstaclePoints
from socialnav.train.ppo.algorithm import collect_rollout, train_ppo
from socialnav.train.ppo.run import setup_ppo_run
from socialnav.train.ppo.state import initial_state
from socialnav.train.ppo.worlds import step_worlds
from socialnav.train.worlds import MultiWorld, ppo_policy_config
from tests.train.bit_identical_runs import run_digests
from tests.train.ppo_smoke import ppo_smoke
from tests.train.walled_preset import write_walled_preset

#: a fixed-layout hallway with one person and the circle crossing among pillars drawn per episode
MIX = ["narrow_hallway", "circle_crossing_obstacles"]
K = ObstaclePoints().count


@pytest.fixture()
def walls_preset(tmp_path):
    """francis2023 with two of its scenarios and a 10 s time limit."""
    return write_walled_preset(tmp_path, "francis_ppo", MIX)


def test_only_a_mix_with_walls_records_an_encoding():
    assert ppo_policy_config(load_preset("francis2023"))["obstacle_encoding"] == ObstaclePoints().to_dict()
    for name in ("wang2022", "crowdnav"):
        assert "obstacle_encoding" not in ppo_policy_config(load_preset(name))


def test_the_rollout_stores_the_points_after_the_human_slots(tmp_path, walls_preset):
    with contextlib.ExitStack() as stack:
        run = setup_ppo_run(walls_preset, tmp_path / "run", ppo_smoke(), stack, progress=False,
                            log=lambda _: None)
        assert run.obstacle_encoding == ObstaclePoints() and run.n_slots == run.n_humans + K
        state = initial_state(run)
        first = state.obs
        rollout = collect_rollout(run, state)
        assert rollout.humans.shape[2] == rollout.masks.shape[2] == run.n_humans + K
        # the first step's inputs are the observation's humans, then its own episodes' points
        _, hf, mk = observation_tensors(first, run.preset.world.dt, run.net.prediction_steps,
                                        obstacle_encoding=ObstaclePoints())
        torch.testing.assert_close(rollout.humans[0], hf)
        assert torch.equal(rollout.masks[0], mk)
        points, mask = ObstaclePoints().nearest(first.robot[:, :2], first.obstacles.maps)
        relative = points - first.robot[:, None, :2] * mask[..., None]  # padded rows stay zero
        np.testing.assert_allclose(hf[:, run.n_humans:, :2].numpy(), relative, atol=1e-6)
        assert mk[:, run.n_humans:].any(dim=1).all()  # every episode has a wall within 4 m at its start
        assert rollout.masks[:, :, run.n_humans:].any()


def test_a_step_keeps_each_episodes_map(walls_preset):
    """The final observation has the maps the step happened in, the next one the maps of the slots'
    episodes after refills; an open floor has none."""
    world = MultiWorld(load_preset(walls_preset), 4, 4, "train", 0)
    try:
        world.reset()
        ended = np.zeros(4, dtype=bool)
        for _ in range(60):  # standing still: every episode times out at 10 s (40 steps), refilled
            before = [m for w in world.worlds for m in w.static_maps]
            _, term, trunc, final, nxt = step_worlds(world, np.zeros((4, 2)))
            after = [m for w in world.worlds for m in w.static_maps]
            assert all(a is b for a, b in zip(final.obstacles.maps, before, strict=True))
            assert all(a is b for a, b in zip(nxt.obstacles.maps, after, strict=True))
            done = term | trunc
            ended |= done
            # the circle crossing's pillars are drawn per episode: a refilled slot has a new map
            assert all(after[b] is not before[b] for b in np.flatnonzero(done) if b >= 2)
        assert ended.all()
    finally:
        world.close()
    world = MultiWorld(load_preset("crowdnav"), 4, 2, "train", 0)
    try:
        world.reset()
        _, _, _, final, nxt = step_worlds(world, np.zeros((2, 2)))
        assert final.obstacles is None and nxt.obstacles is None
    finally:
        world.close()


@pytest.mark.parametrize("policy", ["crowdnav_pp", "ppo_mlp"])
def test_a_run_resumed_among_walls_ends_as_an_uninterrupted_one(tmp_path, walls_preset, policy):
    """Stopped mid-episode and resumed: the episodes in flight get their maps (pillars drawn per
    episode, the hallway's layout) back, so the files are those of the run that was not stopped."""
    s = ppo_smoke(policy=policy)
    train_ppo(walls_preset, tmp_path / "whole", s, progress=False, log=lambda _: None)
    train_ppo(walls_preset, tmp_path / "split", s, progress=False, stop_after=2, log=lambda _: None)
    train_ppo(walls_preset, tmp_path / "split", s, progress=False, log=lambda _: None)
    assert run_digests(tmp_path / "split") == run_digests(tmp_path / "whole")


@pytest.mark.parametrize("policy", ["crowdnav_pp", "ppo_mlp"])
def test_cli_trains_among_walls_and_evaluates_under_francis2023(tmp_path, capsys, policy):
    out = tmp_path / "run"
    rc = main(["train", "--policy", policy, "--preset", "francis2023", "--config", "ppo_smoke",
               "--out", str(out), "--no-progress"])
    assert rc == 0, capsys.readouterr().err
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["updates"] == 4
    ck = load_checkpoint(out / "best.pt", policy, expected_input_dim=-1)
    assert ck.config["ppo_policy"]["obstacle_encoding"] == ObstaclePoints().to_dict()
    if policy == "ppo_mlp":
        assert ck.model.model_kwargs()["obstacle_slots"] == K
    ev = tmp_path / "eval"
    rc = main(["evaluate", "--policy", policy, "--checkpoint", str(out / "best.pt"),
               "--preset", "francis2023", "--scenario", "narrow_hallway", "entering_room", "--episodes", "2",
               "--visibility", "invisible", "--out", str(ev), "--no-progress", "--json"])
    assert rc == 0, capsys.readouterr().err
    manifest = json.loads((ev / "manifest.json").read_text())
    assert manifest["policy"]["obstacle_encoding"] == ObstaclePoints().to_dict()
    assert "preset_mismatch_allowed" not in manifest["policy"]
    assert (ev / "summary.json").is_file()
    # and on an open floor (crowdnav: the same robot, dt and rewards): the K point slots all masked
    rc = main(["evaluate", "--policy", policy, "--checkpoint", str(out / "best.pt"), "--preset", "crowdnav",
               "--scenario", "circle_crossing", "--episodes", "2", "--out", str(tmp_path / "open"),
               "--no-progress", "--json"])
    assert rc == 0, capsys.readouterr().err




def test_a_record_whose_network_cannot_take_point_slots_is_refused_among_walls(
    tmp_path, walls_preset, isolated_registries
):
    def two_argument_kwargs(settings, n_humans):  # written before walls: no obstacle_slots
        return catalog.mlp_actor_critic_kwargs(settings, n_humans)

    spec = dataclasses.replace(catalog.get_learned_spec("ppo_mlp"), name="old_mlp", label="Old MLP",
                               network_kwargs=two_argument_kwargs)
    catalog.register_learned_policy(spec)
    with pytest.raises(ConfigError, match="'old_mlp': its record's network_kwargs takes no obstacle_slots"):
        train_ppo(walls_preset, tmp_path / "run", ppo_smoke(policy="old_mlp"), progress=False,
                  log=lambda _: None)
    assert not (tmp_path / "run").exists()
    # on an open floor it trains as before
    s = ppo_smoke(policy="old_mlp", total_env_steps=64)
    assert train_ppo("crowdnav", tmp_path / "open", s, progress=False, log=lambda _: None).finished

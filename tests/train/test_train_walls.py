"""Training among walls: the scenario mix keeps the fixed crowds of the francis2023 scenarios (padded
human slots), each transition carries its own episode's obstacle points, the checkpoint records the
encoding, and it is evaluated under the walled preset without a mismatch."""

from __future__ import annotations

import numpy as np
import pytest
import torch
import yaml

from socialnav.cli import main
from socialnav.policies.learned import load_checkpoint
from socialnav.presets import load_preset
from socialnav.sim.obstacle_points import ObstaclePoints
from socialnav.train.value.settings import load_train_settings
from socialnav.train.value.trainer import train
from socialnav.train.worlds import MultiWorld
from tests.train.ppo_smoke import ppo_smoke
from tests.train.walled_preset import write_walled_preset

TINY = """\
collection_batch: 6
threads: 1
checkpoint_every: 6
log_every: 3
imitation: {episodes: 6, epochs: 1}
rl: {episodes: 9, validate_every: 9, val_episodes: 3, target_update_every: 6, warmup_transitions: 20,
     gradient_steps_per_episode: 1, epsilon_decay_episodes: 6}
"""

#: one scenario of each crowd: one person head-on (fixed), a standing group of 3 (fixed), 4 humans
MIX = ["narrow_hallway", "pedestrian_obstruction", "circle_crossing_obstacles"]


@pytest.fixture()
def walls_preset(tmp_path):
    """francis2023 with three of its scenarios and a 10 s time limit."""
    return write_walled_preset(tmp_path, "francis_quick", MIX)


def test_the_training_mix_keeps_fixed_crowds_and_pads_the_slots(walls_preset):
    world = MultiWorld(load_preset(walls_preset), 4, 6, "train", 0)
    try:
        world.reset()
        assert [w.n_agents - 1 for w in world.worlds] == [1, 3, 4]
        assert world.n_human_slots == 4
        obs = world.observe()
        assert obs.humans.shape == (6, 4, 5)
        assert obs.human_mask.sum(axis=1).tolist() == [1, 1, 3, 3, 4, 4]
        assert obs.obstacles is not None and all(m is not None for m in obs.obstacles.maps)
        res = world.step(np.zeros((6, 2)))
        assert res.final_humans.shape == (6, 4, 5) and len(res.final_maps) == 6
        assert res.final_maps[0] is world.worlds[0].static_maps[0]
    finally:
        world.close()


def test_train_among_walls_records_the_encoding_and_evaluates(tmp_path, walls_preset, capsys):
    settings_path = tmp_path / "tiny.yaml"
    settings_path.write_text(TINY)
    out = tmp_path / "run"
    result = train("rgl", walls_preset, out, load_train_settings(settings_path), progress=False)
    assert result.finished and result.episodes == 9 and result.gradient_steps > 0
    ck = load_checkpoint(out / "best.pt", "rgl")
    assert ck.config["value_policy"]["obstacle_encoding"] == ObstaclePoints().to_dict()
    last = torch.load(out / "last.pt", weights_only=True)
    assert last["extra"]["resume"]["episode"] == 9
    # evaluated under the walled preset: no mismatch, the encoding in effect
    from socialnav.policies.learned_loading import load_learned_policy

    policy = load_learned_policy("rgl", out / "best.pt", preset=load_preset(walls_preset))
    assert policy.preset_mismatch == []
    assert policy.value_policy.obstacle_encoding == ObstaclePoints()
    rc = main(["evaluate", "--policy", "rgl", "--checkpoint", str(out / "best.pt"), "--preset", walls_preset,
               "--scenario", "narrow_hallway", "--episodes", "2", "--visibility", "invisible",
               "--out", str(tmp_path / "eval"), "--no-progress", "--json"])
    assert rc == 0, capsys.readouterr().err
    # and on an open floor (crowdnav: the same robot, dt and rewards): K padded point slots
    assert load_learned_policy("rgl", out / "best.pt", preset=load_preset("crowdnav")).preset_mismatch == []
    rc = main(["evaluate", "--policy", "rgl", "--checkpoint", str(out / "best.pt"), "--preset", "crowdnav",
               "--scenario", "circle_crossing", "--episodes", "2", "--out", str(tmp_path / "open"),
               "--no-progress", "--json"])
    assert rc == 0, capsys.readouterr().err


def test_replay_states_carry_each_episodes_own_points(walls_preset):
    """The stored next state of a slot that finished and was refilled has the points of the map it
    finished on (here: the same scenario map, checked against the encoding computed by hand)."""
    from socialnav.policies.learned import ValuePolicy, build
    from socialnav.train.value.rl import encoded_step

    pol = ValuePolicy(build("rgl"), obstacle_encoding=ObstaclePoints().to_dict())
    world = MultiWorld(load_preset(walls_preset), 4, 3, "train", 0)
    try:
        world.reset()
        obs = pol.encode(world.observe())
        assert obs.humans.shape == (3, 4 + 16, 5) and obs.static_slots == 16
        res = encoded_step(pol, world.step(np.zeros((3, 2))))
        assert res.final_humans.shape == (3, 20, 5)
        for b in range(3):
            pts, mask = ObstaclePoints().agents(res.final_robot[b : b + 1, :2], [res.final_maps[b]])
            np.testing.assert_array_equal(res.final_humans[b, 4:], pts[0])
            np.testing.assert_array_equal(res.final_mask[b, 4:], mask[0])
    finally:
        world.close()


def test_ppo_trains_on_the_walled_mix_with_its_fixed_crowds(tmp_path, walls_preset):
    """The PPO trainer steps the same mix: a crowd of 3 beside a preset count of 2 gets 3 slots, and
    the scenarios that do not fix their crowd keep the preset's 2."""
    from socialnav.train.ppo.algorithm import train_ppo

    data = yaml.safe_load(open(walls_preset))
    data["training"]["n_humans"] = 2
    preset = tmp_path / "two.yaml"
    preset.write_text(yaml.safe_dump(data))
    settings = ppo_smoke()
    result = train_ppo(str(preset), tmp_path / "ppo", settings, progress=False)
    assert result.finished
    config = yaml.safe_load((tmp_path / "ppo" / "config.yaml").read_text())
    assert config["n_humans"] == 3
    world = MultiWorld(load_preset(str(preset)), 2, 3, "train", 0)
    try:
        assert [w.n_agents - 1 for w in world.worlds] == [1, 3, 2] and world.n_human_slots == 3
    finally:
        world.close()

"""Slow: a brief SARL training run must beat the untrained network on validation."""

import dataclasses

import pytest
import torch

from socialnav.policies.learned import ValuePolicy, build
from socialnav.presets import load_preset
from socialnav.train.episodes import validate
from socialnav.train.run_directory import derive_seeds
from socialnav.train.value.settings import TrainSettings
from socialnav.train.value.trainer import train
from socialnav.train.worlds import MultiWorld


@pytest.mark.slow
def test_sarl_brief_training_beats_untrained(tmp_path):
    preset = load_preset("crowdnav")
    settings = TrainSettings(
        collection_batch=64,
        log_every=50,
        checkpoint_every=200,
        imitation=dataclasses.replace(TrainSettings().imitation, episodes=300, epochs=10),
        rl=dataclasses.replace(
            TrainSettings().rl,
            episodes=400,
            validate_every=200,
            val_episodes=100,
            epsilon_decay_episodes=200,
            target_update_every=100,
        ),
    )
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(derive_seeds(settings.seed)["init"])
        untrained = ValuePolicy(build("sarl"))
    val_world = MultiWorld(preset, 5, 64, "val", 0, 100)
    before = validate(untrained, val_world, False, preset.world.reward.success_reward)
    result = train("sarl", preset, tmp_path / "run", settings, progress=False)
    assert result.finished
    assert result.best_val["success"] >= before["success"] + 0.3, (before, result.best_val)

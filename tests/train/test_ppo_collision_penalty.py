"""PPO's ``collision_penalty``: a training-only reward for a collision in place of the preset's."""

from __future__ import annotations

import contextlib

import numpy as np
import pytest
import torch

from socialnav.settings import ConfigError
from socialnav.train.ppo.algorithm import collect_rollout
from socialnav.train.ppo.run import setup_ppo_run
from socialnav.train.ppo.settings import load_ppo_settings
from socialnav.train.ppo.state import initial_state
from tests.train.ppo_smoke import ppo_smoke


def _smoke(**changes):
    return ppo_smoke(bootstrap_timeouts=False, **changes)


def _first_rollout(tmp_path, settings):
    with contextlib.ExitStack() as stack:
        run = setup_ppo_run("wang2022", tmp_path, settings, stack, progress=False, log=lambda _: None)
        state = initial_state(run)
        return collect_rollout(run, state), run.config["train"], state


def test_a_collision_earns_the_set_penalty_and_nothing_else_changes(tmp_path):
    """The same first rollout (rewards do not steer it): every collision step's reward is -1 where the
    preset gives -0.25, every other reward is the same, and the episode statistics keep the preset's."""
    plain, plain_record, plain_state = _first_rollout(tmp_path / "plain", _smoke())
    harsh, harsh_record, harsh_state = _first_rollout(tmp_path / "harsh", _smoke(collision_penalty=-1.0))
    torch.testing.assert_close(plain.raws, harsh.raws, rtol=0, atol=0)
    lower = (plain.rewards - harsh.rewards).numpy()
    collided = np.isclose(lower, 0.75, rtol=0, atol=1e-6)
    assert collided.sum() >= 1  # the smoke network collides: the penalty has a step to act on
    assert (lower[~collided] == 0).all()
    assert (plain.dones.numpy()[collided]).all()  # only terminal steps
    assert "collision_penalty" not in plain_record and harsh_record["collision_penalty"] == -1.0
    assert plain_state.returns_sum == harsh_state.returns_sum  # train_return: the world's reward


def test_a_positive_collision_penalty_is_refused_naming_the_file_and_the_value(tmp_path):
    path = tmp_path / "ppo.yaml"
    path.write_text("collision_penalty: 0.5\n")
    with pytest.raises(ConfigError, match=r"collision_penalty .*0\.5"):
        load_ppo_settings(path)

"""PPO's ``collision_penalty``: a training-only reward for a collision in place of the preset's."""

from __future__ import annotations

import contextlib
import dataclasses

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


def _first_rollout(tmp_path, settings, update=0):
    """The first rollout of a 10-update run, collected as if ``update`` of its updates were done; with
    the run and its state."""
    settings = dataclasses.replace(settings, total_env_steps=10 * settings.batch_steps)
    with contextlib.ExitStack() as stack:
        run = setup_ppo_run("wang2022", tmp_path, settings, stack, progress=False, log=lambda _: None)
        assert run.n_updates == 10
        state = initial_state(run)
        state.update = update
        return collect_rollout(run, state), run, state


def test_a_collision_earns_the_set_penalty_and_nothing_else_changes(tmp_path):
    """The same first rollout (rewards do not steer it): every collision step's reward is -1 where the
    preset gives -0.25, every other reward is the same, and the episode statistics keep the preset's."""
    plain, plain_run, plain_state = _first_rollout(tmp_path / "plain", _smoke())
    harsh, harsh_run, harsh_state = _first_rollout(tmp_path / "harsh", _smoke(collision_penalty=-1.0))
    plain_record, harsh_record = plain_run.config["train"], harsh_run.config["train"]
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


@pytest.mark.parametrize(
    ("update", "weight"), [(0, 0.0), (25, 0.0), (40, 0.3), (50, 0.5), (75, 1.0), (99, 1.0)]
)
def test_the_ramp_moves_a_collision_s_reward_linearly_between_its_start_and_end(update, weight):
    s = load_ppo_settings(
        collision_penalty=-1.0, collision_penalty_ramp_start=0.25, collision_penalty_ramp_end=0.75
    )
    assert s.collision_weight(update, 100) == pytest.approx(weight, abs=1e-12)
    step = load_ppo_settings(
        collision_penalty=-1.0, collision_penalty_ramp_start=0.5, collision_penalty_ramp_end=0.5
    )
    assert step.collision_weight(update, 100) == (1.0 if update >= 50 else 0.0)  # a ramp of no length: a step
    no_ramp = load_ppo_settings(collision_penalty=-1.0)
    assert no_ramp.collision_weight(update, 100) == 1.0  # from the first update


def test_halfway_up_the_ramp_a_collision_earns_halfway_between_the_presets_and_the_penalty(tmp_path):
    """Same rollout (rewards do not steer it): before the ramp the rewards are the preset's, halfway they
    are lower by half of 0.75 (-0.25 - -1) on the collision steps and nowhere else; the record names the
    ramp."""
    ramp = dict(collision_penalty=-1.0, collision_penalty_ramp_start=0.2, collision_penalty_ramp_end=0.6)
    plain, _, _ = _first_rollout(tmp_path / "plain", _smoke(), 4)
    before, _, _ = _first_rollout(tmp_path / "before", _smoke(**ramp), 1)
    halfway, run, _ = _first_rollout(tmp_path / "halfway", _smoke(**ramp), 4)  # 4 of 10 done: 0.2 to 0.6
    torch.testing.assert_close(plain.raws, halfway.raws, rtol=0, atol=0)
    torch.testing.assert_close(plain.rewards, before.rewards, rtol=0, atol=0)
    lower = (plain.rewards - halfway.rewards).numpy()
    collided = np.isclose(lower, 0.375, rtol=0, atol=1e-6)
    assert collided.sum() >= 1
    assert (lower[~collided] == 0).all()
    record = run.config["train"]
    assert record["collision_penalty_ramp_start"] == 0.2 and record["collision_penalty_ramp_end"] == 0.6


@pytest.mark.parametrize(
    ("changes", "named"),
    [
        (dict(collision_penalty_ramp_end=0.5), r"collision_penalty_ramp_end .*needs collision_penalty"),
        (dict(collision_penalty=-1.0, collision_penalty_ramp_start=0.6, collision_penalty_ramp_end=0.4),
         r"collision_penalty_ramp_start .*<= collision_penalty_ramp_end \(0\.4\)"),
        (dict(collision_penalty=-1.0, collision_penalty_ramp_end=1.5), r"collision_penalty_ramp_end"),
    ],
)
def test_a_ramp_without_a_penalty_or_backwards_or_beyond_the_run_is_refused(tmp_path, changes, named):
    path = tmp_path / "ppo.yaml"
    path.write_text("".join(f"{k}: {v}\n" for k, v in changes.items()))
    with pytest.raises(ConfigError, match=named) as refused:
        load_ppo_settings(path)
    assert str(path) in str(refused.value)

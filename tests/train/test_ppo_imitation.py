"""PPO's warm start by imitation (``imitation_updates``): DAgger from a native planner, then PPO.

The teacher's actions are the network's labels and, in a falling share of the environments, the
worlds' actions; the labels map back onto the actions through the network's squash; a run imitates
for exactly its first updates, learns the teacher's actions there, resumes bit for bit and refuses a
warm start longer than its schedule.
"""

from __future__ import annotations

import csv
import dataclasses

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from socialnav.policies.learned.attn_graph import squash_actions
from socialnav.settings import ConfigError
from socialnav.train.ppo.algorithm import train_ppo
from socialnav.train.ppo.imitation import (
    imitation_actions,
    imitation_loss,
    teacher_share,
    teacher_steps,
    unsquash_actions,
)
from socialnav.train.ppo.settings import PPOSettings
from tests.train.bit_identical_runs import run_digests
from tests.train.ppo_smoke import ppo_smoke
from tests.train.walled_preset import write_walled_preset

MIX = ["narrow_hallway", "circle_crossing_obstacles"]


@pytest.fixture()
def walls_preset(tmp_path):
    return write_walled_preset(tmp_path, "francis_imitation", MIX)


def _smoke(**changes):
    return ppo_smoke(policy="lidar_ppo", lidar_beams=36, **changes)


def _curves(run_dir):
    with open(run_dir / "curves.csv", newline="") as f:
        return list(csv.DictReader(f))


def test_the_teachers_share_falls_linearly_from_all_to_none():
    assert [teacher_share(u, 4) for u in range(6)] == [1.0, 0.75, 0.5, 0.25, 0.0, 0.0]
    assert teacher_share(0, 0) == 0.0  # no imitation: PPO from the first update


def test_the_teacher_steps_its_share_of_the_environments():
    gen = torch.Generator().manual_seed(3)
    state = gen.get_state()
    assert teacher_steps(1.0, 5, gen).all() and not teacher_steps(0.0, 5, gen).any()
    assert torch.equal(gen.get_state(), state)  # no draw where the mixture is no mixture
    picked = teacher_steps(0.25, 40_000, gen)
    assert abs(picked.mean() - 0.25) < 0.01
    again = teacher_steps(0.25, 40_000, torch.Generator().manual_seed(3))
    np.testing.assert_array_equal(picked, again)  # the run's generator decides: resumable


@settings(max_examples=60, deadline=None)
@given(
    speed=st.floats(0.0, 1.0), angle=st.floats(-np.pi, np.pi), v_pref=st.floats(0.5, 2.0),
    v=st.floats(0.0, 1.0), turn=st.floats(-1.0, 1.0), reverse=st.sampled_from([0.0, 0.3]),
)
def test_a_teachers_action_is_what_its_label_squashes_to(speed, angle, v_pref, v, turn, reverse):
    vp = np.array([v_pref])
    holonomic = np.array([[speed * v_pref * np.cos(angle), speed * v_pref * np.sin(angle)]])
    raw = unsquash_actions(holonomic, "radial", vp, np.pi / 4)
    np.testing.assert_allclose(squash_actions(raw, "holonomic", vp, np.pi / 4), holonomic, atol=1e-12)
    limit = np.pi / 4
    headed = np.array([[-reverse + v * (v_pref + reverse), turn * limit]])
    kinematics = "diff_drive" if reverse else "unicycle"
    raw = unsquash_actions(headed, "span", vp, limit, reverse)
    assert np.all(np.abs(raw) <= 1.0)
    np.testing.assert_allclose(squash_actions(raw, kinematics, vp, limit, reverse), headed, atol=1e-12)


def test_a_label_faster_than_the_robot_is_the_squashed_action():
    # by hand: (3, 4) at v_pref 1 is 5 m/s, scaled onto the unit disc as the squash would scale it
    raw = unsquash_actions(np.array([[3.0, 4.0]]), "radial", np.array([1.0]), 0.5)
    np.testing.assert_allclose(raw, [[0.6, 0.8]])
    with pytest.raises(ValueError, match="squash"):
        unsquash_actions(np.zeros((1, 2)), "tanh", np.ones(1), 0.5)


class _Teacher:
    """Walks every robot at 0.5 m/s along +y."""

    def act(self, obs):
        return np.tile([0.0, 0.5], (len(obs.robot), 1))


class _Obs:
    robot = np.zeros((4, 9))
    robot[:, 7] = 1.0


def test_an_imitation_step_labels_with_the_teacher_and_mixes_the_actions():
    mean = torch.tensor([[2.0, 0.0], [0.3, 0.0], [0.0, 0.0], [0.0, -0.4]])
    gen = torch.Generator().manual_seed(0)
    label, action = imitation_actions(_Teacher(), _Obs(), mean, 1.0, gen, "holonomic", 0.5, 0.0)
    np.testing.assert_allclose(label.numpy(), np.tile([0.0, 0.5], (4, 1)))
    np.testing.assert_allclose(action, np.tile([0.0, 0.5], (4, 1)))  # β = 1: the teacher acts
    label, action = imitation_actions(_Teacher(), _Obs(), mean, 1e-9, gen, "holonomic", 0.5, 0.0)
    np.testing.assert_allclose(label.numpy(), np.tile([0.0, 0.5], (4, 1)))  # still the teacher's label
    # β ~ 0: the network's own mean action, squashed (2 m/s onto the 1 m/s disc)
    np.testing.assert_allclose(action, [[1.0, 0.0], [0.3, 0.0], [0.0, 0.0], [0.0, -0.4]])


def test_the_imitation_loss_is_the_teachers_negative_log_likelihood_plus_the_value_loss():
    mean, log_std = torch.zeros(1, 2), torch.zeros(2)
    label = torch.tensor([[1.0, 0.0]])
    loss = imitation_loss(mean, log_std, label, torch.tensor([0.0]), torch.tensor([2.0]), value_coef=0.5)
    # by hand: NLL = 0.5·1² + 2·½ln(2π); value loss ½·2² = 2, weighted 0.5
    nll = 0.5 + np.log(2 * np.pi)
    assert float(loss.policy) == pytest.approx(nll)
    assert float(loss.value) == pytest.approx(2.0)
    assert float(loss.total) == pytest.approx(nll + 1.0)
    assert float(loss.approx_kl) == 0.0 and float(loss.clip_fraction) == 0.0


def test_a_run_imitates_for_its_first_updates_then_runs_ppo(tmp_path, walls_preset):
    s = _smoke(imitation_updates=2)
    train_ppo(walls_preset, tmp_path / "run", s, progress=False, log=lambda _: None)
    rows = _curves(tmp_path / "run")
    assert [r["phase"] for r in rows] == ["il", "il", "ppo", "ppo"]
    # imitation rows have no probability ratio; PPO's have one (its KL is measured)
    assert all(float(r["approx_kl"]) == 0.0 for r in rows[:2])
    assert float(rows[2]["approx_kl"]) != 0.0
    plain = tmp_path / "plain"
    train_ppo(walls_preset, plain, _smoke(), progress=False, log=lambda _: None)
    assert run_digests(plain) != run_digests(tmp_path / "run")  # the warm start reaches the network


def test_imitation_learns_the_teachers_actions(tmp_path, walls_preset):
    # every update imitates orca_route: the negative log-likelihood of its actions falls (2.13 -> 1.02
    # when written), by more than σ's fall alone would give (σ 1 -> 0.62: at most 2·ln(1/0.62) = 0.96
    # with the mean's error unchanged, which at σ 1 already costs ~0.3)
    s = _smoke(imitation_updates=12, total_env_steps=12 * 64, epochs=4, lr=1e-2, validate_every=12)
    train_ppo(walls_preset, tmp_path / "run", s, progress=False, log=lambda _: None)
    rows = _curves(tmp_path / "run")
    nll = [float(r["policy_loss"]) for r in rows]
    assert len(nll) == 12 and all(r["phase"] == "il" for r in rows)
    assert nll[-1] < nll[0] - 0.8


def test_a_run_resumed_during_imitation_ends_as_an_uninterrupted_one(tmp_path, walls_preset):
    s = _smoke(imitation_updates=3)  # stopped at update 2: β = 1/3 mixes the actions with the generator
    train_ppo(walls_preset, tmp_path / "whole", s, progress=False, log=lambda _: None)
    train_ppo(walls_preset, tmp_path / "split", s, progress=False, stop_after=2, log=lambda _: None)
    train_ppo(walls_preset, tmp_path / "split", s, progress=False, log=lambda _: None)
    assert run_digests(tmp_path / "split") == run_digests(tmp_path / "whole")


def test_a_warm_start_longer_than_the_schedule_is_refused(tmp_path, walls_preset):
    with pytest.raises(ConfigError, match="imitation_updates 5 must be <= the schedule's 4 updates"):
        train_ppo(walls_preset, tmp_path / "run", _smoke(imitation_updates=5), progress=False,
                  log=lambda _: None)
    assert not (tmp_path / "run" / "curves.csv").exists()  # refused before anything is written
    with pytest.raises(ConfigError, match="imitation_teacher"):
        PPOSettings.from_dict({"imitation_teacher": "sarl"})


def test_the_warm_start_is_recorded_only_when_used():
    assert "imitation_updates" not in PPOSettings().to_dict()
    record = dataclasses.replace(PPOSettings(), imitation_updates=300).to_dict()
    assert record["imitation_updates"] == 300 and "imitation_teacher" not in record


def _adam_steps(run_dir):
    resume = torch.load(run_dir / "last.pt", weights_only=False)["extra"]["resume"]
    return int(next(iter(resume["optimizer"]["state"].values()))["step"])


def test_the_imitation_optimises_with_its_own_rate_and_steps(tmp_path, walls_preset):
    s = _smoke(imitation_updates=2, imitation_lr=1e-3, imitation_epochs=3, imitation_minibatches=4)
    train_ppo(walls_preset, tmp_path / "run", s, progress=False, log=lambda _: None)
    rows = _curves(tmp_path / "run")
    # imitation_lr decays over the 2 imitation updates; PPO's 3e-4 over the 4 updates goes on from there
    assert [float(r["lr"]) for r in rows] == pytest.approx([1e-3, 5e-4, 3e-4 * 2 / 4, 3e-4 * 1 / 4])
    # 2 imitation updates of 3 x 4 minibatch steps, then 2 PPO updates of ppo_smoke's 2 x 2
    assert _adam_steps(tmp_path / "run") == 2 * 12 + 2 * 4


def test_more_imitation_minibatches_than_environments_are_refused(tmp_path, walls_preset):
    with pytest.raises(ConfigError, match="imitation_minibatches"):
        PPOSettings.from_dict({"n_envs": 4, "imitation_minibatches": 5})

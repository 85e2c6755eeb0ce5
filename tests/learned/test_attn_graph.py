"""The attention-graph actor-critic (crowdnav_pp): masking, permutation invariance, the sequence pass
against step-by-step calls, the features, and the Policy wrapper's per-episode recurrent state."""

import math

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from socialnav.policies.learned.attn_graph import AttnGraphNet, human_features, robot_features
from socialnav.sim.observation import Observation

from .helpers import SMALL_ATTN_GRAPH as SMALL


def _net(seed=0, **kw):
    torch.manual_seed(seed)
    net = AttnGraphNet(**{**SMALL, **kw}).eval()
    # non-trivial normalisation statistics, so that padding is tested through them too
    g = torch.Generator().manual_seed(seed)
    net.update_obs_stats(
        torch.randn(64, 9, generator=g),
        torch.randn(64, 3, net.input_dim, generator=g),
        torch.ones(64, 3, dtype=torch.bool),
    )
    return net


def _outputs(net, robot, humans, mask, h):
    with torch.no_grad():
        mean, value, h2 = net.step(robot, humans, mask, h, torch.zeros(robot.shape[0], dtype=torch.bool))
    return torch.cat([mean, value[:, None], h2], -1)


@settings(max_examples=40, deadline=None)
@given(
    n_real=st.integers(0, 5),
    n_pad=st.integers(1, 4),
    seed=st.integers(0, 2**16),
    garbage=st.floats(-1e3, 1e3, allow_nan=False),
    self_attention=st.booleans(),
)
def test_padded_humans_change_nothing(n_real, n_pad, seed, garbage, self_attention):
    net = _net(seed % 7, self_attention=self_attention)
    g = torch.Generator().manual_seed(seed)
    robot = torch.randn(3, 9, generator=g)
    humans = torch.randn(3, n_real, net.input_dim, generator=g)
    h = torch.randn(3, net.gru_hidden, generator=g)
    base = _outputs(net, robot, humans, torch.ones(3, n_real, dtype=torch.bool), h)
    # padded slots hold arbitrary values, anywhere among the real ones
    pad = torch.full((3, n_pad, net.input_dim), garbage)
    perm = torch.randperm(n_real + n_pad, generator=g)
    padded = torch.cat([humans, pad], 1)[:, perm]
    mask = torch.cat([torch.ones(3, n_real, dtype=torch.bool), torch.zeros(3, n_pad, dtype=torch.bool)], 1)[
        :, perm
    ]
    out = _outputs(net, robot, padded, mask, h)
    assert torch.isfinite(out).all()
    torch.testing.assert_close(out, base, rtol=1e-5, atol=1e-5)


def test_order_of_the_humans_does_not_matter():
    net = _net()
    g = torch.Generator().manual_seed(1)
    robot, humans = torch.randn(4, 9, generator=g), torch.randn(4, 5, net.input_dim, generator=g)
    mask = torch.rand(4, 5, generator=g) > 0.3
    h = torch.zeros(4, net.gru_hidden)
    perm = torch.tensor([3, 0, 4, 1, 2])
    torch.testing.assert_close(
        _outputs(net, robot, humans[:, perm], mask[:, perm], h),
        _outputs(net, robot, humans, mask, h),
        rtol=1e-5,
        atol=1e-6,
    )


def test_humans_do_change_the_output():
    net = _net()
    g = torch.Generator().manual_seed(2)
    robot, humans = torch.randn(2, 9, generator=g), torch.randn(2, 3, net.input_dim, generator=g)
    h = torch.zeros(2, net.gru_hidden)
    with_humans = _outputs(net, robot, humans, torch.ones(2, 3, dtype=torch.bool), h)
    without = _outputs(net, robot, humans, torch.zeros(2, 3, dtype=torch.bool), h)
    assert not torch.allclose(with_humans, without)


def test_sequence_pass_equals_step_by_step():
    net = _net()
    g = torch.Generator().manual_seed(3)
    t, b = 6, 4
    robot, humans = torch.randn(t, b, 9, generator=g), torch.randn(t, b, 5, net.input_dim, generator=g)
    mask = torch.rand(t, b, 5, generator=g) > 0.4
    starts = torch.rand(t, b, generator=g) > 0.7
    h0 = torch.randn(b, net.gru_hidden, generator=g)
    with torch.no_grad():
        mean, value = net.sequence(robot, humans, mask, h0, starts)
        h = h0
        for i in range(t):
            m, v, h = net.step(robot[i], humans[i], mask[i], h, starts[i])
            torch.testing.assert_close(mean[i], m, rtol=1e-5, atol=1e-6)
            torch.testing.assert_close(value[i], v, rtol=1e-5, atol=1e-6)


def test_features_are_hand_computed():
    # robot at (1, 2) moving (0.5, 0), goal (4, 6), radius 0.3, v_pref 1.5, heading π/2
    robot = torch.tensor([[1.0, 2.0, 0.5, 0.0, 0.3, 4.0, 6.0, 1.5, math.pi / 2]], dtype=torch.float64)
    rf = robot_features(robot)
    np.testing.assert_allclose(rf[0].numpy(), [3, 4, 5, 0.5, 0, 0.3, 1.5, 0, 1], atol=1e-12)
    humans = torch.tensor([[[2.0, 2.0, 1.0, -1.0, 0.3], [9.0, 9.0, 9.0, 9.0, 0.3]]], dtype=torch.float64)
    hf = human_features(robot, humans, torch.tensor([[True, False]]), dt=0.25, steps=2)
    # now (1, 0), then +0.25·(1, −1) per step; the padded slot is all zeros
    np.testing.assert_allclose(hf[0, 0].numpy(), [1, 0, 1.25, -0.25, 1.5, -0.5])
    assert hf[0, 1].abs().sum() == 0


def test_observation_statistics_leave_padding_out():
    net = AttnGraphNet(**SMALL, prediction_steps=0)
    humans = torch.tensor([[[1.0, 2.0], [100.0, 100.0]], [[3.0, 4.0], [0.0, 0.0]]])
    net.update_obs_stats(torch.zeros(2, 9), humans, torch.tensor([[True, False], [True, False]]))
    np.testing.assert_allclose(net.human_mean.numpy(), [2.0, 3.0])
    np.testing.assert_allclose(net.human_var.numpy(), [1.0, 1.0])
    net.update_obs_stats(torch.zeros(1, 9), torch.tensor([[[5.0, 6.0]]]), torch.tensor([[True]]))
    np.testing.assert_allclose(net.human_mean.numpy(), [3.0, 4.0])  # mean of 1, 3, 5 and 2, 4, 6
    np.testing.assert_allclose(net.human_var.numpy(), [8 / 3, 8 / 3])


def _obs(time, b=2, kinematics="holonomic"):
    robot = np.tile([0.0, -4.0, 0.0, 0.0, 0.3, 0.0, 4.0, 1.5, math.pi / 2], (b, 1))
    humans = np.zeros((b, 2, 5))
    humans[:, 0] = [1.0, 0.0, 0.0, 0.0, 0.3]
    return Observation(
        robot,
        humans,
        np.array([[True, False]] * b),
        np.ones(b, bool),
        np.asarray(time, float),
        0.25,
        kinematics,
    )


def test_policy_resets_the_recurrent_state_where_an_episode_starts():
    from socialnav.policies.learned.ppo_policy import RecurrentActorPolicy

    policy = RecurrentActorPolicy(
        "crowdnav_pp", _net(), kinematics="holonomic", rotation_limit=math.pi / 4, dt=0.25
    )
    first = policy.act(_obs([0.0, 0.0]))
    policy.act(_obs([0.25, 0.25]))
    again = policy.act(_obs([0.5, 0.0]))  # slot 1 holds a fresh episode: it acts as at its first step
    np.testing.assert_array_equal(again[1], first[1])
    assert not np.array_equal(again[0], first[0])
    assert (np.hypot(again[:, 0], again[:, 1]) <= 1.5 + 1e-12).all()
    inactive = _obs([0.0, 0.0])
    inactive.active[0] = False
    assert policy.act(inactive)[0].tolist() == [0.0, 0.0]


def test_checkpoint_round_trip_through_the_policy_registry(tmp_path):
    from socialnav.policies.building import build_policy
    from socialnav.policies.learned import save_checkpoint
    from socialnav.policies.learned.checkpoint import CheckpointError
    from socialnav.policies.learned_loading import PresetMismatchError
    from socialnav.presets import load_preset
    from socialnav.train.worlds import ppo_policy_config

    preset = load_preset("wang2022")
    net = _net(prediction_steps=3)
    path = tmp_path / "a.pt"
    save_checkpoint(
        path, "crowdnav_pp", net, config={"ppo_policy": ppo_policy_config(preset), "preset": preset.to_dict()}
    )
    policy = build_policy("crowdnav_pp", preset, path)
    assert policy.describe()["policy"] == "crowdnav_pp" and policy.network.prediction_steps == 3
    obs = _obs([0.0, 0.0])
    torch.manual_seed(0)
    np.testing.assert_array_equal(policy.act(obs), policy.act(_obs([0.0, 0.0])))  # deterministic
    with pytest.raises(PresetMismatchError, match="robot.v_pref"):
        build_policy("crowdnav_pp", load_preset("crowdnav"), path)
    save_checkpoint(tmp_path / "b.pt", "crowdnav_pp", net, config={})
    with pytest.raises(CheckpointError, match="ppo_policy"):
        build_policy("crowdnav_pp", preset, tmp_path / "b.pt")


def test_unicycle_checkpoints_act_with_the_squash_they_were_trained_with(tmp_path):
    """A unicycle record with ``action_squash: span`` spans the commands; one without it (trained
    before the unicycle spanned them) clips v to [0, v_pref], so old checkpoints keep their results."""
    from socialnav.policies.building import build_policy
    from socialnav.policies.learned import save_checkpoint
    from socialnav.policies.learned.ppo_inputs import network_inputs
    from socialnav.presets import load_preset
    from socialnav.train.worlds import ppo_policy_config

    preset = load_preset("wang2022_unicycle")
    net = _net(seed=3)
    record = ppo_policy_config(preset)
    legacy = {k: v for k, v in record.items() if k != "action_squash"}
    for name, ppo_policy in (("span.pt", record), ("clip.pt", legacy)):
        save_checkpoint(tmp_path / name, "crowdnav_pp", net,
                        config={"ppo_policy": ppo_policy, "preset": preset.to_dict()})
    obs = _obs([0.0, 0.0], kinematics="unicycle")
    with torch.no_grad():
        robot, humans, mask = network_inputs(net, obs, 0.25, "cpu")
        start = torch.ones(2, dtype=torch.bool)
        mean, _, _ = net.step(robot, humans, mask, net.initial_state(2, "cpu"), start)
    raw = mean.double().numpy()
    limit = preset.world.rotation_limit
    spanned = build_policy("crowdnav_pp", preset, tmp_path / "span.pt").act(obs)
    clipped = build_policy("crowdnav_pp", preset, tmp_path / "clip.pt").act(obs)
    u = np.clip(raw, -1.0, 1.0)
    np.testing.assert_allclose(spanned, np.stack([(u[:, 0] + 1) / 2 * 1.5, u[:, 1] * limit], 1), rtol=1e-6)
    np.testing.assert_allclose(
        clipped, np.stack([np.clip(raw[:, 0], 0, 1.5), np.clip(raw[:, 1], -limit, limit)], 1), rtol=1e-6
    )
    assert not np.allclose(spanned, clipped)

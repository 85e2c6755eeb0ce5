"""Value networks: masking, padding, permutation invariance, zero humans, architecture sizes."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from socialnav.policies.learned import SARL, ValuePolicy, build
from socialnav.policies.learned.networks import masked_softmax

from .helpers import NETWORKS, obs_dict, random_scene


def _policy(name, seed=0, dtype=torch.float64):
    torch.manual_seed(seed)
    return ValuePolicy(build(name).to(dtype))


def _compact(humans, mask, b):
    """Episode b with its real humans only (padding removed)."""
    return humans[b : b + 1, mask[b]], np.ones((1, int(mask[b].sum())), bool)


@pytest.mark.parametrize("name", NETWORKS)
@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(1, 6), garbage=st.sampled_from([1.0, 1e3, 1e6]))
def test_padding_with_garbage_does_not_change_values(name, seed, n, garbage):
    pol = _policy(name)
    rng = np.random.default_rng(seed)
    robot, humans, mask = random_scene(rng, 4, n, garbage=garbage)
    q = pol.values(obs_dict(robot, humans, mask))
    assert np.all(np.isfinite(q))
    for b in range(4):
        h, m = _compact(humans, mask, b)
        qb = pol.values(obs_dict(robot[b : b + 1], h, m))
        np.testing.assert_allclose(q[b], qb[0], rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("name", NETWORKS)
def test_nan_and_inf_in_padding_do_not_leak(name):
    pol = _policy(name)
    robot, humans, mask = random_scene(np.random.default_rng(1), 3, 4)
    mask[:, 0] = True
    mask[:, 3] = False
    mask[2, :] = False
    clean = pol.values(obs_dict(robot, humans, mask))
    humans = humans.copy()
    humans[:, 3] = np.nan
    humans[1, 3, 0] = np.inf
    humans[2] = np.nan
    dirty = pol.values(obs_dict(robot, humans, mask))
    np.testing.assert_allclose(dirty, clean, rtol=1e-12)


@pytest.mark.parametrize("name", NETWORKS)
def test_zero_humans_is_finite_and_equals_empty_episode(name):
    pol = _policy(name)
    robot, humans, _ = random_scene(np.random.default_rng(2), 3, 5)
    mask = np.zeros((3, 5), bool)
    q = pol.values(obs_dict(robot, humans, mask))
    assert np.all(np.isfinite(q))
    q0 = pol.values(obs_dict(robot, np.zeros((3, 0, 5)), np.zeros((3, 0), bool)))
    np.testing.assert_allclose(q, q0, rtol=1e-12)
    idx, act = pol.act(obs_dict(robot, humans, mask))
    assert idx.shape == (3,) and act.shape == (3, 2)


@pytest.mark.parametrize("name", ["cadrl", "sarl", "om_sarl", "lstm_rl"])
@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_permutation_invariance(name, seed):
    pol = _policy(name)
    rng = np.random.default_rng(seed)
    robot, humans, mask = random_scene(rng, 3, 5, garbage=10.0)
    q = pol.values(obs_dict(robot, humans, mask))
    perm = rng.permutation(5)
    qp = pol.values(obs_dict(robot, humans[:, perm], mask[:, perm]))
    np.testing.assert_allclose(q, qp, rtol=1e-9, atol=1e-9)


def test_sarl_zero_humans_uses_robot_state_with_zero_feature():
    torch.manual_seed(0)
    net = SARL().double()
    joint = torch.randn(4, 3, 13, dtype=torch.float64)
    joint[:, :, :6] = joint[:, :1, :6]
    mask = torch.zeros(4, 3, dtype=torch.bool)
    v = net.value(joint, mask)
    want = net.mlp3(torch.cat([joint[:, 0, :6], torch.zeros(4, 50, dtype=torch.float64)], 1)).squeeze(-1)
    torch.testing.assert_close(v, want)


def test_masked_softmax_stable_and_guarded():
    s = torch.tensor([[1000.0, 1001.0, float("nan")], [-1e30, 5.0, 3.0], [1.0, 2.0, 3.0]])
    m = torch.tensor([[True, True, False], [False, False, False], [True, False, True]])
    w = masked_softmax(s, m)
    assert torch.isfinite(w).all()
    torch.testing.assert_close(w[0, :2], torch.softmax(torch.tensor([0.0, 1.0]), 0))
    assert w[0, 2] == 0 and torch.all(w[1] == 0)
    torch.testing.assert_close(w[2].sum(), torch.tensor(1.0))


def test_sarl_attention_matches_concat_formulation():
    torch.manual_seed(3)
    net = SARL().double()
    e = torch.randn(5, 4, 100, dtype=torch.float64)
    mask = torch.rand(5, 4) < 0.7
    mask[:, 0] = True
    g = (e * mask[..., None]).sum(1) / mask.sum(1, keepdim=True)
    cat = torch.cat([e, g[:, None].expand_as(e)], dim=-1)
    want = net.attention(cat).squeeze(-1)
    torch.testing.assert_close(net.attention_scores(e, mask), want)


def test_lstm_closest_human_last_and_padding_position_irrelevant():
    torch.manual_seed(4)
    net = build("lstm_rl").double()
    joint = torch.randn(1, 3, 13, dtype=torch.float64)
    joint[..., 11] = torch.tensor([1.0, 3.0, 2.0])  # distances
    mask = torch.ones(1, 3, dtype=torch.bool)
    v = net.value(joint, mask)
    # manual: order by decreasing distance = slots 1, 2, 0
    x = net.mlp1(joint[0, [1, 2, 0]]).unsqueeze(0)
    _, (h, _) = net.lstm(x)
    want = net.mlp2(torch.cat([joint[:, 0, :6], h[-1]], 1)).squeeze(-1)
    torch.testing.assert_close(v, want)
    # padding first or last gives the same result
    pad = torch.full((1, 2, 13), 7.0, dtype=torch.float64)
    pm = torch.zeros(1, 2, dtype=torch.bool)
    v_first = net.value(torch.cat([pad, joint], 1), torch.cat([pm, mask], 1))
    v_last = net.value(torch.cat([joint, pad], 1), torch.cat([mask, pm], 1))
    torch.testing.assert_close(v_first, v)
    torch.testing.assert_close(v_last, v)


def test_architecture_sizes():
    def widths(seq):
        return [(m.in_features, m.out_features) for m in seq if isinstance(m, torch.nn.Linear)]

    cadrl = build("cadrl")
    assert widths(cadrl.value_mlp) == [(13, 150), (150, 100), (100, 100), (100, 1)]
    sarl = build("sarl")
    assert widths(sarl.mlp1) == [(13, 150), (150, 100)] and isinstance(sarl.mlp1[-1], torch.nn.ReLU)
    assert widths(sarl.mlp2) == [(100, 100), (100, 50)]
    assert widths(sarl.attention) == [(200, 100), (100, 100), (100, 1)]
    assert widths(sarl.mlp3) == [(56, 150), (150, 100), (100, 100), (100, 1)]
    om = build("om_sarl")
    assert om.input_dim == 61 and om.with_om and widths(om.mlp1)[0] == (61, 150)
    lstm = build("ga3c_cadrl")
    assert widths(lstm.mlp1) == [(13, 150), (150, 100), (100, 100), (100, 50)]
    assert lstm.lstm.hidden_size == 50 and lstm.lstm.input_size == 50
    assert widths(lstm.mlp2) == [(56, 150), (150, 100), (100, 100), (100, 1)]
    raw = build("lstm_rl", with_interaction_module=False)
    assert raw.lstm.input_size == 13


def _naive_sarl(net, joint, mask):
    """Textbook SARL forward on real humans only (one state at a time, concat attention input)."""
    out = []
    for i in range(joint.shape[0]):
        x = joint[i, mask[i]]
        s = joint[i, 0, :6]
        if x.shape[0] == 0:
            feat = torch.zeros(net.mlp2_dims[-1], dtype=joint.dtype)
        else:
            e = net.mlp1(x)
            h = net.mlp2(e)
            g = e.mean(0, keepdim=True).expand_as(e)
            w = torch.softmax(net.attention(torch.cat([e, g], 1)).squeeze(-1), 0)
            feat = (w[:, None] * h).sum(0)
        out.append(net.mlp3(torch.cat([s, feat])))
    return torch.cat(out)


@pytest.mark.parametrize("name", ["sarl", "om_sarl"])
def test_sarl_matches_textbook_forward_and_gradients(name):
    torch.manual_seed(5)
    net = build(name).double()
    d = net.input_dim
    joint = torch.randn(6, 4, d, dtype=torch.float64)
    joint[:, :, :6] = joint[:, :1, :6]
    mask = torch.rand(6, 4) < 0.6
    mask[0] = False
    mask[1] = True
    v = net.value(joint, mask)
    ref = _naive_sarl(net, joint, mask)
    torch.testing.assert_close(v, ref)
    g1 = torch.autograd.grad(v.sum(), list(net.parameters()))
    g2 = torch.autograd.grad(ref.sum(), list(net.parameters()))
    for a, b in zip(g1, g2, strict=True):
        torch.testing.assert_close(a, b)


@pytest.mark.parametrize("name", ["cadrl", "lstm_rl", "sarl", "om_sarl"])
def test_networks_train_with_backward(name):
    torch.manual_seed(6)
    net = build(name)
    joint = torch.randn(8, 3, net.input_dim)
    mask = torch.rand(8, 3) < 0.7
    mask[0] = False
    loss = (net.value(joint, mask) - 1.0).pow(2).mean()
    loss.backward()
    assert all(p.grad is not None and torch.isfinite(p.grad).all() for p in net.parameters())

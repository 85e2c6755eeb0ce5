"""RGL, the learned state predictor and model-predictive planning (MP-RGL)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from socialnav.policies.learned import (
    RGL,
    StatePredictor,
    ValuePolicy,
    build,
    load_checkpoint,
    save_checkpoint,
)
from socialnav.policies.learned.actions import discrete_actions
from socialnav.policies.learned.checkpoint import CheckpointError
from socialnav.policies.learned.state import RewardParams, propagate_robot, reward, swept_reward

from .helpers import obs_dict, random_scene

DT = 0.25


def _rgl(seed=0, name="rgl"):
    torch.manual_seed(seed)
    return build(name).to(torch.float64)


def _predictor(seed=0, perturb=0.0):
    torch.manual_seed(seed)
    p = StatePredictor().to(torch.float64)
    if perturb:
        with torch.no_grad():
            p.motion[-1].weight.normal_(0.0, perturb)
            p.motion[-1].bias.normal_(0.0, perturb)
    return p


# ------------------------------------------------------------------ relation matrix and padding
@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(1, 7), garbage=st.sampled_from([0.0, 1.0, 1e4]))
def test_relation_rows_sum_to_one_over_present_nodes_and_padding_has_no_effect(seed, n, garbage):
    net = _rgl(seed % 7)
    rng = np.random.default_rng(seed)
    robot, humans, mask = random_scene(rng, 5, n, garbage=garbage)
    pol = ValuePolicy(net)
    joint = pol.transform(torch.as_tensor(robot), torch.as_tensor(humans), torch.as_tensor(mask))
    m = torch.as_tensor(mask)
    a = net.relation_matrix(joint, m)
    assert a.shape == (5, n + 1, n + 1)
    present = torch.cat([torch.ones(5, 1, dtype=torch.bool), m], dim=1)
    np.testing.assert_allclose(a.sum(-1).numpy(), 1.0, atol=1e-12)  # every row, robot included
    assert torch.all(a.masked_select(~present.unsqueeze(1).expand_as(a)) == 0)  # padded columns
    # Values with padding equal the values of the same episodes with their real humans only.
    v = net.value(joint, m)
    for b in range(5):
        real = mask[b]
        jb = pol.transform(
            torch.as_tensor(robot[b : b + 1]),
            torch.as_tensor(humans[b : b + 1, real] if real.any() else np.zeros((1, 1, 5))),
            torch.as_tensor(np.ones((1, max(int(real.sum()), 1)), bool) & real.any()),
        )
        vb = net.value(jb, torch.as_tensor(np.ones((1, max(int(real.sum()), 1)), bool) & real.any()))
        np.testing.assert_allclose(v[b].item(), vb.item(), rtol=1e-9, atol=1e-12)


def test_rgl_architecture_and_scaled_initialisation():
    net = RGL()
    assert net.graph.x_dim == 32 and len(net.graph.convs) == 2
    assert [m.out_features for m in net.value_mlp if isinstance(m, torch.nn.Linear)] == [150, 100, 100, 1]
    # Xavier: variance 2 / (fan_in + fan_out) = 1/32 for a 32×32 matrix, far below randn's 1.
    assert float(net.graph.w_a.var()) < 0.1
    for conv in net.graph.convs:
        assert float(conv.weight.var()) < 0.1


def test_zero_humans_rgl_values_the_robot_state_alone():
    net = _rgl()
    robot, humans, _ = random_scene(np.random.default_rng(3), 2, 3)
    pol = ValuePolicy(net)
    q_empty = pol.values(obs_dict(robot, np.zeros((2, 0, 5)), np.zeros((2, 0), bool)))
    q_masked = pol.values(obs_dict(robot, humans, np.zeros((2, 3), bool)))
    assert np.all(np.isfinite(q_empty))
    np.testing.assert_allclose(q_empty, q_masked, rtol=1e-12)


# ------------------------------------------------------------------ swept reward
def test_swept_reward_catches_a_collision_inside_the_step():
    # Robot crosses x = 0 from (-0.5, 0) to (0.5, 0) in one step; a standing human at (0, 0.5):
    # the ends are 0.707 m from the human (clearance 0.107 > 0), mid-step it is 0.5 m (clearance -0.1).
    robot = torch.tensor([[-0.5, 0.0, 0.0, 0.0, 0.2, 10.0, 0.0, 4.0, 0.0]], dtype=torch.float64)
    robot_next = robot.clone().unsqueeze(1)
    robot_next[..., 0] = 0.5
    robot_next[..., 2] = 4.0
    humans = torch.tensor([[[0.0, 0.5, 0.0, 0.0, 0.4]]], dtype=torch.float64)
    mask = torch.ones(1, 1, dtype=torch.bool)
    p = RewardParams()
    assert swept_reward(robot, robot_next, humans, humans, mask, p).item() == p.collision_penalty
    end = reward(robot_next, humans.unsqueeze(1), mask.unsqueeze(1), p).item()
    # End positions only: no collision, only discomfort (clearance 0.7071 - 0.6 = 0.1071 < 0.2).
    assert end == pytest.approx((math.sqrt(0.5) - 0.6 - 0.2) * 0.5 * 0.25)


def test_swept_reward_discomfort_and_goal_by_hand():
    robot = torch.tensor([[0.0, 0.0, 0.0, 0.0, 0.3, 0.0, 2.0, 1.0, 0.0]], dtype=torch.float64)
    nxt = robot.clone().unsqueeze(1).repeat(1, 2, 1)
    nxt[0, 0, 1] = 0.25  # moves 0.25 m up, towards the goal
    nxt[0, 1, 1] = 1.8  # lands within its radius of the goal (2.0 - 1.8 < 0.3)
    # A human moving down from (0.9, 1.0) to (0.9, 0.75): relative motion keeps x = 0.9.
    humans = torch.tensor([[[0.9, 1.0, 0.0, -1.0, 0.3]]], dtype=torch.float64)
    hn = humans.clone()
    hn[..., 1] = 0.75
    mask = torch.ones(1, 1, dtype=torch.bool)
    r = swept_reward(robot, nxt, humans, hn, mask, RewardParams())
    # Action 0: relative position (0.9, 1.0) → (0.9, 0.5): closest at the end, 1.0296 - 0.6 = 0.4296
    # clearance: no discomfort, reward 0.
    assert r[0, 0].item() == 0.0
    # Action 1: relative (0.9, 1.0) → (0.9, -1.05): passes x = 0.9 exactly, clearance 0.3 > 0.2 → goal.
    assert r[0, 1].item() == 1.0
    hn2 = hn.clone()
    hn2[..., 0] = 0.7  # now the sweep passes at 0.7..0.9 m: clearance ≈ 0.15 < 0.2 at its closest
    r2 = swept_reward(robot, nxt[:, :1], humans, hn2, mask, RewardParams())
    d0 = np.array([0.9, 1.0])
    dd = np.array([-0.2, -0.25 - 0.25])
    s = np.clip(-(d0 @ dd) / (dd @ dd), 0, 1)
    clearance = np.linalg.norm(d0 + s * dd) - 0.6
    expected = (clearance - 0.2) * 0.5 * 0.25 if clearance < 0.2 else 0.0
    assert r2.item() == pytest.approx(expected)


# ------------------------------------------------------------------ planning
@torch.no_grad()
def _ref_one_step(pol, pred, r, h, m):
    """Unbatched one-step lookahead: one action at a time (reference for the batched code)."""
    acts = discrete_actions(pol.kinematics, r[7:8], pol.rotation_limit)[0]
    rt, ht, mt = r[None], h[None], m[None]
    hn = pred(rt, ht, mt, DT)
    disc = pol.gamma ** (DT * float(r[7]))
    qs, rews, nexts = [], [], []
    for a in acts:
        rn = propagate_robot(rt, a.view(1, 1, 2), pol.kinematics, DT)  # (1, 1, 9)
        rew = swept_reward(rt, rn, ht, hn, mt, pol.reward_params)[0, 0].item()
        v = pol.network.value(pol.transform(rn[:, 0], hn, mt), mt).item()
        qs.append(rew + disc * v)
        rews.append(rew)
        nexts.append(rn[0, 0])
    return np.array(qs), np.array(rews), nexts, hn[0], disc


@torch.no_grad()
def _ref_value(pol, pred, r, h, m, depth, width):
    v = pol.network.value(pol.transform(r[None], h[None], m[None]), m[None]).item()
    if depth == 1:
        return v
    q, rews, nexts, hn, disc = _ref_one_step(pol, pred, r, h, m)
    top = np.argsort(-q, kind="stable")[:width]
    best = max(rews[a] + disc * _ref_value(pol, pred, nexts[a], hn, m, depth - 1, width) for a in top)
    return v / depth + (depth - 1) / depth * best


def _ref_root(pol, pred, r, h, m, depth, width):
    q, rews, nexts, hn, disc = _ref_one_step(pol, pred, r, h, m)
    if depth == 1:
        return q
    out = np.full_like(q, -np.inf)
    for a in np.argsort(-q, kind="stable")[:width]:
        out[a] = rews[a] + disc * _ref_value(pol, pred, nexts[a], hn, m, depth, width)
    return out


@pytest.mark.parametrize("depth,width", [(1, 1), (2, 2), (3, 2), (2, 3)])
def test_batched_planning_equals_one_episode_at_a_time_reference(depth, width):
    net, pred = _rgl(1, "mp_rgl"), _predictor(2, perturb=0.05)
    pol = ValuePolicy(
        net,
        information="learned",
        predictor=pred,
        planning_depth=depth,
        planning_width=width,
        reward_rule="swept",
    )
    robot, humans, mask = random_scene(np.random.default_rng(7), 3, 4)
    mask[0, 2:] = False
    batched = pol.values(obs_dict(robot, humans, mask))
    for b in range(3):
        real = mask[b]
        h = torch.as_tensor(humans[b, real])
        ref = _ref_root(
            pol, pred, torch.as_tensor(robot[b]), h, torch.ones(len(h), dtype=torch.bool), depth, width
        )
        np.testing.assert_allclose(batched[b], ref, rtol=1e-9, atol=1e-10)
        # ...and equal to planning the episode alone through the batched code.
        alone = pol.values(
            obs_dict(robot[b : b + 1], humans[b : b + 1, real], np.ones((1, real.sum()), bool))
        )
        np.testing.assert_allclose(batched[b], alone[0], rtol=1e-9, atol=1e-10)
    finite = np.isfinite(batched).sum(axis=1)
    assert np.all(finite == (81 if depth == 1 else width))


def test_d1_w1_mp_rgl_scores_every_action_as_the_one_step_lookahead_with_the_same_predictor():
    net, pred = _rgl(4, "mp_rgl"), _predictor(5, perturb=0.05)
    robot, humans, mask = random_scene(np.random.default_rng(11), 4, 5)
    mp = ValuePolicy(
        net, information="learned", predictor=pred, planning_depth=1, planning_width=1, reward_rule="swept"
    )
    q = mp.values(obs_dict(robot, humans, mask))
    for b in range(4):
        real = mask[b]
        h = torch.as_tensor(humans[b, real])
        ref, *_ = _ref_one_step(mp, pred, torch.as_tensor(robot[b]), h, torch.ones(len(h), dtype=torch.bool))
        np.testing.assert_allclose(q[b], ref, rtol=1e-9, atol=1e-10)
    # The deeper plan picks among the one-step top-w and differs from it somewhere.
    deep = ValuePolicy(
        net, information="learned", predictor=pred, planning_depth=2, planning_width=2, reward_rule="swept"
    )
    q2 = deep.values(obs_dict(robot, humans, mask))
    top2 = np.argsort(-q, axis=1)[:, :2]
    for b in range(4):
        assert q2[b].argmax() in top2[b]
    assert not np.allclose(q2[np.isfinite(q2)], np.sort(q, axis=1)[:, ::-1][:, :2].reshape(-1))


def test_planning_settings_are_validated():
    net, pred = _rgl(), _predictor()
    with pytest.raises(ValueError, match="predictor"):
        ValuePolicy(net, information="learned")
    with pytest.raises(ValueError, match="oracle"):
        ValuePolicy(net, information="oracle", planning_depth=2)
    with pytest.raises(ValueError, match="planning_depth"):
        ValuePolicy(net, information="learned", predictor=pred, planning_depth=0)
    with pytest.raises(ValueError, match="reward_rule"):
        ValuePolicy(net, reward_rule="sometimes")


# ------------------------------------------------------------------ the predictor learns
def _transitions(rng, m, n, law):
    robot, humans, mask = random_scene(rng, m, n, p_real=0.8)
    mask[:, 0] = True
    nxt = humans.copy()
    v = law(humans[..., 2:4])
    nxt[..., 2:4] = v
    nxt[..., 0:2] = humans[..., 0:2] + v * DT
    t = [torch.as_tensor(x) for x in (robot, humans, mask, nxt, mask)]
    return t


def _train(pred, data, steps, seed=0):
    opt = torch.optim.Adam(pred.parameters(), lr=3e-3)
    gen = torch.Generator().manual_seed(seed)
    m = data[0].shape[0]
    for _ in range(steps):
        idx = torch.randint(0, m, (128,), generator=gen)
        loss = pred.loss(*(x[idx] for x in data), DT)
        opt.zero_grad()
        loss.backward()
        opt.step()


@pytest.mark.parametrize(
    "law,name",
    [(lambda v: v, "constant velocity"), (lambda v: 0.5 * v, "halving speed")],
)
def test_predictor_learns_a_crowd_to_small_error(law, name):
    rng = np.random.default_rng(0)
    pred = _predictor(3, perturb=0.3)  # start far from any law: the head is randomised
    train = _transitions(rng, 4000, 5, law)
    test = _transitions(rng, 500, 5, law)
    with torch.no_grad():
        before = pred.loss(*test, DT).item()
    _train(pred, train, 600)
    with torch.no_grad():
        after = pred.loss(*test, DT).item()
    # Per-coordinate position MSE; 1e-4 m² is an RMS error of 1 cm over a 0.25 s step.
    assert before > 1e-3, (name, before)
    assert after < 1e-4 and after < before / 20, (name, before, after)


@torch.no_grad()
def test_predictor_leaves_padded_humans_unchanged_and_ignores_them():
    pred = _predictor(6, perturb=0.2)
    robot, humans, mask = random_scene(np.random.default_rng(4), 3, 4, garbage=1e3)
    mask[:, 0] = True
    out = pred(torch.as_tensor(robot), torch.as_tensor(humans), torch.as_tensor(mask), DT).numpy()
    np.testing.assert_array_equal(out[~mask], humans[~mask])
    for b in range(3):
        real = mask[b]
        alone = pred(
            torch.as_tensor(robot[b : b + 1]),
            torch.as_tensor(humans[b : b + 1, real]),
            torch.ones(1, int(real.sum()), dtype=torch.bool),
            DT,
        ).numpy()
        np.testing.assert_allclose(out[b, real], alone[0], rtol=1e-9, atol=1e-12)


# ------------------------------------------------------------------ checkpoints
def test_checkpoint_keeps_the_predictor_and_refuses_other_policies(tmp_path):
    net, pred = _rgl(0, "mp_rgl").float(), _predictor(1, perturb=0.1).float()
    path = save_checkpoint(tmp_path / "mp.pt", "mp_rgl", net, config={"value_policy": {}}, predictor=pred)
    ck = load_checkpoint(path, "mp_rgl")
    assert ck.predictor is not None
    for k, v in pred.state_dict().items():
        assert torch.equal(ck.predictor.state_dict()[k], v)
    with pytest.raises(CheckpointError, match=r"holds policy 'mp_rgl', expected 'rgl' \(load it as 'mp_rgl'"):
        load_checkpoint(path, "rgl")
    rgl_path = save_checkpoint(tmp_path / "rgl.pt", "rgl", _rgl().float())
    with pytest.raises(CheckpointError, match=r"holds policy 'rgl', expected 'sarl'"):
        load_checkpoint(rgl_path, "sarl")
    assert load_checkpoint(rgl_path, "rgl").predictor is None


def test_learned_information_needs_a_checkpoint_with_a_predictor(tmp_path):
    from socialnav.policies.learned_loading import load_learned_policy

    rgl_path = save_checkpoint(
        tmp_path / "rgl.pt",
        "rgl",
        _rgl().float(),
        config={"value_policy": {"information": "constant_velocity"}},
    )
    with pytest.raises(ValueError, match="stores no state predictor"):
        load_learned_policy("rgl", rgl_path, information="learned")
    mp_path = save_checkpoint(
        tmp_path / "mp.pt",
        "mp_rgl",
        _rgl(0, "mp_rgl").float(),
        config={"value_policy": {"information": "learned", "planning_depth": 2, "planning_width": 2}},
        predictor=_predictor().float(),
    )
    pol = load_learned_policy("mp_rgl", mp_path, planning_depth=1)
    assert pol.value_policy.planning_depth == 1 and pol.value_policy.planning_width == 2
    assert pol.describe()["information"] == "learned"

"""ValuePolicy: batched scoring equals per-episode scoring, lookahead formula, ε-greedy, oracle."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from socialnav.policies.learned import RewardParams, ValuePolicy, build
from socialnav.policies.learned.actions import discrete_actions
from socialnav.policies.learned.state import (
    propagate_humans_constant_velocity,
    propagate_robot,
    reward,
    rotate,
)

from .helpers import NETWORKS, obs_dict, random_scene


def _policy(name, kinematics="holonomic", information="constant_velocity", dtype=torch.float64):
    torch.manual_seed(11)
    return ValuePolicy(build(name).to(dtype), kinematics=kinematics, information=information)


@pytest.mark.parametrize("kinematics", ["holonomic", "unicycle"])
@pytest.mark.parametrize("name", NETWORKS)
def test_batched_equals_one_episode_at_a_time(name, kinematics):
    pol = _policy(name, kinematics)
    robot, humans, mask = random_scene(np.random.default_rng(5), 7, 5, garbage=3.0)
    q = pol.values(obs_dict(robot, humans, mask))
    idx, act = pol.act(obs_dict(robot, humans, mask))
    for b in range(7):
        ob = obs_dict(robot[b : b + 1], humans[b : b + 1], mask[b : b + 1])
        np.testing.assert_allclose(pol.values(ob)[0], q[b], rtol=1e-10, atol=1e-12)
        ib, ab = pol.act(ob)
        assert ib[0] == idx[b]
        np.testing.assert_allclose(ab[0], act[b])


def test_batched_equals_single_float32():
    pol = _policy("sarl", dtype=torch.float32)
    robot, humans, mask = random_scene(np.random.default_rng(6), 16, 5)
    q = pol.values(obs_dict(robot, humans, mask))
    for b in range(16):
        ob = obs_dict(robot[b : b + 1], humans[b : b + 1], mask[b : b + 1])
        np.testing.assert_allclose(pol.values(ob)[0], q[b], rtol=1e-5, atol=1e-5)


@pytest.mark.parametrize("kinematics", ["holonomic", "unicycle"])
def test_values_follow_lookahead_formula(kinematics):
    pol = _policy("sarl", kinematics)
    robot, humans, mask = random_scene(np.random.default_rng(7), 2, 3)
    mask[:, 0] = True
    q = pol.values(obs_dict(robot, humans, mask, dt=0.25))
    r_t, h_t, m_t = torch.as_tensor(robot), torch.as_tensor(humans), torch.as_tensor(mask)
    acts = discrete_actions(kinematics, r_t[:, 7])
    for b in range(2):
        for a in (0, 1, 40, 80):
            nxt = propagate_robot(r_t[b : b + 1], acts[b : b + 1, a : a + 1], kinematics, 0.25)[0]  # (1, 9)
            hn = propagate_humans_constant_velocity(h_t[b : b + 1], 0.25)
            joint = rotate(nxt, hn, kinematics)
            with torch.no_grad():
                v = pol.network.value(joint, m_t[b : b + 1])
            rr = reward(nxt, hn, m_t[b : b + 1], RewardParams())
            want = rr + 0.9 ** (0.25 * robot[b, 7]) * v
            assert q[b, a] == pytest.approx(float(want), rel=1e-10, abs=1e-12)


def test_epsilon_greedy_explicit_generator():
    pol = _policy("cadrl")
    robot, humans, mask = random_scene(np.random.default_rng(8), 64, 3)
    ob = obs_dict(robot, humans, mask)
    with pytest.raises(ValueError, match="Generator"):
        pol.act(ob, epsilon=0.5)
    i1, _ = pol.act(ob, epsilon=0.5, generator=torch.Generator().manual_seed(3))
    i2, _ = pol.act(ob, epsilon=0.5, generator=torch.Generator().manual_seed(3))
    np.testing.assert_array_equal(i1, i2)
    greedy, _ = pol.act(ob)
    assert 0 < np.mean(i1 != greedy) < 0.9
    i_all, a_all = pol.act(ob, epsilon=1.0, generator=torch.Generator().manual_seed(4))
    assert len(np.unique(i_all)) > 20
    want = discrete_actions("holonomic", torch.as_tensor(robot[:, 7])).numpy()[np.arange(64), i_all]
    np.testing.assert_allclose(a_all, want)


def test_oracle_information():
    cv = _policy("sarl")
    oracle = _policy("sarl", information="oracle")
    robot, humans, mask = random_scene(np.random.default_rng(9), 4, 3)
    ob = obs_dict(robot, humans, mask)
    with pytest.raises(ValueError, match="next_humans"):
        oracle.act(ob)
    nxt = humans.copy()
    nxt[..., :2] += humans[..., 2:4] * 0.25
    np.testing.assert_allclose(oracle.values(ob, next_humans=nxt), cv.values(ob), rtol=1e-12)
    moved = nxt.copy()
    moved[..., :2] += 1.0
    assert not np.allclose(oracle.values(ob, next_humans=moved), cv.values(ob))


def test_torch_inputs_and_outputs():
    pol = _policy("sarl", dtype=torch.float32)
    robot, humans, mask = random_scene(np.random.default_rng(10), 3, 2)
    ob = {k: torch.as_tensor(v) for k, v in obs_dict(robot, humans, mask).items() if k != "dt"}
    idx, act = pol.act(ob)
    assert torch.is_tensor(idx) and idx.dtype == torch.int64 and act.shape == (3, 2)
    assert torch.is_tensor(pol.values(ob))


@pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device")
def test_cuda_matches_cpu():
    cpu = _policy("om_sarl", dtype=torch.float32)
    gpu = ValuePolicy(build("om_sarl"), device="cuda")
    gpu.network.load_state_dict(cpu.network.state_dict())
    robot, humans, mask = random_scene(np.random.default_rng(12), 8, 4)
    ob = obs_dict(robot, humans, mask)
    np.testing.assert_allclose(gpu.values(ob), cpu.values(ob), rtol=1e-4, atol=1e-5)
    i, _ = gpu.act(ob, epsilon=0.3, generator=torch.Generator().manual_seed(0))
    assert i.shape == (8,)


@pytest.mark.parametrize("name", ["sarl", "om_sarl"])
@pytest.mark.parametrize("reward_rule", ["end", "swept"])
@pytest.mark.parametrize("states_per_pass", [1, 100, 250])
def test_states_per_pass_blocks_give_identical_values(name, reward_rule, states_per_pass):
    # 9 episodes × 81 actions = 729 states in blocks of 1, 100 or 250 (the last one shorter).
    torch.manual_seed(13)
    net = build(name)
    robot, humans, mask = random_scene(np.random.default_rng(14), 9, 4, garbage=3.0)
    ob = obs_dict(robot, humans, mask)
    one = ValuePolicy(net, states_per_pass=None, reward_rule=reward_rule)
    blocked = ValuePolicy(net, states_per_pass=states_per_pass, reward_rule=reward_rule)
    np.testing.assert_allclose(blocked.values(ob), one.values(ob), rtol=1e-6, atol=1e-6)
    np.testing.assert_array_equal(blocked.act(ob)[0], one.act(ob)[0])

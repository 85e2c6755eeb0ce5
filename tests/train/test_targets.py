"""Value targets: Monte-Carlo returns (imitation) and TD targets (RL), hand-computed."""

import math

import numpy as np
import pytest
import torch

from socialnav.train.value.imitation import mc_returns
from socialnav.train.value.rl import epsilon_at, td_loss, td_targets
from socialnav.train.value.settings import RLSettings


def test_mc_returns_hand_computed():
    gamma, dt, v_pref = 0.9, 0.25, 1.0
    g = 0.9**0.25
    r = [0.0, -0.05, 0.0, 1.0]
    out = mc_returns(r, gamma, dt, v_pref)
    assert out[3] == pytest.approx(1.0)
    assert out[2] == pytest.approx(g * 1.0)
    assert out[1] == pytest.approx(-0.05 + g**2)
    assert out[0] == pytest.approx(g * -0.05 + g**3)
    # v_pref enters the exponent: γ^((t−i)·dt·v_pref)
    out2 = mc_returns([0.0, 0.0, 1.0], 0.9, 0.25, 2.0)
    assert out2[0] == pytest.approx(0.9 ** (2 * 0.25 * 2.0))
    assert mc_returns([], 0.9, 0.25, 1.0).shape == (0,)


def test_td_targets_done_mask_and_truncation():
    reward = torch.tensor([1.0, -0.25, 0.0, -0.02])
    done = torch.tensor([True, True, False, False])  # success, collision, timeout (truncated), running
    next_v = torch.tensor([5.0, 5.0, 0.5, 0.8])
    v_pref = torch.tensor([1.0, 1.0, 1.0, 1.5])
    y = td_targets(reward, done, next_v, 0.9, 0.25, v_pref)
    expected = [1.0, -0.25, 0.9**0.25 * 0.5, -0.02 + 0.9 ** (0.25 * 1.5) * 0.8]
    assert y.tolist() == pytest.approx(expected)


class _ConstNet(torch.nn.Module):
    """V(s) = w · robot px (the first joint-state value is dg; use a fixed linear map of it)."""

    def __init__(self, w):
        super().__init__()
        self.w = torch.nn.Parameter(torch.tensor(float(w)))

    def value(self, joint, mask):
        return self.w * joint[:, 0, 0]  # dg of the robot


class _Policy:
    def __init__(self, net):
        self.network = net

    def transform(self, robot, humans, mask):
        from socialnav.policies.learned.state import rotate

        return rotate(robot, humans)


def test_td_loss_uses_target_network_and_masks_terminals():
    from socialnav.train.value.memory import Transitions

    def state(dg):
        r = torch.zeros(1, 9)
        r[0, 5] = dg  # goal at (dg, 0)
        r[0, 7] = 1.0  # v_pref
        r[0, 4] = 0.3
        return r

    robot = torch.cat([state(2.0), state(2.0)])
    nxt = torch.cat([state(1.0), state(1.0)])
    humans = torch.zeros(2, 1, 5)
    mask = torch.ones(2, 1, dtype=torch.bool)
    batch = Transitions(
        robot, humans, mask, torch.tensor([0.0, 1.0]), nxt, humans, mask, torch.tensor([False, True])
    )
    online, target = _ConstNet(0.5), _ConstNet(3.0)
    loss = td_loss(_Policy(online), target, batch, 0.9, 0.25)
    v = torch.tensor([1.0, 1.0])  # 0.5 · dg(2)
    y = torch.tensor([0.9**0.25 * 3.0 * 1.0, 1.0])  # bootstrapped from the TARGET net / terminal
    assert loss.item() == pytest.approx(((v - y) ** 2).mean().item())
    loss.backward()
    assert target.w.grad is None  # targets carry no gradient
    assert online.w.grad is not None


def test_epsilon_schedule():
    rl = RLSettings()
    assert epsilon_at(0, rl) == pytest.approx(0.5)
    assert epsilon_at(2000, rl) == pytest.approx(0.3)
    assert epsilon_at(4000, rl) == pytest.approx(0.1)
    assert epsilon_at(9000, rl) == pytest.approx(0.1)
    assert math.isclose(epsilon_at(5, RLSettings(epsilon_decay_episodes=0)), 0.1)
    assert np.isfinite(epsilon_at(1, rl))


def test_rgl_repo_rule_drops_last_transitions_and_timeouts_and_fixes_targets():
    """rl.td_targets: rgl_repo stores an ended episode without its last transition, nothing of a
    timed-out one, and each stored transition with r + γ̄·V_target(s') computed when it is stored."""
    from types import SimpleNamespace

    from socialnav.train.value.memory import ReplayMemory
    from socialnav.train.value.rl import RGLRepoEpisodes

    def robot_row(dg):
        r = np.zeros(9)
        r[5], r[7], r[4] = dg, 1.0, 0.3
        return r

    humans, mask = np.zeros((2, 1, 5)), np.ones((2, 1), dtype=bool)
    target = _ConstNet(3.0)
    memory = ReplayMemory(100, 1)
    buf = RGLRepoEpisodes(2)
    dgs = [4.0, 3.0, 2.0, 1.0]  # slot 0 walks to its goal in 3 steps; slot 1 times out at step 3
    rewards = [[-0.01, 0.0], [-0.02, 0.0], [1.0, 0.0]]
    for t in range(3):
        obs = SimpleNamespace(
            robot=np.stack([robot_row(dgs[t])] * 2),
            humans=humans,
            human_mask=mask,
            active=np.array([True, True]),
        )
        last = t == 2
        res = SimpleNamespace(
            reward=np.array(rewards[t]),
            final_robot=np.stack([robot_row(dgs[t + 1])] * 2),
            final_humans=humans,
            final_mask=mask,
            terminated=np.array([last, False]),
            truncated=np.array([False, last]),
        )
        buf.add_step(obs, res)
        stored = buf.finish(memory, res, _Policy(None), target, 0.9, 0.25)
        assert stored == (2 if last else 0)
    assert len(memory) == 2  # the success transition (reward 1) and the whole timeout are dropped
    g = 0.9**0.25
    expected = [-0.01 + g * 3.0 * 3.0, -0.02 + g * 3.0 * 2.0]  # r + γ̄ · V_target(s'), V_target = 3·dg
    assert memory.target[:2].tolist() == pytest.approx(expected)
    assert memory.reward[:2].tolist() == pytest.approx([-0.01, -0.02])
    assert buf.rows == [[], []]  # both slots start their next episode empty

    # td_loss with fixed targets regresses on the stored target, whatever the target network says now
    batch = memory.take(torch.arange(2))
    online = _ConstNet(0.5)
    loss = td_loss(_Policy(online), _ConstNet(100.0), batch, 0.9, 0.25, fixed_targets=True)
    v = 0.5 * torch.tensor([4.0, 3.0])
    assert loss.item() == pytest.approx(((v - torch.tensor(expected)) ** 2).mean().item(), rel=1e-5)


def test_rgl_repo_final_rule_stores_the_same_transitions_and_recomputes_targets():
    """rl.td_targets: rgl_repo_final keeps the repository's storage rule (no last transition, no
    timed-out episode) and forms r + γ̄·V_target(s') at each gradient step with the target network of
    that moment (the repository's final trainer), so a new target network changes the loss."""
    from types import SimpleNamespace

    from socialnav.train.value.memory import ReplayMemory
    from socialnav.train.value.rl import RGLRepoEpisodes

    def robot_row(dg):
        r = np.zeros(9)
        r[5], r[7], r[4] = dg, 1.0, 0.3
        return r

    humans, mask = np.zeros((2, 1, 5)), np.ones((2, 1), dtype=bool)
    memory = ReplayMemory(100, 1)
    buf = RGLRepoEpisodes(2, fixed=False)
    dgs = [4.0, 3.0, 2.0, 1.0]
    rewards = [[-0.01, 0.0], [-0.02, 0.0], [1.0, 0.0]]
    for t in range(3):
        last = t == 2
        obs = SimpleNamespace(
            robot=np.stack([robot_row(dgs[t])] * 2),
            humans=humans,
            human_mask=mask,
            active=np.array([True, True]),
        )
        res = SimpleNamespace(
            reward=np.array(rewards[t]),
            final_robot=np.stack([robot_row(dgs[t + 1])] * 2),
            final_humans=humans,
            final_mask=mask,
            terminated=np.array([last, False]),
            truncated=np.array([False, last]),
        )
        buf.add_step(obs, res)
        # the target network passed here must not matter: nothing is computed when storing
        buf.finish(memory, res, _Policy(None), None, 0.9, 0.25)
    assert len(memory) == 2
    assert memory.reward[:2].tolist() == pytest.approx([-0.01, -0.02])
    assert not memory.done[:2].any()  # every stored transition is non-terminal
    assert torch.isnan(memory.target[:2]).all()  # no fixed target
    batch = memory.take(torch.arange(2))
    online = _ConstNet(0.5)
    v = 0.5 * torch.tensor([4.0, 3.0])
    g = 0.9**0.25
    for w in (3.0, 7.0):  # the target network of the gradient step decides the target
        y = torch.tensor([-0.01 + g * w * 3.0, -0.02 + g * w * 2.0])
        loss = td_loss(_Policy(online), _ConstNet(w), batch, 0.9, 0.25, fixed_targets=False)
        assert loss.item() == pytest.approx(((v - y) ** 2).mean().item(), rel=1e-5)

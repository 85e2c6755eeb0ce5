"""AdamSteps: fused Adam's step without its per-call Python, bit-identical to ``optimizer.step()``."""

import io

import pytest
import torch

from socialnav.policies.learned import ValuePolicy, build
from socialnav.train.optim import AdamSteps, load_optimizer_state, make_optimizer, optimizer_state
from socialnav.train.value.memory import ReplayMemory
from socialnav.train.value.rl import replay_td_loss


def _train(name: str, fast: bool, steps: int = 25, resume_at: int | None = None):
    torch.manual_seed(0)
    net, target = build(name), build(name)
    target.eval().requires_grad_(False)
    g = torch.Generator().manual_seed(2)
    k, n = 300, 4
    robot = torch.rand(k, 9, generator=g) * 8 - 4
    robot[:, 4], robot[:, 7] = 0.3, 1.0
    humans = torch.rand(k, n, 5, generator=g) * 8 - 4
    humans[..., 4] = 0.3
    mask = torch.rand(k, n, generator=g) > 0.3
    mem = ReplayMemory(k, n)
    mem.push(robot, humans, mask, torch.rand(k, generator=g), robot + 0.1, humans, mask, torch.zeros(k) > 0)
    opt = make_optimizer(net.parameters(), 1e-3, torch.device("cpu"))
    steps_of = AdamSteps(opt)
    loss_at = replay_td_loss(ValuePolicy(net), target, mem, 0.9, 0.25)
    for i in range(steps):
        if resume_at is not None and i == resume_at:  # as a resumed run: a new optimizer, loaded state
            buffer = io.BytesIO()
            torch.save(optimizer_state(opt), buffer)  # the step counters are views of one tensor here
            saved = torch.load(io.BytesIO(buffer.getvalue()), weights_only=True)
            opt = make_optimizer(net.parameters(), 1e-3, torch.device("cpu"))
            load_optimizer_state(opt, saved)
            steps_of = AdamSteps(opt)
        loss = loss_at(mem.sample_indices(50, g))
        if fast:
            steps_of.zero_grad()
            loss.backward()
            steps_of.step()
        else:
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
    return net, opt, steps_of


@pytest.mark.parametrize("name", ["sarl", "rgl"])
def test_adam_steps_are_bit_identical_to_optimizer_step(name):
    ref_net, ref_opt, _ = _train(name, fast=False)
    net, opt, steps_of = _train(name, fast=True)
    assert steps_of.fast
    for a, b in zip(ref_net.parameters(), net.parameters(), strict=True):
        assert torch.equal(a, b)
    ref_state, state = ref_opt.state_dict()["state"], opt.state_dict()["state"]
    assert ref_state.keys() == state.keys()
    for i in ref_state:
        for key in ("step", "exp_avg", "exp_avg_sq"):
            assert torch.equal(ref_state[i][key], state[i][key]), (i, key)
    assert [int(state[i]["step"]) for i in state] == [25] * len(state)
    # a resumed optimizer (state saved and loaded as a checkpoint does) stays on the same path
    resumed, _, _ = _train(name, fast=True, resume_at=10)
    for a, b in zip(ref_net.parameters(), resumed.parameters(), strict=True):
        assert torch.equal(a, b)


def test_unsupported_settings_fall_back_to_optimizer_step():
    p = torch.nn.Parameter(torch.ones(3))
    for opt in (
        torch.optim.Adam([p], lr=0.1, fused=True, weight_decay=0.01),
        torch.optim.Adam([p], lr=0.1, fused=True, amsgrad=True),
        torch.optim.Adam([p], lr=0.1, foreach=True),
        torch.optim.SGD([p], lr=0.1),
    ):
        steps_of = AdamSteps(opt)
        assert not steps_of.fast
        before = p.detach().clone()
        p.grad = torch.ones(3)
        steps_of.step()  # optimizer.step(): the parameter moves
        assert not torch.equal(before, p.detach())
        steps_of.zero_grad()
        assert p.grad is None

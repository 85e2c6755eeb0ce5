"""``compile: true``'s fused gradient step (train/fused_step.py): one compiled graph that is the TD
loss and Adam's update — checked against the eager loss and ``torch.optim.Adam(fused=True)``, against
a resume (the optimizer's state replaced), new transitions and target-network syncs; networks that do
not trace into one graph are refused with the reason."""

import copy

import pytest
import torch

from socialnav.policies.learned import ValuePolicy, build
from socialnav.train.optim import load_optimizer_state, make_optimizer, optimizer_state
from socialnav.train.value.fused_step import FusedTDStep
from socialnav.train.value.memory import ReplayMemory
from socialnav.train.value.rl import td_loss

N_HUMANS, K, BATCH = 4, 500, 100
GAMMA, DT = 0.9, 0.25


def _transitions(seed: int, k: int = K):
    g = torch.Generator().manual_seed(seed)
    robot = torch.rand(k, 9, generator=g) * 8 - 4
    robot[:, 4], robot[:, 7] = 0.3, 1.0
    humans = torch.rand(k, N_HUMANS, 5, generator=g) * 8 - 4
    humans[..., 4] = 0.3
    mask = torch.rand(k, N_HUMANS, generator=g) > 0.3  # padded humans and empty crowds included
    done = torch.rand(k, generator=g) > 0.8
    target = torch.rand(k, generator=g)  # the fixed targets of rl.td_targets: rgl_repo
    return (
        robot,
        humans,
        mask,
        torch.rand(k, generator=g) - 0.5,
        robot + 0.1,
        humans * 0.9,
        mask,
        done,
        target,
    )


def _memory(seed: int = 1) -> ReplayMemory:
    mem = ReplayMemory(K, N_HUMANS)
    *fields, target = _transitions(seed)
    mem.push(*fields, target=target)
    return mem


class _Pair:
    """The same networks twice: one trained by the fused step, one by the eager loss and Adam."""

    def __init__(self, name: str, fixed_targets: bool) -> None:
        torch.manual_seed(0)
        self.net, self.target = build(name), build(name)
        self.ref_net, self.ref_target = build(name), build(name)
        self.ref_net.load_state_dict(self.net.state_dict())
        for t in (self.target, self.ref_target):
            t.eval().requires_grad_(False)
        self.ref_target.load_state_dict(self.target.state_dict())
        self.memory = _memory()
        self.fixed = fixed_targets
        cpu = torch.device("cpu")
        self.opt = make_optimizer(self.net.parameters(), 1e-3, cpu)
        self.ref_opt = make_optimizer(self.ref_net.parameters(), 1e-3, cpu)
        self.ref_policy = ValuePolicy(self.ref_net)
        self.step, refusal = FusedTDStep.build(
            ValuePolicy(self.net), self.target, self.memory, self.opt, GAMMA, DT, BATCH, fixed_targets
        )
        assert self.step is not None, refusal

    def both(self, idx: torch.Tensor) -> tuple[float, float]:
        fused = float(self.step(idx))
        loss = td_loss(self.ref_policy, self.ref_target, self.memory.take(idx), GAMMA, DT, self.fixed)
        self.ref_opt.zero_grad()
        loss.backward()
        self.ref_opt.step()
        return fused, float(loss.detach())

    def assert_same_networks(self) -> None:
        # Adam moves each weight by about lr = 1e-3 per step whatever the gradient's size, so rounding
        # differences of near-zero gradients show as a few % of one step; a wrong update shows as more
        for a, b in zip(self.net.parameters(), self.ref_net.parameters(), strict=True):
            torch.testing.assert_close(a, b, rtol=1e-4, atol=1e-4)


@pytest.fixture(scope="module", params=[False, True], ids=["recomputed-targets", "fixed-targets"])
def pair(request):
    return _Pair("sarl", request.param)


def test_fused_step_is_the_td_loss_and_adams_update(pair):
    g = torch.Generator().manual_seed(3)
    before = [p.detach().clone() for p in pair.net.parameters()]
    target_before = [p.detach().clone() for p in pair.target.parameters()]
    for _ in range(12):
        fused, eager = pair.both(pair.memory.sample_indices(BATCH, g))
        assert fused == pytest.approx(eager, rel=1e-4, abs=1e-7)
    assert all(not torch.equal(a, b) for a, b in zip(before, pair.net.parameters(), strict=True))
    pair.assert_same_networks()
    assert all(torch.equal(a, b) for a, b in zip(target_before, pair.target.parameters(), strict=True))
    # the optimizer's own state is what the graph updated: step counters and moments as Adam's
    ours, ref = pair.opt.state_dict()["state"], pair.ref_opt.state_dict()["state"]
    assert ours.keys() == ref.keys()
    for i in ours:
        assert float(ours[i]["step"]) == float(ref[i]["step"])
        torch.testing.assert_close(ours[i]["exp_avg"], ref[i]["exp_avg"], rtol=1e-4, atol=1e-7)
        torch.testing.assert_close(ours[i]["exp_avg_sq"], ref[i]["exp_avg_sq"], rtol=1e-4, atol=1e-9)


def test_fused_step_reads_new_transitions_and_target_syncs(pair):
    g = torch.Generator().manual_seed(4)
    *fields, target = _transitions(seed=9, k=K // 2)  # overwrites half of the ring buffer
    pair.memory.push(*fields, target=target)
    pair.target.load_state_dict(pair.net.state_dict())
    pair.ref_target.load_state_dict(pair.ref_net.state_dict())
    for _ in range(4):
        fused, eager = pair.both(pair.memory.sample_indices(BATCH, g))
        assert fused == pytest.approx(eager, rel=1e-4, abs=1e-7)
    pair.assert_same_networks()


def test_fused_step_follows_a_replaced_optimizer_state(pair):
    """A resume loads the optimizer's state into new tensors: the step must use those."""
    saved_state = copy.deepcopy(optimizer_state(pair.opt))  # state_dict() holds the live tensors
    saved_net = {k: v.clone() for k, v in pair.net.state_dict().items()}
    g = torch.Generator().manual_seed(5)
    idx = [pair.memory.sample_indices(BATCH, g) for _ in range(3)]
    first = [float(pair.step(i)) for i in idx]
    after_first = [p.detach().clone() for p in pair.net.parameters()]
    pair.net.load_state_dict(saved_net)
    load_optimizer_state(pair.opt, saved_state)
    again = [float(pair.step(i)) for i in idx]
    assert again == first
    assert all(torch.equal(a, b) for a, b in zip(after_first, pair.net.parameters(), strict=True))
    assert float(pair.opt.state_dict()["state"][0]["step"]) == float(saved_state["state"]["0"]["step"]) + 3


def test_fused_step_refuses_another_minibatch_size(pair):
    with pytest.raises(ValueError, match=f"compiled for {BATCH} indices"):
        pair.step(torch.zeros(BATCH + 1, dtype=torch.long))


@pytest.mark.parametrize("name", ["cadrl", "lstm_rl"])
def test_networks_with_data_dependent_control_flow_are_refused_with_the_reason(name):
    net, target = build(name), build(name)
    target.eval().requires_grad_(False)
    opt = make_optimizer(net.parameters(), 1e-3, torch.device("cpu"))
    step, refusal = FusedTDStep.build(ValuePolicy(net), target, _memory(), opt, GAMMA, DT, BATCH)
    assert step is None
    assert refusal and ":" in refusal  # the exception's type and first line


def test_fused_step_implements_only_plain_adam():
    net, target = build("sarl"), build("sarl")
    for opt, what in (
        (torch.optim.SGD(net.parameters(), lr=0.1), "torch.optim.Adam"),
        (torch.optim.Adam(net.parameters(), lr=1e-3, weight_decay=0.1), "weight_decay"),
        (torch.optim.Adam(net.parameters(), lr=1e-3, amsgrad=True), "amsgrad"),
    ):
        with pytest.raises(ValueError, match=what):
            FusedTDStep(ValuePolicy(net), target, _memory(), opt, GAMMA, DT, BATCH)
    other = build("sarl")
    with pytest.raises(ValueError, match="exactly the policy network's parameters"):
        FusedTDStep(
            ValuePolicy(net),
            target,
            _memory(),
            make_optimizer(other.parameters(), 1e-3, "cpu"),
            GAMMA,
            DT,
            BATCH,
        )


@pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device")
def test_fused_step_on_cuda_matches_the_eager_step():
    torch.manual_seed(0)
    net, target = build("sarl").cuda(), build("sarl").cuda()
    ref_net, ref_target = build("sarl").cuda(), build("sarl").cuda()
    ref_net.load_state_dict(net.state_dict())
    ref_target.load_state_dict(target.state_dict())
    for t in (target, ref_target):
        t.eval().requires_grad_(False)
    mem = ReplayMemory(K, N_HUMANS, device="cuda")
    *fields, fixed = _transitions(1)
    mem.push(*fields, target=fixed)
    opt = make_optimizer(net.parameters(), 1e-3, torch.device("cuda"))
    ref_opt = make_optimizer(ref_net.parameters(), 1e-3, torch.device("cuda"))
    step, refusal = FusedTDStep.build(ValuePolicy(net, device="cuda"), target, mem, opt, GAMMA, DT, BATCH)
    assert step is not None, refusal
    ref_policy = ValuePolicy(ref_net, device="cuda")
    g = torch.Generator().manual_seed(3)
    for _ in range(5):
        idx = mem.sample_indices(BATCH, g)
        fused = float(step(idx))
        loss = td_loss(ref_policy, ref_target, mem.take(idx), GAMMA, DT)
        ref_opt.zero_grad()
        loss.backward()
        ref_opt.step()
        assert fused == pytest.approx(float(loss.detach()), rel=1e-4, abs=1e-7)
    for a, b in zip(net.parameters(), ref_net.parameters(), strict=True):
        torch.testing.assert_close(a, b, rtol=1e-4, atol=1e-4)


@pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device")
def test_cuda_graph_replay_is_bit_identical_to_the_compiled_step():
    """On CUDA the compiled step is recorded once as a CUDA graph; replaying it must give exactly the
    compiled step's losses, parameters and Adam state, across new transitions, a target sync and a
    replaced optimizer state (a resume records the graph again), and the recording changes nothing."""
    runs = {}
    for graphed in (True, False):
        torch.manual_seed(0)
        net, target = build("sarl").cuda(), build("sarl").cuda()
        target.eval().requires_grad_(False)
        mem = ReplayMemory(K, N_HUMANS, device="cuda")
        *fields, fixed = _transitions(1)
        mem.push(*fields, target=fixed)
        opt = make_optimizer(net.parameters(), 1e-3, torch.device("cuda"))
        initial = [p.detach().clone() for p in net.parameters()]
        step = FusedTDStep(ValuePolicy(net, device="cuda"), target, mem, opt, GAMMA, DT, BATCH,
                           cuda_graph=graphed)
        step._compile()
        assert (step._graph is not None) == graphed
        assert all(torch.equal(a, b) for a, b in zip(initial, net.parameters(), strict=True))
        g = torch.Generator().manual_seed(3)
        losses = [step(mem.sample_indices(BATCH, g)) for _ in range(10)]
        *fields, fixed = _transitions(seed=9, k=K // 2)
        mem.push(*fields, target=fixed)
        target.load_state_dict(net.state_dict())
        saved = copy.deepcopy(optimizer_state(opt))
        losses += [step(mem.sample_indices(BATCH, g)) for _ in range(5)]
        load_optimizer_state(opt, saved)  # new state tensors: the graph is recorded again
        losses += [step(mem.sample_indices(BATCH, g)) for _ in range(5)]
        runs[graphed] = (torch.stack(losses).cpu(), [p.detach().cpu() for p in net.parameters()],
                         optimizer_state(opt))
    (l1, p1, s1), (l2, p2, s2) = runs[True], runs[False]
    assert torch.equal(l1, l2)
    assert all(torch.equal(a, b) for a, b in zip(p1, p2, strict=True))
    for i in s1["state"]:
        for key in ("step", "exp_avg", "exp_avg_sq"):
            assert torch.equal(torch.as_tensor(s1["state"][i][key]).cpu(),
                               torch.as_tensor(s2["state"][i][key]).cpu())

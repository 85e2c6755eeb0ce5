"""``compile: true``: the RL loss compiled with torch.compile computes the eager loss (to rounding),
gives the same gradients, and a compiled training run is reproducible for its seed."""

import dataclasses
import os

import pytest
import torch

from socialnav.cli import build_parser
from socialnav.policies.learned import ValuePolicy, build, load_checkpoint
from socialnav.train.value.memory import ReplayMemory
from socialnav.train.value.rl import replay_td_loss
from socialnav.train.value.settings import ConfigError, TrainSettings, load_train_settings, resume_diff
from socialnav.train.value.trainer import train

from .test_trainer import TINY


def _memory(n_humans=4, k=500):
    g = torch.Generator().manual_seed(1)
    robot = torch.rand(k, 9, generator=g) * 8 - 4
    robot[:, 4], robot[:, 7] = 0.3, 1.0
    humans = torch.rand(k, n_humans, 5, generator=g) * 8 - 4
    humans[..., 4] = 0.3
    mask = torch.rand(k, n_humans, generator=g) > 0.3  # padded humans and empty crowds included
    nxt = robot + 0.1
    done = torch.rand(k, generator=g) > 0.8
    mem = ReplayMemory(k, n_humans)
    mem.push(robot, humans, mask, torch.rand(k, generator=g) - 0.5, nxt, humans, mask, done)
    return mem


@pytest.mark.parametrize("name", ["sarl", "cadrl"])
def test_compiled_loss_and_gradients_match_eager(name):
    torch.manual_seed(0)
    net, target = build(name), build(name)
    target.eval().requires_grad_(False)
    policy = ValuePolicy(net)
    mem = _memory()
    idx = torch.arange(0, 400, 4)
    eager = replay_td_loss(policy, target, mem, 0.9, 0.25)
    compiled = replay_td_loss(policy, target, mem, 0.9, 0.25, compiled=True)
    for loss_at in (eager, compiled):
        net.zero_grad(set_to_none=True)
        loss = loss_at(idx)
        loss.backward()
        grads = [p.grad.clone() for p in net.parameters()]
        if loss_at is eager:
            ref_loss, ref_grads = loss.detach(), grads
    assert loss.detach() == pytest.approx(float(ref_loss), rel=1e-5)
    for a, b in zip(grads, ref_grads, strict=True):
        torch.testing.assert_close(a, b, rtol=1e-4, atol=1e-6)
    # the target network takes no gradient, compiled or not
    assert all(p.grad is None for p in target.parameters())
    # another run's networks and memory (same shapes) reuse the graph: it must read them, not the
    # first run's parameters or transitions
    torch.manual_seed(1)
    net2, target2 = build(name), build(name)
    target2.eval().requires_grad_(False)
    mem2 = _memory()
    mem2.reward.mul_(-3.0)
    policy2 = ValuePolicy(net2)
    again = replay_td_loss(policy2, target2, mem2, 0.9, 0.25, compiled=True)(idx)
    expected = replay_td_loss(policy2, target2, mem2, 0.9, 0.25)(idx)
    assert float(again) == pytest.approx(float(expected), rel=1e-5)
    assert float(again) != pytest.approx(float(ref_loss), rel=1e-3)


def test_a_compiled_run_is_reproducible_and_recorded(tmp_path, quick_preset):
    (tmp_path / "tiny.yaml").write_text(TINY)
    settings = dataclasses.replace(load_train_settings(tmp_path / "tiny.yaml"), compile=True)
    runs = [train("sarl", quick_preset, tmp_path / f"run{i}", settings, progress=False) for i in range(2)]
    assert runs[0].gradient_steps == runs[1].gradient_steps > 0
    nets = [load_checkpoint(r.out_dir / "last.pt", "sarl").model.state_dict() for r in runs]
    assert all(torch.equal(nets[0][k], nets[1][k]) for k in nets[0])
    ck = load_checkpoint(runs[0].out_dir / "last.pt", "sarl")
    assert ck.config["train"]["compile"] is True


def test_compile_is_a_boolean_setting_that_may_change_on_resume(tmp_path):
    p = tmp_path / "c.yaml"
    p.write_text("compile: yes please\n")
    with pytest.raises((ConfigError, ValueError), match="compile"):
        load_train_settings(p)
    assert TrainSettings().compile is False
    saved = {"train": TrainSettings().to_dict()}
    now = {"train": dataclasses.replace(TrainSettings(), compile=True).to_dict()}
    assert resume_diff(saved, now) == []
    # a run directory written before the setting existed resumes as an eager run
    old = {"train": {k: v for k, v in TrainSettings().to_dict().items() if k != "compile"}}
    assert resume_diff(old, saved) == []


def test_cli_compile_flag():
    args = build_parser().parse_args(["train", "--policy", "sarl", "--compile"])
    assert args.compile is True
    assert build_parser().parse_args(["train", "--policy", "sarl"]).compile is None


def test_compiled_imitation_fit_matches_eager():
    import numpy as np

    from socialnav.train.value.imitation import Demonstrations, fit_values

    rng = np.random.default_rng(0)
    m, n = 250, 4  # 250 = 2 full minibatches of 100 and a last one of 50: two graph shapes
    robot = rng.uniform(-4, 4, (m, 9))
    robot[:, 4], robot[:, 7] = 0.3, 1.0
    humans = rng.uniform(-4, 4, (m, n, 5))
    humans[..., 4] = 0.3
    demos = Demonstrations(robot, humans, rng.random((m, n)) > 0.3, rng.random(m), 10, {})
    losses = {}
    for compiled in (False, True):
        torch.manual_seed(0)
        policy = ValuePolicy(build("sarl"))
        opt = torch.optim.Adam(policy.network.parameters(), lr=1e-3, fused=True)
        losses[compiled] = fit_values(
            policy, demos, 3, 100, torch.Generator().manual_seed(1), opt, compiled=compiled
        )
    assert len(losses[True]) == 3 and losses[True][-1] < losses[True][0]
    np.testing.assert_allclose(losses[True], losses[False], rtol=1e-4)


def test_inductor_gets_a_cache_of_its_own_per_cpu_capability(monkeypatch):
    """Kernels Inductor compiled under one vector ISA must not be reused under another (they failed with
    an index out of bounds when ATEN_CPU_CAPABILITY=avx2 ran after AVX-512). Unset, or Inductor's own
    default (which it writes there itself when it first compiles), becomes a directory per capability; a
    directory the user set is kept."""
    import tempfile

    import torch

    from socialnav.train.optim import use_inductor_cache_of_these_kernels

    capability = "_" + torch.backends.cpu.get_cpu_capability().lower()
    monkeypatch.delenv("TORCHINDUCTOR_CACHE_DIR", raising=False)
    use_inductor_cache_of_these_kernels()
    chosen = os.environ["TORCHINDUCTOR_CACHE_DIR"]
    assert chosen.endswith(capability) and chosen.startswith(tempfile.gettempdir())
    monkeypatch.setenv("TORCHINDUCTOR_CACHE_DIR", chosen[: -len(capability)])  # Inductor's default
    use_inductor_cache_of_these_kernels()
    assert os.environ["TORCHINDUCTOR_CACHE_DIR"] == chosen
    monkeypatch.setenv("TORCHINDUCTOR_CACHE_DIR", "/somewhere/else")
    use_inductor_cache_of_these_kernels()
    assert os.environ["TORCHINDUCTOR_CACHE_DIR"] == "/somewhere/else"

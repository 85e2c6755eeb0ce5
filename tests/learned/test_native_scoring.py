"""The native SARL / OM-SARL scorer: the same function as the PyTorch module, deterministic, fresh."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from socialnav import _core
from socialnav.policies.building import shipped_checkpoint
from socialnav.policies.learned import SARL, ValuePolicy, build, load_checkpoint
from socialnav.policies.learned.native_scoring import NativeSarlScorer, ScorerError, native_unavailable_reason

from .helpers import obs_dict, random_scene

# The kernels need AVX2/FMA (every x86-64 CPU since 2013-2015); elsewhere "auto" falls back to torch,
# which test_auto_falls_back_where_native_does_not_apply covers.
needs_native = pytest.mark.skipif(not _core.SarlScorer.supported(), reason="CPU without AVX2/FMA")


def _network(name: str, seed: int = 0) -> SARL:
    torch.manual_seed(seed)
    net = build(name)
    # Larger weights than the default init so that the values spread and rounding is measured
    # against values of order 1, as in a trained network.
    with torch.no_grad():
        for p in net.parameters():
            p.mul_(1.5)
    return net.eval()


def _inputs(rng: np.random.Generator, m: int, n: int, d: int, p_real: float = 0.7):
    joint = torch.from_numpy(rng.normal(0, 1.5, (m, n, d)).astype(np.float32))
    mask = torch.from_numpy(rng.random((m, n)) < p_real)
    return joint, mask


def _scored(seed: int, m: int, n: int):
    """A SARL network, inputs, its native scorer and the scorer's values of them."""
    net = _network("sarl")
    joint, mask = _inputs(np.random.default_rng(seed), m, n, 13)
    scorer = NativeSarlScorer(net)
    return net, joint, mask, scorer, scorer.value(joint, mask)


@needs_native
@pytest.mark.parametrize("name", ["sarl", "om_sarl"])
@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), m=st.integers(1, 70), n=st.integers(1, 7))
def test_values_equal_the_torch_module_to_float32_rounding(name, seed, m, n):
    net = _network(name)
    rng = np.random.default_rng(seed)
    joint, mask = _inputs(rng, m, n, net.input_dim)
    mask[0] = False  # a state without any real human: valued from the robot part alone
    with torch.inference_mode():
        ref = net.value(joint, mask)
    got = NativeSarlScorer(net).value(joint, mask)
    assert got.shape == (m,) and got.dtype == torch.float32
    np.testing.assert_allclose(got.numpy(), ref.numpy(), rtol=2e-6, atol=2e-6)


@needs_native
def test_values_equal_the_torch_module_without_the_global_state():
    """SARL without the mean embedding: the attention MLP reads e_i alone (no global term)."""
    torch.manual_seed(3)
    net = SARL(with_global_state=False).eval()
    joint, mask = _inputs(np.random.default_rng(3), 50, 4, 13)
    with torch.inference_mode():
        ref = net.value(joint, mask)
    got = NativeSarlScorer(net).value(joint, mask)
    np.testing.assert_allclose(got.numpy(), ref.numpy(), rtol=2e-6, atol=2e-6)


@needs_native
def test_padded_humans_never_leak_even_as_nan():
    net = _network("sarl")
    rng = np.random.default_rng(1)
    joint, mask = _inputs(rng, 40, 5, 13)
    mask[:, 0] = True
    dirty = joint.clone()
    dirty[~mask] = float("nan")
    scorer = NativeSarlScorer(net)
    assert torch.equal(scorer.value(dirty, mask), scorer.value(joint, mask))


@needs_native
def test_a_states_value_does_not_depend_on_batch_tile_or_threads():
    net = _network("sarl")
    rng = np.random.default_rng(2)
    joint, mask = _inputs(rng, 301, 5, 13)
    ref = NativeSarlScorer(net).value(joint, mask)
    for tile in (16, 48, 128):
        assert torch.equal(NativeSarlScorer(net, states_per_tile=tile).value(joint, mask), ref)
    previous = torch.get_num_threads()
    try:
        for threads in (1, 3):
            torch.set_num_threads(threads)
            assert torch.equal(NativeSarlScorer(net).value(joint, mask), ref)
    finally:
        torch.set_num_threads(previous)
    scorer = NativeSarlScorer(net)
    alone = torch.cat([scorer.value(joint[i : i + 7], mask[i : i + 7]) for i in range(0, 301, 7)])
    assert torch.equal(alone, ref)


@needs_native
def test_weights_changed_in_place_are_picked_up():
    net, joint, mask, scorer, before = _scored(3, 20, 4)
    with torch.no_grad():
        net.mlp3[-1].bias.add_(1.0)  # the value's output bias: every value moves by exactly 1
    after = scorer.value(joint, mask)
    np.testing.assert_allclose(after.numpy(), before.numpy() + 1.0, rtol=0, atol=1e-5)
    net.load_state_dict(_network("sarl", seed=5).state_dict())
    with torch.inference_mode():
        ref = net.value(joint, mask).numpy()
    np.testing.assert_allclose(scorer.value(joint, mask).numpy(), ref, atol=2e-6)


@needs_native
def test_shipped_sarl_chooses_the_same_actions_natively():
    """The shipped checkpoint on random scenes: same values to rounding, and the same actions."""
    net = load_checkpoint(shipped_checkpoint("sarl", "wang2022"), "sarl").model
    native = ValuePolicy(net, scorer="native")
    ref = ValuePolicy(net, scorer="torch")
    assert native.active_scorer == "native" and ref.active_scorer == "torch"
    rng = np.random.default_rng(4)
    robot, humans, mask = random_scene(rng, 64, 5)
    obs = obs_dict(robot, humans, mask)
    q_native, q_ref = native.values(obs), ref.values(obs)
    np.testing.assert_allclose(q_native, q_ref, rtol=0, atol=1e-5)
    np.testing.assert_array_equal(native.act(obs)[0], ref.act(obs)[0])


def test_auto_falls_back_where_native_does_not_apply():
    cadrl = build("cadrl")
    assert ValuePolicy(cadrl, scorer="auto").active_scorer == "torch"
    with pytest.raises(ValueError, match="scorer 'native' is not available: .*SARL and OM-SARL only"):
        ValuePolicy(cadrl, scorer="native")
    double = build("sarl").to(torch.float64)
    assert "float32" in native_unavailable_reason(double, torch.device("cpu"))
    assert ValuePolicy(double, scorer="auto").active_scorer == "torch"
    with pytest.raises(ValueError, match="unknown scorer 'fast'"):
        ValuePolicy(build("sarl"), scorer="fast")


@needs_native
def test_training_with_gradients_uses_the_module():
    """With autograd on, values come from the module (the native scorer has no gradients)."""
    net = _network("sarl").train()
    policy = ValuePolicy(net, scorer="native")
    rng = np.random.default_rng(6)
    joint, mask = _inputs(rng, 8, 3, 13)
    v = policy._network_values(joint, mask)
    assert v.requires_grad
    with torch.no_grad():
        assert not policy._network_values(joint, mask).requires_grad


@needs_native
def test_a_network_moved_to_float64_is_refused_or_falls_back():
    net = _network("sarl")
    rng = np.random.default_rng(7)
    robot, humans, mask = random_scene(rng, 3, 2)
    obs = obs_dict(robot, humans, mask)
    strict, auto = ValuePolicy(net, scorer="native"), ValuePolicy(net, scorer="auto")
    net.to(torch.float64)
    with pytest.raises(ValueError, match="float32"):
        strict.values(obs)
    np.testing.assert_array_equal(auto.values(obs), ValuePolicy(net, scorer="torch").values(obs))


@needs_native
def test_bad_buffers_are_refused_by_the_core():
    net = _network("sarl")
    scorer = NativeSarlScorer(net)
    packed = scorer._scorer()
    pool = _core.ThreadPool(1)
    joint = np.zeros((4, 2, 13), np.float32)
    with pytest.raises(ValueError, match=r"joint must be \(M, N, 13\)"):
        packed.values(np.zeros((4, 2, 12), np.float32), np.ones((4, 2), bool), np.empty(4, np.float32), pool)
    with pytest.raises(ValueError, match="mask: expected 8 elements"):
        packed.values(joint, np.ones((4, 3), bool), np.empty(4, np.float32), pool, 32)
    with pytest.raises(ValueError, match="multiple of 16"):
        packed.values(joint, np.ones((4, 2), bool), np.empty(4, np.float32), pool, 20)
    with pytest.raises(ValueError, match="N must be"):
        scorer.value(torch.zeros(3, 0, 13), torch.zeros(3, 0, dtype=torch.bool))


@needs_native
def test_a_pickled_scorer_rebuilds_its_native_state():
    """Evaluation workers receive the policy pickled."""
    import pickle

    _, joint, mask, scorer, before = _scored(8, 10, 3)
    clone = pickle.loads(pickle.dumps(scorer))
    assert torch.equal(clone.value(joint, mask), before)


def test_a_cpu_without_the_kernels_uses_the_module(monkeypatch):
    monkeypatch.setattr(_core.SarlScorer, "supported", staticmethod(lambda: False))
    net = build("sarl")
    assert "AVX2/FMA" in native_unavailable_reason(net, torch.device("cpu"))
    assert ValuePolicy(net, scorer="auto").active_scorer == "torch"
    with pytest.raises(ValueError, match="scorer 'native' is not available: .*AVX2/FMA"):
        ValuePolicy(net, scorer="native")
    # Neither a GPU nor anything else than float32 on the CPU is the native scorer's.
    assert "runs on the CPU" in native_unavailable_reason(net, torch.device("cuda"))


@needs_native
def test_an_empty_batch_gives_no_values():
    scorer = NativeSarlScorer(_network("sarl"))
    out = scorer.value(torch.zeros(0, 4, 13), torch.zeros(0, 4, dtype=torch.bool))
    assert out.shape == (0,)


def test_evaluate_refuses_a_scorer_it_cannot_use_naming_the_scorer(tmp_path, capsys):
    from socialnav.cli import main

    args = ["evaluate", "--episodes", "2", "--no-progress", "--policy-arg"]
    assert main([*args, "scorer=native", "--policy", "cadrl", "--out", str(tmp_path / "a")]) != 0
    err = capsys.readouterr().err
    assert "cadrl: scorer 'native' is not available: the native scorer evaluates SARL and OM-SARL only" in err
    assert "checkpoint" not in err  # the checkpoint is fine: the message must not blame it
    assert main([*args, "scorer=fastest", "--policy", "sarl", "--out", str(tmp_path / "b")]) != 0
    assert "unknown scorer 'fastest'; expected one of auto, torch, native" in capsys.readouterr().err
    assert not (tmp_path / "a" / "summary.json").exists()


needs_avx512 = pytest.mark.skipif(
    not _core.SarlScorer.kernel_supported("avx512"), reason="CPU without AVX-512F"
)


@needs_avx512
@pytest.mark.parametrize("name", ["sarl", "om_sarl"])
def test_the_avx512_and_avx2_kernels_give_bit_identical_values(name):
    """Same operations in the same order per output: only the width of the instructions differs.
    Tiles of 16 and 48 states make the AVX-512 kernel run its 16-column remainder panels too."""
    net = _network(name)
    joint, mask = _inputs(np.random.default_rng(5), 333, 6, net.input_dim)
    ref = NativeSarlScorer(net, kernel="avx2").value(joint, mask)
    for tile in (16, 32, 48, 128):
        wide = NativeSarlScorer(net, states_per_tile=tile, kernel="avx512")
        assert wide.kernel == "avx512"
        assert torch.equal(wide.value(joint, mask), ref)


@needs_native
def test_the_kernel_is_chosen_at_run_time_and_can_be_forced(monkeypatch):
    net = _network("sarl")
    monkeypatch.delenv("SOCIALNAV_SCORER_KERNEL", raising=False)
    widest = "avx512" if _core.SarlScorer.kernel_supported("avx512") else "avx2"
    assert NativeSarlScorer(net).kernel == widest
    assert ValuePolicy(net, scorer="auto").native_kernel == widest
    assert ValuePolicy(net, scorer="torch").native_kernel is None
    monkeypatch.setenv("SOCIALNAV_SCORER_KERNEL", "avx2")
    assert NativeSarlScorer(net).kernel == "avx2"
    assert NativeSarlScorer(net, kernel="auto").kernel == widest  # the argument wins over the variable
    monkeypatch.setenv("SOCIALNAV_SCORER_KERNEL", "sse2")
    with pytest.raises(ScorerError, match=r"\$SOCIALNAV_SCORER_KERNEL: unknown native scorer kernel 'sse2'"):
        NativeSarlScorer(net)
    monkeypatch.delenv("SOCIALNAV_SCORER_KERNEL")
    monkeypatch.setattr(_core.SarlScorer, "kernel_supported", staticmethod(lambda name: name == "avx2"))
    with pytest.raises(ScorerError, match="this CPU cannot run the native scorer's avx512 kernel"):
        NativeSarlScorer(net, kernel="avx512")


@needs_avx512
def test_the_manifest_records_the_kernel_and_another_kernel_resumes_and_replays(tmp_path, monkeypatch):
    """The kernel is recorded for information: its values are bit-identical, so a run resumed or
    replayed on a CPU that uses the other kernel reuses and reproduces the results."""
    import json

    from socialnav.cli import main

    out = tmp_path / "run"
    args = ["evaluate", "--policy", "sarl", "--scenario", "passing", "--episodes", "3", "--no-progress",
            "--out", str(out)]
    monkeypatch.setenv("SOCIALNAV_SCORER_KERNEL", "avx512")
    assert main(args) == 0
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["policy"]["scorer"] == "native" and manifest["policy"]["native_kernel"] == "avx512"
    chunks = {p: p.stat().st_mtime_ns for p in (out / "episodes").rglob("*.parquet")}
    summary = (out / "summary.json").read_text()
    monkeypatch.setenv("SOCIALNAV_SCORER_KERNEL", "avx2")
    assert main(args) == 0
    assert {p: p.stat().st_mtime_ns for p in (out / "episodes").rglob("*.parquet")} == chunks
    assert (out / "summary.json").read_text() == summary
    assert main(["replay", str(out), "--episode", "passing/invisible/1"]) == 0

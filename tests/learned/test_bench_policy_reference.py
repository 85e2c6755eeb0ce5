"""bench_policy's references: its layer chain performs exactly SARL's matmuls (no more, no fewer)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest
from torch import nn

from socialnav.policies.learned import build

BENCH = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_policy.py"


@pytest.fixture(scope="module")
def bench():
    spec = importlib.util.spec_from_file_location("bench_policy", BENCH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _linear_macs(seq: nn.Sequential) -> int:
    return sum(m.in_features * m.out_features for m in seq if isinstance(m, nn.Linear))


@pytest.mark.parametrize("humans, states", [(5, 1024), (1, 81), (10, 7)])
def test_layer_chain_multiply_adds_are_sarls(bench, humans, states):
    net = build("sarl")
    att0 = net.attention[0]
    e_dim = net.mlp1_dims[-1]
    per_human = _linear_macs(net.mlp1) + _linear_macs(net.mlp2) + _linear_macs(net.attention)
    per_human -= att0.out_features * e_dim  # attention[0]'s global half runs once per state
    per_state = att0.out_features * e_dim + _linear_macs(net.mlp3)
    expected = 2 * states * (humans * per_human + per_state)
    run, flops = bench.layer_chain(humans, states)
    assert flops == expected
    # ... and the count the fraction is computed with differs only by the attention-weighted sum.
    performed = bench.sarl_flops_per_env_step(humans)["performed"] / bench.N_ACTIONS * states
    assert performed - flops == pytest.approx(2 * states * humans * net.mlp2_dims[-1])
    run()


def test_matmul_windows_last_at_least_the_asked_time(bench):
    import time

    windows = bench.MatmulWindows(n=64)
    start = time.perf_counter()
    rate = windows.gflops(0.01)
    assert time.perf_counter() - start >= 0.01 and rate > 0

"""bench_world.py --scaling-ceiling: independent 1-thread worlds, one process per CPU (issue #32)."""

import importlib.util
import os
import sys
from pathlib import Path

from tests._env import subprocess_env

ROOT = Path(__file__).resolve().parents[2]


def _bench_world():
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        path = ROOT / "benchmarks" / "bench_world.py"
        spec = importlib.util.spec_from_file_location("bench_world_ceiling", path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    return module


def test_independent_worlds_run_one_measured_world_per_cpu(monkeypatch):
    bench = _bench_world()
    # The child processes inherit the environment: they must import the socialnav this process imported.
    monkeypatch.setenv("PYTHONPATH", subprocess_env()["PYTHONPATH"])
    rates = bench.independent_worlds([0, 0], batch=8, seconds=0.05)
    assert len(rates) == 2
    assert all(rate > 0 for rate in rates)


def test_the_ceiling_keys_compare_the_threaded_world_with_the_independent_ones(monkeypatch):
    bench = _bench_world()
    calls = []

    def fake_independent(cpus, batch, seconds):
        calls.append(list(cpus))
        return [100.0] * len(cpus)

    monkeypatch.setattr(bench, "independent_worlds", fake_independent)
    monkeypatch.setattr(bench, "usable_cpus", lambda: [0, 1, 2, 3])
    keys = bench.scaling_ceiling({1: 100.0, 4: 300.0}, batch=64, seconds=0.1)
    assert calls == [[1], [0, 1, 2, 3]]  # one alone on the second CPU, then one per CPU
    assert keys["independent_worlds"] == 4
    assert keys["independent_ceiling_4_vs_1"] == 4.0  # 4 x 100 against 100
    assert keys["fraction_of_independent_ceiling_4"] == 0.75  # 300 of 400
    # More threads than CPUs: the ceiling is taken over the CPUs there are, with no fraction to report.
    calls.clear()
    keys = bench.scaling_ceiling({1: 100.0, 16: 900.0}, batch=64, seconds=0.1)
    assert calls == [[1], [0, 1, 2, 3]] and "fraction_of_independent_ceiling_4" not in keys
    # A container that allows only some CPUs: the worlds go to those.
    calls.clear()
    monkeypatch.setattr(bench, "usable_cpus", lambda: [4, 5])
    keys = bench.scaling_ceiling({1: 100.0, 2: 150.0}, batch=64, seconds=0.1)
    assert calls == [[5], [4, 5]] and keys["fraction_of_independent_ceiling_2"] == 0.75


def test_usable_cpus_are_the_ones_this_process_may_run_on():
    bench = _bench_world()
    cpus = bench.usable_cpus()
    assert cpus and cpus == sorted(set(cpus))
    if hasattr(os, "sched_getaffinity"):
        assert set(cpus) == os.sched_getaffinity(0)

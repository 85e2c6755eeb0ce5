"""Simulating chunks in worker processes gives bit-identical per-episode results."""

import dataclasses

import pytest

torch = pytest.importorskip("torch")

from socialnav.evaluate.runner import run_protocol  # noqa: E402
from socialnav.policies.building import build_policy  # noqa: E402
from socialnav.presets import load_preset  # noqa: E402


def small(chunk_size):
    preset = load_preset("wang2022")
    evaluation = dataclasses.replace(preset.evaluation, chunk_size=chunk_size)
    return dataclasses.replace(preset, evaluation=evaluation)


@pytest.fixture
def one_thread():
    # Thread count does not change results; one thread keeps the in-process run fast on a busy machine.
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


def test_worker_simulation_is_bit_identical_to_in_process(tmp_path, one_thread):
    preset = small(4)  # several chunks per cell, so the workers really share the run
    policy = build_policy("sarl", preset)
    kwargs = dict(scenarios=["random", "passing"], episodes=8, progress=False)
    serial = run_protocol(policy, preset, tmp_path / "serial", workers=0, **kwargs)
    parallel = run_protocol(
        policy, preset, tmp_path / "parallel", workers=2, simulate_in_workers=True, **kwargs
    )
    assert parallel.computed_episodes == serial.computed_episodes == 8 * 2 + 8

    def key(r):
        return (r["scenario"], r["visibility"], r["index"])

    a = sorted(serial.rows, key=key)
    b = sorted(parallel.rows, key=key)
    assert [key(r) for r in a] == [key(r) for r in b]
    assert {r["outcome"] for r in a} & {"success"}
    for ra, rb in zip(a, b, strict=True):
        assert ra.keys() == rb.keys()
        for k in ra:  # exact equality; NaN matches NaN
            assert ra[k] == rb[k] or (ra[k] != ra[k] and rb[k] != rb[k]), (key(ra), k, ra[k], rb[k])


def test_unpicklable_policy_refused_when_worker_simulation_is_required(tmp_path):
    preset = small(2)
    with pytest.raises(ValueError, match="cannot be simulated in workers"):
        run_protocol(build_policy("orca", preset), preset, tmp_path, scenarios=["passing"], episodes=4,
                     progress=False, workers=2, simulate_in_workers=True)

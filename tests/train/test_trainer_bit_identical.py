"""Fixed-seed trainings write what the trainer wrote before its rewrite as phases.

tests/data/train_bit_identical.json holds, per tiny run, the digests of its files and a numeric
summary of them (tests/train/bit_identical_runs.py says how both are made). Each run is trained once
here and checked twice:

- bit for bit against the digests, on the CPU and kernels that recorded them only: another CPU's
  PyTorch kernels (MKL and ATen dispatch by vendor and ISA) round float sums differently, so there the
  test skips and says which environment it would need;
- within ``TOLERANCE`` against the summaries, everywhere: counters, random-generator states, outcomes
  and shapes exactly, float tensors and curves to rounding. Any change of the random draws' order, of a
  schedule counter, of a loss or of a saved record still fails it.

The interrupted runs are compared bit for bit with the uninterrupted run trained in the same session,
which holds on any machine.
"""

import json
from pathlib import Path

import pytest

from tests.train.bit_identical_runs import (
    DIGESTS,
    PPO_POLICIES,
    TOLERANCE,
    VALUE_POLICIES,
    compare_summaries,
    environment,
    run_digests,
    run_summary,
    train_ppo_tiny,
    train_value,
)

REFERENCE = json.loads(DIGESTS.read_text())
RECORDED_HERE = environment() == REFERENCE["environment"]
NOT_HERE = (
    f"digests hold only where they were recorded: {REFERENCE['environment']}; this is {environment()} "
    "(the summaries are compared within a tolerance instead)"
)


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """Each reference run, trained once for the module: policy → run directory."""
    base = tmp_path_factory.mktemp("reference_runs")
    runs: dict[str, Path] = {}

    def run(policy: str) -> Path:
        if policy not in runs:
            out = base / policy
            (train_value if policy in VALUE_POLICIES else train_ppo_tiny)(policy, out)
            runs[policy] = out
        return runs[policy]

    return run


@pytest.mark.skipif(not RECORDED_HERE, reason=NOT_HERE)
@pytest.mark.parametrize("policy", VALUE_POLICIES + PPO_POLICIES)
def test_training_is_bit_identical_on_the_recording_machine(trained, policy):
    assert run_digests(trained(policy)) == REFERENCE["runs"][policy]


@pytest.mark.parametrize("policy", VALUE_POLICIES + PPO_POLICIES)
def test_training_matches_the_reference_within_rounding_on_any_machine(trained, policy):
    problems = compare_summaries(REFERENCE["summaries"][policy], run_summary(trained(policy)))
    assert not problems, f"{policy} trains differently:\n" + "\n".join(problems[:20])


def test_the_tolerant_comparison_catches_a_changed_training(trained):
    """A summary that moved by ten times the tolerance, or whose counter moved by one, is caught."""
    summary = run_summary(trained("sarl"))
    moved = json.loads(json.dumps(summary))
    key = next(k for k, v in moved.items() if k != "curves.csv" and v[0] == "float" and v[1] > 1 and v[3] > 0)
    moved[key][3] *= 1 + 10 * TOLERANCE
    assert any(key in p for p in compare_summaries(summary, moved))
    counted = json.loads(json.dumps(summary))
    counter = next(
        k for k, v in counted.items() if k != "curves.csv" and v[0] == "exact" and type(v[1]) is int
    )
    counted[counter][1] += 1
    assert any(counter in p for p in compare_summaries(summary, counted))
    assert compare_summaries(summary, json.loads(json.dumps(summary))) == []


def test_interrupted_ppo_run_ends_as_the_uninterrupted_one(trained, tmp_path):
    """Stopped after update 2 (its checkpoint is written there) and resumed: the same files, bit for
    bit, as the uninterrupted run of this machine."""
    out = tmp_path / "crowdnav_pp"
    train_ppo_tiny("crowdnav_pp", out, stop_after=2)
    train_ppo_tiny("crowdnav_pp", out)
    assert run_digests(out) == run_digests(trained("crowdnav_pp"))


def test_interrupted_imitation_ends_as_the_uninterrupted_one(trained, tmp_path, monkeypatch):
    """Killed after the first of two imitation epochs and resumed: the same il.pt as the uninterrupted
    run of this machine (the RL phase's replay memory is not saved, so only the imitation's result is
    compared after a restart)."""
    import socialnav.train.value.imitation as imitation

    uninterrupted = run_digests(trained("sarl"))["il.pt"]
    real = imitation.fit_values

    class Killed(BaseException):
        pass

    def one_epoch_then_kill(policy, demos, epochs, batch_size, generator, optimizer, on_epoch, done, **kw):
        def on_epoch_then_kill(epoch, loss):
            on_epoch(epoch, loss)
            raise Killed

        real(policy, demos, epochs, batch_size, generator, optimizer, on_epoch_then_kill, done, **kw)

    out = tmp_path / "sarl"
    monkeypatch.setattr(imitation, "fit_values", one_epoch_then_kill)
    with pytest.raises(Killed):
        train_value("sarl", out)
    monkeypatch.setattr(imitation, "fit_values", real)
    assert (out / "il_state.pt").exists() and not (out / "il.pt").exists()
    train_value("sarl", out)
    assert run_digests(out)["il.pt"] == uninterrupted

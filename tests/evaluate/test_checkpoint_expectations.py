"""Every shipped checkpoint still behaves as recorded in checkpoint_expectations.json.

A change of the simulator, the policies, the metrics or a checkpoint that alters what a shipped
policy does fails here. If the change is deliberate, regenerate the file with
``python tools/update_checkpoint_expectations.py`` and commit it with the change.
"""

import json
from pathlib import Path

import pytest

pytest.importorskip("torch")

from socialnav._io import file_sha256  # noqa: E402
from socialnav.evaluate.expectations import EPISODES, METRICS, compare, fingerprint  # noqa: E402
from socialnav.policies.building import shipped_checkpoints  # noqa: E402

PATH = Path(__file__).with_name("checkpoint_expectations.json")
EXPECTED = json.loads(PATH.read_text())
HOW = "rerun `python tools/update_checkpoint_expectations.py` if the change is deliberate"
SHIPPED = shipped_checkpoints()


def test_expectations_were_made_with_the_current_settings():
    assert EXPECTED["episodes_per_scenario"] == EPISODES
    assert EXPECTED["metrics"] == list(METRICS)


def test_every_shipped_checkpoint_has_expectations_and_no_stale_ones():
    shipped = {e.file for e in SHIPPED}
    missing = sorted(shipped - set(EXPECTED["checkpoints"]))
    stale = sorted(set(EXPECTED["checkpoints"]) - shipped)
    assert not missing, f"shipped checkpoints without expectations: {missing}; {HOW}"
    assert not stale, f"expectations of checkpoints that no longer ship: {stale}; {HOW}"


@pytest.mark.parametrize("entry", SHIPPED, ids=[e.file for e in SHIPPED])
def test_shipped_checkpoint_behaves_as_recorded(entry):
    expected = EXPECTED["checkpoints"].get(entry.file)
    assert expected is not None, f"{entry.file} has no expectations; {HOW}"
    assert file_sha256(entry.path) == expected["sha256"], f"{entry.file} was replaced; {HOW}"
    actual = fingerprint(entry)
    assert len(actual) >= 4
    problems = compare(expected["episodes"], actual)
    assert not problems, f"{entry.file} behaves differently ({HOW}):\n" + "\n".join(problems[:20])


def test_compare_reports_outcome_steps_and_metric_changes():
    base = {"scenario": "random", "index": 3, "outcome": "success", "steps": 40,
            **{k: 1.0 for k in METRICS}}
    assert compare([base], [dict(base)]) == []
    assert compare([base], [{**base, "path_length": 1.0 + 1e-9}]) == []  # within tolerance
    # another CPU's rounding (an Intel Xeon against the recording AMD EPYC) is within tolerance
    jerk = "m4_jerk.mean_sq"
    assert compare([{**base, jerk: 37.297486}], [{**base, jerk: 37.297584}]) == []
    problems = compare([base], [{**base, "outcome": "collision", "steps": 39, "path_length": 1.001}])
    assert len(problems) == 3
    assert any("outcome" in p for p in problems) and any("path_length" in p for p in problems)
    assert compare([base], [{**base, "index": 4}])[0].startswith("episodes differ")
    assert compare([base], [{**base, "m4_jerk.mean_sq": None}])  # NaN where a value was expected

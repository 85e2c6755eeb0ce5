"""The checkpoints shipped with the package load with weights_only and navigate well."""

import json

import pytest

pytest.importorskip("torch")

from socialnav.cli import main  # noqa: E402
from socialnav.policies.building import list_shipped_checkpoints, shipped_checkpoint  # noqa: E402


def test_sarl_crowdnav_ships_and_is_used_without_a_path(tmp_path, capsys):
    assert "sarl_crowdnav" in list_shipped_checkpoints()
    assert shipped_checkpoint("sarl", "crowdnav").is_file()
    code = main(["evaluate", "--policy", "sarl", "--preset", "crowdnav", "--episodes", "40", "--out",
                 str(tmp_path), "--json", "--no-progress"])
    row = json.loads(capsys.readouterr().out)["rows"][0]
    assert code == 0
    assert row["information"] == "constant_velocity"
    assert row["success_rate"] >= 0.9  # 0.996 over the 500 test episodes


def test_shipped_checkpoint_of_another_policy_is_refused():
    from socialnav.policies.learned import load_checkpoint
    from socialnav.policies.learned.checkpoint import CheckpointError

    with pytest.raises(CheckpointError, match="holds policy 'sarl'.*expected 'cadrl'"):
        load_checkpoint(shipped_checkpoint("sarl", "crowdnav"), "cadrl")

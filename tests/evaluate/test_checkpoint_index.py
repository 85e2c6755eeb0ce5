"""The checkpoint index (socialnav/checkpoints/index.yaml) and the lookup of shipped checkpoints."""

import shutil

import pytest

import socialnav.policies.building as building
from socialnav.evaluate.multi import default_specs
from socialnav.policies.building import (
    checkpoint_dir,
    read_checkpoint_index,
    shipped_checkpoint,
    shipped_checkpoints,
    unindexed_checkpoint_files,
)
from socialnav.settings import ConfigError


def test_index_and_directory_agree():
    assert unindexed_checkpoint_files() == [], "add an entry to socialnav/checkpoints/index.yaml"
    for entry in read_checkpoint_index():
        assert entry.exists or entry.pending, f"{entry.file} is indexed but missing (mark it pending: true)"
        assert entry.file.endswith(".pt")
    assert {e.file for e in shipped_checkpoints()} >= {"sarl_wang2022.pt", "sarl_crowdnav.pt"}


@pytest.fixture
def fake_dir(tmp_path, monkeypatch):
    shutil.copy(checkpoint_dir() / "index.yaml", tmp_path / "index.yaml")
    monkeypatch.setattr(building, "checkpoint_dir", lambda: tmp_path)
    return tmp_path


def test_cadrl_circle_file_is_cadrl_original_for_wang2022(fake_dir):
    assert shipped_checkpoint("cadrl", "wang2022", "original") is None  # pending: not shipped yet
    (fake_dir / "cadrl_circle_wang2022.pt").write_bytes(b"x")
    (fake_dir / "cadrl_wang2022.pt").write_bytes(b"x")  # indexed
    (fake_dir / "lstm_rl_crowdnav.pt").write_bytes(b"x")  # not indexed: recognised by its name
    entries = {e.file: e for e in shipped_checkpoints("wang2022") + shipped_checkpoints("crowdnav")}
    original = entries["cadrl_circle_wang2022.pt"]
    assert (original.policy, original.preset, original.variant) == ("cadrl", "wang2022", "original")
    assert (original.name, original.label) == ("cadrl_original", "CADRL (original)")
    assert original.paper_row == "CADRL"
    retrained = entries["cadrl_wang2022.pt"]
    assert (retrained.policy, retrained.variant, retrained.name, retrained.paper_row) == (
        "cadrl", "protocol", "cadrl", "CADRL")
    # The default checkpoint of a policy is the protocol one, never the original-training one.
    assert shipped_checkpoint("cadrl", "wang2022") == fake_dir / "cadrl_wang2022.pt"
    assert shipped_checkpoint("cadrl", "wang2022", "original") == fake_dir / "cadrl_circle_wang2022.pt"
    assert shipped_checkpoint("cadrl", "crowdnav") is None
    unindexed = entries["lstm_rl_crowdnav.pt"]
    assert (unindexed.policy, unindexed.preset, unindexed.variant) == ("lstm_rl", "crowdnav", "protocol")
    assert unindexed_checkpoint_files() == ["lstm_rl_crowdnav.pt"]
    specs = [s.name for s in default_specs("wang2022")]
    assert specs[-3:] == ["linear", "orca", "social_force"]
    assert {"cadrl_original", "cadrl"} <= set(specs)


def test_lstm_rl_name_is_not_mistaken_for_another_policy(fake_dir):
    # crowdnav: no index entry for these, so policy and paper row come from the file name alone
    (fake_dir / "lstm_rl_crowdnav.pt").write_bytes(b"x")
    (fake_dir / "om_sarl_crowdnav.pt").write_bytes(b"x")
    (fake_dir / "mp_rgl_crowdnav.pt").write_bytes(b"x")
    entries = {e.file: e for e in shipped_checkpoints("crowdnav")}
    assert entries["lstm_rl_crowdnav.pt"].policy == "lstm_rl"
    assert entries["om_sarl_crowdnav.pt"].policy == "om_sarl"
    assert entries["mp_rgl_crowdnav.pt"].policy == "mp_rgl"
    assert entries["om_sarl_crowdnav.pt"].paper_row == "OM-SARL"
    assert entries["mp_rgl_crowdnav.pt"].paper_row is None
    assert entries["lstm_rl_crowdnav.pt"].paper_row == "GA3C-CADRL"


@pytest.mark.parametrize(
    "text, message",
    [
        ("checkpoints:\n  - {file: a.pt, policy: sarl}\n", "missing field"),
        ("checkpoints:\n  - {file: a.pt, policy: sarl, preset: x, name: s, label: S, colour: red}\n",
         "unknown field"),
        ("checkpoints:\n  - {file: a.pt, policy: sarl, preset: x, name: s, label: S, variant: new}\n",
         "variant 'new'"),
        ("checkpoints:\n  - {file: a.pt, policy: sarl, preset: x, name: s, label: S}\n"
         "  - {file: b.pt, policy: sarl, preset: x, name: s, label: S}\n", "used twice"),
        ("checkpoints: [\n", "not valid YAML"),
    ],
)
def test_bad_index_is_a_clear_error(fake_dir, text, message):
    (fake_dir / "index.yaml").write_text(text)
    with pytest.raises(ConfigError, match=message):
        read_checkpoint_index()

"""Checkpoints: round trip, refusal messages naming both policies, weights_only loading, atomicity."""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np
import pytest
import torch

import socialnav
from socialnav.policies.learned import LEARNED_POLICIES, RewardParams, ValuePolicy, build
from socialnav.policies.learned.checkpoint import CheckpointError, load_checkpoint, save_checkpoint

from .helpers import NETWORKS, obs_dict, random_scene


def test_registry_names():
    assert {"cadrl", "lstm_rl", "ga3c_cadrl", "sarl", "om_sarl"} <= set(LEARNED_POLICIES)
    with pytest.raises(KeyError, match="known"):
        build("nope")


@pytest.mark.parametrize("name", NETWORKS)
def test_round_trip(tmp_path, name):
    torch.manual_seed(0)
    net = build(name)
    cfg = {"gamma": 0.9, "reward": RewardParams(), "dims": (1, 2), "path": tmp_path}
    path = save_checkpoint(
        tmp_path / f"{name}.pt", name, net, cfg, {"episode": 7, "val_success": np.float64(0.5)}
    )
    ck = load_checkpoint(path, name)
    assert ck.policy == name and ck.input_dim == net.input_dim
    assert ck.config["reward"]["collision_penalty"] == -0.25 and ck.config["dims"] == [1, 2]
    assert ck.extra == {"episode": 7, "val_success": 0.5}
    robot, humans, mask = random_scene(np.random.default_rng(0), 3, 4)
    ob = obs_dict(robot, humans, mask)
    np.testing.assert_array_equal(ValuePolicy(net).values(ob), ValuePolicy(ck.model).values(ob))
    assert not ck.model.training
    # the file is readable by plain torch.load with weights_only=True
    payload = torch.load(path, weights_only=True)
    assert payload["policy"] == name and "state_dict" in payload
    assert [p for p in os.listdir(tmp_path) if p.endswith(".tmp")] == []
    assert payload["socialnav_version"] == socialnav.__version__ == ck.socialnav_version


def test_a_checkpoint_from_before_versions_were_recorded_loads(tmp_path):
    path = save_checkpoint(tmp_path / "old.pt", "sarl", build("sarl"), {}, {})
    payload = torch.load(path, weights_only=True)
    del payload["socialnav_version"]
    torch.save(payload, path)
    assert load_checkpoint(path, "sarl").socialnav_version is None


def test_alias_ga3c_cadrl(tmp_path):
    path = save_checkpoint(tmp_path / "g.pt", "ga3c_cadrl", build("ga3c_cadrl"), {}, {})
    assert load_checkpoint(path, "lstm_rl").policy == "lstm_rl"
    assert load_checkpoint(path, "ga3c_cadrl").policy == "lstm_rl"


def test_refuses_other_policy_naming_both(tmp_path):
    path = save_checkpoint(tmp_path / "x.pt", "cadrl", build("cadrl"), {}, {})
    with pytest.raises(CheckpointError) as err:
        load_checkpoint(path, "sarl")
    assert str(err.value) == (f"checkpoint {path} holds policy 'cadrl', expected 'sarl' (load it as 'cadrl', "
                              "e.g. --policy cadrl)")
    path = save_checkpoint(tmp_path / "om.pt", "om_sarl", build("om_sarl"), {}, {})
    with pytest.raises(
        CheckpointError, match=r"holds policy 'om_sarl', expected 'sarl' \(load it as 'om_sarl'"
    ):
        load_checkpoint(path, "sarl")


def test_refuses_other_input_size_naming_both(tmp_path):
    path = save_checkpoint(tmp_path / "s.pt", "sarl", build("sarl", input_dim=14), {}, {})
    with pytest.raises(
        CheckpointError, match=r"holds policy 'sarl' with input size 14 per human, expected 13"
    ):
        load_checkpoint(path, "sarl")
    assert load_checkpoint(path, "sarl", expected_input_dim=14).input_dim == 14


@dataclass
class _Evil:
    x: int = 1

    def __reduce__(self):  # would run code under a full unpickler
        return (os.getcwd, ())


def test_weights_only_refuses_arbitrary_objects(tmp_path):
    path = tmp_path / "evil.pt"
    torch.save({"format": "socialnav.learned/1", "policy": "sarl", "input_dim": 13, "obj": _Evil()}, path)
    with pytest.raises(CheckpointError) as err:
        load_checkpoint(path, "sarl")
    message = str(err.value)
    # one line naming the refused object, and never torch's advice to load it with weights_only=False
    assert "refused: it holds the object" in message and "getcwd" in message
    assert "\n" not in message and "weights_only=False" not in message and "\x1b" not in message


def test_refuses_non_plain_config(tmp_path):
    with pytest.raises(TypeError, match="config.bad"):
        save_checkpoint(tmp_path / "c.pt", "sarl", build("sarl"), {"bad": object()}, {})
    assert not (tmp_path / "c.pt").exists()


def test_not_a_checkpoint(tmp_path):
    path = tmp_path / "other.pt"
    torch.save({"hello": torch.zeros(1)}, path)
    with pytest.raises(CheckpointError, match="learned-policy checkpoint: it records no format"):
        load_checkpoint(path, "sarl")
    torch.save({"format": "socialnav.learned/9", "policy": "sarl"}, path)  # the found format is named
    with pytest.raises(CheckpointError, match=r"its format is 'socialnav.learned/9', expected format "
                       r"'socialnav.learned/1'"):
        load_checkpoint(path, "sarl")


def test_a_network_with_non_finite_weights_is_refused_naming_the_tensor(tmp_path, capsys):
    """A diverged run's weights (NaN) would score every action NaN: refused at load, also by the CLI."""
    net = build("sarl")
    with torch.no_grad():
        first = next(iter(net.state_dict()))
        net.state_dict()[first].view(-1)[:3] = float("nan")
    path = save_checkpoint(tmp_path / "nan.pt", "sarl", net, {}, {})
    with pytest.raises(CheckpointError, match=rf"state_dict\['{first}'\] holds 3 non-finite value\(s\)"):
        load_checkpoint(path, "sarl")
    from socialnav.cli import main

    out = tmp_path / "run"
    code = main(["evaluate", "--policy", "sarl", "--checkpoint", str(path), "--episodes", "2",
                 "--no-progress", "--out", str(out)])
    assert code != 0
    assert "non-finite" in capsys.readouterr().err
    assert not (out / "summary.json").exists()


def test_a_stable_baselines3_model_given_as_a_checkpoint_points_to_sb3(tmp_path):
    import zipfile

    path = tmp_path / "ppo.zip"
    with zipfile.ZipFile(path, "w") as archive:  # the layout of SB3's model.save: a "data" member and more
        archive.writestr("data", "{}")
        archive.writestr("policy.pth", b"\0")
    with pytest.raises(CheckpointError, match=r"a Stable-Baselines3 model: evaluate it with --policy sb3:"):
        load_checkpoint(path, "sarl")
    other = tmp_path / "other.zip"
    with zipfile.ZipFile(other, "w") as archive:
        archive.writestr("weights.bin", b"\0")
    with pytest.raises(CheckpointError) as err:
        load_checkpoint(other, "sarl")
    assert "damaged or not a torch file" in str(err.value) and "sb3" not in str(err.value)


def test_a_truncated_checkpoint_is_called_damaged(tmp_path):
    from socialnav.policies.building import shipped_checkpoint

    whole = shipped_checkpoint("sarl", "wang2022").read_bytes()
    path = tmp_path / "cut.pt"
    path.write_bytes(whole[: len(whole) // 2])
    with pytest.raises(CheckpointError, match=r"cut.pt is damaged"):
        load_checkpoint(path, "sarl")

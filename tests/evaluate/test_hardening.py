"""The runner refuses what would give silently wrong numbers, and leaves nothing half-written."""

from __future__ import annotations

import dataclasses
import json
import os
import shutil

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from socialnav._io import (
    CorruptFileError,
    DirectoryLock,
    DirectoryLockedError,
    atomic_write_rows_parquet,
    read_parquet_verified,
)
from socialnav.cli import main
from socialnav.evaluate.manifest import describe_differences
from socialnav.evaluate.runner import ResumeMismatchError, run_protocol
from socialnav.policies import make_policy
from socialnav.presets import load_preset
from socialnav.settings import ConfigError
from socialnav.sim.settings import MAX_STEPS, MAX_THREADS, WorldSettings

KW = dict(scenarios=["circle_crossing"], episodes=3, progress=False, workers=0)


def test_corrupted_parquet_page_is_refused_though_it_still_decodes(tmp_path):
    path = tmp_path / "rows.parquet"
    table = pa.table({"path_length": np.full(64, 8.29)})
    pq.write_table(table, path, compression="none", write_page_checksum=True)
    data = bytearray(path.read_bytes())
    at = bytes(data).index(np.float64(8.29).tobytes())  # first value of the (uncompressed) data page
    data[at : at + 8] = np.float64(88.96).tobytes()
    path.write_bytes(bytes(data))
    # Without verification the damage goes unnoticed: a wrong number, no error.
    assert pq.read_table(path).column("path_length")[0].as_py() == 88.96
    with pytest.raises(CorruptFileError, match="rows.parquet: damaged"):
        read_parquet_verified(path)


def test_result_files_are_written_with_page_checksums(tmp_path):
    atomic_write_rows_parquet(tmp_path / "a.parquet", [{"x": 1.0}], {"k": "v"})
    meta = pq.ParquetFile(tmp_path / "a.parquet")
    assert meta.schema_arrow.metadata[b"k"] == b"v"
    data = bytearray((tmp_path / "a.parquet").read_bytes())
    at = bytes(data).index(np.float64(1.0).tobytes())
    data[at + 7] ^= 0x01
    (tmp_path / "a.parquet").write_bytes(bytes(data))
    with pytest.raises(CorruptFileError):
        read_parquet_verified(tmp_path / "a.parquet")


def test_locked_directory_is_refused_and_lock_dies_with_holder(tmp_path):
    preset = load_preset("crowdnav")
    with DirectoryLock(tmp_path, "evaluation"):
        with pytest.raises(
            DirectoryLockedError, match=f"in use by another evaluation \\(pid {os.getpid()}\\)"
        ):
            run_protocol(make_policy("orca"), preset, tmp_path, **KW)
    assert not (tmp_path / "manifest.json").exists()
    run_protocol(make_policy("orca"), preset, tmp_path, **KW)  # released: runs


def test_several_policies_and_reproduce_lock_their_own_directory(tmp_path):
    from socialnav.evaluate.multi import PolicySpec, run_policies
    from socialnav.evaluate.reproduce import run_reproduction

    specs = [PolicySpec("orca", "orca", "ORCA")]
    with DirectoryLock(tmp_path, "evaluation of several policies"):
        with pytest.raises(DirectoryLockedError, match="in use by another evaluation of several policies"):
            run_policies(specs, load_preset("crowdnav"), tmp_path, scenarios=["passing"], episodes=1,
                         progress=False)
        with pytest.raises(DirectoryLockedError, match="in use by another reproduction"):
            run_reproduction(tmp_path, specs=specs, episodes=1, progress=False)
    assert not (tmp_path / "policies").exists()  # refused before any policy ran
    run_policies(specs, load_preset("crowdnav"), tmp_path, scenarios=["passing"], episodes=1,
                 progress=False)  # released: runs
    assert (tmp_path / "policies" / "orca" / "manifest.json").exists()


def test_chunk_of_another_configuration_is_refused(tmp_path):
    preset = load_preset("crowdnav")
    run_protocol(make_policy("orca", safety_space=0.0), preset, tmp_path / "a", **KW)
    run_protocol(make_policy("orca", safety_space=0.3), preset, tmp_path / "b", **KW)
    chunk = "episodes/circle_crossing__invisible/00000-00003.parquet"
    shutil.copy(tmp_path / "b" / chunk, tmp_path / "a" / chunk)
    with pytest.raises(ResumeMismatchError, match="00000-00003.parquet does not belong to this run"):
        run_protocol(make_policy("orca", safety_space=0.0), preset, tmp_path / "a", **KW)


def test_invalid_settings_write_nothing_and_an_empty_manifest_blocks_nothing(tmp_path):
    preset = load_preset("crowdnav")
    evaluation = dataclasses.replace(preset.evaluation, split="train")
    train_split = dataclasses.replace(preset, evaluation=evaluation)
    with pytest.raises(ValueError, match="GiB"):  # the train split has episodes enough for the bound
        run_protocol(
            make_policy("orca"), train_split, tmp_path / "o", batch_size=10**8, **{**KW, "episodes": 10**6}
        )
    with pytest.raises(ValueError, match="more than the 1000 of the 'test' split"):
        run_protocol(make_policy("orca"), preset, tmp_path / "o", **{**KW, "episodes": 1001})
    assert not (tmp_path / "o").exists()
    # A directory with a manifest and no result (a run refused or killed at once) takes the new run.
    (tmp_path / "p").mkdir()
    (tmp_path / "p" / "manifest.json").write_text(json.dumps({"preset": "something else"}))
    result = run_protocol(make_policy("orca"), preset, tmp_path / "p", **KW)
    assert result.computed_episodes == 3


def test_manifest_differences_name_the_cell_and_the_values():
    old = {"cells": [{"scenario": "random", "visibility": "visible", "episodes": 10}], "chunk_size": 5}
    new = {
        "cells": [
            {"scenario": "random", "visibility": "visible", "episodes": 20},
            {"scenario": "random", "visibility": "invisible", "episodes": 20},
        ],
        "chunk_size": 5,
    }
    assert describe_differences(old, new) == (
        "cells[random/visible].episodes: 10 -> 20; cells: random/invisible only in this run"
    )


def test_world_bounds_are_checked_before_allocation():
    with pytest.raises(ConfigError, match="threads"):
        WorldSettings(threads=MAX_THREADS + 1)
    with pytest.raises(ConfigError, match=f"more than the {MAX_STEPS} allowed"):
        WorldSettings(dt=0.001, time_limit=1000.0)
    WorldSettings(dt=0.001, time_limit=MAX_STEPS * 0.001 - 0.01)  # just inside
    with pytest.raises(ConfigError, match="continuation_cap"):
        WorldSettings(dt=0.01, continue_after_success=True, continuation_cap=1e4)


def test_worlds_share_one_native_pool_and_close_releases_the_world_at_once():
    """Worlds and native policies of one thread count run on the process's pool: making and closing
    many worlds starts no threads beyond that pool's, and a closed world refuses to step."""
    import gc

    from socialnav.scenarios import make_scenario
    from socialnav.sim.world import World

    def threads() -> int:
        return len(os.listdir("/proc/self/task"))

    gc.disable()  # the point: no reliance on the cycle collector
    try:
        before = threads()
        with World(WorldSettings(threads=16), make_scenario("circle_crossing", n_humans=2), 2, count=2) as w:
            w.reset()
            with_one_pool = threads()
            assert with_one_pool <= before + 15  # 15 workers + the caller, at most (the pool may exist)
        for _ in range(10):
            scenario = make_scenario("circle_crossing", n_humans=2)
            with World(WorldSettings(threads=16), scenario, 2, count=2) as x:
                x.reset()
        assert threads() == with_one_pool
        with pytest.raises(RuntimeError, match="closed"):
            w.step(np.zeros((2, 2)))
    finally:
        gc.enable()


def test_checkpoint_under_mismatching_preset_is_refused_naming_both_values(tmp_path, capsys):
    pytest.importorskip("torch")
    preset = tmp_path / "fast.yaml"
    preset.write_text("name: fast\nworld: {dt: 0.1}\nrobot: {v_pref: 1.5}\n")
    from socialnav.policies.building import shipped_checkpoint

    ckpt = str(shipped_checkpoint("sarl", "wang2022"))
    argv = [
        "evaluate",
        "--policy",
        "sarl",
        "--checkpoint",
        ckpt,
        "--preset",
        str(preset),
        "--scenario",
        "circle_crossing",
        "--episodes",
        "2",
        "--out",
        str(tmp_path / "o"),
        "--no-progress",
    ]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "dt 0.25 in the checkpoint, 0.1 in preset 'fast'" in err and "--allow-preset-mismatch" in err
    assert not (tmp_path / "o").exists()
    assert main([*argv, "--allow-preset-mismatch"]) == 0
    captured = capsys.readouterr()
    assert "warning: preset mismatch allowed: dt 0.25 in the checkpoint, 0.1 in preset 'fast'" in captured.err
    manifest = json.loads((tmp_path / "o" / "manifest.json").read_text())
    assert manifest["policy"]["preset_mismatch_allowed"] == [
        "dt 0.25 in the checkpoint, 0.1 in preset 'fast'"
    ]
    # stated above every table: on stdout, in the written tables and in summary.json
    caveat = ("preset mismatch allowed (--allow-preset-mismatch): "
              "dt 0.25 in the checkpoint, 0.1 in preset 'fast'")
    assert captured.out.startswith(f"> **Caveat:** {caveat}\n")
    assert (tmp_path / "o" / "table2.md").read_text().startswith(f"> **Caveat:** {caveat}\n")
    assert (tmp_path / "o" / "table2.tex").read_text().startswith(f"% caveat: {caveat}\n")
    assert json.loads((tmp_path / "o" / "summary.json").read_text())["caveats"] == [caveat]


def test_a_checkpoint_trained_without_walls_is_refused_among_walls_naming_both(tmp_path, capsys):
    """The value networks have no obstacle input: a checkpoint trained on open floors is refused on
    scenarios with walls (here francis2023's world with wang2022's robot, so walls are the only
    difference) unless the mismatch is allowed, which is recorded."""
    pytest.importorskip("torch")
    from importlib import resources

    import yaml

    data = yaml.safe_load((resources.files("socialnav.configs") / "francis2023.yaml").read_text())
    data["robot"]["v_pref"] = 1.5
    data["name"] = "walls_fast"
    preset = tmp_path / "walls_fast.yaml"
    preset.write_text(yaml.safe_dump(data))
    argv = ["evaluate", "--policy", "sarl", "--preset", str(preset), "--scenario", "narrow_doorway",
            "--visibility", "invisible", "--episodes", "2", "--out", str(tmp_path / "o"), "--no-progress"]
    from socialnav.policies.building import shipped_checkpoint

    argv += ["--checkpoint", str(shipped_checkpoint("sarl", "wang2022"))]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert ("walls: the checkpoint was trained without walls (on circle_crossing, random, "
            "parallel_traffic, perpendicular_traffic), preset 'walls_fast' evaluates scenarios with "
            "walls (narrow_doorway)") in err  # the run's scenarios
    assert "dt " not in err and "robot.v_pref" not in err  # nothing else differs
    assert main([*argv, "--allow-preset-mismatch"]) == 0
    manifest = json.loads((tmp_path / "o" / "manifest.json").read_text())
    assert manifest["policy"]["preset_mismatch_allowed"][0].startswith("walls: the checkpoint was trained")
    capsys.readouterr()
    # replay rebuilds the policy against the run's scenarios, as the run did
    assert main(["replay", str(tmp_path / "o"), "--episode", "narrow_doorway/invisible/0", "--quiet"]) == 0


def test_walled_scenarios_asked_for_under_an_open_floor_preset_are_checked_too(tmp_path, capsys):
    # wang2022 lists no walled scenario; --scenario names one: the walls-less checkpoint is refused
    pytest.importorskip("torch")
    argv = ["evaluate", "--policy", "sarl", "--scenario", "circle_crossing", "blind_corner", "--episodes",
            "2", "--visibility", "invisible", "--out", str(tmp_path / "o"), "--no-progress"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "preset 'wang2022' evaluates scenarios with walls (blind_corner) that its network" in err
    assert not (tmp_path / "o").exists()
    assert main([*argv[:3], "--episodes", "2", "--out", str(tmp_path / "p"), "--no-progress"]) == 0


def test_other_kinematics_are_refused_even_with_allow_preset_mismatch(tmp_path, capsys):
    pytest.importorskip("torch")
    preset = tmp_path / "uni.yaml"
    preset.write_text("name: uni\nworld: {kinematics: unicycle}\n")
    from socialnav.policies.building import shipped_checkpoint

    argv = ["evaluate", "--policy", "sarl", "--checkpoint", str(shipped_checkpoint("sarl", "wang2022")),
            "--preset", str(preset), "--scenario", "circle_crossing",
            "--episodes", "2", "--out", str(tmp_path / "o"), "--no-progress", "--allow-preset-mismatch"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "kinematics 'holonomic' in the checkpoint, 'unicycle' in preset 'uni'" in err
    assert "--allow-preset-mismatch does not cover kinematics" in err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(("arg", "message"), [
    ("determinstic=false", "policy 'crowdnav_pp' has no parameter(s) determinstic; valid: deterministic"),
    ("deterministic=maybe", "policy 'crowdnav_pp': deterministic must be true or false, got 'maybe'"),
    ("device=cuda:999", "policy 'crowdnav_pp': device 'cuda:999', but CUDA is not available"),
])
def test_learned_policy_arguments_are_checked_before_the_checkpoint(tmp_path, capsys, arg, message):
    torch = pytest.importorskip("torch")
    if "cuda" in arg and torch.cuda.is_available():
        pytest.skip("this machine has CUDA")
    argv = ["evaluate", "--policy", "crowdnav_pp", "--scenario", "passing", "--episodes", "2",
            "--out", str(tmp_path / "o"), "--no-progress", "--policy-arg", arg]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and "checkpoint" not in err
    with pytest.raises(ValueError, match=r"policy 'sarl': planning_depth must be an integer >= 1, got 0"):
        from socialnav.policies import make_policy

        make_policy("sarl", checkpoint="unused.pt", planning_depth=0)
    with pytest.raises(ValueError, match=r"policy 'sarl' is learned: make_policy needs checkpoint=PATH"):
        make_policy("sarl")  # said, instead of a factory's missing positional argument


def test_a_resume_with_another_network_at_the_checkpoint_path_is_refused(tmp_path, capsys):
    pytest.importorskip("torch")
    import shutil

    from socialnav.policies.building import shipped_checkpoint

    ckpt = tmp_path / "model.pt"
    shutil.copy(shipped_checkpoint("sarl", "wang2022"), ckpt)
    argv = ["evaluate", "--policy", "sarl", "--checkpoint", str(ckpt), "--scenario", "passing",
            "--episodes", "2", "--out", str(tmp_path / "o"), "--no-progress"]
    assert main(argv) == 0
    manifest = json.loads((tmp_path / "o" / "manifest.json").read_text())
    assert len(manifest["checkpoint_sha256"]) == 64
    torch = pytest.importorskip("torch")
    saved = torch.load(ckpt, weights_only=False)
    first = next(iter(saved["state_dict"]))
    saved["state_dict"][first] = saved["state_dict"][first] + 1e-3  # another network, same path
    torch.save(saved, ckpt)
    capsys.readouterr()
    assert main(argv) != 0
    assert "checkpoint_sha256" in capsys.readouterr().err


def test_a_checkpoint_that_records_no_world_is_evaluated_with_a_warning(tmp_path, capsys):
    # saved by hand (docs/policies_learned.md's snippet): no config.value_policy, so no world to compare
    pytest.importorskip("torch")
    from socialnav.policies.building import shipped_checkpoint
    from socialnav.policies.learned import build, save_checkpoint

    hand = save_checkpoint(tmp_path / "hand.pt", "sarl", build("sarl"), config={"kinematics": "holonomic"})
    argv = ["evaluate", "--policy", "sarl", "--scenario", "circle_crossing", "--episodes", "1",
            "--visibility", "invisible", "--no-progress", "--json"]
    assert main([*argv, "--checkpoint", str(hand), "--out", str(tmp_path / "a")]) == 0
    assert (f"warning: checkpoint {hand} records no training world (config.value_policy): its dt, "
            "kinematics, reward and robot v_pref cannot be compared with preset 'wang2022'"
            ) in capsys.readouterr().err
    trained = str(shipped_checkpoint("sarl", "wang2022"))
    assert main([*argv, "--checkpoint", trained, "--out", str(tmp_path / "b")]) == 0
    assert "records no training world" not in capsys.readouterr().err


def test_the_same_checkpoint_under_another_path_string_is_refused_with_the_way_to_resume(
        tmp_path, monkeypatch, capsys):
    pytest.importorskip("torch")
    import shutil

    from socialnav.policies.building import shipped_checkpoint

    shutil.copy(shipped_checkpoint("sarl", "wang2022"), tmp_path / "sarl.pt")
    monkeypatch.chdir(tmp_path)
    argv = ["evaluate", "--policy", "sarl", "--scenario", "circle_crossing", "--episodes", "1",
            "--visibility", "invisible", "--out", str(tmp_path / "o"), "--quiet"]
    assert main([*argv, "--checkpoint", "sarl.pt"]) == 0
    assert main([*argv, "--checkpoint", str(tmp_path / "sarl.pt")]) == 2
    err = capsys.readouterr().err
    assert ("or resume it: the checkpoint is the same file (SHA-256 equal) given as another path; give "
            "--checkpoint sarl.pt as the run did") in err
    assert main([*argv, "--checkpoint", "sarl.pt"]) == 0  # as said

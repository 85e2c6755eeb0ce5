"""Stored trajectories of an evaluation: layout, resumption, episode ids, and bit-for-bit replay."""

import dataclasses
import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from socialnav.cli import main
from socialnav.evaluate.execution import simulate_chunk
from socialnav.evaluate.plan import plan_cells
from socialnav.evaluate.replay import replay_episode
from socialnav.evaluate.results import ResultsError, list_episodes, load_episode
from socialnav.evaluate.runner import run_protocol
from socialnav.policies import make_policy
from socialnav.presets import load_preset
from socialnav.trajectory import write_trajectories

ROOT = Path(__file__).resolve().parents[2]


def small_preset(**evaluation):
    preset = load_preset("wang2022")
    settings = {"episodes": 6, "chunk_size": 4, **evaluation}
    return dataclasses.replace(preset, evaluation=dataclasses.replace(preset.evaluation, **settings))


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("run")
    run_protocol(
        make_policy("orca", safety_space=0.2),
        small_preset(),
        out,
        scenarios=["circle_crossing", "passing"],
        episodes=6,
        progress=False,
        workers=0,
    )
    return out


def test_trajectory_files_mirror_the_episode_files(run_dir):
    episodes = sorted(p.relative_to(run_dir / "episodes") for p in (run_dir / "episodes").rglob("*.parquet"))
    trajs = sorted(
        p.relative_to(run_dir / "trajectories") for p in (run_dir / "trajectories").rglob("*.parquet")
    )
    assert episodes == trajs
    assert [str(p) for p in trajs] == [
        "circle_crossing__invisible/00000-00004.parquet",
        "circle_crossing__invisible/00004-00006.parquet",
        "circle_crossing__visible/00000-00004.parquet",
        "circle_crossing__visible/00004-00006.parquet",
        "passing__invisible/00000-00004.parquet",
        "passing__invisible/00004-00006.parquet",
    ]
    manifest = json.loads((run_dir / "manifest.json").read_text())
    assert manifest["trajectories"] is True and manifest["batch_size"] == 256


def test_list_and_load_episodes_by_id(run_dir):
    ids = list_episodes(run_dir)
    assert len(ids) == 18
    assert ids[:2] == ["circle_crossing/invisible/0", "circle_crossing/invisible/1"]
    assert "passing/invisible/5" in ids
    traj = load_episode(run_dir, "circle_crossing/visible/5")
    assert traj.settings["episode"] == "circle_crossing/visible/5"
    assert traj.settings["index"] == 5 and traj.settings["visibility"] == "visible"
    # the stored episode is exactly the simulated one (float64, nothing rounded)
    preset = small_preset()
    cell = [c for c in plan_cells(preset, ["circle_crossing"], 6, "visible")][0]
    fresh = simulate_chunk(make_policy("orca", safety_space=0.2), preset, cell, 4, 6, "orca")[1]
    np.testing.assert_array_equal(traj.positions, fresh.positions)
    np.testing.assert_array_equal(traj.velocities, fresh.velocities)
    np.testing.assert_array_equal(traj.continuation, fresh.continuation)
    np.testing.assert_array_equal(traj.min_clearance, fresh.min_clearance)
    assert traj.outcome == fresh.outcome and traj.dt == fresh.dt


@pytest.mark.parametrize(
    "episode, message",
    [
        ("circle_crossing/invisible/9", "indices 0..3, 4..5"),
        ("passing/visible/0", "stored scenario/visibility: circle_crossing/invisible"),
        ("circle_crossing-3", "not of the form <scenario>/<visibility>/<index>"),
    ],
)
def test_unknown_episode_errors_list_what_exists(run_dir, episode, message):
    with pytest.raises(ResultsError, match=message):
        load_episode(run_dir, episode)


def test_not_a_result_directory(tmp_path):
    with pytest.raises(ResultsError, match="no such result directory"):
        list_episodes(tmp_path / "missing")
    with pytest.raises(ResultsError, match="no manifest.json"):
        list_episodes(tmp_path)
    for sub, what in (("policies", "`socialnav evaluate --policy all`"), ("evaluate", "a sweep's jobs")):
        (tmp_path / sub / "job").mkdir(parents=True)
        (tmp_path / sub / "job" / "manifest.json").write_text("{}")
        expected = f"holds the runs of {what}: pass them, e.g. `socialnav report {tmp_path}/{sub}/*`"
        with pytest.raises(ResultsError, match=re.escape(expected)):
            list_episodes(tmp_path)
        (tmp_path / sub / "job" / "manifest.json").unlink()


def test_metrics_command_reads_a_stored_chunk(run_dir, capsys):
    path = run_dir / "trajectories" / "passing__invisible" / "00000-00004.parquet"
    assert main(["metrics", str(path), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert [e["episode"] for e in data["episodes"]] == [f"passing/invisible/{i}" for i in range(4)]


def test_no_trajectories_opt_out(tmp_path):
    run_protocol(
        make_policy("orca"),
        small_preset(),
        tmp_path,
        scenarios=["random"],
        visibility="invisible",
        progress=False,
        workers=0,
        trajectories=False,
    )
    assert not (tmp_path / "trajectories").exists()
    assert json.loads((tmp_path / "manifest.json").read_text())["trajectories"] is False
    with pytest.raises(ResultsError, match="--no-trajectories"):
        load_episode(tmp_path, "random/invisible/0")


def test_resume_redoes_a_chunk_that_has_only_one_of_its_two_files(tmp_path):
    policy, preset = make_policy("orca"), small_preset()
    kwargs = dict(scenarios=["random"], visibility="invisible", progress=False, workers=0)
    run_protocol(policy, preset, tmp_path, **kwargs)
    traj_file = tmp_path / "trajectories" / "random__invisible" / "00004-00006.parquet"
    score_file = tmp_path / "episodes" / "random__invisible" / "00000-00004.parquet"
    before = load_episode(tmp_path, "random/invisible/5")
    traj_file.unlink()  # killed between the two writes of chunk 2 ...
    score_file.unlink()  # ... or a lost score file of chunk 1
    assert "random/invisible/5" not in list_episodes(tmp_path)  # a half-written chunk is not listed
    again = run_protocol(policy, preset, tmp_path, **kwargs)
    assert again.computed_episodes == 6  # both chunks, and only them
    assert traj_file.exists() and score_file.exists()
    np.testing.assert_array_equal(load_episode(tmp_path, "random/invisible/5").positions, before.positions)


def test_replay_cli_reproduces_orca_episodes_bit_for_bit(run_dir, tmp_path, capsys):
    for episode in ("circle_crossing/visible/5", "passing/invisible/2"):
        assert main(["replay", str(run_dir), "--episode", episode, "--out", str(tmp_path / "r.parquet")]) == 0
        out = capsys.readouterr().out
        assert "identical" in out and "max |difference| 0" in out
    assert main(["render", str(tmp_path / "r.parquet"), "--out", str(tmp_path / "r.png"), "--quiet"]) == 0


def test_replay_detects_a_tampered_trajectory(tmp_path, capsys):
    run_protocol(
        make_policy("orca"),
        small_preset(),
        tmp_path,
        scenarios=["random"],
        visibility="invisible",
        progress=False,
        workers=0,
    )
    path = tmp_path / "trajectories" / "random__invisible" / "00000-00004.parquet"
    from socialnav.trajectory import read_trajectories

    trajs = read_trajectories(path)
    pos = trajs[2].positions.copy()
    pos[3, 1, 0] += 1e-12  # one human coordinate, one ulp-sized change
    trajs[2] = dataclasses.replace(trajs[2], positions=pos)
    write_trajectories(path, trajs)
    result = replay_episode(tmp_path, "random/invisible/2")
    assert not result.identical and 0 < result.max_abs_diff < 1e-11
    assert any("positions" in d and "(3, 1, 0)" in d for d in result.differences)
    assert main(["replay", str(tmp_path), "--episode", "random/invisible/2"]) == 1
    assert "DIFFERS" in capsys.readouterr().out


def test_replay_reproduces_a_learned_policy_with_its_checkpoint(tmp_path):
    pytest.importorskip("torch")
    from socialnav.policies.building import build_policy, shipped_checkpoint

    preset = small_preset(episodes=5, chunk_size=5)
    ckpt = shipped_checkpoint("sarl", "wang2022")
    policy = build_policy("sarl", preset, ckpt)
    run_protocol(
        policy,
        preset,
        tmp_path,
        scenarios=["circle_crossing"],
        visibility="invisible",
        progress=False,
        workers=0,
        batch_size=3,
        extra_manifest={"checkpoint": str(ckpt)},
    )
    for episode in ("circle_crossing/invisible/1", "circle_crossing/invisible/4"):
        result = replay_episode(tmp_path, episode)
        assert result.identical, result.differences
        assert result.max_abs_diff == 0.0


@pytest.mark.parametrize(
    ("name", "overrides"),
    [("crowdnav_pp", {}), ("mp_rgl", {"planning_depth": 1, "planning_width": 1}),
     ("sarl", {"information": "oracle"})],
)
def test_replay_rebuilds_the_recorded_settings_of_every_learned_kind(tmp_path, name, overrides):
    # a PPO policy takes no information or scorer; --planning-depth/--information runs record theirs
    pytest.importorskip("torch")
    from socialnav.policies.building import build_policy

    preset = small_preset(episodes=2, chunk_size=2)
    policy = build_policy(name, preset, None, **overrides)
    for key, value in overrides.items():
        assert policy.describe()[key] == value
    run_protocol(policy, preset, tmp_path, scenarios=["circle_crossing"], visibility="invisible",
                 progress=False, workers=0, batch_size=2)
    result = replay_episode(tmp_path, "circle_crossing/invisible/1")
    assert result.identical and result.max_abs_diff == 0.0, result.differences


@pytest.mark.parametrize("scorer", ["torch", "legacy"])
def test_replay_rebuilds_the_recorded_scorer(tmp_path, scorer):
    """A run scored by the module replays with the module; so does a manifest from before the scorer
    was recorded (those runs were all scored by the module)."""
    pytest.importorskip("torch")
    import json

    from socialnav.policies.building import build_policy, shipped_checkpoint

    preset = small_preset(episodes=3, chunk_size=3)
    ckpt = shipped_checkpoint("sarl", "wang2022")
    policy = build_policy("sarl", preset, ckpt, scorer="torch")
    assert policy.describe()["scorer"] == "torch"
    run_protocol(
        policy, preset, tmp_path, scenarios=["circle_crossing"], visibility="invisible", progress=False,
        workers=0, batch_size=3, extra_manifest={"checkpoint": str(ckpt)},
    )
    if scorer == "legacy":
        path = tmp_path / "manifest.json"
        manifest = json.loads(path.read_text())
        del manifest["policy"]["scorer"]
        path.write_text(json.dumps(manifest))
    result = replay_episode(tmp_path, "circle_crossing/invisible/2")
    assert result.identical, result.differences


def test_replay_as_a_subprocess(run_dir):
    proc = subprocess.run(
        [sys.executable, "-m", "socialnav.cli", "replay", str(run_dir), "--episode", "passing/invisible/4"],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    assert "passing/invisible/4: replay identical" in proc.stdout
    bad = subprocess.run(
        [sys.executable, "-m", "socialnav.cli", "replay", str(run_dir), "--episode", "passing/invisible/40"],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=120,
    )
    assert bad.returncode == 2 and "Traceback" not in bad.stderr
    assert "has indices 0..3, 4..5" in bad.stderr


def test_replay_from_another_directory_says_where_a_relative_checkpoint_was_looked_for(
        tmp_path, monkeypatch, capsys):
    pytest.importorskip("torch")
    import shutil

    from socialnav.cli import main
    from socialnav.policies.building import shipped_checkpoint

    (tmp_path / "work" / "ck").mkdir(parents=True)
    shutil.copy(shipped_checkpoint("sarl", "wang2022"), tmp_path / "work" / "ck" / "sarl.pt")
    monkeypatch.chdir(tmp_path / "work")
    argv = ["evaluate", "--policy", "sarl", "--checkpoint", "ck/sarl.pt", "--scenario", "circle_crossing",
            "--episodes", "1", "--visibility", "invisible", "--out", str(tmp_path / "run"), "--quiet"]
    assert main(argv) == 0
    episode = ["replay", str(tmp_path / "run"), "--episode", "circle_crossing/invisible/0", "--quiet"]
    assert main(episode) == 0  # from the directory the run was started in
    monkeypatch.chdir(tmp_path)
    assert main(episode) == 2
    err = capsys.readouterr().err
    assert "the policy's checkpoint ck/sarl.pt does not exist (looked for from" in err
    assert "relative to the directory it was started from; replay from that directory" in err


def test_replay_refuses_a_checkpoint_replaced_since_the_run(tmp_path, capsys):
    # another network saved at the same path would replay other decisions: named, not a "DIFFERS"
    pytest.importorskip("torch")
    import shutil

    from socialnav.cli import main
    from socialnav.policies.building import shipped_checkpoint

    ckpt = tmp_path / "sarl.pt"
    shutil.copy(shipped_checkpoint("sarl", "wang2022"), ckpt)
    argv = ["evaluate", "--policy", "sarl", "--checkpoint", str(ckpt), "--scenario", "circle_crossing",
            "--episodes", "1", "--visibility", "invisible", "--out", str(tmp_path / "run"), "--quiet"]
    assert main(argv) == 0
    episode = ["replay", str(tmp_path / "run"), "--episode", "circle_crossing/invisible/0", "--quiet"]
    assert main(episode) == 0
    shutil.copy(shipped_checkpoint("om_sarl", "wang2022"), ckpt)
    assert main(episode) == 2
    assert f"checkpoint {ckpt} changed since the run (SHA-256 recorded: " in capsys.readouterr().err

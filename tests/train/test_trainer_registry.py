"""A trainer registered from outside the package is found everywhere a trainer appears.

``tests/train/random_search_trainer.py`` registers ``random_search`` (a trainer) and ``tiny_actor`` (the
learned policy it trains). In this process they are registered by importing it; in a subprocess by an
installed package's entry point of group ``socialnav.trainers``. Either way: ``socialnav list`` shows
it, its settings load (a bad value refused naming the file and the field), ``socialnav train --policy
tiny_actor`` runs it into a run directory kept by the shared bookkeeping (another trainer's directory
refused, both ways), its checkpoints load as policies, and a sweep's training job names it.
"""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import pytest

from socialnav.settings import ConfigError
from socialnav.train import registry
from tests._env import subprocess_env

ROOT = Path(__file__).resolve().parents[2]
PLUGIN = "tests.train.random_search_trainer"
GOOD = "candidates: 2\nval_episodes: 2\n"


@pytest.fixture
def random_search(isolated_registries, monkeypatch):
    """The trainer and its policy registered in this process, undone after the test."""
    import importlib

    monkeypatch.setattr(registry, "_TRAINERS", dict(registry._TRAINERS))
    module = importlib.import_module(PLUGIN)
    module.register()
    return module


def _plugin_env(tmp_path: Path) -> dict[str, str]:
    """A subprocess environment in which an installed package declares the trainer's entry point."""
    dist = tmp_path / "site" / "socialnav_random_search-0.1.dist-info"
    dist.mkdir(parents=True)
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: socialnav-random-search\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text(f"[socialnav.trainers]\nrandom_search = {PLUGIN}:TRAINER\n")
    return subprocess_env(tmp_path / "site", ROOT)


def _socialnav(env: dict[str, str], cwd: Path, *argv: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "socialnav.cli", *argv], capture_output=True, text=True,
                          env=env, cwd=cwd)


def test_the_builtin_trainers_are_registered_and_each_policy_has_one():
    from socialnav.policies.learned_catalog import learned_policy_names

    names = [t.name for t in registry.list_trainers()]
    assert names[:2] == ["value", "ppo"]
    for policy in learned_policy_names():
        assert registry.trainer_for_policy(policy).name in ("value", "ppo")
    assert registry.trainer_for_policy("sarl").checkpoints == ("il.pt", "best.pt", "last.pt")
    with pytest.raises(ConfigError, match=r"--policy 'orca': not a policy that `socialnav train` trains; "
                       r"value-based: cadrl, .*; PPO: crowdnav_pp, ppo_mlp"):
        registry.trainer_for_policy("orca")


def test_a_malformed_trainer_record_is_refused(random_search):
    trainer = random_search.TRAINER
    with pytest.raises(ValueError, match="already registered"):
        registry.register_trainer(dataclasses.replace(trainer, description="another one"))
    with pytest.raises(ValueError, match=r"unknown option\(s\) \['epochs'\]"):
        dataclasses.replace(trainer, name="other", options={"epochs": "x"})
    with pytest.raises(ValueError, match="checkpoint_kind 'weights' must be one of"):
        dataclasses.replace(trainer, name="other", checkpoint_kind="weights")
    assert registry.register_trainer(trainer) is trainer  # the same record again: a no-op
    from socialnav.policies import register_learned_policy

    register_learned_policy(dataclasses.replace(random_search.SPEC, name="orphan", trainer="nope"))
    with pytest.raises(ConfigError, match="policy 'orphan': its record names trainer 'nope', which is not "
                       "registered"):
        registry.trainer_for_policy("orphan")
    register_learned_policy(dataclasses.replace(random_search.SPEC, name="mismatch", network_kwargs=None,
                                                checkpoint_kind="value_policy"))
    with pytest.raises(ConfigError, match="its record's checkpoint_kind is 'value_policy', and its trainer "
                       "'random_search' writes 'ppo_policy' checkpoints"):
        registry.trainer_for_policy("mismatch")


def test_settings_load_and_a_bad_value_names_the_file_and_the_field(random_search, tmp_path):
    trainer = registry.get_trainer("random_search")
    good = tmp_path / "good.yaml"
    good.write_text(GOOD)
    settings = trainer.load_settings(good, policy="tiny_actor", seed=3, collection_batch=4)
    assert (settings.candidates, settings.seed, settings.val_episodes) == (2, 3, 4)
    bad = tmp_path / "bad.yaml"
    bad.write_text("sigma: -1\n")
    with pytest.raises(ConfigError, match=rf"^{bad}: sigma must be > 0, got -1"):
        trainer.load_settings(bad)
    typo = tmp_path / "typo.yaml"
    typo.write_text("candidate: 3\n")
    with pytest.raises(ConfigError,
                       match=rf"^{typo}: unknown setting\(s\) candidate \(did you mean candidates\?\)"):
        trainer.load_settings(typo)
    with pytest.raises(ConfigError, match=r"^--collection-batch: val_episodes must be >= 1, got 0"):
        trainer.load_settings(good, collection_batch=0)
    with pytest.raises(ConfigError, match=r"--rl-episodes: not a setting of the random-search trainer of "
                       r"'tiny_actor'"):
        trainer.load_settings(good, policy="tiny_actor", rl_episodes=3)


def test_train_list_and_the_shared_run_directory(random_search, tmp_path, capsys):
    from socialnav.cli import main
    from socialnav.policies import build_policy
    from socialnav.presets import load_preset

    assert main(["list", "--json"]) == 0
    listed = json.loads(capsys.readouterr().out)
    trainers = {t["name"]: t for t in listed["trainers"]}
    assert trainers["random_search"]["policies"] == ["tiny_actor"]
    assert trainers["random_search"]["checkpoint_kind"] == "ppo_policy"
    assert "tiny_actor" in {p["name"] for p in listed["policies"]}

    config, out = tmp_path / "rs.yaml", tmp_path / "run"
    config.write_text(GOOD)
    argv = ["train", "--policy", "tiny_actor", "--preset", "crowdnav", "--config", str(config),
            "--out", str(out), "--no-progress"]
    assert main(argv) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["candidates"] == 2 and summary["out"] == str(out) and not summary["resumed"]
    for name in ("config.json", "config.yaml", "curves.csv", "best.pt", "last.pt", ".lock"):
        assert (out / name).is_file(), name
    record = json.loads((out / "config.json").read_text())
    assert (record["trainer"], record["policy"], record["train"]["candidates"]) == (
        "random_search", "tiny_actor", 2)
    assert (out / "curves.csv").read_text().splitlines()[0].startswith("candidate,val_success")
    policy = build_policy("tiny_actor", load_preset("crowdnav"), out / "best.pt")  # loads as an actor
    assert policy.name == "tiny_actor"

    # the same command resumes it; another trainer's run is refused in its directory, and it in theirs
    assert main(argv) == 0
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])["resumed"]
    assert main(["train", "--policy", "sarl", "--config", "smoke", "--out", str(out), "--no-progress"]) == 2
    said = capsys.readouterr().err
    assert (f"{out} holds a run of the 'random_search' trainer (policy 'tiny_actor'), and 'sarl' trains "
            "with the 'value' trainer: use another --out") in said
    legacy = tmp_path / "value_run"  # a value-based run's record from before records named their trainer
    legacy.mkdir()
    (legacy / "config.json").write_text(json.dumps({"value_policy": {}, "policy": "sarl", "train": {}}))
    assert main([*argv[:-3], "--out", str(legacy), "--no-progress"]) == 2
    assert f"{legacy} holds a run of the 'value' trainer (policy 'sarl')" in capsys.readouterr().err
    assert sorted(p.name for p in legacy.iterdir()) == [".lock", "config.json"]  # nothing written

    # options it does not take, and a config of another trainer, are refused naming them
    assert main([*argv, "--rl-episodes", "4"]) == 2
    said = capsys.readouterr().err
    assert "--rl-episodes: not a setting of the random-search trainer of 'tiny_actor'" in said
    other = ["train", "--policy", "tiny_actor", "--config", "ppo_smoke", "--out", str(tmp_path / "x")]
    assert main(other) == 2
    assert "--config ppo_smoke: a PPO config, and tiny_actor trains with the random-search trainer" in (
        capsys.readouterr().err)


def test_a_sweep_job_names_it(random_search, tmp_path):
    from socialnav.sweep.spec import parse_sweep
    from socialnav.sweep.tasks import train_job

    config = tmp_path / "rs.yaml"
    config.write_text(GOOD)
    spec = parse_sweep({"jobs": [{"kind": "train", "policy": "tiny_actor", "preset": "crowdnav",
                                  "config": str(config), "collection_batch": 2, "name": "rs"}]})
    (job,) = spec.jobs
    assert job.params["policy"] == "tiny_actor"
    done = train_job(None, job.params, str(tmp_path / "job"), 1, None)  # as a worker runs it
    assert done["candidates"] == 2 and Path(done["best_checkpoint"]).is_file()
    with pytest.raises(ConfigError,
                       match=r"information: not a setting of the random-search trainer of 'tiny_actor'"):
        parse_sweep({"jobs": [{"kind": "train", "policy": "tiny_actor", "information": "oracle"}]})
    bad = tmp_path / "bad.yaml"
    bad.write_text("sigma: 0\n")
    with pytest.raises(ConfigError, match=rf"config: {bad}: sigma must be > 0"):
        parse_sweep({"jobs": [{"kind": "train", "policy": "tiny_actor", "config": str(bad)}]})


def test_an_entry_point_registers_it_for_list_train_and_a_sweep(tmp_path):
    env = _plugin_env(tmp_path)
    listed = _socialnav(env, tmp_path, "list", "--json")
    assert listed.returncode == 0, listed.stderr
    assert {t["name"]: t["policies"] for t in json.loads(listed.stdout)["trainers"]}["random_search"] == [
        "tiny_actor"]
    config = tmp_path / "rs.yaml"
    config.write_text(GOOD)
    trained = _socialnav(env, tmp_path, "train", "--policy", "tiny_actor", "--preset", "crowdnav", "--config",
                         str(config), "--out", str(tmp_path / "run"), "--no-progress")
    assert trained.returncode == 0, trained.stderr
    assert json.loads(trained.stdout.splitlines()[-1])["candidates"] == 2
    # its checkpoint evaluated from the command line (the policy comes with the trainer's plugin)
    evaluated = _socialnav(env, tmp_path, "evaluate", "--policy", "tiny_actor", "--checkpoint",
                           str(tmp_path / "run" / "best.pt"), "--preset", "crowdnav", "--episodes", "2",
                           "--out", str(tmp_path / "eval"), "--no-progress", "--quiet")
    assert evaluated.returncode == 0, evaluated.stderr
    sweep = tmp_path / "sweep.yaml"
    sweep.write_text(f"jobs:\n  - {{kind: train, policy: tiny_actor, preset: crowdnav, config: {config}, "
                     "name: rs}\n")
    swept = _socialnav(env, tmp_path, "sweep", str(sweep), "--workers", "1", "--out", str(tmp_path / "sweep"),
                       "--quiet")
    assert swept.returncode == 0, swept.stderr
    assert (tmp_path / "sweep" / "train" / "rs" / "best.pt").is_file()
    record = json.loads((tmp_path / "sweep" / "train" / "rs" / "config.json").read_text())
    assert record["trainer"] == "random_search"


def test_a_refused_resume_names_what_changes_the_training_first(tmp_path):
    # another preset differs in its name, description and evaluation settings too: those come last
    from socialnav.settings import ConfigError
    from socialnav.train.run_directory import refuse_other_settings

    saved = {"preset": {"name": "crowdnav", "description": "a", "evaluation": {k: 1 for k in "abcdef"},
                        "robot": {"v_pref": 1.0}, "world": {"dt": 0.25}}}
    config = {"preset": {"name": "wang2022", "description": "b", "evaluation": {k: 2 for k in "abcdef"},
                         "robot": {"v_pref": 1.5}, "world": {"dt": 0.25}}}
    diff = ["preset.description", *(f"preset.evaluation.{k}" for k in "abcdef"), "preset.name",
            "preset.robot.v_pref"]
    with pytest.raises(ConfigError) as err:
        refuse_other_settings(saved, config, diff, tmp_path)
    message = str(err.value)
    assert message.index("preset.robot.v_pref: 1.0 -> 1.5") < message.index("preset.description")
    assert "; and 3 more); use another --out, or the run's own settings: its config.yaml (--config) and " \
           "the preset it was trained under (--preset)" in message

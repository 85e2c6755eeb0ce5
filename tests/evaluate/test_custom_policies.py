"""Custom policies from the command line: ``--policy module:Class``, the ``socialnav.policies``
entry-point group, typed ``--policy-arg`` values, and the docs page's example run as a script."""

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from tests._env import subprocess_env

from socialnav.cli import main
from socialnav.evaluate.cli import parse_policy_args
from socialnav.policies import make_policy

ROOT = Path(__file__).resolve().parents[2]
HERE = Path(__file__).resolve().parent
MODULE = __name__


class GoalSeeker:
    """Straight to the goal at a fraction of v_pref (a test policy)."""

    information = "none"

    def __init__(self, speed_factor: float = 1.0, tag: str = "plain", flag: bool = False):
        self.name = "goal_seeker"
        self.speed_factor, self.tag, self.flag = speed_factor, tag, flag

    def act(self, observation):
        to_goal = observation.robot[:, 5:7] - observation.robot[:, 0:2]
        dist = np.maximum(np.linalg.norm(to_goal, axis=1, keepdims=True), 1e-9)
        speed = self.speed_factor * observation.robot[:, 7:8]
        return to_goal / dist * np.minimum(speed, dist / observation.dt)

    def describe(self):
        return {"policy": self.name, "information": self.information, "speed_factor": self.speed_factor,
                "tag": self.tag, "flag": self.flag}


def evaluate(capsys, tmp_path, *extra):
    code = main(["evaluate", "--preset", "crowdnav", "--episodes", "6", "--out", str(tmp_path), "--json",
                 "--no-progress", *extra])
    out = capsys.readouterr()
    return code, out.out, out.err


def test_policy_given_as_module_path_with_typed_arguments(tmp_path, capsys):
    code, out, err = evaluate(capsys, tmp_path, "--policy", f"{MODULE}:GoalSeeker",
                              "--policy-arg", "speed_factor=0.5", "--policy-arg", "flag=true",
                              "--policy-arg", "tag=abc")
    assert code == 0, err
    rows = json.loads(out)["rows"]
    assert rows[0]["policy"] == "goal_seeker" and rows[0]["episodes"] == 6
    policy = json.loads((tmp_path / "manifest.json").read_text())["policy"]
    assert policy == {"label": "goal_seeker", "policy": "goal_seeker", "information": "none",
                      "speed_factor": 0.5, "tag": "abc", "flag": True}
    # Half speed: every success takes longer than the straight-line time at v_pref (1 m/s, 8 m).
    assert rows[0]["nav_time_s"] > 8.0 / 0.5 - 1.0


def test_policy_arguments_reach_a_registered_policy(tmp_path, capsys):
    code, _, err = evaluate(capsys, tmp_path, "--policy", "orca", "--policy-arg", "safety_space=0.05")
    assert code == 0, err
    assert json.loads((tmp_path / "manifest.json").read_text())["policy"]["safety_space"] == 0.05


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--policy", f"{MODULE}:GoalSeeker", "--policy-arg", "bogus=1"],
         "has no parameter(s) bogus; valid: flag, speed_factor, tag"),
        (["--policy", "no_such_module_xyz:Thing"], "cannot import module 'no_such_module_xyz'"),
        (["--policy", f"{MODULE}:Nothing"], f"module '{MODULE}' has no attribute 'Nothing'"),
        (["--policy", f"{MODULE}:MODULE"], "is not a class or a factory function"),
        (["--policy", f"{MODULE}:np"], "is not a class or a factory function"),
        (["--policy", "orca", "--policy-arg", "safety_space"], "expected KEY=VALUE"),
        (["--policy", "orca", "--policy-arg", "safety_space=[1"], "not valid YAML"),
        (["--policy", "not_registered"], "unknown policy 'not_registered'"),
        (["--policy", "ORCA"], "unknown policy 'ORCA' (did you mean 'orca'? names are lower case)"),
        (["--policy", "ALL"], "unknown policy 'ALL' (did you mean 'all': every shipped checkpoint"),
        (["--policy", "./my_policy.py:Go"], "not a file path: run from '.' (or with it on PYTHONPATH) "
                                            "with --policy my_policy:Go"),
        (["--policy", "my_policy.py:Go"], "run from the file's directory with --policy my_policy:Go"),
    ],
)
def test_bad_policy_specs_are_one_line_errors(tmp_path, capsys, argv, message):
    code, _, err = evaluate(capsys, tmp_path, *argv)
    assert code == 2
    assert message in err and "Traceback" not in err, err


def test_parse_policy_args_gives_typed_values():
    assert parse_policy_args(["a=0.2", "b=3", "c=true", "d=[1, 2]", "e=fast", "f=null", "g="]) == {
        "a": 0.2, "b": 3, "c": True, "d": [1, 2], "e": "fast", "f": None, "g": ""}
    with pytest.raises(ValueError, match="given twice"):
        parse_policy_args(["a=1", "a=2"])


def test_make_policy_refuses_an_object_that_is_not_a_policy():
    with pytest.raises(ValueError, match="without act, describe"):
        make_policy(f"{MODULE}:NotAPolicy")


class NotAPolicy:
    name = "x"


def _plugin_env(tmp_path: Path, extra: str = "") -> dict:
    dist = tmp_path / "site" / "socialnav_test_plugin-0.1.dist-info"
    dist.mkdir(parents=True)
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: socialnav-test-plugin\nVersion: 0.1\n")
    entries = f"[socialnav.policies]\ngoal_seeker = {MODULE}:GoalSeeker\n{extra}"
    (dist / "entry_points.txt").write_text(entries)
    return subprocess_env(tmp_path / "site", HERE, ROOT)  # ROOT: the module imports tests._env


def test_policy_from_an_entry_point(tmp_path):
    env = _plugin_env(tmp_path)
    cmd = [sys.executable, "-m", "socialnav.cli"]
    listed = subprocess.run([*cmd, "list", "--json"], capture_output=True, text=True, env=env, cwd=tmp_path)
    assert listed.returncode == 0, listed.stderr
    names = {p["name"]: p for p in json.loads(listed.stdout)["policies"]}
    assert names["goal_seeker"]["parameters"] == {"speed_factor": 1.0, "tag": "plain", "flag": False}
    run = subprocess.run(
        [*cmd, "evaluate", "--policy", "goal_seeker", "--policy-arg", "speed_factor=0.8", "--preset",
         "crowdnav", "--episodes", "4", "--out", str(tmp_path / "out"), "--json", "--no-progress"],
        capture_output=True, text=True, env=env, cwd=tmp_path,
    )
    assert run.returncode == 0, run.stderr
    assert json.loads(run.stdout)["rows"][0]["episodes"] == 4
    manifest = json.loads((tmp_path / "out" / "manifest.json").read_text())
    assert manifest["policy"]["speed_factor"] == 0.8 and manifest["policy"]["label"] == "goal_seeker"


def test_a_plugin_under_a_taken_or_reserved_name_is_said_not_registered(tmp_path):
    env = _plugin_env(tmp_path, f"orca = {MODULE}:GoalSeeker\nall = {MODULE}:GoalSeeker\n")
    listed = subprocess.run([sys.executable, "-m", "socialnav.cli", "list", "--json"], capture_output=True,
                            text=True, env=env, cwd=tmp_path)
    assert listed.returncode == 0, listed.stderr
    names = {p["name"]: p for p in json.loads(listed.stdout)["policies"]}
    assert "goal_seeker" in names and "all" not in names
    assert names["orca"]["parameters"] == {"safety_space": 0.2, "threads": 0}  # the built-in stays
    assert "policy plugin 'orca'" in listed.stderr and "the name is taken by another policy" in listed.stderr
    assert "policy plugin 'all'" in listed.stderr and "cannot be registered" in listed.stderr


def test_register_policy_refuses_names_the_command_line_reads_otherwise():
    from socialnav.policies import register_policy

    for name in ("all", "pkg.mod:Thing", "sb3:model.zip", ""):
        with pytest.raises(ValueError, match="cannot be registered"):
            register_policy(name, description="x")


def test_docs_example_runs_as_a_script_and_from_the_cli(tmp_path):
    text = (ROOT / "docs" / "custom_policies.md").read_text()
    code = re.search(r"## A complete example.*?```python\n(.*?)```", text, re.S).group(1)
    (tmp_path / "cautious.py").write_text(code)
    env = subprocess_env()
    result = subprocess.run([sys.executable, "cautious.py"], cwd=tmp_path, capture_output=True, text=True,
                            env=env, timeout=300)
    assert result.returncode == 0, result.stderr[-3000:]
    assert re.search(r"circle_crossing invisible success \d\.\d\d", result.stdout), result.stdout
    # The same module from the command line, found in the current directory.
    cli = subprocess.run(
        [sys.executable, "-m", "socialnav.cli", "evaluate", "--policy", "cautious:Cautious", "--policy-arg",
         "slow_factor=0.3", "--preset", "crowdnav", "--episodes", "5", "--out", "cli", "--json",
         "--no-progress"],
        cwd=tmp_path, capture_output=True, text=True, env=env, timeout=300,
    )
    assert cli.returncode == 0, cli.stderr[-3000:]
    assert json.loads((tmp_path / "cli" / "manifest.json").read_text())["policy"]["slow_factor"] == 0.3


class Faulty(GoalSeeker):
    """Fails the way a user's policy can: raises, returns a wrong shape, or NaN for one episode."""

    def __init__(self, mode: str = "raise"):
        super().__init__()
        self.name, self.mode = "faulty", mode

    def act(self, observation):
        actions = super().act(observation)
        if self.mode == "raise":
            return actions @ np.ones((3, 2))  # a shape bug deep in the user's code
        if self.mode == "shape":
            return actions[:, :1]
        actions[np.flatnonzero(observation.active)[-1]] = np.nan
        return actions

    def describe(self):
        return {"policy": self.name, "information": self.information, "mode": self.mode}


@pytest.mark.parametrize(
    "mode, message",
    [
        ("raise", r"policy 'faulty' failed in circle_crossing/invisible, episode\(s\) \[0, 1, 2, 3, 4, 5\] "
                  r"at t = 0 s: ValueError: matmul"),
        ("shape", r"policy 'faulty' returned actions of shape \(6, 1\) in circle_crossing/invisible, "
                  r"episode\(s\) \[0, 1, 2, 3, 4, 5\] at t = 0 s; expected \(6, 2\)"),
        ("nan", r"policy 'faulty' returned non-finite actions \(NaN or inf\) in circle_crossing/invisible, "
                r"episode\(s\) \[5\] at t = 0 s"),
    ],
)
def test_a_failing_policy_is_named_with_the_episodes_it_acted_for(tmp_path, capsys, mode, message):
    code, _, err = evaluate(capsys, tmp_path, "--policy", f"{MODULE}:Faulty", "--policy-arg", f"mode={mode}",
                            "--scenario", "circle_crossing", "--visibility", "invisible")
    assert code == 2
    assert re.search(message, err), err


class DiesInWorkers(GoalSeeker):
    """Kills the worker process it is pickled into (as a crash or a policy module's top-level code would)."""

    def __init__(self):
        super().__init__()
        self.name = "dies_in_workers"
        self.parent = os.getpid()

    def act(self, observation):
        if os.getpid() != self.parent:
            os._exit(3)
        return super().act(observation)

    def describe(self):
        return {"policy": self.name, "information": self.information}


def test_a_worker_that_dies_is_explained_not_a_bare_broken_pool(tmp_path, capsys):
    # two chunks, so that they are simulated in worker processes
    code = main(["evaluate", "--preset", "wang2022", "--scenario", "circle_crossing", "random",
                 "--visibility", "invisible", "--episodes", "2", "--out", str(tmp_path), "--no-progress",
                 "--policy", f"{MODULE}:DiesInWorkers"])
    err = capsys.readouterr().err
    assert code == 2
    assert "an evaluation worker process died while running" in err
    assert 'if __name__ == "__main__":' in err and "rerun to resume" in err
    assert "terminated abruptly" not in err


POLICY_MODULE = '''
import numpy as np


class FileSeeker:
    """Goal seeker whose speed factor is read from a model file it declares."""

    information = "none"

    def __init__(self, model):
        self.name, self.model = "file_seeker", model
        self.factor = float(open(model).read())

    def act(self, observation):
        to_goal = observation.robot[:, 5:7] - observation.robot[:, 0:2]
        dist = np.maximum(np.linalg.norm(to_goal, axis=1, keepdims=True), 1e-9)
        return to_goal / dist * np.minimum(self.factor * observation.robot[:, 7:8], dist / observation.dt)

    def describe(self):
        return {"policy": self.name, "information": self.information, "model": self.model}

    def source_files(self):
        return [self.model]
'''


def test_a_changed_policy_module_or_model_file_is_never_silently_reused(tmp_path, monkeypatch):
    """Resuming is keyed on what the policy was built from: its module's source and declared files."""
    import importlib

    from socialnav.evaluate.runner import ResumeMismatchError, run_protocol
    from socialnav.presets import load_preset

    (tmp_path / "file_seeker_mod.py").write_text(POLICY_MODULE)
    model = tmp_path / "model.txt"
    model.write_text("0.8")
    monkeypatch.syspath_prepend(str(tmp_path))
    mod = importlib.import_module("file_seeker_mod")
    preset, out = load_preset("crowdnav"), tmp_path / "run"

    def run():
        return run_protocol(mod.FileSeeker(str(model)), preset, out, episodes=2, progress=False, workers=0)

    run()
    sources = json.loads((out / "manifest.json").read_text())["policy_sources"]
    assert set(sources) == {"module", str(model)}
    assert run().computed_episodes == 0  # unchanged: resumed, nothing recomputed
    model.write_text("0.5")
    with pytest.raises(ResumeMismatchError, match=rf"policy_sources.{re.escape(str(model))}"):
        run()
    model.write_text("0.8")
    (tmp_path / "file_seeker_mod.py").write_text(POLICY_MODULE + "\n# tuned\n")
    with pytest.raises(ResumeMismatchError, match="policy_sources.module: "):
        run()


class Forgetful(GoalSeeker):
    """Its describe() does not record its arguments (many users' policies don't)."""

    def describe(self):
        return {"policy": "forgetful"}


def test_a_module_policy_is_replayed_and_its_arguments_guard_a_resume(tmp_path, capsys):
    argv = ["evaluate", "--policy", f"{MODULE}:Forgetful", "--scenario", "passing", "--episodes", "2",
            "--out", str(tmp_path), "--quiet"]
    assert main([*argv, "--policy-arg", "speed_factor=0.5"]) == 0
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert manifest["policy_entry"] == f"{MODULE}:Forgetful"
    assert manifest["policy_args"] == {"speed_factor": 0.5}
    capsys.readouterr()
    assert main(["replay", str(tmp_path), "--episode", "passing/invisible/1"]) == 0
    assert "identical" in capsys.readouterr().out
    # the same policy with another argument is another run, although its describe() is the same
    assert main([*argv, "--policy-arg", "speed_factor=0.9"]) == 2
    assert "policy_args.speed_factor: 0.5 -> 0.9" in capsys.readouterr().err


@pytest.mark.parametrize(("arg", "message"), [
    ("safety_space=abc", "policy 'orca': safety_space must be a finite number, got 'abc'"),
    ("safety_space=.nan", "policy 'orca': safety_space must be a finite number, got nan"),
    ("threads=1.5", "policy 'orca': threads must be an integer >= 0, got 1.5"),
    # a policy of one's own: each value of its default's kind (GoalSeeker: float, str, bool)
    ("flag=1", ":GoalSeeker': flag must be true or false, got 1"),
    ("tag=3", ":GoalSeeker': tag must be text, got 3"),
])
def test_a_native_policys_parameter_of_the_wrong_type_is_named(tmp_path, capsys, arg, message):
    policy = "orca" if "orca" in message else f"{MODULE}:GoalSeeker"
    argv = ["evaluate", "--policy", policy, "--scenario", "passing", "--episodes", "2", "--out",
            str(tmp_path), "--quiet", "--policy-arg", arg]
    assert main(argv) == 2
    assert message in capsys.readouterr().err


class Telepath(GoalSeeker):
    """Claims an information setting the runner does not know."""

    information = "telepathy"


class Unrecordable(GoalSeeker):
    """Describes itself with a value no manifest can hold."""

    def describe(self):
        return {**super().describe(), "shaping": lambda d: d}


class NumpyDescribed(GoalSeeker):
    """Describes itself with numpy values (recorded as plain numbers and lists)."""

    def describe(self):
        return {**super().describe(), "gain": np.float32(0.5), "n": np.int64(3), "limits": np.array([1, 2])}


def test_a_policys_information_and_record_are_checked_before_the_run(tmp_path, capsys):
    code, _, err = evaluate(capsys, tmp_path / "t", "--policy", f"{MODULE}:Telepath")
    assert code == 2
    assert ("policy 'goal_seeker': information must be one of none, constant_velocity, oracle, learned, got "
            "'telepathy'") in err
    code, _, err = evaluate(capsys, tmp_path / "u", "--policy", f"{MODULE}:Unrecordable")
    assert code == 2
    assert "policy 'goal_seeker': describe()['shaping'] is a function" in err and "plain data" in err
    assert not (tmp_path / "t").exists() and not (tmp_path / "u").exists()  # refused before any file
    code, _, err = evaluate(capsys, tmp_path / "n", "--policy", f"{MODULE}:NumpyDescribed")
    assert code == 0, err
    policy = json.loads((tmp_path / "n" / "manifest.json").read_text())["policy"]
    assert (policy["gain"], policy["n"], policy["limits"]) == (0.5, 3, [1, 2])
    class NotANumber(GoalSeeker):
        def describe(self):
            return {**super().describe(), "gain": float("nan")}

    from socialnav.policies.registry import policy_record

    with pytest.raises(ValueError, match=r"describe\(\)\['gain'\] is nan; results record no NaN"):
        policy_record(NotANumber())
    episode = "circle_crossing/invisible/0"  # rebuilt from the record, and identical
    assert main(["replay", str(tmp_path / "n"), "--episode", episode, "--quiet"]) == 0


class Named(GoalSeeker):
    """Takes its name as a parameter (make_policy's and build_policy's own arguments are positional)."""

    def __init__(self, name: str = "named", speed_factor: float = 1.0):
        super().__init__(speed_factor)
        self.name = name


def test_a_policy_parameter_called_name(tmp_path, capsys):
    policy = make_policy(f"{MODULE}:Named", name="mine")
    assert policy.name == "mine"
    code, out, err = evaluate(capsys, tmp_path, "--policy", f"{MODULE}:Named", "--policy-arg", "name=ours")
    assert code == 0, err
    assert json.loads(out)["rows"][0]["policy"] == "ours"


class LidarSeeker(GoalSeeker):
    """A policy that brings a lidar and whose describe() names nothing (the manifest records both)."""

    sensors = {"lidar_beams": 8}

    def act(self, observation):
        assert observation.lidar is not None and observation.lidar.shape[1] == 8
        return super().act(observation)

    def describe(self):
        return {}


def test_a_module_policys_lidar_is_recorded_and_it_replays_without_a_name(tmp_path, capsys):
    argv = ["evaluate", "--policy", f"{MODULE}:LidarSeeker", "--scenario", "passing", "--episodes", "2",
            "--out", str(tmp_path), "--quiet"]
    assert main(argv) == 0
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert manifest["policy_sensors"] == {"lidar_beams": 8}
    assert "sensing" not in manifest["preset"]["world"]  # the preset's defaults, as given
    capsys.readouterr()
    assert main(["replay", str(tmp_path), "--episode", "passing/invisible/1"]) == 0
    assert "identical" in capsys.readouterr().out

"""``socialnav evaluate --policy sb3:PATH``: a model trained on the 5-human mix evaluated on the
single-human sweeps, the model's SHA-256 in the manifest (a changed file is refused on resume and by
replay), replay reproducing an episode, and models refused for another action space, kinematics or
observation setting (both sides named)."""

import hashlib
import json
from importlib import resources

import numpy as np
import pytest
import yaml

pytest.importorskip(
    "stable_baselines3", reason="stable-baselines3 is not installed (pip install 'socialnav[sb3]')"
)

from stable_baselines3 import PPO  # noqa: E402

from socialnav.cli import main  # noqa: E402
from socialnav.integrations.sb3 import SocialNavVecEnv, save_model  # noqa: E402
from socialnav.sim.learner_obs import ObservationSettings  # noqa: E402

FIVE = ObservationSettings(frame="robot", max_humans=5)
SINGLE = ["--scenario", "passing", "overtaking", "crossing", "--episodes", "3", "--no-progress"]
PASSING = ["--scenario", "passing", "--episodes", "2", "--no-progress"]


def train(path, steps=256, **env):
    """A briefly trained PPO model (its quality does not matter here)."""
    venv = SocialNavVecEnv(env.pop("env", "socialnav/CircleCrossing-v0"), 8, **env)
    model = PPO("MultiInputPolicy", venv, n_steps=32, batch_size=64, n_epochs=1, seed=0, device="cpu")
    model.learn(steps)
    venv.close()
    return save_model(model, path)


@pytest.fixture(scope="module")
def model5(tmp_path_factory):
    return train(tmp_path_factory.mktemp("sb3") / "ppo5.zip", preset="wang2022", observation=FIVE)


def evaluate(capsys, *argv):
    code = main(["evaluate", *argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_five_human_model_on_single_human_sweeps_then_replay(model5, tmp_path, capsys):
    out = tmp_path / "run"
    code, stdout, err = evaluate(capsys, "--policy", f"sb3:{model5}", "--out", str(out), "--json", *SINGLE)
    assert code == 0, err
    rows = json.loads(stdout)["rows"]
    assert {r["scenario"] for r in rows if r["scenario"] != "all"} >= {"passing", "overtaking", "crossing"}
    manifest = json.loads((out / "manifest.json").read_text())
    policy = manifest["policy"]
    assert policy["sha256"] == hashlib.sha256(model5.read_bytes()).hexdigest()
    assert policy["algorithm"] == "PPO" and policy["deterministic"] is True
    assert policy["observation"]["max_humans"] == 5 and policy["label"] == "sb3-ppo5"
    assert main(["replay", str(out), "--episode", "crossing/invisible/2"]) == 0
    assert "identical" in capsys.readouterr().out
    # the same run again is resumed: nothing is simulated twice
    code, stdout, err = evaluate(capsys, "--policy", f"sb3:{model5}", "--out", str(out), *SINGLE)
    assert code == 0 and "0 episodes simulated" in stdout


def test_a_changed_model_file_is_never_reused(tmp_path, capsys):
    path = train(tmp_path / "m.zip", preset="wang2022", observation=FIVE)
    out = tmp_path / "run"
    assert evaluate(capsys, "--policy", f"sb3:{path}", "--out", str(out), *PASSING)[0] == 0
    before = hashlib.sha256(path.read_bytes()).hexdigest()
    import torch

    model = PPO.load(path)
    with torch.no_grad():  # as if trained further: other weights, same settings
        for param in model.policy.parameters():
            param.add_(0.01)
    model.save(path)  # the record is kept (it is an attribute of the model)
    after = hashlib.sha256(path.read_bytes()).hexdigest()
    assert after != before
    code, _, err = evaluate(capsys, "--policy", f"sb3:{path}", "--out", str(out), *PASSING)
    assert code != 0 and "policy.sha256" in err and before[:20] in err
    code = main(["replay", str(out), "--episode", "passing/invisible/0"])
    err = capsys.readouterr().err
    assert code != 0 and "changed since the run" in err and before in err and after in err
    fresh = tmp_path / "fresh"
    assert evaluate(capsys, "--policy", f"sb3:{path}", "--out", str(fresh), *PASSING)[0] == 0
    assert json.loads((fresh / "manifest.json").read_text())["policy"]["sha256"] == after


def test_mismatched_action_space_kinematics_and_observation_are_refused(model5, tmp_path, capsys):
    slow = train(tmp_path / "slow.zip", preset="wang2022", scenario_params={"robot_v_pref": 0.5})
    code, _, err = evaluate(capsys, "--policy", f"sb3:{slow}", "--out", str(tmp_path / "a"), *PASSING)
    assert code != 0 and "action space Box[-0.5, 0.5]" in err and "Box[-1.5, 1.5]" in err
    assert "preset 'wang2022'" in err
    uni = train(tmp_path / "uni.zip", preset="wang2022", world={"kinematics": "unicycle"})
    code, _, err = evaluate(capsys, "--policy", f"sb3:{uni}", "--out", str(tmp_path / "b"), *PASSING)
    assert code != 0 and "kinematics 'unicycle' in the model file, 'holonomic' in preset 'wang2022'" in err
    code, _, err = evaluate(capsys, "--policy", f"sb3:{model5}", "--policy-arg", "max_humans=3", "--out",
                            str(tmp_path / "c"), *PASSING)
    assert code != 0 and "max_humans = 5 in the model file, 3 asked" in err
    code, _, err = evaluate(capsys, "--policy", f"sb3:{model5}", "--policy-arg", "algo=SAC", "--out",
                            str(tmp_path / "d"), *PASSING)
    assert code != 0 and "algorithm 'SAC' asked" in err and "'PPO' in the model file" in err
    code, _, err = evaluate(capsys, "--policy", f"sb3:{model5}", "--preset", "crowdnav", "--out",
                            str(tmp_path / "e"), "--episodes", "2", "--no-progress")
    assert code != 0 and "Box[-1.5, 1.5]" in err and "Box[-1, 1]" in err and "preset 'crowdnav'" in err
    assert not (tmp_path / "a").exists()  # refused before anything is written
    code, _, err = evaluate(capsys, "--policy", f"sb3:{tmp_path / 'none.zip'}", *PASSING)
    assert code != 0 and "none.zip does not exist" in err
    code, _, err = evaluate(capsys, "--policy", f"sb3:{model5.parent}", *PASSING)
    assert code != 0 and "is a directory; give the model's .zip file (it holds " in err
    assert model5.name in err


def test_discrete_and_unrecorded_models(tmp_path, capsys):
    disc = train(tmp_path / "disc.zip", preset="wang2022", action_set="discrete",
                 observation=ObservationSettings(max_humans=5))
    code, _, err = evaluate(capsys, "--policy", f"sb3:{disc}", "--out", str(tmp_path / "disc"), *PASSING)
    assert code == 0, err
    # plain model.save on the raw env (no socialnav record): accepted with its algorithm named, since
    # the raw layout's conversion is known
    import gymnasium as gym
    from stable_baselines3.common.vec_env import DummyVecEnv

    raw = DummyVecEnv([lambda: gym.make("socialnav/CircleCrossing-v0", preset="wang2022")])
    PPO("MultiInputPolicy", raw, n_steps=16, batch_size=16, n_epochs=1, device="cpu").learn(16).save(
        tmp_path / "plain.zip"
    )
    plain = f"sb3:{tmp_path / 'plain.zip'}"
    code, _, err = evaluate(capsys, "--policy", plain, "--out", str(tmp_path / "p1"), *PASSING)
    assert code != 0 and "--policy-arg algo=PPO" in err
    code, _, err = evaluate(capsys, "--policy", plain, "--policy-arg", "algo=SAC", "--out",
                            str(tmp_path / "p0"), *PASSING)
    assert code != 0 and "plain.zip: cannot be loaded as SAC" in err
    code, stdout, err = evaluate(capsys, "--policy", plain, "--policy-arg", "algo=PPO", "--out",
                                 str(tmp_path / "p2"), "--json", *PASSING)
    assert code == 0, err
    policy = json.loads((tmp_path / "p2" / "manifest.json").read_text())["policy"]
    assert policy["record"] == "inferred" and policy["observation"]["dtype"] == "float64"
    assert policy["observation"]["max_humans"] == 5  # the raw 5-human layout, padded on passing
    assert all(np.isfinite(r["success_rate"]) for r in json.loads(stdout)["rows"])
    # plain model.save on the adapter (the learner's float32 layout): refused, saying what the raw one is
    venv = SocialNavVecEnv("socialnav/CircleCrossing-v0", 2, preset="wang2022")
    PPO("MultiInputPolicy", venv, n_steps=16, batch_size=16, n_epochs=1, device="cpu").learn(16).save(
        tmp_path / "adapter.zip"
    )
    venv.close()
    code, _, err = evaluate(capsys, "--policy", f"sb3:{tmp_path / 'adapter.zip'}", "--policy-arg", "algo=PPO",
                            "--out", str(tmp_path / "p3"), *PASSING)
    assert code != 0
    assert "not the raw env's (float64, world frame, SI units: {human_mask: MultiBinary(5)" in err
    assert "must be saved with socialnav.integrations.sb3.save_model, which records the conversion" in err


def test_a_model_blind_to_walls_is_refused_among_walls_unless_allowed(tmp_path, capsys):
    # trained on an open floor without obstacle points, at francis2023's robot (v_pref 1 m/s, holonomic)
    model5 = train(tmp_path / "open.zip", preset="crowdnav", observation=FIVE)
    walls = ["--preset", "francis2023", "--scenario", "narrow_hallway", "--episodes", "2", "--no-progress",
             "--visibility", "invisible"]
    code, _, err = evaluate(capsys, "--policy", f"sb3:{model5}", "--out", str(tmp_path / "refused"), *walls)
    assert code != 0
    assert ("walls: the model's observation has no obstacle points (obstacle_points = 0) nor a lidar, preset "
            "'francis2023' evaluates scenarios with walls (") in err and "narrow_hallway" in err
    assert "--allow-preset-mismatch" in err
    out = tmp_path / "allowed"
    code, _, err = evaluate(capsys, "--policy", f"sb3:{model5}", "--out", str(out), "--allow-preset-mismatch",
                            *walls)
    assert code == 0, err
    recorded = json.dumps(json.loads((out / "manifest.json").read_text()))
    assert "obstacle_points = 0" in recorded  # the mismatch is recorded in the results


LIDAR = ObservationSettings(frame="robot", max_humans=5, parts=("robot", "humans", "lidar"))


def test_a_lidar_model_brings_its_lidar_and_refuses_another(tmp_path, capsys):
    # docs/perception.md: a saved model records its sensing; sb3:PATH evaluates it with the same lidar
    model = train(tmp_path / "lidar.zip", preset="crowdnav", observation=LIDAR,
                  world={"sensing": {"lidar_beams": 12, "lidar_range": 5.0}})
    out = tmp_path / "brought"
    code, _, err = evaluate(capsys, "--policy", f"sb3:{model}", "--preset", "crowdnav", "--out", str(out),
                            *PASSING)
    assert code == 0, err
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["policy"]["sensors"] == {"lidar_beams": 12, "lidar_fov": 2 * np.pi, "lidar_range": 5.0}
    # a lidar sees the walls: a walled preset is no mismatch for it
    code, _, err = evaluate(capsys, "--policy", f"sb3:{model}", "--preset", "francis2023", "--scenario",
                            "narrow_hallway", "--episodes", "1", "--visibility", "invisible", "--no-progress",
                            "--out", str(tmp_path / "walls"))
    assert code == 0, err
    data = yaml.safe_load((resources.files("socialnav.configs") / "crowdnav.yaml").read_text())
    data["name"] = "lidar24"
    data["world"]["sensing"] = {"lidar_beams": 24}
    other = tmp_path / "lidar24.yaml"
    other.write_text(yaml.safe_dump(data))
    code, _, err = evaluate(capsys, "--policy", f"sb3:{model}", "--preset", str(other), "--out",
                            str(tmp_path / "refused"), *PASSING)
    assert code != 0
    assert ("lidar.zip under preset 'lidar24': the policy brings a lidar the world already has in another "
            "form: lidar_beams 24 (world) vs 12, lidar_range 10.0 (world) vs 5.0 (the model file's)") in err

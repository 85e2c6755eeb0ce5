"""Issue #47, a model file cannot run code: ``sb3:PATH`` models are loaded without unpickling any field of
the zip. A field whose pickle names an object no SB3 model holds refuses the model (its opcodes read, never
run), and so does one in a field socialnav cannot rebuild, also in a worker's copy of the policy and through
``socialnav evaluate``; a legitimate model still predicts exactly as SB3's own load of it; a record that is
not a dict and a device this machine lacks are refused by name; and a pickled ``--checkpoint`` is refused
without running it."""

import base64
import json
import pickle
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from socialnav.cli import main


class Payload:
    """Unpickling it creates ``marker`` (``open(marker, "w")``): the file's code has run."""

    def __init__(self, marker: Path):
        self.marker = str(marker)

    def __reduce__(self):
        return (open, (self.marker, "w"))


def payload(marker: Path) -> str:
    """A ``:serialized:`` value as SB3 writes one (base64 of a pickle) whose unpickling creates marker."""
    return base64.b64encode(pickle.dumps(Payload(marker))).decode()


def rewrite(source: Path, target: Path, change) -> Path:
    """``source``'s zip with its ``data`` JSON passed through ``change(data)`` (in place), as ``target``."""
    with zipfile.ZipFile(source) as archive:
        members = {name: archive.read(name) for name in archive.namelist()}
    data = json.loads(members["data"])
    change(data)
    members["data"] = json.dumps(data, indent=4).encode()
    with zipfile.ZipFile(target, "w") as archive:
        for name, content in members.items():
            archive.writestr(name, content)
    return target


def poisoned(source: Path, target: Path, field: str, marker: Path) -> Path:
    """``source`` with the pickle of ``field`` replaced by a payload (its readable parts kept)."""

    def change(data):
        assert ":serialized:" in data[field], f"{field} is not pickled in the model file"
        data[field][":serialized:"] = payload(marker)

    return rewrite(source, target, change)


@pytest.fixture(scope="module")
def sb3():
    return pytest.importorskip(
        "stable_baselines3", reason="stable-baselines3 is not installed (pip install 'socialnav[sb3]')"
    )


@pytest.fixture(scope="module")
def preset():
    from socialnav.presets import load_preset

    return load_preset("wang2022")


@pytest.fixture(scope="module")
def model(sb3, tmp_path_factory):
    """A briefly trained PPO saved by socialnav.integrations.sb3.save_model (its quality does not matter)."""
    from socialnav.integrations.sb3 import SocialNavVecEnv, save_model
    from socialnav.sim.learner_obs import ObservationSettings

    venv = SocialNavVecEnv("socialnav/CircleCrossing-v0", 8, preset="wang2022",
                           observation=ObservationSettings(frame="robot", max_humans=5))
    ppo = sb3.PPO("MultiInputPolicy", venv, n_steps=8, batch_size=64, n_epochs=1, seed=0, device="cpu")
    ppo.learn(64)
    venv.close()
    return save_model(ppo, tmp_path_factory.mktemp("sb3") / "ppo.zip")


def observations(space, n=16):
    space.seed(0)
    return [space.sample() for _ in range(n)]


def same_predictions(a, b, space) -> bool:
    return all(
        np.array_equal(a.predict(obs, deterministic=True)[0], b.predict(obs, deterministic=True)[0])
        for obs in observations(space)
    )


def load(path, preset, **kwargs):
    from socialnav.integrations.sb3_policy import load_sb3_policy

    return load_sb3_policy(f"sb3:{path}", preset, **kwargs)


REBUILT = ["lr_schedule", "clip_range", "policy_class", "observation_space", "action_space", "_last_obs",
           "_last_episode_starts", "ep_info_buffer", "ep_success_buffer", "rollout_buffer_class"]


@pytest.mark.parametrize("field", REBUILT)
def test_a_payload_in_any_pickled_field_refuses_the_model_without_running_it(field, model, preset, tmp_path):
    """The payload's pickle names io.open (builtins.open), which no SB3 model holds: the file is refused,
    naming the field and the object, after its opcodes were read and nothing was run."""
    from socialnav.integrations.sb3_policy import SB3ModelError

    marker = tmp_path / "ran"
    evil = poisoned(model, tmp_path / "evil.zip", field, marker)
    refusal = rf"evil\.zip: field {field} of the model file names io\.open"
    with pytest.raises(SB3ModelError, match=refusal):
        load(evil, preset)
    assert not marker.exists()


@pytest.mark.parametrize("algorithm", ["PPO", "A2C", "SAC", "TD3", "DDPG", "DQN"])
def test_every_pickled_field_of_a_legitimate_model_passes_the_scan(algorithm, preset, tmp_path, sb3):
    """What SB3 2.9 pickles for each algorithm (classes, schedules, buffers, spaces, generators) names only
    objects the scan allows, so a model saved by socialnav is never refused for it."""
    from socialnav.integrations.sb3 import SocialNavVecEnv, save_model
    from socialnav.integrations.sb3_files import read_saved_data
    from socialnav.sim.learner_obs import ObservationSettings

    discrete = algorithm == "DQN"
    observation = ObservationSettings(frame="world" if discrete else "robot", max_humans=5)
    venv = SocialNavVecEnv("socialnav/CircleCrossing-v0", 2, preset="wang2022",
                           action_set="discrete" if discrete else "continuous", observation=observation)
    options = {"PPO": {"n_steps": 8, "batch_size": 8, "n_epochs": 1}, "A2C": {"n_steps": 4}}.get(
        algorithm, {"learning_starts": 0, "buffer_size": 100})
    learner = getattr(sb3, algorithm)("MultiInputPolicy", venv, seed=0, device="cpu", **options)
    learner.learn(16)
    path = save_model(learner, tmp_path / f"{algorithm}.zip")
    venv.close()
    read_saved_data(path, path.read_bytes())  # raises for a field the scan refuses
    assert load(path, preset).model.__class__.__name__ == algorithm


def test_a_pickled_field_socialnav_cannot_rebuild_refuses_the_model_first(model, preset, tmp_path):
    from socialnav.integrations.sb3_policy import SB3ModelError

    marker = tmp_path / "ran"

    # pickles the scan lets through (a number, a plain dict): refused by the rebuild, by name
    harmless = base64.b64encode(pickle.dumps(42)).decode()

    def extra(data):
        data["backdoor"] = {":type:": "<class 'object'>", ":serialized:": harmless}

    def custom_kwargs(data):
        data["policy_kwargs"] = {":type:": "<class 'dict'>", ":serialized:": harmless,
                                 "activation_fn": "<class 'evil.Activation'>"}

    with pytest.raises(SB3ModelError, match=r"x\.zip: field backdoor of the model file is a pickled"):
        load(rewrite(model, tmp_path / "x.zip", extra), preset)
    with pytest.raises(SB3ModelError, match=r"y\.zip: field policy_kwargs .* activation_fn = \"<class 'evil"):
        load(rewrite(model, tmp_path / "y.zip", custom_kwargs), preset)
    assert not marker.exists()


def test_a_workers_copy_of_the_policy_never_unpickles_the_file(model, preset, tmp_path, sb3):
    from socialnav.integrations.sb3_policy import SB3ModelError

    policy = load(model, preset)
    marker = tmp_path / "ran"
    copy = pickle.loads(pickle.dumps(policy))
    assert same_predictions(copy.model, sb3.PPO.load(model, device="cpu"), copy.model.observation_space)
    # the bytes a worker loads from are the policy's own: here, a poisoned copy of the same model
    policy._data = poisoned(model, tmp_path / "evil.zip", "lr_schedule", marker).read_bytes()
    with pytest.raises(SB3ModelError, match="lr_schedule of the model file names io.open"):
        pickle.loads(pickle.dumps(policy))
    assert not marker.exists()

    def extra(data):
        data["backdoor"] = {":type:": "<class 'object'>", ":serialized:": payload(marker)}

    policy._data = rewrite(model, tmp_path / "x.zip", extra).read_bytes()
    with pytest.raises(SB3ModelError, match="backdoor"):
        pickle.loads(pickle.dumps(policy))
    assert not marker.exists()


PASSING = ["--preset", "wang2022", "--scenario", "passing", "--episodes", "1", "--no-progress"]


def test_socialnav_evaluate_never_runs_a_model_files_code(model, tmp_path, capsys):
    marker = tmp_path / "ran"

    def extra(data):
        data["backdoor"] = {":type:": "<class 'object'>", ":serialized:": payload(marker)}

    refused = rewrite(model, tmp_path / "refused.zip", extra)
    out = tmp_path / "out"
    code = main(["evaluate", "--policy", f"sb3:{refused}", "--out", str(out), *PASSING])
    err = capsys.readouterr().err
    assert code != 0 and len(err.strip().splitlines()) == 1, err
    assert "refused.zip: field backdoor" in err
    assert not marker.exists() and not out.exists()
    # a payload in a field socialnav would rebuild: refused all the same, in one line, nothing written
    evil = poisoned(model, tmp_path / "evil.zip", "clip_range", marker)
    code = main(["evaluate", "--policy", f"sb3:{evil}", "--out", str(tmp_path / "run"), *PASSING])
    err = capsys.readouterr().err
    assert code != 0 and len(err.strip().splitlines()) == 1, err
    assert "evil.zip: field clip_range of the model file names io.open" in err
    assert not marker.exists() and not (tmp_path / "run").exists()


def test_a_legitimate_model_predicts_exactly_as_sb3s_own_load(model, preset, sb3):
    policy = load(model, preset)
    trusted = sb3.PPO.load(model, device="cpu")  # SB3's plain load, of a file this test wrote itself
    assert type(policy.model.policy) is type(trusted.policy)
    mine, theirs = policy.model.policy.state_dict(), trusted.policy.state_dict()
    assert mine.keys() == theirs.keys() and all(np.array_equal(mine[k], theirs[k]) for k in mine)
    assert same_predictions(policy.model, trusted, trusted.observation_space)
    assert policy.describe()["record"] == "saved"


def test_a_model_saved_without_a_record_loads_with_its_algorithm_named(preset, tmp_path, sb3):
    import gymnasium as gym
    from stable_baselines3.common.vec_env import DummyVecEnv

    raw = DummyVecEnv([lambda: gym.make("socialnav/CircleCrossing-v0", preset="wang2022")])
    sb3.PPO("MultiInputPolicy", raw, n_steps=16, batch_size=16, n_epochs=1, device="cpu").learn(16).save(
        tmp_path / "plain.zip"
    )
    policy = load(tmp_path / "plain.zip", preset, algo="PPO")
    described = policy.describe()
    assert described["record"] == "inferred" and described["observation"]["max_humans"] == 5
    assert described["observation"]["dtype"] == "float64"
    trusted = sb3.PPO.load(tmp_path / "plain.zip", device="cpu")
    assert same_predictions(policy.model, trusted, trusted.observation_space)
    marker = tmp_path / "ran"
    evil = poisoned(tmp_path / "plain.zip", tmp_path / "evil.zip", "observation_space", marker)
    with pytest.raises(ValueError, match="field observation_space of the model file names io.open"):
        load(evil, preset, algo="PPO")
    assert not marker.exists()


def test_a_record_that_is_not_a_dict_is_named(model, preset, tmp_path):
    from socialnav.integrations.sb3_policy import SB3ModelError

    def as_string(data):
        data["socialnav_record"] = "trust me"

    with pytest.raises(SB3ModelError, match=r"odd\.zip: field socialnav_record of the model file is a str"):
        load(rewrite(model, tmp_path / "odd.zip", as_string), preset)


def test_a_record_that_contradicts_the_files_spaces_is_refused(model, preset, tmp_path):
    from socialnav.integrations.sb3_policy import SB3ModelError

    def slower(data):
        data["socialnav_record"]["robot_v_pref"] = 0.5

    with pytest.raises(SB3ModelError, match="field action_space of the model file, Box.*socialnav record"):
        load(rewrite(model, tmp_path / "lies.zip", slower), preset)


def test_a_device_this_machine_lacks_is_refused(model, preset, tmp_path, capsys):
    import torch

    if torch.cuda.is_available():
        pytest.skip("this machine has CUDA")
    from socialnav.integrations.sb3_policy import SB3ModelError

    with pytest.raises(SB3ModelError, match=r"--policy-arg device=cuda, but this machine has no cuda device"):
        load(model, preset, device="cuda")
    out = tmp_path / "out"
    code = main(["evaluate", "--policy", f"sb3:{model}", "--policy-arg", "device=cuda", "--out", str(out),
                 *PASSING])
    err = capsys.readouterr().err
    assert code != 0 and "device=cuda" in err and len(err.strip().splitlines()) == 1, err
    assert not out.exists()


@pytest.mark.parametrize("kind", ["torch.save", "pickle"])
def test_a_pickled_checkpoint_is_refused_without_running_it(kind, tmp_path):
    torch = pytest.importorskip("torch")
    marker = tmp_path / "ran"
    evil = tmp_path / "evil.pt"
    if kind == "torch.save":
        torch.save({"format": 1, "state_dict": Payload(marker)}, evil)
    else:
        evil.write_bytes(pickle.dumps(Payload(marker)))
    out = tmp_path / "out"
    result = subprocess.run(
        [sys.executable, "-m", "socialnav", "evaluate", "--policy", "sarl", "--checkpoint", str(evil),
         "--preset", "wang2022", "--episodes", "1", "--out", str(out)],
        capture_output=True, text=True, timeout=300,
    )
    assert result.returncode != 0
    assert len(result.stderr.strip().splitlines()) == 1 and "evil.pt" in result.stderr, result.stderr
    assert not marker.exists()
    assert not out.exists() or not any(out.iterdir())

"""The SB3 VecEnv adapter against SB3's contract: SB3's env checker on the wrapped single env, the same
rollouts as SB3's own DummyVecEnv (auto-reset, terminal observations, truncation), seeds that reproduce
a rollout, the attribute methods, and a short PPO run that learns a trivial task."""

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip(
    "stable_baselines3", reason="stable-baselines3 is not installed (pip install 'socialnav[sb3]')"
)

from stable_baselines3 import PPO  # noqa: E402
from stable_baselines3.common.env_checker import check_env  # noqa: E402
from stable_baselines3.common.vec_env import DummyVecEnv, VecMonitor  # noqa: E402

import socialnav  # noqa: E402,F401
from socialnav.envs.learner_wrappers import LearnerObservation  # noqa: E402
from socialnav.integrations.sb3 import SocialNavVecEnv, find_training_record  # noqa: E402
from socialnav.sim.learner_obs import ObservationSettings  # noqa: E402

SHORT = {"scenario_params": {"n_humans": 3}, "world": {"time_limit": 4.0}}


@pytest.mark.parametrize("frame", ["world", "robot"])
def test_sb3_env_checker_accepts_the_wrapped_single_env(frame):
    env = LearnerObservation(gym.make("socialnav/CircleCrossing-v0"), ObservationSettings(frame=frame))
    check_env(env, warn=True)


def test_adapter_steps_exactly_like_sb3s_dummy_vec_env():
    settings = ObservationSettings(frame="robot", max_humans=4)
    adapter = SocialNavVecEnv("socialnav/CircleCrossing-v0", 1, observation=settings, **SHORT)
    dummy = DummyVecEnv(
        [lambda: LearnerObservation(gym.make("socialnav/CircleCrossing-v0", **SHORT), settings)]
    )
    assert adapter.observation_space == dummy.observation_space and adapter.action_space == dummy.action_space
    adapter.seed(11), dummy.seed(11)
    a, d = adapter.reset(), dummy.reset()
    rng = np.random.default_rng(0)
    outcomes = []
    for _ in range(120):
        action = rng.uniform(-1.0, 1.0, size=(1, 2))
        a, ar, adone, ainfo = adapter.step(action)
        d, dr, ddone, dinfo = dummy.step(action)
        for key in a:
            np.testing.assert_array_equal(a[key], d[key])
        np.testing.assert_array_equal(ar, dr)
        np.testing.assert_array_equal(adone, ddone)
        if adone[0]:
            outcome = ainfo[0]["outcome"]
            outcomes.append(outcome)
            for key in a:
                np.testing.assert_array_equal(ainfo[0]["terminal_observation"][key],
                                              dinfo[0]["terminal_observation"][key])
            truncated = ainfo[0]["TimeLimit.truncated"]
            assert truncated is dinfo[0]["TimeLimit.truncated"] is (outcome == "timeout")
            assert ainfo[0]["is_success"] == (outcome == "success")
            assert ainfo[0]["episode_index"] == dinfo[0]["episode_index"]
            # the returned observation is the next episode's first
            assert not np.array_equal(a["robot"], ainfo[0]["terminal_observation"]["robot"][None])
    assert "timeout" in outcomes and len(outcomes) >= 5  # truncations seen, several auto-resets
    adapter.close(), dummy.close()


def rollout(venv, steps=60):
    rng = np.random.default_rng(1)
    out = [venv.reset()["humans"].copy()]  # (the robot starts alike in every circle crossing)
    for _ in range(steps):
        obs, reward, done, infos = venv.step(rng.uniform(-1, 1, size=(venv.num_envs, 2)))
        out += [obs["humans"].copy(), reward.copy(), done.copy()]
        out += [i["terminal_observation"]["humans"] for i in infos if "terminal_observation" in i]
    return out


def test_a_seed_reproduces_a_rollout_and_reset_continues_the_stream():
    venvs = [SocialNavVecEnv("socialnav/CircleCrossing-v0", 8, **SHORT) for _ in range(3)]
    venvs[0].seed(5), venvs[1].seed(5), venvs[2].seed(6)
    first, same, other = (rollout(v) for v in venvs)
    assert all(np.array_equal(x, y) for x, y in zip(first, same, strict=True))
    assert not np.array_equal(first[0], other[0])
    # reset() without a new seed continues the stream: no episode is played twice
    seen = set()
    for _ in range(3):
        venvs[0].reset()
        indices = [info["episode_index"] for info in venvs[0].reset_infos]
        assert not seen & set(indices)
        seen |= set(indices)
    for v in venvs:
        v.close()


def test_attribute_methods():
    venv = SocialNavVecEnv("passing", 4, observation=ObservationSettings(max_humans=5))
    assert venv.get_attr("render_mode") == [None] * 4
    assert venv.get_attr("num_envs", indices=[0, 2]) == [4, 4]
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        venv.get_attr("nope")
    with pytest.raises(NotImplementedError, match="share one native world"):
        venv.set_attr("render_mode", "rgb_array")
    with pytest.raises(NotImplementedError, match="rows of one native world"):
        venv.env_method("reset")
    record = venv.env_method("training_record", indices=[1])[0]
    assert record["observation"]["max_humans"] == 5 and record["scenario"] == "passing"
    assert venv.env_is_wrapped(gym.Wrapper) == [False] * 4
    assert find_training_record(VecMonitor(venv)) == record
    dummy = DummyVecEnv(
        [lambda: LearnerObservation(gym.make("socialnav/Passing-v0"), ObservationSettings(max_humans=5))]
    )
    assert find_training_record(dummy) == record
    with pytest.raises(ValueError, match="unknown env id"):
        SocialNavVecEnv("socialnav/Nope-v0", 2)
    venv.close()


def test_ppo_learns_to_reach_a_goal_without_humans():
    """Sparse CrowdSim reward, goal 1.5 m away, robot frame: 20k env-steps (a few seconds) reach a
    success rate >= 0.9 on 50 test episodes (100 % for each of 8 seeds tried when this was written)."""
    import torch

    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # small networks: one thread is fastest, and immune to other load
    try:
        success = _train_and_test_reaching()
    finally:
        torch.set_num_threads(threads)
    assert success >= 0.9


def _train_and_test_reaching() -> float:
    task = {"scenario_params": {"n_humans": 0, "circle_radius": 0.75}, "world": {"time_limit": 10.0},
            "observation": ObservationSettings(frame="robot")}
    venv = SocialNavVecEnv("circle_crossing", 32, **task)
    model = PPO("MultiInputPolicy", venv, n_steps=32, batch_size=256, n_epochs=10, learning_rate=1e-3,
                gamma=0.9, seed=0, device="cpu")
    model.learn(32 * 32 * 20)
    test = SocialNavVecEnv("circle_crossing", 50, split="test", **task)
    test.seed(123)
    obs, outcomes = test.reset(), {}
    for _ in range(45):
        action, _ = model.predict(obs, deterministic=True)
        obs, _, done, infos = test.step(action)
        for b in np.flatnonzero(done):
            outcomes.setdefault(b, infos[b]["outcome"])
    assert len(outcomes) == 50
    venv.close(), test.close()
    return sum(o == "success" for o in outcomes.values()) / 50


def test_wrong_number_of_actions_and_dict_observation_settings():
    venv = SocialNavVecEnv("circle_crossing", 4, observation={"frame": "robot", "max_humans": 5})
    assert venv.transform.settings.max_humans == 5
    venv.reset()
    with pytest.raises(ValueError, match=r"actions of shape \(3, 2\): expected \(4, 2\) \(one action of the "
                       r"action space per env, 4 envs\)"):
        venv.step(np.zeros((3, 2)))
    with pytest.raises(Exception, match="no_such_field"):
        SocialNavVecEnv("circle_crossing", 2, observation={"no_such_field": 1})

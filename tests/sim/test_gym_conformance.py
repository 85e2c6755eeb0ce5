"""Gymnasium's public API over the socialnav envs: finite scenarios, distinct streams per copy of
``gym.make_vec``, terminal-step info, registration and the env checker on every id."""

import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import socialnav  # noqa: F401  (registers the ids)
from socialnav.envs.episode_order import SEED_STRIDE, EpisodeOrder
from socialnav.envs.registration import ENV_IDS

STRAIGHT = np.array([0.0, 1.0])


def run_episode(env, action=STRAIGHT, limit=1000):
    steps = 0
    for _ in range(limit):
        obs, reward, terminated, truncated, info = env.step(action)
        steps += 1
        if terminated or truncated:
            return obs, reward, steps, info
    raise AssertionError("episode did not end")


# -- item 2: finite scenarios cycle --------------------------------------------------------------
@pytest.mark.parametrize("make", [
    lambda: gym.make("socialnav/CircleCrossing-v0", scenario="passing"),
    lambda: gym.make("socialnav/Passing-v0"),
])
def test_single_env_cycles_through_a_finite_scenario(make):
    env = make()
    seen = []
    _, info = env.reset(seed=3)
    seen.append(info["episode_index"])
    for _ in range(44):
        start, info = env.reset()
        seen.append(info["episode_index"])
    # Each round of 20 resets plays every episode once (a seeded order), then a new round starts.
    assert sorted(seen[:20]) == list(range(20)) and sorted(seen[20:40]) == list(range(20))
    assert seen[:20] != seen[20:40]
    # The 45th episode is a real one: the robot moves and the episode ends with an outcome.
    obs, _, _, _, info = env.step(STRAIGHT)
    assert info["outcome"] == "running" and info["time"] == pytest.approx(0.25)
    assert not np.array_equal(obs["robot"][:2], start["robot"][:2])
    _, _, steps, info = run_episode(env)
    assert info["outcome"] in ("success", "collision", "timeout") and info["episode_index"] == seen[-1]


def test_single_env_refuses_an_index_outside_a_finite_scenario_and_steps_after_the_end():
    env = gym.make("socialnav/Passing-v0")
    with pytest.raises(ValueError, match=r"episode index must be in 0\.\.19, got 20"):
        env.reset(options={"index": 20})
    with pytest.raises(ValueError, match="unknown reset option"):
        env.reset(options={"episode": 2})
    raw = env.unwrapped
    raw.reset(options={"index": 19})
    run_episode(raw)
    with pytest.raises(RuntimeError, match="call reset"):
        raw.step(STRAIGHT)


def test_native_vector_env_never_idles_a_slot_on_a_finite_scenario():
    venv = gym.make_vec("socialnav/Passing-v0", num_envs=8, vectorization_mode="vector_entry_point",
                        world={"human_model": "linear"})
    _, info = venv.reset(seed=0)
    assert sorted(info["episode_index"]) == sorted(set(info["episode_index"]))
    finished = []
    for _ in range(600):
        _, _, term, trunc, info = venv.step(np.tile(STRAIGHT, (8, 1)))
        assert np.all(info["episode_index"] >= 0) and np.all(info["episode_index"] < 20)
        if "final_info" in info:
            finished.extend(info["final_info"]["episode_index"][info["_final_info"]])
    assert len(finished) > 40  # more than two rounds of the 20 episodes, every slot busy
    first_round = finished[:12]  # 8 at reset + the first 12 refills = one permutation of 20
    assert len(set(first_round)) == len(first_round)


def test_episode_order_seeded_streams_are_disjoint_and_cycles_are_permutations():
    a, b = EpisodeOrder(None, seed=0), EpisodeOrder(None, seed=1)
    pos = np.arange(1000)
    assert not set(a(pos)) & set(b(pos))
    np.testing.assert_array_equal(b(pos), SEED_STRIDE + pos)
    test_split = EpisodeOrder(1000, seed=4)
    out = test_split(np.arange(3000))
    for k in range(3):
        assert sorted(out[1000 * k : 1000 * (k + 1)]) == list(range(1000))
    np.testing.assert_array_equal(EpisodeOrder(20, start=18)(np.arange(4)), [18, 19, 0, 1])
    big = EpisodeOrder(None, seed=2**64 + 5)(np.arange(2))
    assert 0 <= big[0] < 2**32 * SEED_STRIDE


# -- item 3: every copy of gym.make_vec gets its own stream ---------------------------------------
def _episodes_per_copy(venv, n, seed, steps=260):
    _, info = venv.reset(seed=seed)
    per_copy = [[int(i)] for i in info["episode_index"]]
    for _ in range(steps):
        _, _, _, _, info = venv.step(np.tile(STRAIGHT, (n, 1)))
        if "final_info" in info:
            for b in np.flatnonzero(info["_final_info"]):
                per_copy[b].append(int(info["episode_index"][b]))  # the slot's new episode
    return per_copy


@pytest.mark.parametrize("mode", ["sync", "vector_entry_point"])
@pytest.mark.parametrize("seed", [None, 0])
def test_make_vec_copies_play_distinct_episodes(mode, seed):
    n = 4
    kwargs = {"autoreset_mode": gym.vector.AutoresetMode.SAME_STEP} if mode == "sync" else {}
    venv = gym.make_vec("socialnav/CircleCrossing-v0", num_envs=n, vectorization_mode=mode,
                        vector_kwargs=kwargs, world={"human_model": "linear"})
    per_copy = _episodes_per_copy(venv, n, seed)
    every = [i for episodes in per_copy for i in episodes]
    assert sum(len(e) > 1 for e in per_copy) >= 2  # episodes did end and restart
    assert len(every) == len(set(every)), per_copy  # no episode played twice, by any copy
    venv.close()


def test_make_vec_async_copies_start_on_distinct_episodes():
    venv = gym.make_vec("socialnav/CircleCrossing-v0", num_envs=3, vectorization_mode="async")
    try:
        _, info = venv.reset()
        assert len(set(info["episode_index"])) == 3
        _, info = venv.reset(seed=0)
        assert set(info["episode_index"]) == {0, SEED_STRIDE, 2 * SEED_STRIDE}
    finally:
        venv.close()


def test_seeded_single_env_is_reproducible_and_index_replays_an_episode():
    env = gym.make("socialnav/Random-v0")
    first, info = env.reset(seed=42)
    again, info2 = env.reset(seed=42)
    np.testing.assert_array_equal(first["humans"], again["humans"])
    replay, info3 = env.reset(options={"index": info["episode_index"]})
    np.testing.assert_array_equal(first["humans"], replay["humans"])
    assert info["episode_index"] == info2["episode_index"] == info3["episode_index"]


# -- item 4: terminal-step info ------------------------------------------------------------------
def test_single_env_terminal_info_describes_the_finished_episode():
    env = gym.make("socialnav/Passing-v0", world={"human_model": "linear"})
    _, start = env.reset(options={"index": 19})  # far offset: a straight robot succeeds
    _, reward, steps, info = run_episode(env)
    assert info["outcome"] == "success" and reward == pytest.approx(1.0)
    assert info["time"] == pytest.approx(steps * 0.25) and info["time"] > 0
    assert info["episode_index"] == start["episode_index"] == 19
    assert np.isfinite(info["dmin"]) and info["dmin"] > 0


def test_vector_env_info_has_outcome_and_final_info_like_sync_make_vec():
    n = 4
    native = gym.make_vec("socialnav/CircleCrossing-v0", num_envs=n, vectorization_mode="vector_entry_point",
                          world={"human_model": "linear"})
    sync = gym.make_vec("socialnav/CircleCrossing-v0", num_envs=n, vectorization_mode="sync",
                        vector_kwargs={"autoreset_mode": gym.vector.AutoresetMode.SAME_STEP},
                        world={"human_model": "linear"})
    infos = {}
    for name, venv in (("native", native), ("sync", sync)):
        _, info = venv.reset(seed=0)
        assert list(info["outcome"]) == ["running"] * n and info["_outcome"].all()
        steps = np.zeros(n, dtype=int)
        for _ in range(300):
            _, _, term, trunc, info = venv.step(np.tile(STRAIGHT, (n, 1)))
            steps += 1
            if "final_info" in info:
                done = term | trunc
                fin = info["final_info"]
                np.testing.assert_array_equal(info["_final_info"], done)
                np.testing.assert_array_equal(fin["_outcome"], done)
                for b in np.flatnonzero(done):
                    assert fin["outcome"][b] in ("success", "collision", "timeout")
                    assert fin["time"][b] == pytest.approx(steps[b] * 0.25)
                    assert info["outcome"][b] == "running" and info["time"][b] == 0.0
                steps[done] = 0
                infos[name] = info
                break
    native_info, sync_info = infos["native"], infos["sync"]
    assert set(native_info) == set(sync_info)
    assert set(native_info["final_info"]) == set(sync_info["final_info"])
    for key in ("outcome", "dmin", "time", "episode_index"):
        assert native_info["final_info"][key].dtype.kind == sync_info["final_info"][key].dtype.kind, key
        assert native_info[key].dtype.kind == sync_info[key].dtype.kind, key


# -- item 5: registration, ids, preset keyword, env checker ------------------------------------
@pytest.mark.parametrize(
    "code",
    [
        "import socialnav, gymnasium as gym; gym.make('socialnav/Passing-v0').reset(seed=0)",
        "import gymnasium as gym; gym.make('socialnav:socialnav/CircleCrossing-v0').reset(seed=0)",
    ],
)
def test_ids_are_registered_by_importing_socialnav(code):
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr


def test_every_scenario_of_the_protocol_has_an_id():
    from socialnav.presets import MULTI_HUMAN, SINGLE_HUMAN

    scenarios = {kw["scenario"] for kw in ENV_IDS.values()}
    assert set(MULTI_HUMAN) | set(SINGLE_HUMAN) <= scenarios
    assert all(env_id in gym.registry for env_id in ENV_IDS)


def test_preset_keyword_configures_the_env_as_the_protocol():
    env = gym.make("socialnav/CircleCrossing-v0", preset="wang2022")
    obs, _ = env.reset(seed=0)
    assert obs["humans"].shape == (5, 5)
    assert obs["robot"][7] == pytest.approx(1.5)  # the robot's v_pref under wang2022
    assert env.action_space.high[0] == pytest.approx(1.5)
    assert env.unwrapped._cfg.settings.time_limit == 30.0
    single = gym.make("socialnav/Crossing-v0", preset="wang2022")
    obs, _ = single.reset(seed=0)
    assert obs["humans"].shape == (1, 5) and obs["robot"][7] == pytest.approx(1.5)
    # Explicit arguments win over the preset's.
    env = gym.make("socialnav/CircleCrossing-v0", preset="wang2022", scenario_params={"n_humans": 3},
                   world={"time_limit": 10.0})
    assert env.reset(seed=0)[0]["humans"].shape == (3, 5)
    assert env.unwrapped._cfg.settings.time_limit == 10.0 and env.unwrapped._cfg.settings.dt == 0.25
    # a section given is merged field by field: a lidar added keeps the preset's 5 m detection range
    env = gym.make("socialnav/CircleCrossing-v0", preset="wang2022_partial",
                   world={"sensing": {"lidar_beams": 8}})
    sensing = env.unwrapped._cfg.settings.sensing
    assert (sensing.range, sensing.lidar_beams) == (5.0, 8)
    obs, _ = env.reset(seed=0)
    seen = obs["humans"][obs["human_mask"].astype(bool)]
    assert obs["lidar"].shape == (8,) and (np.hypot(*(seen[:, :2] - obs["robot"][:2]).T) <= 5.0).all()
    with pytest.raises(Exception, match="unknown preset"):
        gym.make("socialnav/CircleCrossing-v0", preset="wang2023")


@pytest.mark.parametrize("env_id", sorted(ENV_IDS))
@pytest.mark.parametrize("kwargs", [{}, {"preset": "wang2022", "action_set": "discrete"}])
def test_gymnasium_env_checker_passes_on_every_id(env_id, kwargs):
    check_env(gym.make(env_id, **kwargs).unwrapped, skip_render_check=True)


@pytest.mark.parametrize(("action", "message"), [
    (np.zeros(3), r"action of shape \(3,\): expected \(2,\)"),
    (np.zeros((1, 2)), r"action of shape \(1, 2\): expected \(2,\)"),
    (0.5, r"action of shape \(\): expected \(2,\)"),
    (None, "action is None"),
    (["a", "b"], "action \\['a', 'b'\\]: expected numbers"),
])
def test_single_env_names_a_malformed_action(action, message):
    env = gym.make("socialnav/CircleCrossing-v0")
    env.reset(seed=0)
    with pytest.raises(ValueError, match=message):
        env.unwrapped.step(action)


def test_discrete_actions_must_be_integer_indices_and_vector_actions_one_per_env():
    env = gym.make("socialnav/CircleCrossing-v0", action_set="discrete")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="expected integer indices, got float64"):
        env.unwrapped.step(3.5)
    env.unwrapped.step(np.int64(3))
    venv = gym.make_vec("socialnav/CircleCrossing-v0", num_envs=3, vectorization_mode="vector_entry_point")
    venv.reset(seed=0)
    with pytest.raises(ValueError, match=r"action of shape \(2,\): expected \(3, 2\) \(the action space's "
                       r"shape, one action per env\)"):
        venv.step(np.zeros(2))


def test_check_env_passes_on_the_learner_wrapper_given_a_dict():
    from socialnav.envs.learner_wrappers import LearnerObservation

    env = LearnerObservation(gym.make("socialnav/Passing-v0"), {"frame": "robot"})
    check_env(env, skip_render_check=True)
    assert env.spec is not None and env.transform.settings.frame == "robot"

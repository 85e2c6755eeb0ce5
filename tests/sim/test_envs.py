"""Gymnasium contract of the single and the vector env."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import socialnav.envs.registration  # noqa: F401  (registers the ids)
from socialnav.envs.single import SocialNavEnv
from socialnav.envs.vector import SocialNavVectorEnv


@pytest.mark.parametrize("kwargs", [{}, {"action_set": "discrete"}, {"world": {"kinematics": "unicycle"}}])
def test_single_env_passes_gymnasium_checker(kwargs):
    check_env(SocialNavEnv(**kwargs), skip_render_check=True)


def test_registered_ids_make_both_envs():
    env = gym.make("socialnav/CircleCrossing-v0")
    obs, info = env.reset(seed=5)
    assert obs["humans"].shape == (5, 5) and info["episode_index"] == 5 * 10_000_000
    obs, info = env.reset(options={"index": 7})
    assert info["episode_index"] == 7
    venv = gym.make_vec("socialnav/CircleCrossing-v0", num_envs=4, vectorization_mode="vector_entry_point")
    obs, _ = venv.reset(seed=0)
    assert obs["robot"].shape == (4, 9)


def test_reset_seed_reproduces_the_episode():
    env = SocialNavEnv()
    first, _ = env.reset(seed=11)
    env.step(np.array([0.0, 1.0]))
    again, _ = env.reset(seed=11)
    np.testing.assert_array_equal(first["humans"], again["humans"])
    other, _ = env.reset(seed=12)
    assert not np.array_equal(first["humans"], other["humans"])


def test_single_env_episode_ends_with_outcome():
    env = SocialNavEnv(world={"human_model": "linear"})
    env.reset(seed=0)
    for _ in range(200):
        obs, reward, terminated, truncated, info = env.step(np.array([0.0, 1.0]))
        if terminated or truncated:
            break
    assert info["outcome"] in ("success", "collision", "timeout")
    assert (reward == 1.0) == (info["outcome"] == "success")


def test_vector_env_autoresets_in_the_same_step():
    venv = SocialNavVectorEnv(num_envs=8, world={"human_model": "linear"})
    obs, info = venv.reset(seed=0)
    np.testing.assert_array_equal(info["episode_index"], np.arange(8))
    seen_final = False
    for _ in range(200):
        obs, reward, terminated, truncated, info = venv.step(np.tile([0.0, 1.0], (8, 1)))
        assert reward.shape == (8,) and terminated.dtype == bool
        done = terminated | truncated
        if done.any():
            seen_final = True
            b = int(np.flatnonzero(done)[0])
            assert info["_final_obs"][b]
            assert info["final_obs"][b]["robot"].shape == (9,)
            assert info["episode_index"][b] >= 8  # the slot already holds a fresh episode
            assert obs["robot"][b][1] == pytest.approx(-4.0)  # the new episode's start
            break
    assert seen_final
    assert venv.observation_space.contains(obs)


@pytest.mark.parametrize("kinematics", ["holonomic", "unicycle"])
def test_env_action_table_equals_the_learned_policies_table(kinematics):
    torch = pytest.importorskip("torch")
    from socialnav.policies.learned.actions import discrete_actions as learned_actions
    from socialnav.sim.actions import discrete_actions

    ours = discrete_actions(kinematics, 1.5)
    theirs = learned_actions(kinematics, torch.tensor([1.5], dtype=torch.float64))[0].numpy()
    np.testing.assert_allclose(ours, theirs, atol=1e-12)
    assert np.any((ours[:, 1] == 0.0) & (ours[:, 0] > 0)) if kinematics == "unicycle" else True


def test_single_env_outcome_comes_from_the_world_not_the_reward():
    # With a zero success reward the outcome must still read "success" (not inferred from the reward).
    env = SocialNavEnv(scenario="passing", scenario_params={"n_humans": 1},
                       world={"human_model": "linear", "reward": {"success_reward": 0.0}})
    env.reset(options={"index": 19})  # the human walks at the far offset: a straight robot passes clear
    for _ in range(200):
        _, reward, terminated, truncated, info = env.step(np.array([0.0, 1.0]))
        if terminated or truncated:
            break
    assert info["outcome"] == "success" and reward == 0.0


@pytest.mark.parametrize("make", [lambda w: SocialNavEnv(world=w), lambda w: SocialNavVectorEnv(2, world=w)])
def test_the_evaluations_continuation_is_refused_by_the_envs(make):
    # With it, an env episode ran on after the robot's success (reward 1, not terminated) past the time limit.
    with pytest.raises(ValueError, match="world.continue_after_success: the evaluation's M_III continuation"):
        make({"continue_after_success": True})


def test_a_single_human_sweep_larger_than_its_split_is_refused_at_construction():
    with pytest.raises(ValueError, match=r"'passing' has 1200 episodes, more than the 1000 of split 'test'"):
        SocialNavEnv(scenario="passing", scenario_params={"repeats": 60}, split="test")

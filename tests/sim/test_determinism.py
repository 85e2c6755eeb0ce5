"""Same seeds -> bit-identical trajectories, whatever the batch size or thread count."""

import numpy as np
import pytest

from socialnav.policies import make_policy
from socialnav.scenarios import make_scenario
from socialnav.sim.settings import WorldSettings
from socialnav.sim.world import World

SINGLE_HUMAN = ("passing", "overtaking", "crossing")


def run(batch: int, episodes: int, threads: int = 1, scenario: str = "circle_crossing", **settings):
    world = World(
        WorldSettings(threads=threads, **settings),
        make_scenario(scenario, **({} if scenario in SINGLE_HUMAN else {"n_humans": 5})),
        batch,
        split="test",
        count=episodes,
    )
    policy = make_policy("orca", safety_space=0.1, threads=threads)
    world.reset()
    trajs = []
    while world.busy:
        trajs += world.step(policy.act(world.observe())).finished
    return {t.settings["index"]: t for t in trajs}


def assert_identical(a, b):
    assert sorted(a) == sorted(b)
    for k in a:
        ta, tb = a[k], b[k]
        assert ta.outcome == tb.outcome
        for name in ("positions", "velocities", "min_clearance", "radii", "goals", "v_pref"):
            np.testing.assert_array_equal(
                getattr(ta, name), getattr(tb, name), err_msg=f"{name} of episode {k}"
            )


@pytest.mark.parametrize(
    "settings",
    [
        {},
        {"human_model": "social_force", "visibility": "visible"},
        {"kinematics": "unicycle", "crowdsim_compat": True},
    ],
)
def test_batch_size_does_not_change_episodes(settings):
    one = run(1, 64, **settings)
    many = run(256, 64, **settings)  # more slots than episodes: some stay idle
    some = run(7, 64, threads=2, **settings)  # refills happen in a different order
    assert len(one) == 64
    assert_identical(one, many)
    assert_identical(one, some)


def test_episode_can_be_replayed_alone():
    full = run(16, 40)
    world = World(
        WorldSettings(threads=1),
        make_scenario("circle_crossing", n_humans=5),
        1,
        split="test",
        start=33,
        count=1,
    )
    policy = make_policy("orca", safety_space=0.1, threads=1)
    world.reset()
    trajs = []
    while world.busy:
        trajs += world.step(policy.act(world.observe())).finished
    assert_identical({33: full[33]}, {33: trajs[0]})


@pytest.mark.parametrize("scenario", ["circle_crossing", "parallel_traffic", "passing"])
def test_thread_count_does_not_change_episodes(scenario):
    """Dynamic chunking hands episodes to whichever thread is free: results must not depend on it."""
    one = run(256, 300, threads=1, scenario=scenario)
    assert len(one) == (300 if scenario != "passing" else 20)
    for threads in (2, 16):
        assert_identical(one, run(256, 300, threads=threads, scenario=scenario))


def test_native_generation_in_the_world_equals_the_python_generator():
    """A world refilling its slots natively (in the core's threads) runs the same episodes as one
    loading `scenario.generate`'s EpisodeBatch (the path of custom scenarios)."""
    native = run(64, 200, threads=2)
    world = World(
        WorldSettings(threads=2), make_scenario("circle_crossing", n_humans=5), 64, split="test", count=200
    )
    assert world._native_scenario is not None
    world._native_scenario = None
    policy = make_policy("orca", safety_space=0.1, threads=2)
    world.reset()
    trajs = []
    while world.busy:
        trajs += world.step(policy.act(world.observe())).finished
    assert_identical(native, {t.settings["index"]: t for t in trajs})


def test_policies_sharing_a_native_pool_may_act_from_two_python_threads():
    """Native policies of one thread count share a worker pool; the core releases the GIL, so two
    Python threads can call it at once: the pool runs one job at a time and both get their answers."""
    from concurrent.futures import ThreadPoolExecutor

    worlds = [
        World(
            WorldSettings(threads=2),
            make_scenario("circle_crossing", n_humans=5),
            512,
            split="test",
            count=512,
        )
        for _ in range(2)
    ]
    observations = [w.reset() for w in worlds]
    policies = [make_policy("orca", threads=2) for _ in range(2)]
    expected = [p.act(o) for p, o in zip(policies, observations, strict=True)]

    def act_many(i):
        return [policies[i].act(observations[i]) for _ in range(50)]

    with ThreadPoolExecutor(2) as ex:
        results = list(ex.map(act_many, range(2)))
    for i in range(2):
        for got in results[i]:
            np.testing.assert_array_equal(got, expected[i])


def _observed_run(threads: int, batch: int = 48, episodes: int = 150):
    """Steps with the native refill writing the next and the final observations (observe=True,
    final_observation=True); returns every step's observation arrays, final observations and the
    trajectories."""
    world = World(WorldSettings(threads=threads), make_scenario("circle_crossing", n_humans=5), batch,
                  split="test", count=episodes)
    policy = make_policy("orca", safety_space=0.1, threads=threads)
    obs = world.reset()
    seen, finals, trajs = [], [], []
    while world.busy:
        result = world.step(policy.act(obs), observe=True, final_observation=True)
        obs = result.observation
        seen.append((obs.robot, obs.humans, obs.human_mask, obs.active, obs.time))
        if result.final_observation is not None:
            f = result.final_observation
            finals.append((f.robot, f.humans, f.human_mask, f.active, f.time))
        trajs += result.finished
    return seen, finals, {t.settings["index"]: t for t in trajs}


def test_native_refill_and_observation_pass_is_identical_for_any_thread_count():
    """The refill pass (finished slots' final observations, their new episodes, every slot's next
    observation) runs over chunks of slots in the worker threads: 1, 2 and 16 threads give the same
    observations, final observations and trajectories, until the stream runs dry (idle slots)."""
    seen1, finals1, trajs1 = _observed_run(1)
    assert len(trajs1) == 150 and len(finals1) > 10
    for threads in (2, 16):
        seen, finals, trajs = _observed_run(threads)
        assert_identical(trajs1, trajs)
        assert len(seen) == len(seen1) and len(finals) == len(finals1)
        for a, b in zip(seen1 + finals1, seen + finals, strict=True):
            for x, y in zip(a, b, strict=True):
                np.testing.assert_array_equal(x, y)


def test_native_refill_observation_is_what_observe_returns():
    world = World(WorldSettings(threads=2), make_scenario("circle_crossing", n_humans=5), 32, split="test",
                  count=80)
    policy = make_policy("orca", safety_space=0.1, threads=2)
    obs = world.reset()
    refills = 0
    while world.busy:
        result = world.step(policy.act(obs), observe=True, final_observation=True)
        obs = result.observation
        refills += result.final_observation is not None
        again = world.observe()
        for name in ("robot", "humans", "human_mask", "active", "time"):
            np.testing.assert_array_equal(getattr(obs, name), getattr(again, name), err_msg=name)
    assert refills > 5

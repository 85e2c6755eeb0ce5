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

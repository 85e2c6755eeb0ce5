"""The native per-step report, refill and observation (issue #13) against the Python bookkeeping they
replace: the same StepResult, the same refilled episodes and the same observation, bit for bit."""

import multiprocessing

import numpy as np
import pytest

from socialnav import _core
from socialnav.policies import make_policy
from socialnav.scenarios import ScenarioGenerationError, episode_seeds, make_scenario
from socialnav.sim.observation import Observation
from socialnav.sim.pool import shared_pool
from socialnav.sim.recorder import OUTCOME_NAMES
from socialnav.sim.settings import WorldSettings
from socialnav.sim.world import World

FIELDS = ("robot", "humans", "human_mask", "active", "time")


def reference_step(world: World, actions: np.ndarray) -> dict:
    """World.step as the Python code before the native report computed it: the core's plain step,
    then the report read off the state arrays, then the Python refill (`World._fill`)."""
    world._core.step(np.ascontiguousarray(actions, dtype=np.float64))
    done = world.done.view(bool).nonzero()[0]
    status = world.status[done]
    report = {
        "final_observation": world.observe().take(done) if done.size else None,
        "reward": world.reward.copy(),
        "terminated": np.zeros(world.batch_size, dtype=bool),
        "truncated": np.zeros(world.batch_size, dtype=bool),
        "final_dmin": np.full(world.batch_size, np.nan),
        "final_episode": np.full(world.batch_size, -1, dtype=np.int64),
        "outcome": np.full(world.batch_size, "", dtype=object),
    }
    report["terminated"][done] = status != _core.STATUS_TIMEOUT
    report["truncated"][done] = status == _core.STATUS_TIMEOUT
    report["final_dmin"][done] = world.dmin[done]
    report["final_episode"][done] = world.episode_index[done]
    report["outcome"][done] = [OUTCOME_NAMES[int(c)] for c in status]
    if done.size:
        world._fill(done)
    return report


def assert_same_observation(a: Observation, b: Observation) -> None:
    for field in FIELDS:
        x, y = getattr(a, field), getattr(b, field)
        assert x.dtype == y.dtype and x.shape == y.shape, field
        assert np.array_equal(x.view(np.uint8), y.view(np.uint8)), field


def assert_same_state(a: World, b: World) -> None:
    for name in ("position", "velocity", "goal", "radius", "v_pref", "mask", "theta", "steps", "status",
                 "arrival", "end_step", "episode_index", "episode_seed"):
        x, y = getattr(a, name), getattr(b, name)
        assert np.array_equal(x.view(np.uint8), y.view(np.uint8)), name


@pytest.mark.parametrize(("threads", "observe", "mapped"), [(1, True, False), (2, True, False),
                                                          (2, False, False), (2, True, True)])
@pytest.mark.parametrize(
    "settings", [{}, {"kinematics": "unicycle", "crowdsim_compat": True, "time_limit": 8.0}]
)
def test_step_report_refill_and_observation_equal_the_python_bookkeeping(threads, observe, mapped, settings):
    """Run to exhaustion (refills, then idle slots): the native path and the Python reference agree on
    every field of every step, the final observations included, and the world states stay equal;
    ``mapped``: a stream whose indices go through an index_map (the Gymnasium envs' orders)."""
    from socialnav.sim.world import EpisodeStream

    def make():
        w = World(WorldSettings(threads=threads, **settings), make_scenario("circle_crossing", n_humans=5),
                  48, split="test", count=150, record=False)
        if mapped:
            w.stream = EpisodeStream(w.scenario, "test", 0, 150, index_map=lambda i: 999 - 3 * i)
        return w

    native, python = make(), make()
    policy = make_policy("orca", safety_space=0.05, threads=threads)
    obs = native.reset()
    python.reset()
    if mapped:
        assert sorted(native.episode_index) == list(range(999 - 3 * 47, 1000, 3))
    steps = ended = 0
    while native.busy:
        actions = policy.act(obs)
        got = native.step(actions, observe=observe, final_observation=True)
        want = reference_step(python, actions)
        if want["final_observation"] is None:
            assert got.final_observation is None
        else:
            assert_same_observation(got.final_observation, want["final_observation"])
        for name in ("reward", "terminated", "truncated", "final_dmin", "final_episode"):
            x, y = getattr(got, name), want[name]
            assert x.dtype == y.dtype, name
            np.testing.assert_array_equal(x, y, err_msg=f"{name} at step {steps}")
        assert got.outcome.tolist() == want["outcome"].tolist()
        assert_same_state(native, python)
        assert (got.observation is not None) == observe
        obs = got.observation if observe else native.observe()
        assert_same_observation(obs, python.observe())
        assert_same_observation(obs, native.observe())
        ended += int((got.terminated | got.truncated).sum())
        steps += 1
    assert ended == 150 and not python.busy
    assert (native.status == _core.STATUS_IDLE).all() and (native.episode_index == -1).all()


def test_step_observe_on_the_python_refill_path_equals_observe():
    """Worlds that refill in Python (custom scenarios) return the same observations."""
    scenario = make_scenario("circle_crossing", n_humans=3)
    w = World(WorldSettings(threads=2), scenario, 16, split="test", count=40)
    w._native_scenario = None
    policy = make_policy("orca", threads=2)
    obs = w.reset()
    finished = 0
    while w.busy:
        res = w.step(policy.act(obs), observe=True, final_observation=True)
        assert_same_observation(res.observation, w.observe())
        done = np.flatnonzero(res.terminated | res.truncated)
        assert (res.final_observation is None) == (done.size == 0)
        obs = res.observation
        finished += len(res.finished)
    assert finished == 40
    assert w.step(np.zeros((16, 2))).observation is None  # only when asked


def test_a_stream_without_count_ends_with_its_split():
    # no count on the test split: its last indices, then the world is done (it ran into index 1000
    # and raised after hundreds of episodes)
    w = World(WorldSettings(), make_scenario("circle_crossing", n_humans=2), 4, split="test", start=996,
              record=False)
    w.reset()
    done = []
    for _ in range(400):
        if not w.busy:
            break
        ended = w.step(np.zeros((4, 2))).final_episode
        done += [int(i) for i in ended if i >= 0]
    assert not w.busy and sorted(done) == [996, 997, 998, 999]


def test_a_count_past_the_end_of_a_split_is_refused_at_once():
    scenario = make_scenario("circle_crossing", n_humans=2)
    with pytest.raises(ValueError, match=r"split 'test' holds episode indices 0..999: start 998 \+ count 4 "
                       r"runs past them"):
        World(WorldSettings(), scenario, 4, split="test", start=998, count=4, record=False)
    with pytest.raises(ValueError, match=r"start 25 is past the scenario's last episode \(it has 20"):
        World(WorldSettings(), make_scenario("passing"), 4, start=25, record=False)


def test_a_refill_that_cannot_place_its_humans_raises_the_generators_error():
    scenario = make_scenario("circle_crossing", randomize_attributes=True, n_humans=10)
    bad = None
    for index in range(1, 1000):
        try:
            scenario.generate(np.array([index]), episode_seeds("test", [index]), native=False)
        except ScenarioGenerationError as err:
            bad, message = index, str(err)
            break
    assert bad is not None
    # The episode before it generates; the refill after it ends asks for the impossible one.
    w = World(WorldSettings(time_limit=2.0), scenario, 1, split="test", start=bad - 1, record=False)
    w.reset()
    with pytest.raises(ScenarioGenerationError) as raised:
        for _ in range(20):
            w.step(np.zeros((1, 2)))
    assert str(raised.value) == message


def test_world_and_native_policy_share_the_process_pool():
    w = World(WorldSettings(threads=2), make_scenario("circle_crossing", n_humans=2), 4, record=False)
    policy = make_policy("orca", threads=2)
    assert policy._pool is shared_pool(2)
    assert shared_pool(2) is shared_pool(2) and shared_pool(1) is not shared_pool(2)
    w.reset()
    with pytest.raises(ValueError, match="threads must be >= 1"):
        shared_pool(0)


def _child_runs_a_world() -> None:
    w = World(WorldSettings(threads=2), make_scenario("circle_crossing", n_humans=3), 64, split="test",
              count=64, record=False)
    policy = make_policy("orca", threads=2)
    obs = w.reset()
    while w.busy:
        obs = w.step(policy.act(obs), observe=True).observation


def test_a_forked_child_starts_pools_of_its_own():
    """A child forked while the parent's pool exists has none of its threads: it must not use it."""
    _child_runs_a_world()  # the parent's pool of 2 exists and has run jobs
    child = multiprocessing.get_context("fork").Process(target=_child_runs_a_world)
    child.start()
    child.join(120)
    if child.exitcode is None:
        child.kill()
    assert child.exitcode == 0


def test_a_forgotten_reset_and_a_reset_mid_run_are_said():
    w = World(WorldSettings(), make_scenario("circle_crossing", n_humans=2), 4, count=8, record=False)
    with pytest.raises(RuntimeError, match=r"step\(\) before reset\(\): every slot is idle"):
        w.step(np.zeros((4, 2)))
    w.reset()
    w.step(np.zeros((4, 2)))
    with pytest.warns(UserWarning, match=r"reset\(\) drops 4 episode\(s\) in flight \(indices 0, 1, 2, 3\)"):
        w.reset()


def test_world_takes_a_settings_dict_and_a_scenario_name_and_names_wrong_types():
    w = World({"dt": 0.25}, "circle_crossing", 2, record=False)
    assert w.settings.dt == 0.25 and w.scenario.name == "circle_crossing"
    with pytest.raises(TypeError, match="settings must be a WorldSettings or a dict of its fields"):
        World(3, "circle_crossing", 2)
    with pytest.raises(TypeError, match="scenario must be a Scenario"):
        World({}, 3, 2)
    with pytest.raises(ValueError, match="batch_size must be an integer >= 1, got True"):
        World({}, "circle_crossing", True)


def test_run_protocol_names_wrong_arguments_and_takes_a_preset_name(tmp_path):
    from socialnav.evaluate import run_protocol
    from socialnav.policies import make_policy

    with pytest.raises(TypeError, match="policy must have name, act"):
        run_protocol(None, "wang2022", tmp_path / "a")
    with pytest.raises(TypeError, match="preset must be a Preset or a preset's name or file, got a int"):
        run_protocol(make_policy("linear"), 3, tmp_path / "b")
    with pytest.raises(TypeError, match="episodes must be an integer, got 2.5"):
        run_protocol(make_policy("linear"), "wang2022", tmp_path / "c", episodes=2.5)
    result = run_protocol(make_policy("linear"), "wang2022", tmp_path / "d", scenarios="crossing", episodes=2,
                          progress=False, workers=0)
    assert [r["scenario"] for r in result.rows] == ["crossing", "crossing"]


def test_tags_cannot_overwrite_the_recorded_provenance_and_must_be_json():
    scenario = make_scenario("circle_crossing", n_humans=2)
    with pytest.raises(ValueError, match=r"tags \['scenario'\] would overwrite what the world records"):
        World(WorldSettings(), scenario, 2, tags={"scenario": "mine"})
    with pytest.raises(ValueError, match="tags must be JSON data"):
        World(WorldSettings(), scenario, 2, tags={"weights": np.zeros(3)})
    World(WorldSettings(), scenario, 2, tags={"policy": "mine", "run": 3})

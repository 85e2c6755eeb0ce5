"""Importers and human-as-robot scoring: round trips, a pedestrian fixture, masks and outcome checks."""

from __future__ import annotations

import dataclasses
import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from socialnav.logs import DataWarning, load_trajectories, read_eth_ucy, score_file, score_trajectories
from socialnav.metrics import score_episode
from socialnav.trajectory import AssumedValueWarning, Trajectory, read_trajectories, write_trajectories
from tests.logs.fixtures import FPS, pedestrian_scene, write_eth_ucy

SIM_KEYS_UNCHANGED = ("path_length", "m4_jerk.mean_sq", "m5_walking_speed.count_ge@v_th=1.5")


@pytest.fixture(scope="module")
def simulated() -> list[Trajectory]:
    from socialnav.policies import make_policy
    from socialnav.scenarios import make_scenario
    from socialnav.sim.settings import WorldSettings
    from socialnav.sim.world import World

    world = World(WorldSettings(), make_scenario("circle_crossing", n_humans=4), 6, count=6)
    policy = make_policy("orca", safety_space=0.1)
    world.reset()
    trajs = []
    while world.busy:
        trajs += world.step(policy.act(world.observe())).finished
    return sorted(trajs, key=lambda t: t.settings["index"])


def _plain(tr: Trajectory) -> Trajectory:
    """What a foreign log can carry: no swept clearance, no continuation, no simulator counts."""
    return dataclasses.replace(tr, min_clearance=None, continuation=None, human_overlaps=None)


def _same(a: dict, b: dict, keys=None, rel=1e-9, abs_=1e-9) -> None:
    for k in keys or a:
        assert a[k] == pytest.approx(b[k], rel=rel, abs=abs_, nan_ok=True), k


def _write_foreign_csv(path: Path, trajs: list[Trajectory]) -> Path:
    """Simulated episodes in another tool's layout: ms clock, named columns, robot id 'r'."""
    lines = ["run,stamp_ms,track,px,py,rad,goal_x,goal_y,result"]
    for tr in trajs:
        ep = tr.settings["index"]
        for k in range(tr.n_steps + 1):
            for a in range(tr.n_agents):
                pid = "r" if a == 0 else f"h{a}"
                x, y = (float(v) for v in tr.positions[k, a])
                gx, gy = (float(v) for v in tr.goals[a])
                lines.append(f"{ep},{round(k * tr.dt * 1000)},{pid},{x!r},{y!r},{tr.radii[a]},{gx!r},{gy!r},"
                             f"{tr.outcome}")
    path.write_text("\n".join(lines) + "\n")
    return path


def test_round_trip_foreign_columns_same_metrics(tmp_path, simulated) -> None:
    path = _write_foreign_csv(tmp_path / "robot_log.csv", simulated)
    cols = "scene=run,time=stamp_ms,id=track,x=px,y=py,radius=rad,gx=goal_x,gy=goal_y,outcome=result"
    back = load_trajectories(path, columns=cols, robot="r", time_unit="ms")
    assert len(back) == len(simulated)
    for orig, tr in zip(simulated, back, strict=True):
        assert tr.outcome == orig.outcome and tr.dt == pytest.approx(orig.dt)
        _same(score_episode(_plain(orig)), score_episode(tr))


def test_round_trip_eth_ucy_human_as_robot(tmp_path, simulated) -> None:
    # every agent written as an ETH/UCY pedestrian; the robot re-imported as the ego
    dt = simulated[0].dt
    fps = 10 / dt  # frames step by 10 per sample, as in the ETH/UCY files
    for orig in simulated:
        if orig.outcome != "success":
            continue
        rows = [(10 * k, 1 + a, *map(float, orig.positions[k, a])) for k in range(orig.n_steps + 1)
                for a in range(orig.n_agents)]
        path = tmp_path / f"ep{orig.settings['index']}.txt"
        path.write_text("".join(f"{f}\t{i}\t{x!r}\t{y!r}\n" for f, i, x, y in rows))
        (ego,) = load_trajectories(path, format="eth-ucy", ego=1, fps=fps, radius=0.3)
        assert ego.settings["mode"] == "human_as_robot" and ego.outcome == "success"
        ref = dataclasses.replace(_plain(orig), goals=np.vstack([orig.positions[-1, 0], orig.goals[1:]]))
        got, want = score_episode(ego), score_episode(ref)
        _same(got, want, [k for k in want if not k.startswith(("m3_", "m6_"))])


def test_rate_change_within_resampling_tolerance(tmp_path, simulated) -> None:
    # jittered clock at about half the rate, re-imported on the simulator's grid
    orig = _plain(next(t for t in simulated if t.outcome == "success"))
    rng = np.random.default_rng(3)
    k = np.arange(0, orig.n_steps + 1, 2)
    stamp = k * orig.dt + rng.uniform(-0.02, 0.02, k.size) * (k > 0) * (k < orig.n_steps)
    lines = ["t,id,x,y,role"]
    for j, kk in enumerate(k):
        for a in range(orig.n_agents):
            x, y = (float(v) for v in orig.positions[kk, a])
            lines.append(f"{float(stamp[j])!r},{a},{x!r},{y!r},{'robot' if a == 0 else 'human'}")
    path = tmp_path / "irregular.csv"
    path.write_text("\n".join(lines) + "\n")
    with pytest.warns(AssumedValueWarning, match="interpolated"):
        (tr,) = load_trajectories(path, dt=orig.dt, radius=0.3)
    assert tr.dt == orig.dt and tr.settings["resampled"] is True
    got, want = score_episode(tr, require_success=False), score_episode(orig, require_success=False)
    assert got["path_length"] == pytest.approx(want["path_length"], rel=0.03)
    assert got["min_clearance"] == pytest.approx(want["min_clearance"], abs=0.05)


# ------------------------------------------------------------------------------ pedestrian fixture
def test_eth_ucy_fixture_gives_plausible_human_as_robot_values(tmp_path) -> None:
    path = write_eth_ucy(tmp_path / "zara_like.txt", pedestrian_scene(seed=1, n=10, frames=60))
    with pytest.warns(AssumedValueWarning, match="radius 0.3"):
        scores = score_file(path, ego="all")
    assert len(scores.rows) == 10 and not scores.warnings
    for row in scores.rows:
        speed = row["path_length"] / row["navigation_time"]
        assert 1.0 <= speed <= 1.55, row["ego"]
        assert row["min_clearance"] > 0.0
        for key, value in row.items():
            if key.startswith(("m6_", "source", "scene", "episode", "ego", "mode", "outcome")):
                continue
            if key.startswith(("min_obstacle_clearance", "obstacle_proximity", "wall_collision")):
                assert math.isnan(value), key  # no map: obstacle metrics are undefined
                continue
            assert math.isfinite(value), key  # every metric, M_III included (known exits)
        assert math.isnan(row["m6_side_preference.sign@frame=world"])  # several humans: M_VI n/a
    (scene,) = [s for s in scores.summaries if s["scope"] == "scene"]
    assert scene["episodes"] == 10
    assert scene["m1_personal_space.duration_s@eps=1.2,distance=clearance.n"] == 10


def test_per_scene_and_dataset_summaries(tmp_path) -> None:
    a = write_eth_ucy(tmp_path / "a.txt", pedestrian_scene(seed=1, n=6))
    b = write_eth_ucy(tmp_path / "b.txt", pedestrian_scene(seed=2, n=4))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AssumedValueWarning)
        trajs = load_trajectories(a, ego="all") + load_trajectories(b, ego="all")
    scores = score_trajectories(trajs)
    scopes = [(s["scope"], s["scenario"], s["episodes"]) for s in scores.summaries]
    assert scopes == [("scene", "a", 6), ("scene", "b", 4), ("dataset", "dataset", 10)]
    key = "path_length.mean"
    pooled = np.mean([r["path_length"] for r in scores.rows])
    assert scores.summaries[-1][key] == pytest.approx(pooled)


def test_entering_and_leaving_agents_are_masked_not_invented(tmp_path) -> None:
    path = write_eth_ucy(tmp_path / "s.txt", pedestrian_scene(seed=4, n=6))
    (scene,) = read_eth_ucy(path, radius=0.3)
    assert scene.dt == pytest.approx(10 / FPS) and not scene.resampled
    assert (~scene.present).any()  # staggered entries
    assert np.isnan(scene.positions[~scene.present]).all()
    tr = scene.ego_trajectory(scene.ids[0])
    absent = ~tr.presence
    assert absent.any() and np.isnan(tr.positions[absent]).all()


# ------------------------------------------------------------------------------ masks keep metrics right
def _pair_with_ghost(present_ghost: np.ndarray | None) -> tuple[Trajectory, Trajectory]:
    k = np.arange(21)
    robot = np.stack([0 * k, -4 + 0.4 * k], 1)
    human = np.tile([0.5, 0.0], (21, 1))
    ghost = np.stack([0.1 + 0 * k, -4 + 0.4 * k], 1)  # on top of the robot: would dominate every metric
    base = np.stack([robot, human], 1)
    kw = dict(radii=0.3, v_pref=[2.0, 1.0, 1.0], outcome="success")
    two = Trajectory.from_positions(base, 0.25, goals=base[-1], radii=0.3, v_pref=[2.0, 1.0],
                                    outcome="success")
    three = np.stack([robot, human, ghost], 1)
    present = np.ones((21, 3), bool)
    present[:, 2] = False if present_ghost is None else present_ghost
    masked = Trajectory.from_positions(three, 0.25, goals=three[-1], present=present, **kw)
    return two, masked


def test_absent_agent_changes_no_metric() -> None:
    two, masked = _pair_with_ghost(None)
    a, b = score_episode(two), score_episode(masked)
    _same(a, b, [k for k in a if not k.startswith("m6_")])
    assert b["n_humans"] == 1.0


def test_partially_present_agent_counts_only_where_present() -> None:
    ghost = np.zeros(21, bool)
    ghost[5:8] = True  # present at samples 5, 6, 7 only, overlapping the robot there
    _, masked = _pair_with_ghost(ghost)
    row = score_episode(masked)
    two, _ = _pair_with_ghost(None)
    base = score_episode(two)
    # M_I: flagged at the 3 present samples in addition to the base flags (the human at 0.5 m lateral)
    key = "m1_personal_space.count@eps=0.2,distance=clearance"
    base_flags = set(np.flatnonzero(np.abs(np.arange(1, 21) * 0.4 - 4) < np.sqrt(0.8**2 - 0.25)) + 1)
    assert row[key] == len(base_flags | {5, 6, 7}) and base[key] == len(base_flags)
    assert row["min_clearance"] == pytest.approx(0.1 - 0.6)
    # M_II: the ghost's velocity exists at samples 6 and 7 only (5 follows an absence)
    key2 = "m2_projected_path.count@tau=0.5,anchor=rear"
    assert row[key2] >= base[key2]


def test_long_format_round_trip_keeps_masks(tmp_path) -> None:
    ghost = np.zeros(21, bool)
    ghost[5:12] = True
    _, masked = _pair_with_ghost(ghost)
    for suffix in (".csv", ".parquet"):
        path = tmp_path / f"m{suffix}"
        write_trajectories(path, [masked])
        (back,) = read_trajectories(path)
        np.testing.assert_array_equal(back.presence, masked.presence)
        np.testing.assert_array_equal(np.isnan(back.positions), np.isnan(masked.positions))
        _same(score_episode(back), score_episode(masked))


# ------------------------------------------------------------------------------ M_III
def test_m3_known_arrival_times_and_robot_censoring() -> None:
    from socialnav.metrics.comfort import aggregated_time

    k = np.arange(9)  # 8 steps of 0.5 s: T = 4 s
    pos = np.stack([np.stack([0 * k, 0.5 * k], 1), np.stack([5 + 0 * k, 0.2 * k], 1)], 1)
    goals = np.array([pos[-1, 0], [5.0, 100.0]])  # the human never reaches its goal in the data
    tr = Trajectory.from_positions(pos, 0.5, radii=0.3, goals=goals, outcome="success")
    assert aggregated_time(tr)["unresolved"] == 1.0 and math.isnan(aggregated_time(tr)["time_s"])
    known = dataclasses.replace(tr, arrival_times=np.array([np.nan, 30.0]))
    assert aggregated_time(known) == {"time_s": 34.0, "steps": 68.0, "censored": 0.0, "unresolved": 0.0}
    # cap 3 s: the robot's 4 s is capped and counted as censored, like the human's 30 s
    assert aggregated_time(known, cap_s=3.0) == {"time_s": 6.0, "steps": 12.0, "censored": 2.0,
                                                 "unresolved": 0.0}

    # A human present from sample 2 (1 s): a known arrival at 3 s took 2 s, as a detected one would.
    present = np.ones((9, 2), bool)
    present[:2, 1] = False
    late = dataclasses.replace(tr, present=present, arrival_times=np.array([np.nan, 3.0]))
    assert aggregated_time(late)["time_s"] == 4.0 + (3.0 - 1.0)
    seen = pos.copy()
    seen[6:, 1] = goals[1]  # the same arrival at sample 6, detected from the positions instead
    detected = Trajectory.from_positions(seen, 0.5, radii=0.3, goals=goals, outcome="success",
                                         present=present)
    assert aggregated_time(detected)["time_s"] == aggregated_time(late)["time_s"]
    with pytest.raises(ValueError, match="agent 1 arrives at 0.5 s, before it enters the data at 1 s"):
        aggregated_time(dataclasses.replace(late, arrival_times=np.array([np.nan, 0.5])))


def test_m3_of_a_pedestrian_scene_counts_each_person_from_its_entry(tmp_path) -> None:
    from socialnav.metrics.comfort import aggregated_time

    # ego 1 walks 0..1.6 s; pedestrian 3 enters at 0.8 s and leaves at 2.0 s: it took 1.2 s
    rows = ["time,id,x,y"]
    rows += [f"{0.2 * i:.1f},1,0,{0.25 * i}" for i in range(9)]
    rows += [f"{0.2 * i:.1f},3,5,{0.3 * i:.1f}" for i in range(4, 11)]
    path = tmp_path / "peds.csv"
    path.write_text("\n".join(rows) + "\n")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AssumedValueWarning)
        (tr,) = load_trajectories(path, ego=1)
    assert tr.present is not None and not tr.present[:4, 1].any() and tr.present[4, 1]
    assert aggregated_time(tr)["time_s"] == pytest.approx(1.6 + (2.0 - 0.8))


# ------------------------------------------------------------------------------ outcome checks
def test_success_label_contradicted_by_geometry_warns(tmp_path) -> None:
    k = np.arange(11)
    robot = np.stack([0 * k, -2 + 0.2 * k], 1)
    human = np.tile([0.2, 0.0], (11, 1))  # the robot drives through the human
    pos = np.stack([robot, human], 1)
    goals = np.array([[0.0, 7.5], [0.2, 0.0]])  # and ends 7.5 m short of its goal
    tr = Trajectory.from_positions(pos, 0.25, radii=0.3, goals=goals, outcome="success")
    with pytest.warns(DataWarning) as caught:
        scores = score_trajectories([tr])
    text = " ".join(str(w.message) for w in caught)
    assert "overlaps agent 1" in text and "7.5 m from its goal" in text
    assert len(scores.warnings) == 2
    clean = Trajectory.from_positions(pos + [[[0, 0], [3.0, 0]]], 0.25, radii=0.3,
                                      goals=np.array([robot[-1], [3.2, 0.0]]), outcome="success")
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataWarning)
        assert not score_trajectories([clean]).warnings


def test_simulated_successes_raise_no_outcome_warning(simulated) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataWarning)
        score_trajectories([t for t in simulated if t.outcome != "unknown"])

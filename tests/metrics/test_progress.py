"""Progress among walls (metrics/progress.py): stuck agents and humans' arrivals, by hand-computed values."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from socialnav.evaluate.report import render_reports, table2
from socialnav.evaluate.summary import summarize_group
from socialnav.maps.static_map import StaticMap
from socialnav.metrics import score_episode, score_keys
from socialnav.metrics.progress import (
    STUCK_PROGRESS_M,
    STUCK_WINDOW_S,
    human_arrival,
    human_arrivals,
    humans_had_full_time,
    humans_stuck,
    robot_stuck_time,
    route_distances,
    stuck_flags,
    stuck_spacing,
)
from socialnav.metrics.score import fill_missing_keys
from socialnav.presets import load_preset
from socialnav.trajectory import Trajectory

#: A wall segment along y = 0 from x = -3 to 3, between (0, -1) and the goal (0, 1).
WALL = StaticMap.from_polygons([[[-3.0, 0.0], [3.0, 0.0]]])
FAR = StaticMap.from_polygons([[[50.0, 50.0], [51.0, 50.0]]])  # a map whose wall is nowhere near
PROGRESS_KEYS = {"human_arrival", "human_arrival.full_time", "humans_stuck", "robot_stuck_time"}


def _traj(robot: np.ndarray, goal: tuple[float, float], *, dt: float = 0.25, humans: np.ndarray | None = None,
          human_goals: np.ndarray | None = None, smap: StaticMap | None = None, outcome: str = "timeout",
          **kwargs: object) -> Trajectory:
    """The robot along ``robot`` (K+1, 2), radius 0.3; humans (K+1, H, 2) if given."""
    pos = robot[:, None, :] if humans is None else np.concatenate([robot[:, None, :], humans], axis=1)
    goals = np.array([goal] + ([] if human_goals is None else list(human_goals)), dtype=float)
    return Trajectory.from_positions(pos, dt, radii=0.3, v_pref=1.0, goals=goals, outcome=outcome,
                                     static_map=smap, **kwargs)


def _still(seconds: float, dt: float, at: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    return np.tile(np.array(at, dtype=float), (round(seconds / dt) + 1, 1))


# ------------------------------------------------------------------------------------------- spacing
@pytest.mark.parametrize(("dt", "expected"), [(0.25, (4, 5)), (0.1, (10, 5)), (0.5, (2, 5)), (1.0, (1, 5)),
                                              (0.3, (3, 6)), (2.0, (1, 3))])
def test_the_route_distance_is_evaluated_every_second_with_a_window_covering_5_s(dt, expected) -> None:
    assert stuck_spacing(dt) == expected
    stride, lag = expected
    assert STUCK_WINDOW_S <= lag * stride * dt < STUCK_WINDOW_S + max(1.0, dt)


# -------------------------------------------------------------------------------------- stuck, robot
@pytest.mark.parametrize("dt", [0.1, 0.25, 0.5, 1.0])
def test_standing_still_2_m_from_the_goal_for_6_s_is_stuck_from_5_s_on(dt) -> None:
    # evaluated at t = 0, 1, ..., 6 s; windows end at t = 5 and 6 s, both with no progress: 2 s stuck
    tr = _traj(_still(6.0, dt), (2.0, 0.0), dt=dt)
    index, flags, spacing = stuck_flags(tr, 0, continuation=False)
    assert spacing == pytest.approx(1.0)
    assert index.tolist() == [round(t / dt) for t in range(7)]
    assert flags.tolist() == [False] * 5 + [True, True]
    assert robot_stuck_time(tr) == {"value": pytest.approx(2.0)}


def test_walking_at_1_m_s_towards_the_goal_is_not_stuck() -> None:
    t = np.arange(25) * 0.25  # 6 s
    tr = _traj(np.stack([t, np.zeros_like(t)], axis=1), (10.0, 0.0))  # 5 m of progress per window
    assert not stuck_flags(tr, 0)[1].any()
    assert robot_stuck_time(tr)["value"] == 0.0
    slow = _traj(np.stack([0.09 * t, np.zeros_like(t)], axis=1), (10.0, 0.0))  # 0.45 m per 5 s < P
    assert robot_stuck_time(slow)["value"] == pytest.approx(2.0)


def test_walking_in_a_circle_makes_no_progress() -> None:
    # radius 1 m, one turn every 5 s (1.26 m/s, a walking speed): D(t - 5) = D(t) exactly, so every
    # evaluated sample from t = 5 s on is stuck: t = 5, 6, 7, 8 s -> 4 s, though the robot walked 10 m
    t = np.arange(33) * 0.25
    circle = np.stack([np.cos(2 * np.pi * t / 5), np.sin(2 * np.pi * t / 5)], axis=1)
    tr = _traj(circle, (5.0, 0.0))
    assert np.linalg.norm(np.diff(circle, axis=0), axis=1).sum() > 9.9
    assert robot_stuck_time(tr)["value"] == pytest.approx(4.0)


def test_an_agent_at_its_goal_is_not_stuck_nor_after_it_arrived() -> None:
    at_goal = _traj(_still(8.0, 0.25), (0.1, 0.0))  # within its radius (0.3 m) all along
    assert robot_stuck_time(at_goal)["value"] == 0.0
    # arrives at t = 1 s, then is pushed 1 m off and stands there: arrived, never stuck again
    path = np.zeros((33, 2))
    path[:5, 0] = np.linspace(-1.0, 0.0, 5)
    path[5:, 0] = 1.0
    assert robot_stuck_time(_traj(path, (0.0, 0.0)))["value"] == 0.0
    # a known arrival time counts as an arrival from that time on (t = 6 s: only t = 5 s is stuck)
    known = _traj(_still(8.0, 0.25), (2.0, 0.0), arrival_times=[6.0])
    assert robot_stuck_time(known)["value"] == pytest.approx(1.0)


# ------------------------------------------------------------------------------------ behind a wall
def _along_the_wall() -> np.ndarray:
    """The robot walks 2.5 m along the wall's far side towards its middle, (2.5, -1) -> (0, -1), in 5 s,
    then stands 1 s: its goal (0, 1) is behind the wall."""
    t = np.arange(25) * 0.25
    return np.stack([np.maximum(2.5 - 0.5 * t, 0.0), -np.ones_like(t)], axis=1)


def test_route_distances_go_round_the_wall() -> None:
    tr = _traj(_along_the_wall(), (0.0, 1.0), smap=WALL)
    d = route_distances(tr, 0, np.array([[0.0, -1.0], [2.5, -1.0], [0.0, 2.0], [np.nan, np.nan]]))
    # round the wall's end (3, 0): over the polyline through the end (6.32 m, not the 2 m straight line),
    # by at most 4 radii: the route passes the end at the visibility graph's corners offset by r (and 1 %),
    # (±3.3, -0.3) and (±3.3, 0.3): 3.38 + 0.6 + 3.38 = 7.36 m
    assert d[0] == pytest.approx(2 * math.hypot(3.3, 0.7) + 0.6, abs=0.05)
    assert 2 * math.sqrt(10) < d[0] < 2 * math.sqrt(10) + 4 * 0.3
    assert d[1] == pytest.approx(math.hypot(0.8, 0.7) + 0.6 + math.hypot(3.3, 0.7), abs=0.05)  # 5.04 m
    assert d[2] == pytest.approx(1.0)  # sees the goal: straight
    assert math.isnan(d[3])
    euclid = route_distances(_traj(_along_the_wall(), (0.0, 1.0)), 0, np.array([[0.0, -1.0]]))
    assert euclid.tolist() == [2.0]
    # no route from inside a solid polygon: the Euclidean distance stands in
    box = StaticMap.from_polygons([[[2, -1], [3, -1], [3, 1], [2, 1]]])
    inside = route_distances(_traj(_still(1.0, 0.25), (5.0, 0.0), smap=box), 0, np.array([[2.5, 0.0]]))
    assert inside.tolist() == [2.5]


def test_behind_a_wall_the_euclidean_distance_shrinks_and_the_route_does_not() -> None:
    # Euclidean: 3.20 m -> 2 m in the first window (1.2 m of "progress"), 2.83 -> 2 m in the second;
    # route: 5.04 m -> 7.36 m and 5.46 m -> 7.36 m, longer: stuck at t = 5 and 6 s with the wall
    open_floor = _traj(_along_the_wall(), (0.0, 1.0))
    walled = _traj(_along_the_wall(), (0.0, 1.0), smap=WALL)
    assert robot_stuck_time(open_floor)["value"] == 0.0
    assert robot_stuck_time(walled)["value"] == pytest.approx(2.0)
    # a map whose wall is elsewhere measures as the open floor
    assert robot_stuck_time(_traj(_along_the_wall(), (0.0, 1.0), smap=FAR))["value"] == 0.0


def test_a_human_pressed_against_the_wall_is_stuck_in_the_continuation() -> None:
    # robot succeeds at once; the human (goal behind the wall) walks 0.95 m up to the wall in 1 s, then
    # stays pressed against it for the 9 s of the continuation. Its route (round the wall's end, past the
    # graph's corner (3.3, -0.3)) shrank by 3.45 - 3.30 = 0.15 m only: stuck from t = 5 s on, t = 5..10 s
    robot = _still(1.0, 0.25, (9.0, 9.0))
    human = np.zeros((5, 1, 2))
    human[:, 0, 1] = np.linspace(-1.3, -0.35, 5)
    cont = np.zeros((36, 2, 2))
    cont[:, 0] = (9.0, 9.0)
    cont[:, 1] = (0.0, -0.35)
    tr = _traj(robot, (9.0, 9.0), humans=human, human_goals=[(0.0, 1.0)], smap=WALL, outcome="success",
               continuation=cont)
    index, flags, _ = stuck_flags(tr, 1)
    assert index[-1] == 40 and flags.tolist() == [False] * 5 + [True] * 6
    assert robot_stuck_time(tr)["value"] == 0.0  # the robot arrived
    assert humans_stuck(tr)["value"] == 1.0
    no_continuation = _traj(robot, (9.0, 9.0), humans=human, human_goals=[(0.0, 1.0)], smap=WALL)
    assert humans_stuck(no_continuation)["value"] == 0.0  # 1 s of data: no window


# ------------------------------------------------------------------------------------------- arrivals
def _three_humans(outcome: str, continuation: bool) -> Trajectory:
    """Human 1 reaches its goal at t = 1 s, human 2 only in the continuation, human 3 never."""
    k = 5
    robot = _still(1.0, 0.25, (5.0, 5.0))
    humans = np.zeros((k, 3, 2))
    humans[:, 0, 0] = np.linspace(-1.0, 0.0, k)  # goal (0, 0): reached at the last sample
    humans[:, 1, 0] = 10.0  # goal (10, 2): 2 m away in the episode
    humans[:, 2, 0] = 20.0  # goal (20, 5): never
    goals = [(0.0, 0.0), (10.0, 2.0), (20.0, 5.0)]
    cont = None
    if continuation:
        cont = np.zeros((8, 4, 2))
        cont[:, 0] = (5.0, 5.0)
        cont[:, 1] = (0.0, 0.0)
        cont[:, 2, 0], cont[:, 2, 1] = 10.0, np.linspace(0.25, 2.0, 8)  # at (10, 2) at the end
        cont[:, 3] = (20.0, 0.0)
    return _traj(robot, (5.0, 5.0), humans=humans, human_goals=goals, smap=WALL, outcome=outcome,
                 continuation=cont)


def test_arrivals_count_the_continuation() -> None:
    success = _three_humans("success", continuation=True)
    assert human_arrivals(success) == (3, 2)
    assert humans_had_full_time(success)
    assert human_arrival(success) == {"value": pytest.approx(2 / 3), "full_time": pytest.approx(2 / 3)}


def test_after_a_collision_the_humans_could_not_arrive() -> None:
    collision = _three_humans("collision", continuation=False)
    assert human_arrivals(collision) == (3, 1)
    assert not humans_had_full_time(collision)
    out = human_arrival(collision)
    assert out["value"] == pytest.approx(1 / 3) and math.isnan(out["full_time"])
    # a success without a continuation (the invisible pass) has the whole time only if everyone arrived
    assert not humans_had_full_time(_three_humans("success", continuation=False))
    robot = _still(1.0, 0.25, (5.0, 5.0))
    arrived = _traj(robot, (5.0, 5.0), humans=np.zeros((5, 1, 2)), human_goals=[(0.1, 0.0)],
                    outcome="success")
    assert humans_had_full_time(arrived) and human_arrival(arrived) == {"value": 1.0, "full_time": 1.0}


def test_arrival_is_within_the_radius_strictly_and_nan_without_humans() -> None:
    robot = _still(1.0, 0.25)
    humans = np.zeros((5, 2, 2))
    humans[:, 0] = (0.29, 0.0)  # 0.29 m < r = 0.3: arrived
    humans[:, 1] = (0.31, 0.0)  # 0.31 m: not
    tr = _traj(robot, (0.0, 0.0), humans=humans, human_goals=[(0.0, 0.0), (0.0, 0.0)])
    assert human_arrivals(tr) == (2, 1)
    alone = human_arrival(_traj(robot, (0.0, 0.0)))
    assert math.isnan(alone["value"]) and math.isnan(alone["full_time"])
    assert human_arrivals(_traj(robot, (0.0, 0.0))) == (0, 0)


# ---------------------------------------------------------------------------------- logs without a map
def test_a_log_without_a_map_is_measured_on_the_open_floor_and_absent_samples_never_stuck() -> None:
    # a log (outcome unknown): a human standing 3 m from its goal for 8 s, absent from t = 4 s to 6 s
    robot = _still(8.0, 0.25)
    human = np.tile([[3.0, 0.0]], (33, 1, 1))
    present = np.ones((33, 2), dtype=bool)
    present[16:25, 1] = False  # t = 4 .. 6 s
    human[~present[:, 1]] = np.nan
    tr = _traj(robot, (5.0, 5.0), humans=human, human_goals=[(0.0, 0.0)], outcome="unknown", present=present)
    index, flags, _ = stuck_flags(tr, 1)
    # evaluated t = 0..8 s; stuck at t = 5..8 unless t or t - 5 is absent (t = 5, 6 s): t = 7, 8 s
    assert flags.tolist() == [False] * 7 + [True, True]
    assert humans_stuck(tr)["value"] == 1.0
    assert human_arrivals(tr) == (1, 0)
    # score_episode reports them only where there is a map
    row = score_episode(tr, require_success=False)
    assert not PROGRESS_KEYS & set(row)
    with_map = score_episode(_traj(robot, (5.0, 5.0), humans=human, human_goals=[(0.0, 0.0)],
                                   outcome="unknown", present=present, smap=FAR), require_success=False)
    assert PROGRESS_KEYS <= set(with_map) and with_map["humans_stuck"] == 1.0


# ------------------------------------------------------------------------------------- score and tables
def test_score_keys_with_and_without_a_map() -> None:
    walled = score_episode(_traj(_along_the_wall(), (0.0, 1.0), smap=WALL))
    open_floor = score_episode(_traj(_along_the_wall(), (0.0, 1.0)))
    assert list(walled) == score_keys(static_map=True) and list(open_floor) == score_keys()
    assert set(walled) - set(open_floor) == PROGRESS_KEYS
    assert walled["robot_stuck_time"] == pytest.approx(2.0)
    assert {k: v for k, v in walled.items() if k in open_floor}.keys() == open_floor.keys()


def test_fill_missing_keys_gives_every_row_every_column() -> None:
    a, b = {"x": 1.0, "side": "left"}, {"x": 2.0, "y": 3.0, "side": "right"}
    filled = fill_missing_keys([a, b])
    assert [list(r) for r in filled] == [["x", "y", "side"]] * 2
    assert math.isnan(filled[0]["y"]) and filled[1] == b
    same = [a, dict(a)]
    assert all(x is y for x, y in zip(fill_missing_keys(same), same, strict=True))


def _episode_rows(visibility: str, smap: StaticMap | None) -> list[dict]:
    rows = []
    for i, outcome in enumerate(["success", "collision"]):
        tr = _three_humans(outcome, continuation=outcome == "success")
        if smap is None:
            tr = Trajectory.from_positions(tr.positions, tr.dt, radii=tr.radii, v_pref=tr.v_pref,
                                           goals=tr.goals, outcome=outcome, continuation=tr.continuation)
        rows.append({"policy": "orca", "scenario": "narrow_doorway", "visibility": visibility, "index": i,
                     "outcome": outcome, **score_episode(tr)})
    return rows


def test_table2_of_a_run_with_walls_has_the_progress_columns() -> None:
    summary = [summarize_group(("orca", "narrow_doorway", v), _episode_rows(v, WALL))
               for v in ("invisible", "visible")]
    # humans at goal: over the successful episode only (2 of 3); humans stuck: none in 3 s of data
    assert summary[1]["human_arrival.full_time.mean"] == pytest.approx(2 / 3)
    assert summary[1]["human_arrival.full_time.n"] == 1 and summary[1]["human_arrival.n"] == 2
    assert summary[1]["human_arrival.mean"] == pytest.approx(0.5)
    text = table2(summary)
    header = next(line for line in text.splitlines() if line.startswith("| Policy"))
    assert header.endswith("| M_V≥ (s) | Humans at goal % | Humans stuck | Robot stuck (s) |")
    assert "| 66.67 | 0.00 ± 0.00 | 0.00 ± 0.00 |" in text
    assert "Note: Humans at goal %: the humans that reached their goal" in text
    metrics = render_reports(summary, load_preset("francis2023"))["summary.json"]
    assert '"name": "robot_stuck_time"' in metrics


def test_open_floor_tables_and_summaries_have_no_progress_columns() -> None:
    summary = [summarize_group(("orca", "circle_crossing", v), _episode_rows(v, None))
               for v in ("invisible", "visible")]
    assert not any(k.startswith(("human_arrival", "humans_stuck", "robot_stuck")) for r in summary for k in r)
    files = render_reports(summary, load_preset("wang2022"))
    assert "Humans" not in files["table2.md"] and "stuck" not in files["table2.md"]
    assert "human_arrival" not in files["summary.json"] and "robot_stuck" not in files["summary.csv"]


def test_a_group_of_episodes_with_and_without_maps_averages_over_the_walled_ones() -> None:
    rows = _episode_rows("visible", WALL)[:1] + [{**r, "index": 5} for r in _episode_rows("visible", None)]
    out = summarize_group(("orca", "pooled", "visible"), rows)
    assert out["human_arrival.n"] == 1 and out["human_arrival.mean"] == pytest.approx(2 / 3)


# ------------------------------------------------------------------------------------------- properties
coords = st.floats(-6.0, 6.0, allow_nan=False, allow_infinity=False)


@st.composite
def walks(draw: st.DrawFn) -> Trajectory:
    dt = draw(st.sampled_from([0.1, 0.25, 0.4, 1.0, 2.0]))
    k = draw(st.integers(1, 80))
    a = 1 + draw(st.integers(0, 3))
    pos = draw(arrays(np.float64, (k + 1, a, 2), elements=coords))
    goals = draw(arrays(np.float64, (a, 2), elements=coords))
    smap = draw(st.sampled_from([None, WALL]))
    return Trajectory.from_positions(pos, dt, radii=0.3, v_pref=1.0, goals=goals, outcome="timeout",
                                     static_map=smap)


@given(walks(), st.floats(0.0, 3.0))
@settings(max_examples=60, deadline=None)
def test_stuck_time_never_exceeds_the_episode_and_grows_with_the_threshold(tr: Trajectory, p: float) -> None:
    stuck = robot_stuck_time(tr)["value"]
    stride, lag = stuck_spacing(tr.dt)
    assert 0.0 <= stuck <= max(0.0, tr.duration - (lag - 1) * stride * tr.dt) + 1e-9
    assert stuck <= max(0.0, tr.duration - STUCK_WINDOW_S) + stride * tr.dt + 1e-9
    lo = stuck_flags(tr, 0, progress_m=min(p, STUCK_PROGRESS_M))[1]
    hi = stuck_flags(tr, 0, progress_m=max(p, STUCK_PROGRESS_M))[1]
    assert not (lo & ~hi).any()  # a larger P flags a superset
    assert 0 <= humans_stuck(tr)["value"] <= tr.n_humans
    share = human_arrival(tr)["value"]
    assert (tr.n_humans == 0 and math.isnan(share)) or 0.0 <= share <= 1.0


def test_socialnav_metrics_prints_logs_with_and_without_a_map(capsys: pytest.CaptureFixture[str]) -> None:
    from socialnav.logs.command import _print_text
    from socialnav.logs.scoring import score_trajectories

    walled = _traj(_along_the_wall(), (0.0, 1.0), smap=WALL, outcome="unknown")
    open_floor = _traj(_along_the_wall(), (0.0, 1.0), outcome="unknown")
    with pytest.warns(UserWarning, match="M_V"):  # v_pref 1 m/s <= v_th: said once per call
        scores = score_trajectories([open_floor, walled], require_success=False)
    assert "robot_stuck_time" not in scores.rows[0] and scores.rows[1]["robot_stuck_time"] == 2.0
    _print_text(scores, per_episode=True, require_success=False)
    out = capsys.readouterr().out
    # the walled episode's value, its scene's mean and the dataset's (the open floor's scene has none)
    assert out.count("robot_stuck_time") == 3

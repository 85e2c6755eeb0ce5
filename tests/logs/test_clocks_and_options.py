"""Robot logs as they come: clocks of different rates, jitter, dropped samples, and options that do not fit.

Each case is small enough to compute by hand; the expected values are in the comments.
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from socialnav.logs import load_trajectories, score_file, score_trajectories
from socialnav.metrics import score_episode
from socialnav.trajectory import AssumedValueWarning, TrajectoryFormatError


def _csv(path: Path, header: str, rows: list[str]) -> Path:
    path.write_text("\n".join([header, *rows]) + "\n")
    return path


def _load(path: Path, **kwargs: object):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AssumedValueWarning)
        return load_trajectories(path, **kwargs)


def test_people_logged_slower_than_the_robot_are_kept(tmp_path: Path) -> None:
    # robot at 50 Hz walking up x = 0 at 1 m/s for 4 s; a person standing at x = 0.8 logged at 10 Hz.
    # Gaps are judged on each agent's own clock (0.1 s), not the scene's median step (0.02 s).
    rows = [f"{k * 0.02:.2f},0,0.0,{k * 0.02:.4f},robot" for k in range(201)]
    rows += [f"{k * 0.1:.1f},1,0.8,2.0,human" for k in range(41)]
    (tr,) = _load(_csv(tmp_path / "rates.csv", "t,id,x,y,role", rows), radius=0.3)
    assert tr.dt == pytest.approx(0.02) and tr.n_agents == 2 and tr.presence[:, 1].all()
    scores = score_episode(tr, require_success=False)
    assert scores["n_humans"] == 1
    assert scores["min_clearance"] == pytest.approx(0.8 - 0.6)  # centre distance 0.8, radii 0.3 + 0.3


def test_the_grid_follows_the_robots_clock(tmp_path: Path) -> None:
    # the robot stamped at 0.01 + 0.5 k, the person at 0.5 k: the grid passes through the robot's samples,
    # so its whole 2 s run is scored (a grid from the scene's first stamp, 0, cut it to 1.5 s)
    rows = [f"{0.01 + 0.5 * k:.2f},0,0.0,{0.5 * k},robot" for k in range(5)]
    rows += [f"{0.5 * k},1,3.0,{0.5 * k},human" for k in range(5)]
    (tr,) = _load(_csv(tmp_path / "offset.csv", "t,id,x,y,role", rows), radius=0.3)
    assert tr.dt == pytest.approx(0.5) and tr.n_steps * tr.dt == pytest.approx(2.0)
    np.testing.assert_allclose(tr.positions[:, 0, 1], [0.0, 0.5, 1.0, 1.5, 2.0], atol=1e-12)
    assert tr.settings["t0"] == pytest.approx(0.01)
    assert not tr.presence[-1, 1]  # 2.01 s is after the person's last stamp: absent, not extrapolated


def test_a_jittered_clock_fits_the_step_to_the_run(tmp_path: Path) -> None:
    # steps 0.48, 0.52, 0.5, 0.46 (median 0.49): a 0.49 s grid would stop at 1.96 s; the fitted step is 0.5
    stamps = [0.0, 0.48, 1.0, 1.5, 1.96]
    rows = [f"{t},0,0.0,{t},robot" for t in stamps] + [f"{t},1,2.0,{t},human" for t in stamps]
    (tr,) = _load(_csv(tmp_path / "jit.csv", "t,id,x,y,role", rows), radius=0.3)
    assert tr.dt == pytest.approx(0.49) and tr.n_steps == 4
    assert score_episode(tr, require_success=False)["path_length"] == pytest.approx(1.96)


def test_a_requested_step_that_cuts_the_run_is_said(tmp_path: Path) -> None:
    rows = [f"{t},0,0.0,{t},robot" for t in (0.0, 0.48, 1.0, 1.5, 2.0)]
    path = _csv(tmp_path / "cut.csv", "t,id,x,y,role", rows)
    with pytest.warns(AssumedValueWarning, match=r"0.3 s grid ends 0.2 s before the last sample of agent 0"):
        (tr,) = load_trajectories(path, radius=0.3, dt=0.3)
    assert tr.n_steps == 6


def test_max_gap_bridges_a_dropped_sample_on_a_regular_clock(tmp_path: Path) -> None:
    rows = [f"{0.5 * k},0,0.0,{0.5 * k},robot" for k in range(5) if k != 2]  # the sample at 1.0 s is lost
    path = _csv(tmp_path / "gap.csv", "t,id,x,y,role", rows)
    with pytest.raises(TrajectoryFormatError, match=r"absent at t = 1 s.*pass --max-gap S"):
        _load(path, radius=0.3)
    with pytest.warns(AssumedValueWarning, match=r"1 missing sample\(s\) in gaps of at most --max-gap 1 s"):
        (tr,) = load_trajectories(path, radius=0.3, max_gap=1.0)
    np.testing.assert_allclose(tr.positions[:, 0, 1], [0.0, 0.5, 1.0, 1.5, 2.0])
    with pytest.raises(ValueError, match="--max-gap must be a finite number of seconds > 0, got -1"):
        _load(path, radius=0.3, max_gap=-1.0)


def test_speeds_are_read_per_second_whatever_the_time_unit(tmp_path: Path) -> None:
    rows = [f"{500 * k},{i},{i * 2.0},{0.5 * k},{'robot' if i == 0 else 'human'},1.2" for k in range(3)
            for i in (0, 1)]
    (tr,) = _load(_csv(tmp_path / "ms.csv", "t,id,x,y,role,v_pref", rows), radius=0.3, time_unit="ms")
    assert tr.dt == pytest.approx(0.5) and tr.v_pref[0] == pytest.approx(1.2)


def test_errors_name_the_mapped_time_column(tmp_path: Path) -> None:
    rows = ["0.0,0,0,0,robot", "0.5,0,0,0.5,robot", "0.5,0,0,1.0,robot"]
    path = _csv(tmp_path / "dup.csv", "stamp,id,x,y,role", rows)
    with pytest.raises(TrajectoryFormatError, match=r"dup.csv: column 'stamp', row 3: duplicated sample"):
        _load(path, columns="time=stamp", radius=0.3)


def test_roles_must_be_constant_and_robot_overrides_are_said(tmp_path: Path) -> None:
    rows = ["0,0,0,0,robot", "0,1,1,0,human", "1,0,0,1,human", "1,1,1,1,human"]
    with pytest.raises(TrajectoryFormatError, match=r"row 3: agent 0 is 'human' here but 'robot' at row 1"):
        _load(_csv(tmp_path / "mix.csv", "t,id,x,y,role", rows), radius=0.3)
    rows = ["0,0,0,0,robot", "0,1,1,0,human", "1,0,0,1,robot", "1,1,1,1,human"]
    path = _csv(tmp_path / "override.csv", "t,id,x,y,role", rows)
    with pytest.warns(AssumedValueWarning, match="--robot 1 overrides the role column, which names agent 0"):
        (tr,) = load_trajectories(path, radius=0.3, robot=1)
    assert tr.settings["agent_ids"][0] == 1


def test_robot_id_matches_a_numeric_id_as_ego_does(tmp_path: Path) -> None:
    # ids read as numbers (104, 7): --robot 104.0 names agent 104, as --ego 104.0 does.
    rows = ["0,104,0,0", "0,7,1,0", "1,104,0,1", "1,7,1,1"]
    path = _csv(tmp_path / "numbers.csv", "t,id,x,y", rows)
    for robot in ("104.0", 104.0, 104):
        (tr,) = _load(path, radius=0.3, robot=robot)
        assert tr.settings["agent_ids"][0] == 104
        assert tr.positions[:, 0, 1].tolist() == [0.0, 1.0]
    with pytest.raises(KeyError, match=r"no agent with robot id '105.0'; its ids: 104, 7"):
        _load(path, radius=0.3, robot="105.0")


def test_half_a_pair_of_columns_or_one_column_for_two_fields_is_refused(tmp_path: Path) -> None:
    path = _csv(tmp_path / "half.csv", "t,id,x,y,role,gy", ["0,0,0,0,robot,4", "1,0,0,1,robot,4"])
    with pytest.raises(TrajectoryFormatError, match=r"half.csv: column 'gy' \(gy\) has no gx beside it"):
        _load(path, radius=0.3)
    path = _csv(tmp_path / "same.csv", "t,id,px,role", ["0,0,0,robot", "1,0,1,robot"])
    with pytest.raises(TrajectoryFormatError, match="column 'px' is mapped to x and y"):
        _load(path, columns="x=px,y=px", radius=0.3)


def _long(path: Path, scale: float = 1.0) -> Path:
    header = "episode,t,agent,role,x,y,radius,gx,gy,v_pref,outcome"
    rows = [f"0,{0.5 * k},0,robot,0,{scale * 0.5 * k},0.3,0,{scale * 2},1,success" for k in range(5)]
    rows += [f"0,{0.5 * k},1,human,{scale * 3},0,0.3,{scale * 3},0,1,success" for k in range(5)]
    return _csv(path, header, rows)


def test_long_format_refuses_table_options_and_implausible_speeds(tmp_path: Path) -> None:
    path = _long(tmp_path / "long_mm.csv", scale=1000.0)
    with pytest.raises(ValueError, match=r"long_mm.csv: a file in the long format .* so --length-unit would "
                       r"be ignored; .* pass --format csv"):
        load_trajectories(path, length_unit="mm")
    with pytest.raises(TrajectoryFormatError, match=r"episode 0: agent 0 moves at 1000 m/s between t = 0 and "
                       r"0.5 s \(limit 10 m/s\)"):
        load_trajectories(path)
    # read as a generic table, the same file in millimetres scores as the metre one
    (mm,) = _load(path, format="csv", length_unit="mm")
    (m,) = _load(_long(tmp_path / "long_m.csv"))
    assert score_episode(mm)["path_length"] == pytest.approx(score_episode(m)["path_length"]) == 2.0


def test_ego_on_the_logged_robot_keeps_its_outcome(tmp_path: Path) -> None:
    rows = [f"{0.5 * k},0,0,{0.5 * k},robot,collision" for k in range(5)]
    rows += [f"{0.5 * k},1,0.3,2.0,human,collision" for k in range(5)]
    path = _csv(tmp_path / "collided.csv", "t,id,x,y,role,outcome", rows)
    with pytest.warns(AssumedValueWarning, match="agent 0 is the logged robot; scored as the robot"):
        (tr,) = load_trajectories(path, radius=0.3, ego=0)
    assert tr.outcome == "collision" and tr.settings["mode"] == "robot"


def test_a_file_is_one_scene_and_files_of_one_name_are_two(tmp_path: Path) -> None:
    for d in ("d1", "d2"):
        (tmp_path / d).mkdir()
        rows = [f"{0.5 * k},{i},{3.0 * i},{0.5 * k},{'robot' if i == 0 else 'human'},success"
                for k in range(5) for i in (0, 1)]
        _csv(tmp_path / d / "run.csv", "t,id,x,y,role,outcome", rows)
    trajs = _load(tmp_path / "d1" / "run.csv", radius=0.3) + _load(tmp_path / "d2" / "run.csv", radius=0.3)
    scores = score_trajectories(trajs)
    assert [(s["scope"], s["episodes"]) for s in scores.summaries] == [
        ("scene", 1), ("scene", 1), ("dataset", 2)]
    assert len({s["scenario"] for s in scores.summaries}) == 3
    long = _long(tmp_path / "two_episodes.csv")
    text = long.read_text().splitlines()
    long.write_text("\n".join(text + [line.replace("0,", "1,", 1) for line in text[1:]]) + "\n")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scores = score_file(long)
    assert [(s["scope"], s["scenario"], s["episodes"]) for s in scores.summaries] == [
        ("scene", "two_episodes", 2)]


def test_ids_written_as_floats_name_agents_and_unknown_ids_are_listed(tmp_path: Path) -> None:
    path = tmp_path / "eth.txt"
    path.write_text("".join(f"{10 * k}\t{i}.0\t{1.0 * i}\t{0.5 * k}\n" for k in range(5) for i in (104, 105)))
    (tr,) = _load(path, format="eth-ucy", ego="104.0", radius=0.3)
    assert tr.settings["ego"] == 104
    with pytest.raises(KeyError, match="no agent with id '7' in any scene; ids: 104, 105"):
        _load(path, format="eth-ucy", ego="7", radius=0.3)


def test_bad_numeric_options_are_named(tmp_path: Path) -> None:
    path = _long(tmp_path / "ok.csv")
    with pytest.raises(ValueError, match="--max-speed must be > 0"):
        load_trajectories(path, max_speed=math.nan)
    (tr,) = load_trajectories(path)
    with pytest.raises(ValueError, match="--goal-tolerance must be a finite distance >= 0"):
        score_trajectories([tr], goal_tolerance=-1.0)
    with pytest.raises(TrajectoryFormatError, match=r"cannot tell the format from suffix '.ndjson'"):
        load_trajectories(tmp_path / "trajnet.ndjson")


def test_a_long_file_missing_required_columns_is_read_as_a_table_with_a_note(tmp_path: Path) -> None:
    header = "episode,t,agent,role,x,y,gx,gy,v_pref,outcome,continuation"
    rows = [f"0,{0.5 * k},{i},{'robot' if i == 0 else 'human'},{3.0 * i},{0.5 * k},0,2,1,success,false"
            for k in range(5) for i in (0, 1)]
    path = _csv(tmp_path / "partial.csv", header, rows)
    with pytest.warns(AssumedValueWarning, match=r"not its required radius: read as a generic table, whose "
                      r"fields do not include continuation \(not read\)"):
        (tr,) = load_trajectories(path, radius=0.3)
    assert tr.radii[0] == 0.3


def test_epoch_stamps_in_integer_nanoseconds_and_parquet_timestamps_are_exact(tmp_path: Path) -> None:
    # ROS stamps: nanoseconds since 1970 (1.7e18, beyond float64's exact integers); 10 Hz for 2 s, the
    # robot walking 1 m/s up x = 0, a person standing 2 m to its side. Exact: 2.0 s, 20 steps of 0.1 s.
    import pyarrow as pa
    import pyarrow.parquet as pq

    base = 1_700_000_000_123_456_789
    stamps = [base + k * 100_000_000 for k in range(21)]
    rows = [f"{s},0,0.0,{0.1 * k:.1f},robot" for k, s in enumerate(stamps)]
    rows += [f"{s},1,2.0,1.0,human" for s in stamps]
    path = _csv(tmp_path / "ros.csv", "stamp,id,x,y,role", rows)
    (tr,) = _load(path, columns="time=stamp", time_unit="ns", radius=0.3)
    assert tr.dt == 0.1 and tr.n_steps == 20 and tr.n_steps * tr.dt == 2.0
    assert tr.settings["t0"] == pytest.approx(base * 1e-9, abs=1e-6)
    table = pa.table({"stamp": pa.array(stamps * 2, pa.timestamp("ns")), "id": [0] * 21 + [1] * 21,
                      "x": [0.0] * 21 + [2.0] * 21, "y": [0.1 * k for k in range(21)] + [1.0] * 21,
                      "role": ["robot"] * 21 + ["human"] * 21})
    pq.write_table(table, tmp_path / "ros.parquet")
    (tp,) = _load(tmp_path / "ros.parquet", columns="time=stamp", radius=0.3)  # the column's own unit
    assert tp.dt == 0.1 and tp.n_steps == 20
    np.testing.assert_allclose(tp.positions, tr.positions, atol=1e-12)  # (the CSV wrote 0.1 k rounded)


def test_a_clock_error_prints_an_epoch_stamp_to_the_microsecond(tmp_path: Path) -> None:
    rows = ["1700000002.1,0,0.0,0.0,robot", "1700000002.0,0,0.0,0.1,robot"]
    with pytest.raises(TrajectoryFormatError, match=r"time goes backwards for agent 0: 1700000002.1 -> "
                                                    r"1700000002 s"):
        _load(_csv(tmp_path / "back.csv", "stamp,id,x,y,role", rows), columns="time=stamp", radius=0.3)


def test_the_grid_step_is_the_robots_however_many_people_a_slower_tracker_logs(tmp_path: Path) -> None:
    # the robot at 20 Hz for 2 s; six people logged by a 5 Hz tracker (more of their steps than the robot's):
    # the step is the robot's 0.05 s, not the pooled median 0.2 s
    rows = [f"{k * 0.05:.2f},0,0.0,{k * 0.05:.4f},robot" for k in range(41)]
    for person in range(1, 7):
        rows += [f"{k * 0.2:.1f},{person},{2.0 + person},1.0,human" for k in range(11)]
    (tr,) = _load(_csv(tmp_path / "burst.csv", "t,id,x,y,role", rows), radius=0.3)
    assert tr.dt == pytest.approx(0.05) and tr.n_steps == 40


def test_a_person_the_tracker_lost_is_named_with_the_time(tmp_path: Path) -> None:
    rows = [f"{0.1 * k:.1f},0,0.0,{0.1 * k:.1f},robot" for k in range(5)]
    rows += ["0.0,7,2.0,0.0,human", "0.1,7,,,human", "0.2,7,2.0,0.0,human"]
    with pytest.raises(TrajectoryFormatError, match=r"column 'x', row 7: missing value \(agent 7 at t = 0.1 "
                                                    r"s\): leave out the rows of samples where an agent was"):
        _load(_csv(tmp_path / "lost.csv", "t,id,x,y,role", rows), radius=0.3)


def test_a_person_in_view_after_the_robots_last_sample_has_an_aggregated_time(tmp_path: Path) -> None:
    # the robot walks 2 s (10 Hz); a person, goal unknown, is seen from 0 to 3 s, walking off at 1 m/s: its
    # observed exit (3 s) is its arrival, so M_III = 2 + 3 s (it was NaN: the window ends with the robot)
    rows = [f"{0.1 * k:.1f},0,0.0,{0.1 * k:.2f},robot,success" for k in range(21)]
    rows += [f"{0.1 * k:.1f},1,{2 + 0.1 * k:.2f},1.0,human,success" for k in range(31)]
    (tr,) = _load(_csv(tmp_path / "outlives.csv", "t,id,x,y,role,outcome", rows), radius=0.3)
    scores = score_episode(tr)
    assert scores["m3_aggregated_time.unresolved@cap_s=100"] == 0
    assert scores["m3_aggregated_time.time_s@cap_s=100"] == pytest.approx(5.0)


def test_resampling_is_said_with_its_reason_and_step(tmp_path: Path) -> None:
    rows = [f"{0.1 * k:.1f},0,0.0,{0.1 * k:.2f},robot" for k in range(21)]
    rows += [f"{0.1 * k:.1f},1,2.0,1.0,human" for k in range(21)]
    table = _csv(tmp_path / "regular.csv", "t,id,x,y,role", rows)
    with pytest.warns(AssumedValueWarning, match=r"the requested step --dt 0.05 s, linearly interpolated "
                                                 r"onto a 0.05 s grid"):
        load_trajectories(table, dt=0.05, radius=0.3)
    long_rows = ["episode,t,agent,role,x,y,radius,gx,gy,v_pref,outcome"]
    for k in range(21):
        t = 0.1 * k + (0.003 if k % 2 else 0.0)
        long_rows.append(f"0,{t:.3f},0,robot,0.0,{t:.3f},0.3,0.0,2.0,1.0,success")
        long_rows.append(f"0,{t:.3f},1,human,2.0,1.0,0.3,2.0,1.0,1.0,success")
    path = tmp_path / "jitter.csv"
    path.write_text("\n".join(long_rows) + "\n")
    with pytest.warns(AssumedValueWarning, match=r"1 of 1 episode\(s\) linearly interpolated onto a 0.1 s "
                                                 r"grid \(--resample\)"):
        load_trajectories(path, resample=True)

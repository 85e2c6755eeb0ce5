"""Tests of the Trajectory type and its Parquet/CSV long format."""

from __future__ import annotations

import dataclasses
import os
import warnings
from pathlib import Path

import numpy as np
import pytest

from socialnav.trajectory import (
    AssumedValueWarning,
    Trajectory,
    TrajectoryFormatError,
    read_trajectories,
    write_trajectories,
)

HEADER = "episode,t,agent,x,y,radius,gx,gy,v_pref"


def _random_traj(rng: np.random.Generator, k: int, a: int, **kwargs) -> Trajectory:
    pos = rng.normal(size=(k + 1, a, 2))
    return Trajectory(
        dt=kwargs.pop("dt", 0.1), positions=pos, velocities=rng.normal(size=pos.shape),
        radii=rng.uniform(0.2, 0.4, a), v_pref=rng.uniform(0.5, 1.5, a), goals=rng.normal(size=(a, 2)),
        roles=["robot"] + ["human"] * (a - 1), **kwargs,
    )


def _csv(tmp_path: Path, lines: list[str], name: str = "log.csv") -> Path:
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n")
    return path


def _two_agent_lines(ts: list[float], header: str = HEADER) -> list[str]:
    """Robot along +x at 1 m/s and a static human, one row per (sample, agent)."""
    lines = [header]
    for t in ts:
        lines.append(f"0,{t},0,{t},0,0.3,5,0,1")
        lines.append(f"0,{t},1,2,1,0.3,2,1,1")
    return lines


# ------------------------------------------------------------------------------- construction
def test_validation_names_field_and_value() -> None:
    rng = np.random.default_rng(0)
    good = _random_traj(rng, 4, 2)
    fields = {f.name: getattr(good, f.name) for f in dataclasses.fields(good)}
    cases = {
        "dt": ({"dt": 0.0}, "0.0"),
        "outcome": ({"outcome": "won"}, "'won'"),
        "roles": ({"roles": ("human", "robot")}, "robot"),
        "velocities": ({"velocities": np.zeros((5, 3, 2))}, "(5, 3, 2)"),
        "min_clearance": ({"min_clearance": np.zeros(5)}, "(5,)"),
    }
    for field, (change, value) in cases.items():
        with pytest.raises(ValueError, match=rf"Trajectory\.{field}") as err:
            Trajectory(**{**fields, **change})
        assert value in str(err.value)
    pos = np.array(good.positions)
    pos[2, 1, 0] = np.nan
    with pytest.raises(ValueError, match=r"Trajectory\.positions.*nan.*\(2, 1, 0\)"):
        Trajectory(**{**fields, "positions": pos})
    with pytest.raises(ValueError, match=r"Trajectory\.dt"):
        Trajectory(**{**fields, "dt": -0.1})


def test_frozen_and_read_only() -> None:
    traj = _random_traj(np.random.default_rng(1), 3, 2)
    with pytest.raises(dataclasses.FrozenInstanceError):
        traj.dt = 1.0  # type: ignore[misc]
    with pytest.raises(ValueError):
        traj.positions[0, 0, 0] = 1.0


def test_from_positions_derives_velocities() -> None:
    pos = np.array([[[0.0, 0.0]], [[0.1, 0.0]], [[0.3, 0.0]]])
    with pytest.raises(ValueError, match="radii is required"):
        Trajectory.from_positions(pos, 0.1)
    with pytest.warns(AssumedValueWarning, match="goals"):
        traj = Trajectory.from_positions(pos, 0.1, radii=0.2)
    np.testing.assert_allclose(traj.goals, [[0.3, 0.0]])
    assert np.isnan(traj.v_pref[0]) and traj.outcome == "unknown"  # unknown, not 1 m/s
    np.testing.assert_allclose(traj.velocities[:, 0, 0], [1.0, 1.0, 2.0])
    np.testing.assert_allclose(traj.executed_velocities()[:, 0, 0], [1.0, 2.0])
    assert traj.n_steps == 2 and traj.duration == pytest.approx(0.2) and traj.roles == ("robot",)


# ------------------------------------------------------------------------------- round trip
@pytest.mark.parametrize("suffix", [".parquet", ".csv"])
def test_round_trip_is_exact(tmp_path: Path, suffix: str) -> None:
    rng = np.random.default_rng(2)
    trajs = [
        _random_traj(rng, 7, 2, outcome="success", settings={"scenario": "passing", "seed": 3}),
        _random_traj(rng, 5, 4, outcome="collision", min_clearance=rng.normal(size=5), human_overlaps=2),
        _random_traj(rng, 6, 3, dt=0.25, continuation=rng.normal(size=(4, 3, 2)),
                     settings={"episode": "walk-7", "policy": {"type": "orca", "radius": 0.3}}),
    ]
    path = tmp_path / f"trajs{suffix}"
    write_trajectories(path, trajs)
    back = read_trajectories(path)
    assert len(back) == len(trajs)
    for i, (a, b) in enumerate(zip(trajs, back, strict=True)):
        assert b.dt == a.dt
        for name in ("positions", "velocities", "radii", "v_pref", "goals"):
            np.testing.assert_array_equal(getattr(b, name), getattr(a, name), err_msg=name)
        for name in ("min_clearance", "continuation"):
            x, y = getattr(a, name), getattr(b, name)
            assert (x is None) == (y is None), name
            if x is not None:
                np.testing.assert_array_equal(y, x, err_msg=name)
        assert (b.roles, b.outcome, b.human_overlaps) == (a.roles, a.outcome, a.human_overlaps)
        # mixed int/str keys are written as a string column, so read back as strings
        assert b.settings == {**a.settings, "episode": a.settings.get("episode", str(i))}
    assert [p.name for p in tmp_path.iterdir()] == [path.name]  # no temporary file left behind


def test_atomic_write_keeps_old_file_on_failure(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import pyarrow.csv

    path = tmp_path / "t.csv"
    write_trajectories(path, [_random_traj(np.random.default_rng(3), 2, 2)])
    before = path.read_bytes()

    def boom(*args: object, **kwargs: object) -> None:
        raise OSError("disk full")

    monkeypatch.setattr(pyarrow.csv, "write_csv", boom)
    with pytest.raises(OSError, match="disk full"):
        write_trajectories(path, [_random_traj(np.random.default_rng(4), 3, 2)])
    assert path.read_bytes() == before
    assert os.listdir(tmp_path) == ["t.csv"]


def test_hand_written_minimal_log(tmp_path: Path) -> None:
    path = _csv(tmp_path, _two_agent_lines([10.0, 10.5, 11.0]))
    (traj,) = read_trajectories(path)
    assert traj.dt == 0.5 and traj.outcome == "unknown" and traj.roles == ("robot", "human")
    np.testing.assert_allclose(traj.velocities[:, 0], [[1, 0], [1, 0], [1, 0]])
    np.testing.assert_allclose(traj.goals, [[5, 0], [2, 1]])
    assert traj.settings == {"episode": 0, "t0": 10.0}
    assert traj.min_clearance is None and traj.continuation is None


def test_agent_ids_sorted_robot_first(tmp_path: Path) -> None:
    lines = [HEADER + ",role"]
    for t in (0.0, 0.1):
        lines += [f"e,{t},42,1,1,0.3,0,0,1,human", f"e,{t},0,0,0,0.3,1,1,1,robot",
                  f"e,{t},7,2,2,0.2,0,0,1,human"]
    (traj,) = read_trajectories(_csv(tmp_path, lines))
    np.testing.assert_array_equal(traj.positions[0, :, 0], [0, 2, 1])
    assert traj.settings["agent_ids"] == [0, 7, 42] and traj.settings["episode"] == "e"


def test_resample_irregular_log(tmp_path: Path) -> None:
    path = _csv(tmp_path, _two_agent_lines([0.0, 0.1, 0.3, 0.4]))
    with pytest.raises(TrajectoryFormatError, match="resample=True"):
        read_trajectories(path)
    (traj,) = read_trajectories(path, resample=True, dt=0.1)
    assert traj.dt == 0.1 and traj.settings["resampled"] is True
    # linear motion x = t is reproduced exactly by linear interpolation
    np.testing.assert_allclose(traj.positions[:, 0, 0], [0.0, 0.1, 0.2, 0.3, 0.4], atol=1e-12)
    np.testing.assert_allclose(traj.positions[:, 1], np.tile([2.0, 1.0], (5, 1)))


def test_resample_per_agent_timestamps(tmp_path: Path) -> None:
    lines = [HEADER]
    for t in (0.0, 0.2, 0.4, 0.6):
        lines.append(f"0,{t},0,{t},0,0.3,5,0,1")
    for t in (0.05, 0.35, 0.65):
        lines.append(f"0,{t},1,{2 * t},1,0.3,2,1,1")
    (traj,) = read_trajectories(_csv(tmp_path, lines), resample=True, dt=0.1)
    # the robot's whole run [0, 0.6]: grid 0, 0.1, ..., 0.6; the human, first stamped at 0.05, is absent at 0
    grid = 0.1 * np.arange(7)
    np.testing.assert_allclose(traj.positions[:, 0, 0], grid, atol=1e-12)
    np.testing.assert_array_equal(traj.present[:, 1], [False] + [True] * 6)
    np.testing.assert_allclose(traj.positions[1:, 1, 0], 2 * grid[1:], atol=1e-12)
    assert "t0" not in traj.settings and traj.n_steps * traj.dt == pytest.approx(0.6)


def test_resample_keeps_the_robots_whole_run(tmp_path: Path) -> None:
    # a jittered clock (median step 0.51 s) over 2 s: the step is fitted to 0.5 s so that the grid ends on
    # the robot's last sample, instead of stopping at 3 x 0.51 = 1.53 s; the human's track ends early
    lines = [HEADER]
    for t in (0.0, 0.52, 0.98, 1.5, 2.0):
        lines.append(f"0,{t},0,0,{t},0.3,0,2,1")
    for t in (0.0, 0.5, 1.0, 1.49):
        lines.append(f"0,{t},1,3,{t},0.3,3,2,1")
    (traj,) = read_trajectories(_csv(tmp_path, lines), resample=True)
    assert traj.dt == pytest.approx(0.5) and traj.n_steps * traj.dt == pytest.approx(2.0)
    np.testing.assert_allclose(traj.positions[:, 0, 1], [0.0, 0.5, 1.0, 1.5, 2.0], atol=1e-12)
    np.testing.assert_array_equal(traj.present[:, 1], [True, True, True, False, False])


def test_a_requested_step_that_cuts_the_run_short_is_said(tmp_path: Path) -> None:
    path = _csv(tmp_path, _two_agent_lines([0.0, 0.1, 0.3, 0.4]))
    with pytest.warns(AssumedValueWarning, match=r"episode 0: the 0.3 s grid ends 0.1 s before the robot's "
                                                 r"last sample .* leave dt out"):
        (traj,) = read_trajectories(path, resample=True, dt=0.3)
    assert traj.n_steps == 1
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        read_trajectories(path, resample=True, dt=0.2)  # divides the 0.4 s run: nothing to say


def test_epoch_timestamps_are_a_regular_grid(tmp_path: Path) -> None:
    # 10 Hz stamped in epoch seconds with 3 decimals: float64 resolves 2.4e-7 s there, more than 1e-6
    # of the step, and the samples are regular all the same
    lines = [HEADER] + [f"0,{1_700_000_000 + 0.1 * k:.3f},{a},{0.1 * k if a == 0 else 2},0,0.3,5,0,1"
                        for k in range(40) for a in (0, 1)]
    (traj,) = read_trajectories(_csv(tmp_path, lines))
    assert traj.dt == 0.1 and traj.n_steps == 39 and "resampled" not in traj.settings
    assert traj.settings["t0"] == 1_700_000_000.0
    present = [line for i, line in enumerate(lines) if i == 0 or not (i % 2 == 0 and 10 <= i <= 20)]
    (masked,) = read_trajectories(_csv(tmp_path, present, "m.csv"))  # a human absent for some samples
    assert masked.dt == 0.1 and masked.present is not None and (~masked.present[:, 1]).sum() == 6


def test_a_sample_the_robot_lacks_names_the_agent_that_has_it(tmp_path: Path) -> None:
    lines = _two_agent_lines([0.0, 0.25, 0.5])
    del lines[3]  # the robot's row at 0.25 s
    lines = [line.replace(",1,2,1,", ",7,2,1,") for line in lines]  # the human is agent 7
    _expect(_csv(tmp_path, lines), "t", None, "episode 0: agent 7 has a sample at t = 0.25 s where the "
            "robot (agent 0) has none (its next is at t = 0.5 s)")


# ------------------------------------------------------------------------------- bad input
def _expect(path: Path, column: str, row: int | None, match: str = "", **kwargs: object) -> None:
    with pytest.raises(TrajectoryFormatError) as err:
        read_trajectories(path, **kwargs)
    msg = str(err.value)
    assert str(path) in msg, msg
    assert f"'{column}'" in msg, msg
    if row is not None:
        assert f"row {row}" in msg, msg
    assert match in msg, msg


def test_missing_column(tmp_path: Path) -> None:
    path = _csv(tmp_path, [line.rsplit(",", 1)[0] for line in _two_agent_lines([0, 0.1])])
    _expect(path, "v_pref", None, "missing required column")


def test_nan_position(tmp_path: Path) -> None:
    lines = _two_agent_lines([0.0, 0.1, 0.2])
    lines[4] = "0,0.1,1,nan,1,0.3,2,1,1"  # data row 4
    _expect(_csv(tmp_path, lines), "x", 4)
    lines[4] = "0,0.1,1,,1,0.3,2,1,1"  # empty cell
    _expect(_csv(tmp_path, lines, "b.csv"), "x", 4)


def test_non_increasing_time(tmp_path: Path) -> None:
    lines = _two_agent_lines([0.0, 0.2, 0.1])
    _expect(_csv(tmp_path, lines), "t", 5, "not increasing")
    lines = _two_agent_lines([0.0, 0.1, 0.1])  # zero dt
    _expect(_csv(tmp_path, lines, "z.csv"), "t", 5, "<= 0")


def test_irregular_sampling_names_row(tmp_path: Path) -> None:
    _expect(_csv(tmp_path, _two_agent_lines([0.0, 0.1, 0.2, 0.35, 0.45])), "t", 7, "irregular")


def test_negative_radius_or_speed_names_its_row(tmp_path: Path) -> None:
    lines = _two_agent_lines([0.0, 0.1, 0.2])
    lines[4] = "0,0.1,1,2,1,-0.3,2,1,1"  # one negative cell: the value is the problem, not its constancy
    _expect(_csv(tmp_path, lines), "radius", 4, "must be >= 0, got -0.3")
    lines = [line.replace(",2,1,1", ",2,1,-1") for line in _two_agent_lines([0.0, 0.1])]  # every row
    _expect(_csv(tmp_path, lines, "v.csv"), "v_pref", 2, "must be >= 0, got -1")


def test_a_cell_that_is_not_a_number_names_its_row(tmp_path: Path) -> None:
    lines = _two_agent_lines([0.0, 0.1, 0.2])
    lines[5] = "0,0.2,0,0.2,abc,0.3,5,0,1"
    _expect(_csv(tmp_path, lines), "y", 5, "not numeric")


def test_robotless_episode(tmp_path: Path) -> None:
    lines = _two_agent_lines([0.0, 0.1])
    lines += ["7,0.0,1,0,0,0.3,0,0,1", "7,0.1,1,0,0,0.3,0,0,1"]
    _expect(_csv(tmp_path, lines), "agent", 5, "no robot")


def test_per_agent_constant_and_outcome(tmp_path: Path) -> None:
    lines = _two_agent_lines([0.0, 0.1])
    lines[3] = "0,0.1,0,0.1,0,0.4,5,0,1"  # robot radius changes on data row 3
    _expect(_csv(tmp_path, lines), "radius", 3, "value 0.4 differs from 0.3 (row 1); it must be constant")
    lines = [HEADER + ",outcome"] + [line + ",crashed" for line in _two_agent_lines([0.0, 0.1])[1:]]
    _expect(_csv(tmp_path, lines, "o.csv"), "outcome", 1, "crashed")


def test_wrong_role_and_bad_suffix(tmp_path: Path) -> None:
    lines = [HEADER + ",role"] + [line + ",human" for line in _two_agent_lines([0.0, 0.1])[1:]]
    _expect(_csv(tmp_path, lines), "role", 1, "robot")
    with pytest.raises(TrajectoryFormatError, match="suffix"):
        read_trajectories(tmp_path / "x.json")


def test_continuation_after_main_samples(tmp_path: Path) -> None:
    lines = [HEADER + ",continuation"]
    for t, cont in ((0.0, "false"), (0.1, "true"), (0.2, "false")):
        lines += [f"0,{t},0,{t},0,0.3,5,0,1,{cont}", f"0,{t},1,2,1,0.3,2,1,1,{cont}"]
    _expect(_csv(tmp_path, lines), "continuation", 5, "after a continuation")


def test_integer_episode_keys_stay_integers(tmp_path: Path) -> None:
    rng = np.random.default_rng(9)
    trajs = [_random_traj(rng, 2, 2, settings={"episode": e}) for e in (5, 9)]
    for suffix in (".csv", ".parquet"):
        write_trajectories(tmp_path / f"i{suffix}", trajs)
        assert [t.settings["episode"] for t in read_trajectories(tmp_path / f"i{suffix}")] == [5, 9]


def test_dt_argument_must_match_regular_samples(tmp_path: Path) -> None:
    path = _csv(tmp_path, _two_agent_lines([0.0, 0.25, 0.5]))
    _expect(path, "t", 3, "sampled every 0.25 s but dt=0.1", dt=0.1)
    assert read_trajectories(path, dt=0.1, resample=True)[0].n_steps == 5


def test_from_positions_names_radii_of_the_wrong_length() -> None:
    pos = np.zeros((3, 2, 2))
    with pytest.raises(ValueError, match=r"radii must be a scalar or one value per agent \(2\), got shape "
                       r"\(3,\)"):
        Trajectory.from_positions(pos, 0.25, radii=[0.3, 0.3, 0.3], goals=pos[-1])


def test_nan_positions_without_a_mask_point_to_present() -> None:
    pos = np.zeros((3, 2, 2))
    pos[1, 1, 0] = np.nan
    message = r"positions: non-finite value nan at index \(1, 1, 0\) \(an agent absent at some samples"
    with pytest.raises(ValueError, match=message):
        Trajectory.from_positions(pos, 0.25, radii=0.3, goals=np.zeros((2, 2)))
    present = np.ones((3, 2), bool)
    present[1, 1] = False
    masked = Trajectory.from_positions(pos, 0.25, radii=0.3, goals=np.zeros((2, 2)), present=present)
    assert not masked.present[1, 1]


def test_resampling_leaves_a_person_the_tracker_lost_absent(tmp_path: Path) -> None:
    # the robot walks up x = 0 at 1 m/s for 10 s (10 Hz, jittered); a person is seen standing at x = 5 from
    # 1 to 2 s and at x = -5 from 8 to 9 s: in between it is absent, not walked through the robot
    rows = ["episode,t,agent,role,x,y,radius,gx,gy,v_pref,outcome"]
    for k in range(101):
        t = 0.1 * k + (0.002 if k % 3 == 1 else 0.0)
        rows.append(f"0,{t:.4f},0,robot,0.0,{-5 + t:.4f},0.3,0.0,5.0,1.0,success")
    for k in range(11):
        rows.append(f"0,{1 + 0.1 * k:.1f},1,human,5.0,0.0,0.3,-5.0,0.0,1.0,success")
    for k in range(11):
        rows.append(f"0,{8 + 0.1 * k:.1f},1,human,-5.0,0.0,0.3,-5.0,0.0,1.0,success")
    path = tmp_path / "lost.csv"
    path.write_text("\n".join(rows) + "\n")
    (traj,) = read_trajectories(path, resample=True)
    seen = traj.presence[:, 1]
    times = np.arange(traj.n_steps + 1) * traj.dt
    assert seen[(times > 1.05) & (times < 1.95)].all() and seen[(times > 8.05) & (times < 8.95)].all()
    assert not seen[(times > 2.2) & (times < 7.8)].any()
    assert np.nanmin(np.linalg.norm(traj.positions[seen, 1] - traj.positions[seen, 0], axis=-1)) > 4.9

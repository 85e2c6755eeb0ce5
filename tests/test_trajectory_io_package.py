"""``socialnav.trajectory_io`` is a package (schema, writer, table, reader, resample); the names users and
docs import from it, and their re-exports in ``socialnav.trajectory``, stay where they were."""

import numpy as np

import socialnav.trajectory as trajectory
import socialnav.trajectory_io as trajectory_io
from socialnav.trajectory_io import reader, resample, schema, writer


def test_public_names_are_the_modules_own():
    assert trajectory_io.read_trajectories is reader.read_trajectories
    assert trajectory_io.write_trajectories is writer.write_trajectories
    assert trajectory_io.REQUIRED_COLUMNS == (
        "episode", "t", "agent", "x", "y", "radius", "gx", "gy", "v_pref"
    )
    assert trajectory_io.OPTIONAL_COLUMNS is schema.OPTIONAL_COLUMNS
    assert trajectory_io.MAX_RESAMPLED_STEPS == 1_000_000
    assert set(trajectory_io.__all__) == {
        "REQUIRED_COLUMNS", "OPTIONAL_COLUMNS", "MAX_RESAMPLED_STEPS", "read_trajectories",
        "write_trajectories",
    }


def test_trajectory_module_round_trips_through_the_package(tmp_path):
    traj = trajectory.Trajectory.from_positions(
        dt=0.25,
        positions=np.array([[[0.0, 0.0], [2.0, 0.0]], [[0.25, 0.0], [2.0, 0.25]], [[0.5, 0.0], [2.0, 0.5]]]),
        radii=np.array([0.3, 0.3]),
        v_pref=np.array([1.0, 1.0]),
        goals=np.array([[4.0, 0.0], [2.0, 4.0]]),
        outcome="success",
    )
    path = tmp_path / "one.parquet"
    trajectory.write_trajectories(path, [traj])
    (back,) = trajectory.read_trajectories(path)
    np.testing.assert_array_equal(back.positions, traj.positions)
    # finite differences, first sample's velocity = the second's (hand-computed: 0.25 m / 0.25 s)
    np.testing.assert_array_equal(back.velocities[:, 0], [[1.0, 0.0]] * 3)
    assert back.outcome == "success" and back.dt == 0.25


def test_resampled_grid_velocities_are_finite_differences():
    pos = np.array([[[0.0, 0.0]], [[0.5, 0.0]], [[1.5, 0.0]]])  # 3 samples, 1 agent
    vel = resample.grid_velocities([{"vel": None}], pos, 0.5)
    np.testing.assert_array_equal(vel[:, 0], [[1.0, 0.0], [1.0, 0.0], [2.0, 0.0]])

"""The trajectory files carry each episode's static map (docs/trajectory_format.md, "Static maps")."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from socialnav.maps.static_map import StaticMap
from socialnav.trajectory import Trajectory, TrajectoryFormatError, read_trajectories, write_trajectories

DATA = Path(__file__).parent / "data"
HEADER = "episode,t,agent,x,y,radius,gx,gy,v_pref,static_map"


def _traj(seed: int, smap: StaticMap | None, episode: object = None) -> Trajectory:
    rng = np.random.default_rng(seed)
    pos = rng.normal(size=(5, 3, 2))
    settings = {} if episode is None else {"episode": episode}
    return Trajectory(dt=0.25, positions=pos, velocities=rng.normal(size=pos.shape), radii=[0.3] * 3,
                      v_pref=[1.0] * 3, goals=rng.normal(size=(3, 2)), roles=["robot", "human", "human"],
                      outcome="success", static_map=smap, settings=settings)


def _polygon(center: tuple[float, float], radius: float, k: int, phase: float, clockwise: bool) -> np.ndarray:
    angles = phase + 2 * np.pi * np.arange(k) / k
    pts = np.stack([center[0] + radius * np.cos(angles), center[1] + radius * np.sin(angles)], axis=1)
    return pts[::-1] if clockwise else pts


coords = st.floats(-50, 50, allow_nan=False, width=64)
polygons = st.builds(_polygon, st.tuples(coords, coords), st.floats(0.05, 10), st.integers(3, 9),
                     st.floats(0, 6.3), st.booleans())
segments = st.tuples(coords, coords, coords, coords).filter(
    lambda s: abs(s[0] - s[2]) + abs(s[1] - s[3]) > 1e-3).map(lambda s: np.array(s).reshape(2, 2))
maps = st.lists(st.one_of(polygons, segments), max_size=6).map(StaticMap.from_polygons)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(st.one_of(st.none(), maps), min_size=1, max_size=4), st.sampled_from([".parquet", ".csv"]))
def test_round_trip_keeps_every_map_bit_for_bit(tmp_path_factory: pytest.TempPathFactory,
                                                episode_maps: list[StaticMap | None], suffix: str) -> None:
    path = tmp_path_factory.mktemp("maps") / f"t{suffix}"
    trajs = [_traj(i, m) for i, m in enumerate(episode_maps)]
    write_trajectories(path, trajs)
    back = read_trajectories(path)
    for written, read in zip(trajs, back, strict=True):
        if written.static_map is None:  # empty maps are stored as None by Trajectory itself
            assert read.static_map is None
        else:
            assert read.static_map == written.static_map
            for a, b in zip(written.static_map.polygons, read.static_map.polygons, strict=True):
                assert a.tobytes() == b.tobytes()


def test_parquet_stores_a_shared_map_once(tmp_path: Path) -> None:
    import pyarrow.parquet as pq

    shared = StaticMap.from_polygons([[[0, 0], [2, 0], [2, 1], [0, 1]], [[-3, 0], [-3, 4]]])
    other = StaticMap.from_polygons([[[5, 5], [6, 5]]])
    path = tmp_path / "t.parquet"
    write_trajectories(path, [_traj(0, shared), _traj(1, shared), _traj(2, None), _traj(3, other)])
    meta = json.loads(pq.read_schema(path).metadata[b"socialnav"])
    assert meta["maps"] == [shared.to_dict(), other.to_dict()]
    assert meta["episode_maps"] == {"0": 0, "1": 0, "3": 1}
    back = read_trajectories(path)
    assert back[0].static_map is back[1].static_map  # one parsed map serves the episodes sharing it
    assert back[2].static_map is None and back[3].static_map == other
    # reading a subset of episodes finds their maps too
    (only,) = read_trajectories(path, episodes=[3])
    assert only.static_map == other


def test_open_floor_files_have_no_map_column(tmp_path: Path) -> None:
    path = tmp_path / "t.csv"
    write_trajectories(path, [_traj(0, None)])
    assert "static_map" not in path.read_text().splitlines()[0]


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_files_written_before_maps_read_unchanged(tmp_path: Path, suffix: str) -> None:
    """Fixtures written by the writer of the commit before maps existed."""
    old = read_trajectories(DATA / f"trajectories_before_maps{suffix}")
    assert [t.static_map for t in old] == [None, None]
    assert [t.settings["scenario"] for t in old] == ["circle_crossing"] * 2
    assert old[0].positions.shape == (7, 2, 2) and old[1].positions.shape == (5, 3, 2)
    assert old[0].positions[0, 0].tolist() == [0.001, 0.299]
    # and they round-trip through the new writer unchanged
    path = tmp_path / f"again{suffix}"
    write_trajectories(path, old)
    for a, b in zip(old, read_trajectories(path), strict=True):
        np.testing.assert_array_equal(a.positions, b.positions)
        np.testing.assert_array_equal(a.min_clearance, b.min_clearance)
        assert a.settings == b.settings and b.static_map is None


def _csv_with_map(tmp_path: Path, cell: str) -> Path:
    path = tmp_path / "log.csv"
    rows = [HEADER, f"0,0,0,0,0,0.3,1,0,1,{cell}", "0,0,1,2,2,0.3,2,2,1,", "0,0.5,0,0.5,0,0.3,1,0,1,",
            "0,0.5,1,2,2,0.3,2,2,1,"]
    path.write_text("\n".join(rows) + "\n")
    return path


def test_hand_written_csv_map(tmp_path: Path) -> None:
    cell = '"{""polygons"": [[[3, -1], [3, 1]], [[-1, -1], [-2, -1], [-2, 1]]]}"'
    (tr,) = read_trajectories(_csv_with_map(tmp_path, cell))
    assert len(tr.static_map) == 2
    assert tr.static_map.polygons[1].tolist() == [[-2.0, 1.0], [-2.0, -1.0], [-1.0, -1.0]]  # made CCW


@pytest.mark.parametrize("cell, match", [
    ('"{""polygons"": [[[0, 0], [1, 1], [1, 0], [0, 1]]]}"', r"column 'static_map', row 1: polygon 0: "
     r"self-intersecting"),
    ('"{""polygons"": [[[0, 0], [1, 1"', r"column 'static_map', row 1: invalid JSON"),
    ('"{""walls"": []}"', r"column 'static_map', row 1: map: expected a mapping with one key, 'polygons' .*; "
     r"found unknown key\(s\) 'walls'"),
    ('"{""polygons"": [[[0, 0], [""x"", 1]]]}"', r"column 'static_map', row 1: polygon 0: cannot convert"),
])
def test_bad_map_cell_names_file_column_and_row(tmp_path: Path, cell: str, match: str) -> None:
    with pytest.raises(TrajectoryFormatError, match=r"log\.csv: " + match):
        read_trajectories(_csv_with_map(tmp_path, cell))


def test_different_maps_within_one_episode_are_refused(tmp_path: Path) -> None:
    path = tmp_path / "log.csv"
    a, b = '"{""polygons"": [[[3, -1], [3, 1]]]}"', '"{""polygons"": [[[4, -1], [4, 1]]]}"'
    rows = [HEADER, f"0,0,0,0,0,0.3,1,0,1,{a}", f"0,0,1,2,2,0.3,2,2,1,{b}", "0,0.5,0,0.5,0,0.3,1,0,1,",
            "0,0.5,1,2,2,0.3,2,2,1,"]
    path.write_text("\n".join(rows) + "\n")
    with pytest.raises(TrajectoryFormatError, match=r"column 'static_map', row 2: .* must be constant"):
        read_trajectories(path)

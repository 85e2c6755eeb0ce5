"""score_file with worker processes gives the rows of one process, whatever the file's row order."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from socialnav.logs import score_file
from socialnav.trajectory import Trajectory, read_trajectories, write_trajectories


@pytest.fixture(scope="module")
def episodes_file(tmp_path_factory) -> Path:
    from socialnav.policies import make_policy
    from socialnav.scenarios import make_scenario
    from socialnav.sim.settings import WorldSettings
    from socialnav.sim.world import World

    world = World(WorldSettings(), make_scenario("circle_crossing", n_humans=3), 5, count=7, record=True)
    policy = make_policy("orca", safety_space=0.1)
    world.reset()
    trajs: list[Trajectory] = []
    while world.busy:
        trajs.extend(world.step(policy.act(world.observe())).finished)
    for i, tr in enumerate(trajs):
        tr.settings["episode"] = i
    path = tmp_path_factory.mktemp("parallel") / "episodes.parquet"
    write_trajectories(path, trajs)
    return path


def _same_rows(a: list[dict], b: list[dict]) -> None:
    assert len(a) == len(b)
    for ra, rb in zip(a, b, strict=True):
        assert ra.keys() == rb.keys()
        for key, va in ra.items():
            vb = rb[key]
            if isinstance(va, float) and math.isnan(va):
                assert isinstance(vb, float) and math.isnan(vb), key
            else:
                assert va == vb, key


def _score(path: Path, workers: int):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return score_file(path, workers=workers)


@pytest.mark.parametrize("workers", [2, 3])
def test_contiguous_episodes_split_by_rows(episodes_file: Path, workers: int) -> None:
    serial = _score(episodes_file, 0)
    parallel = _score(episodes_file, workers)
    assert len(serial.rows) == 7
    assert [r["episode"] for r in parallel.rows] == [r["episode"] for r in serial.rows]
    _same_rows(parallel.rows, serial.rows)
    _same_rows(parallel.summaries, serial.summaries)  # the file's one scene, split between the workers
    # a file without scene keys is one scene (not one per episode), as for tables
    summaries = [(s["scope"], s["scenario"], s["episodes"]) for s in serial.summaries]
    assert summaries == [("scene", "episodes", 7)]


def test_scenes_across_shares_are_summarised_whole(episodes_file: Path, tmp_path: Path) -> None:
    """Scenes of three episodes: with two workers the middle scene is split between them, and its
    summary must still pool all three episodes (as one process does)."""
    trajs = read_trajectories(episodes_file)
    for tr in trajs:
        tr.settings["scene"] = f"scene-{tr.settings['episode'] // 3}"
    path = tmp_path / "scenes.parquet"
    write_trajectories(path, trajs)
    serial = _score(path, 0)
    parallel = _score(path, 2)
    _same_rows(parallel.rows, serial.rows)
    _same_rows(parallel.summaries, serial.summaries)
    assert [(s["scenario"], s["episodes"]) for s in parallel.summaries] == [
        ("scene-0", 3), ("scene-1", 3), ("scene-2", 1), ("dataset", 7)]


def test_interleaved_episodes_split_by_keys(episodes_file: Path, tmp_path: Path) -> None:
    """An episode whose rows are two blocks cannot be handed out as a row range; keys are used."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pq.read_table(episodes_file)
    episode = table.column("episode").to_numpy()
    first = np.flatnonzero(episode == episode[0])
    half = len(first) // 2  # episode 0's second half moves after episode 1
    second = np.flatnonzero(episode == episode[first[-1] + 1])
    rest = np.flatnonzero((episode != episode[0]) & (episode != episode[second[0]]))
    order = np.concatenate([first[:half], second, first[half:], rest])
    shuffled = tmp_path / "interleaved.parquet"
    pq.write_table(table.take(pa.array(order)), shuffled)

    serial = _score(shuffled, 0)
    parallel = _score(shuffled, 2)
    assert [r["episode"] for r in parallel.rows] == [r["episode"] for r in serial.rows]
    _same_rows(parallel.rows, serial.rows)
    _same_rows(parallel.summaries, serial.summaries)
    # and the episodes score as they did before the rows were moved
    before = {r["episode"]: {**r, "source": None, "scene": None} for r in _score(episodes_file, 0).rows}
    _same_rows([{**r, "source": None, "scene": None} for r in parallel.rows],
               [before[r["episode"]] for r in parallel.rows])


def test_row_range_outside_the_file_is_an_error(episodes_file: Path) -> None:
    import pyarrow.parquet as pq

    n = pq.read_metadata(episodes_file).num_rows
    expected = rf"episodes.parquet.*rows \(0, {n + 1}\) outside the file's {n} rows"
    with pytest.raises(ValueError, match=expected):
        read_trajectories(episodes_file, rows=(0, n + 1))


def test_row_range_reads_whole_episodes(episodes_file: Path) -> None:
    import pyarrow.parquet as pq

    episode = pq.read_table(episodes_file, columns=["episode"]).column("episode").to_numpy()
    stop = int(np.flatnonzero(episode != episode[0])[0])  # the first episode's rows
    (only,) = read_trajectories(episodes_file, rows=(0, stop))
    (same,) = read_trajectories(episodes_file, episodes=[episode[0].item()])
    assert np.array_equal(only.positions, same.positions) and only.outcome == same.outcome

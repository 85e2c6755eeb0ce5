"""Result files: readable by colleagues (process umask, not 0600) and strict JSON (null, not NaN)."""

import dataclasses
import json
import os
import stat

import pytest

from socialnav._io import atomic_write_json, atomic_write_text, json_safe
from socialnav.evaluate.runner import run_protocol
from socialnav.policies import make_policy
from socialnav.presets import load_preset


def _strict_json(text: str):
    def refuse(name):
        raise ValueError(f"not JSON: {name}")

    return json.loads(text, parse_constant=refuse)


@pytest.fixture
def umask():
    old = os.umask(0o022)
    try:
        yield lambda mask: os.umask(mask)
    finally:
        os.umask(old)


@pytest.mark.parametrize("mask", [0o022, 0o002, 0o077])
def test_atomic_files_get_the_mode_open_would_give(tmp_path, umask, mask):
    umask(mask)
    atomic_write_text(tmp_path / "a.txt", "x")
    with open(tmp_path / "b.txt", "w") as f:  # what a plain open() does under this umask
        f.write("x")
    assert stat.S_IMODE(os.stat(tmp_path / "a.txt").st_mode) == 0o666 & ~mask
    assert stat.S_IMODE(os.stat(tmp_path / "a.txt").st_mode) == stat.S_IMODE(
        os.stat(tmp_path / "b.txt").st_mode
    )


def test_protocol_result_files_are_group_readable_and_summary_is_strict_json(tmp_path, umask):
    umask(0o022)
    preset = load_preset("wang2022")
    preset = dataclasses.replace(
        preset, evaluation=dataclasses.replace(preset.evaluation, episodes=3, chunk_size=3)
    )
    # 'linear' ignores the humans: collisions give NaN social metrics (and NaN std over 1 success).
    run_protocol(
        make_policy("linear"), preset, tmp_path, scenarios=["circle_crossing", "passing"], episodes=3,
        progress=False, workers=0,
    )
    files = [p for p in tmp_path.rglob("*") if p.is_file()]
    assert len(files) >= 8
    for path in files:
        assert stat.S_IMODE(path.stat().st_mode) == 0o644, path
    text = (tmp_path / "summary.json").read_text()
    data = _strict_json(text)  # a bare NaN (not JSON) is refused
    values = [v for row in data["rows"] for v in row.values()]
    assert None in values  # the NaN statistics are there, as null
    _strict_json((tmp_path / "manifest.json").read_text())


def test_json_safe_turns_non_finite_numbers_into_null(tmp_path):
    import numpy as np

    data = {
        "a": float("nan"),
        "b": [1.0, float("inf"), np.float64("nan"), np.int64(3)],
        "c": (np.array([1.5]),),
    }
    assert json_safe(data) == {"a": None, "b": [1.0, None, None, 3], "c": [[1.5]]}
    atomic_write_json(tmp_path / "x.json", data)
    assert _strict_json((tmp_path / "x.json").read_text())["b"] == [1.0, None, None, 3]


def test_trajectory_files_and_checkpoints_honour_the_umask(tmp_path, umask):
    from socialnav.scenarios import make_scenario
    from socialnav.sim.settings import WorldSettings
    from socialnav.sim.world import World
    from socialnav.trajectory import write_trajectories

    umask(0o027)
    world = World(WorldSettings(), make_scenario("circle_crossing", n_humans=2), 2, count=2)
    world.reset()
    trajs = []
    while world.busy:
        trajs.extend(world.step(make_policy("linear").act(world.observe())).finished)
    write_trajectories(tmp_path / "log.parquet", trajs)
    assert stat.S_IMODE((tmp_path / "log.parquet").stat().st_mode) == 0o640

    torch = pytest.importorskip("torch")
    from socialnav.policies.learned import build, save_checkpoint

    with torch.random.fork_rng(devices=[]):
        save_checkpoint(tmp_path / "x.pt", "cadrl", build("cadrl"))
    assert stat.S_IMODE((tmp_path / "x.pt").stat().st_mode) == 0o640

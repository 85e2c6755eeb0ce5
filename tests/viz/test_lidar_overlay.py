"""The ``lidar`` overlay of ``socialnav render``: the scan drawn at a sample is the world's scan of that
sample, with the episode's own lidar (or the default one where its world had none)."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("matplotlib")

from socialnav.cli import main  # noqa: E402
from socialnav.scenarios import make_scenario  # noqa: E402
from socialnav.sim import SensingSettings, World, WorldSettings, lidar_scan  # noqa: E402
from socialnav.trajectory import write_trajectories  # noqa: E402
from socialnav.viz.draw import FrameRenderer, plot_trajectory  # noqa: E402
from socialnav.viz.geometry import episode_view, parse_overlays  # noqa: E402
from socialnav.viz.lidar import DEFAULT_LIDAR, lidar_of, scan_at  # noqa: E402


def _episode(sensing=None):
    settings = WorldSettings(threads=1, time_limit=6.0, **({"sensing": sensing} if sensing else {}))
    with World(settings, make_scenario("narrow_doorway"), 1, count=1) as world:
        world.reset()
        while True:
            to_goal = world.goal[:, 0] - world.position[:, 0]
            finished = world.step(0.8 * to_goal / np.linalg.norm(to_goal, axis=1, keepdims=True)).finished
            if finished:
                return finished[0]


def test_the_drawn_scan_is_the_worlds_scan_of_that_sample():
    traj = _episode(SensingSettings(lidar_beams=48, lidar_range=7.0))
    assert lidar_of(traj) == (48, 2 * math.pi, 7.0)
    view = episode_view(traj, 0.2, 1.0)
    k = 5
    eye, ends = scan_at(view, k)
    v = view.velocities[k, 0]
    ranges = lidar_scan(traj.positions[k, 0], math.atan2(v[1], v[0]), 48, traj.static_map,
                        traj.positions[k, 1:], traj.radii[1:], max_range=7.0)
    np.testing.assert_allclose(np.hypot(*(ends - eye).T), ranges, atol=1e-9)
    assert ranges.min() < 7.0  # the doorway's walls are in range


def test_an_episode_without_a_lidar_gets_the_default_one_and_both_drawings_work(tmp_path):
    traj = _episode()
    assert "sensing" not in traj.settings and lidar_of(traj) == DEFAULT_LIDAR
    assert "lidar" in parse_overlays(["lidar"]) and "lidar" in parse_overlays(["all"])
    fig = plot_trajectory(traj, overlays=["lidar"])
    assert any("lidar (360 beams)" in t.get_text() for t in fig.axes[0].get_legend().get_texts())
    renderer = FrameRenderer(traj, overlays=["lidar"])
    first = renderer.frame(0)
    later = renderer.frame(FrameRenderer.n_samples_of(traj) - 1)
    assert first.shape == later.shape and not np.array_equal(first, later)
    path = tmp_path / "episode.parquet"
    write_trajectories(path, [traj])
    out = tmp_path / "scan.png"
    assert main(["render", str(path), "--overlay", "lidar", "--out", str(out), "--quiet"]) == 0
    assert out.stat().st_size > 0

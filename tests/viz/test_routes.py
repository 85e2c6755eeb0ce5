"""Routes around walls in plots, animations and the HTML viewer (viz/routes.py, issue #48)."""

from __future__ import annotations

import json
import re
import shutil
import subprocess

import numpy as np
import pytest

pytest.importorskip("matplotlib")
pytest.importorskip("PIL")
from PIL import Image  # noqa: E402

from socialnav import _core  # noqa: E402
from socialnav.cli import main  # noqa: E402
from socialnav.evaluate.results import load_manifest  # noqa: E402
from socialnav.evaluate.runner import run_protocol  # noqa: E402
from socialnav.maps.static_map import StaticMap  # noqa: E402
from socialnav.policies import make_policy  # noqa: E402
from socialnav.presets import load_preset  # noqa: E402
from socialnav.trajectory import Trajectory, write_trajectories  # noqa: E402
from socialnav.viz.draw import FrameRenderer, agent_colour, plot_trajectory  # noqa: E402
from socialnav.viz.report import episode_page, write_report  # noqa: E402
from socialnav.viz.routes import episode_routes, robot_route_parameters  # noqa: E402
from tests.viz._node_dom import ELEMENTS

# a wall segment across the y axis: the human walks from below it to above it, the robot beside it
WALL = StaticMap.from_polygons([[[-1.0, 0.0], [1.0, 0.0]]])
ROUTED = {"human_routes": "shortest", "route_clearance": 0.2, "policy": "orca_route", "episode": "w/0"}


def _walk(smap: StaticMap | None = WALL, settings: dict | None = None, robot_x: float = 0.5) -> Trajectory:
    """The human (agent 1) from (0, -2) to (0, 2) through the wall's line; the robot from (robot_x, -3)."""
    k = np.arange(9)[:, None]
    human = np.array([0.0, -2.0]) + k * np.array([0.0, 0.5])
    robot = np.array([robot_x, -3.0]) + k * np.array([0.0, 0.5])
    return Trajectory.from_positions(
        np.stack([robot, human], axis=1), 0.5, radii=[0.3, 0.25], goals=[[robot_x, 1.0], [0.0, 2.0]],
        outcome="success", static_map=smap, settings=dict(ROUTED if settings is None else settings),
    )


def _plan(start, goal, radius: float, clearance: float, smap: StaticMap = WALL) -> np.ndarray:
    vertices, offsets = smap.to_flat()
    points, found, _ = _core.plan_route(np.array(start, float), np.array(goal, float), radius, clearance,
                                        vertices, offsets)
    assert found
    return np.concatenate([np.array([start], float), np.array(points)])


def _dashed(ax) -> list:
    return [ln for ln in ax.lines if ln.get_linestyle() == "--" and len(ln.get_xdata())]


def _data(page: str) -> dict:
    m = re.search(r'<script id="episode-data" type="application/json">(.*?)</script>', page, re.S)
    return json.loads(m.group(1).replace("<\\/", "</"))


def test_plot_draws_each_routed_agents_plan_dashed_under_the_agents() -> None:
    traj = _walk()
    human = _plan([0.0, -2.0], [0.0, 2.0], 0.25, 0.2)  # the human's radius, the world's route_clearance
    robot = _plan([0.5, -3.0], [0.5, 1.0], 0.3 + 0.01 + 0.2, 0.1)  # ORCA's inflation; orca_route's defaults
    assert human.shape[0] >= 3 and robot.shape[0] >= 3  # both bend round the wall's end
    ax = plot_trajectory(traj).axes[0]
    lines = {ln.get_color(): ln for ln in _dashed(ax)}
    assert set(lines) == {agent_colour(0), agent_colour(1)}
    np.testing.assert_array_equal(lines[agent_colour(1)].get_xydata(), human)
    np.testing.assert_array_equal(lines[agent_colour(0)].get_xydata(), robot)
    assert all(ln.get_zorder() < 1 and ln.get_linewidth() < 1 for ln in lines.values())  # thin, under discs
    assert "route planned at the start" in ax.get_legend_handles_labels()[1]


def test_open_floor_straight_and_unrouted_episodes_draw_no_route() -> None:
    assert episode_routes(_walk(smap=None)) == {}
    assert not _dashed(plot_trajectory(_walk(smap=None)).axes[0])
    # no human_routes in the settings, a policy without routes: nothing to draw
    assert episode_routes(_walk(settings={"policy": "orca"})) == {}
    # the robot's way is clear of the wall: its route is the straight line, which is not drawn
    assert set(episode_routes(_walk(robot_x=3.0))) == {1}
    # open floor: the picture is the one drawn without routes, pixel for pixel
    on = plot_trajectory(_walk(smap=None))
    off = plot_trajectory(_walk(smap=None), routes=False)
    on.canvas.draw()
    off.canvas.draw()
    np.testing.assert_array_equal(np.asarray(on.canvas.buffer_rgba()), np.asarray(off.canvas.buffer_rgba()))
    assert not _dashed(plot_trajectory(_walk(), routes=False).axes[0])


def test_the_robots_route_parameters_from_a_manifest_and_from_defaults() -> None:
    traj = _walk()
    assert robot_route_parameters(traj) == pytest.approx((0.51, 0.1))
    run = {"policy": {"policy": "orca_route", "safety_space": 0.0, "route_clearance": 0.3},
           "preset": {"world": {"orca": {"radius_margin": 0.05}}}}
    assert robot_route_parameters(traj, run) == pytest.approx((0.35, 0.3))
    run = {"policy": {"policy": "social_force_route", "route_clearance": 0.25}}
    assert robot_route_parameters(traj, run) == pytest.approx((0.3, 0.25))  # no ORCA inflation
    sf = _walk(settings={"policy": "social_force_route"})
    assert robot_route_parameters(sf) == pytest.approx((0.3, 0.1))
    # a label that names no route policy: no robot route, and the manifest's policy wins over the label
    assert robot_route_parameters(_walk(settings={"policy": "my-router"})) is None
    assert robot_route_parameters(traj, {"policy": {"policy": "orca"}}) is None


def test_animation_frames_draw_the_routes() -> None:
    renderer = FrameRenderer(_walk())
    assert len(renderer.routes) == 2 and all(ln.get_linestyle() == "--" for ln in renderer.routes)
    assert renderer.frame(4).shape == (560, 560, 3)
    assert FrameRenderer(_walk(smap=None)).routes == []


def test_viewer_json_holds_the_routes_in_millimetres() -> None:
    page = episode_page(_walk())
    routes = _data(page)["episodes"][0]["routes"]
    human = _plan([0.0, -2.0], [0.0, 2.0], 0.25, 0.2)
    assert routes["1"] == np.rint(human * 1000).astype(int).reshape(-1).tolist()
    assert set(routes) == {"0", "1"}
    assert 'id="ov-routes"' in page
    plain = episode_page(_walk(smap=None))
    assert "routes" not in _data(plain)["episodes"][0] and 'id="ov-routes"' not in plain
    assert "routes" not in _data(episode_page(_walk(), routes=False))["episodes"][0]


def test_render_cli_routes_and_no_routes(tmp_path) -> None:
    log = tmp_path / "log.csv"
    write_trajectories(log, [_walk()])
    images = {}
    for flag in ("--routes", "--no-routes"):
        out = tmp_path / f"{flag}.png"
        assert main(["render", str(log), flag, "--out", str(out), "--quiet"]) == 0
        images[flag] = np.asarray(Image.open(out).convert("RGB"))
    assert (images["--routes"] != images["--no-routes"]).any(axis=-1).sum() > 200
    assert main(["render", str(log), "--format", "html", "--out", str(tmp_path / "e.html"), "--quiet"]) == 0
    assert set(_data((tmp_path / "e.html").read_text())["episodes"][0]["routes"]) == {"0", "1"}


@pytest.fixture(scope="module")
def routed_run(tmp_path_factory):
    """Two blind-corner episodes of francis2023 (routed humans) with orca_route under another label."""
    out = tmp_path_factory.mktemp("routes-run")
    policy = make_policy("orca_route", safety_space=0.1, route_clearance=0.25)
    run_protocol(policy, load_preset("francis2023"), out, label="router", scenarios=["blind_corner"],
                 episodes=2, visibility="invisible", progress=False, workers=0)
    return out


def test_report_and_render_take_the_robots_parameters_from_the_manifest(routed_run, tmp_path) -> None:
    from socialnav.evaluate.results import load_episode

    assert load_manifest(routed_run)["policy"]["policy"] == "orca_route"
    report = tmp_path / "report.html"
    write_report([routed_run], report, figure_files=False)
    episodes = _data(report.read_text())["episodes"]
    assert episodes
    for ep in episodes:
        traj = load_episode(routed_run, ep["id"])
        assert traj.settings["policy"] == "router" and traj.settings["human_routes"] == "shortest"
        robot = _plan(traj.positions[0, 0], traj.goals[0], 0.3 + 0.01 + 0.1, 0.25, traj.static_map)
        assert ep["routes"]["0"] == np.rint(robot * 1000).astype(int).reshape(-1).tolist()
        for a in range(1, traj.n_agents):
            human = _plan(traj.positions[0, a], traj.goals[a], traj.radii[a],
                          traj.settings["route_clearance"], traj.static_map)
            if human.shape[0] > 2:
                assert ep["routes"][str(a)] == np.rint(human * 1000).astype(int).reshape(-1).tolist()
    page = tmp_path / "e.html"
    argv = ["render", str(routed_run), "--episode", episodes[0]["id"], "--out", str(page), "--quiet"]
    assert main(argv) == 0
    assert _data(page.read_text())["episodes"][0]["routes"] == episodes[0]["routes"]


HARNESS = r"""
const fs = require("fs");
const page = fs.readFileSync(process.argv[2], "utf8");
const data = page.match(/<script id="episode-data" type="application\/json">([\s\S]*?)<\/script>/)[1];
const script = page.match(/<script>([\s\S]*?)<\/script>\s*<\/body>/)[1];
const dashed = [];
let points = 0;
const ctx = new Proxy({ dash: [] }, {
  get: (t, k) => {
    if (k in t) return t[k];
    if (k === "setLineDash") return (d) => { t.dash = d; };
    if (k === "beginPath") return () => { points = 0; };
    if (k === "lineTo" || k === "moveTo") return () => { points += 1; };
    if (k === "stroke") return () => { if (t.dash.join() === "6,4") dashed.push([t.strokeStyle, points]); };
    return () => {};
  },
  set: (t, k, v) => { t[k] = v; return true; },
});
""" + ELEMENTS + r"""
global.document = { getElementById: (id) => (id === "episode-data" ? { textContent: data }
                    : id === "ov-routes" && !page.includes('id="ov-routes"') ? null : el(id)),
                    createElement: () => ({}) };
global.location = { hash: "" };
global.requestAnimationFrame = () => {};
eval(script);
console.log(JSON.stringify(dashed));
"""


def test_viewer_javascript_draws_the_routes_dashed(tmp_path) -> None:
    """viewer.js under node with a recording canvas: one dashed line per route, in the agent's colour."""
    node = shutil.which("node")
    if node is None:
        pytest.skip("node is not installed")
    (tmp_path / "harness.js").write_text(HARNESS)
    drawn = {}
    for name, traj in (("walls", _walk()), ("open", _walk(smap=None))):
        (tmp_path / f"{name}.html").write_text(episode_page(traj))
        out = subprocess.run([node, str(tmp_path / "harness.js"), str(tmp_path / f"{name}.html")],
                             capture_output=True, text=True, timeout=60)
        assert out.returncode == 0, out.stderr
        drawn[name] = json.loads(out.stdout.strip().splitlines()[-1])
    expected = [(agent_colour(a), line.shape[0]) for a, line in sorted(episode_routes(_walk()).items())]
    assert sorted(map(tuple, drawn["walls"])) == sorted(expected)
    assert drawn["open"] == []

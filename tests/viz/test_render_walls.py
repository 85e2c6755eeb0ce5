"""Walls in plots, animations and the HTML viewer (viz/draw.py, viz/geometry.py, viz/report.py)."""

from __future__ import annotations

import dataclasses
import json
import re

import numpy as np
import pytest

pytest.importorskip("matplotlib")
pytest.importorskip("PIL")
from PIL import Image  # noqa: E402

from socialnav.cli import main  # noqa: E402
from socialnav.maps.static_map import StaticMap  # noqa: E402
from socialnav.trajectory import Trajectory, write_trajectories  # noqa: E402
from socialnav.viz.draw import WALL_EDGE, WALL_FACE, FrameRenderer, plot_trajectory  # noqa: E402
from socialnav.viz.geometry import WALL_CONTEXT, scene_bounds  # noqa: E402
from socialnav.viz.report import episode_page  # noqa: E402
from tests.viz._node_dom import ELEMENTS

# a corridor 2 m wide along y (solid side walls 0.2 m thick) with a wall segment across its far end
CORRIDOR = StaticMap.from_polygons([
    [[-1.2, -3], [-1.0, -3], [-1.0, 3], [-1.2, 3]],
    [[1.0, -3], [1.2, -3], [1.2, 3], [1.0, 3]],
    [[-1.0, 3.5], [1.0, 3.5]],
])


def _walk(smap: StaticMap | None) -> Trajectory:
    k = np.arange(9)
    robot = np.stack([np.zeros(9), -2.0 + 0.5 * k], axis=1)
    human = np.tile([-0.65, 1.0], (9, 1))  # standing beside the robot's path, 0.05 m clear
    return Trajectory.from_positions(np.stack([robot, human], axis=1), 0.5, radii=0.3,
                                     goals=[[0, 2.0], [-0.65, 1.0]], outcome="success", static_map=smap)


def _count(img: np.ndarray, colour: str, tol: int = 12) -> int:
    ref = np.array([int(colour[i: i + 2], 16) for i in (1, 3, 5)])
    return int(np.sum(np.all(np.abs(img[..., :3].astype(int) - ref) < tol, axis=-1)))


def _pixels(fig) -> np.ndarray:
    fig.canvas.draw()
    return np.asarray(fig.canvas.buffer_rgba())[..., :3]


def test_plot_fills_polygons_and_draws_segments() -> None:
    walls, open_floor = _pixels(plot_trajectory(_walk(CORRIDOR))), _pixels(plot_trajectory(_walk(None)))
    # anti-aliased text has a few pixels of these greys too: compare with the open floor
    assert _count(walls, WALL_FACE) > _count(open_floor, WALL_FACE) + 5000  # side walls, filled
    assert _count(walls, WALL_EDGE) > _count(open_floor, WALL_EDGE) + 500  # outlines, the end segment


def test_animation_frames_show_the_walls() -> None:
    frame = FrameRenderer(_walk(CORRIDOR)).frame(3)
    assert _count(frame, WALL_FACE) > _count(FrameRenderer(_walk(None)).frame(3), WALL_FACE) + 3000


def test_bounds_take_nearby_walls_and_cut_far_ones() -> None:
    x0, x1, y0, y1 = scene_bounds(_walk(None))
    near = scene_bounds(_walk(CORRIDOR))
    assert near[0] <= -1.2 and near[1] >= 1.2 and near[3] >= 3.5  # the corridor's sides and end
    far = StaticMap.from_polygons([[[-100, 0], [100, 0]]])
    bx0, bx1, _, _ = scene_bounds(_walk(far))
    # a 200 m wall widens the view by WALL_CONTEXT at most on each side (before the aspect rule)
    assert bx1 - bx0 <= max(x1 - x0, y1 - y0) + 2 * WALL_CONTEXT + 1e-9


def test_viewer_page_embeds_walls_in_millimetres() -> None:
    page = episode_page(_walk(CORRIDOR))
    data = json.loads(re.search(r'<script id="episode-data" type="application/json">(.*?)</script>', page,
                                re.S).group(1))
    walls = data["episodes"][0]["walls"]
    assert walls[2] == [-1000, 3500, 1000, 3500]  # the segment: 2 vertices
    assert len(walls[0]) == 8 and walls[0][:2] == [-1200, -3000]
    assert "ep.W.forEach" in page  # the viewer draws them
    plain = json.loads(re.search(r'<script id="episode-data" type="application/json">(.*?)</script>',
                                 episode_page(_walk(None)), re.S).group(1))
    assert "walls" not in plain["episodes"][0]  # open floors: the data are as before


def test_render_cli_with_stored_map_and_with_map_file(tmp_path) -> None:
    log = tmp_path / "log.csv"
    write_trajectories(log, [_walk(CORRIDOR)])
    assert main(["render", str(log), "--out", str(tmp_path / "stored.png"), "--quiet"]) == 0
    stored = np.asarray(Image.open(tmp_path / "stored.png").convert("RGB"))
    assert _count(stored, WALL_FACE) > 5000
    plain = tmp_path / "plain.csv"
    write_trajectories(plain, [dataclasses.replace(_walk(CORRIDOR), static_map=None)])
    (tmp_path / "map.yaml").write_text(
        "walls: [[[-1, 3.5], [1, 3.5]]]\nrectangles: [{x: 1, y: -3, width: 0.2, height: 6}]\n"
    )
    assert (
        main(
            [
                "render",
                str(plain),
                "--map",
                str(tmp_path / "map.yaml"),
                "--out",
                str(tmp_path / "m.png"),
                "--quiet",
            ]
        )
        == 0
    )
    given = np.asarray(Image.open(tmp_path / "m.png").convert("RGB"))
    assert 2000 < _count(given, WALL_FACE) < 0.7 * _count(stored, WALL_FACE)  # one side wall of the two


NODE_HARNESS = r"""
const fs = require("fs");
const page = fs.readFileSync(process.argv[2], "utf8");
const data = page.match(/<script id="episode-data" type="application\/json">([\s\S]*?)<\/script>/)[1];
const script = page.match(/<script>([\s\S]*?)<\/script>\s*<\/body>/)[1];
const calls = [];
const ctx = new Proxy({}, {
  get: (t, k) => (k in t ? t[k]
    : (...args) => calls.push([k, args, t.fillStyle, t.strokeStyle, t.lineWidth])),
  set: (t, k, v) => { t[k] = v; return true; },
});
""" + ELEMENTS + r"""
global.document = { getElementById: (id) => (id === "episode-data" ? { textContent: data } : el(id)),
                    createElement: () => ({}) };
global.location = { hash: "" };
global.requestAnimationFrame = () => {};
eval(script);
const fills = calls.filter(([k, , fill]) => k === "fill" && fill === "#9a9a9a").length;
const thick = calls.filter(([k, , , stroke, w]) => k === "stroke" && stroke === "#4a4a4a" && w >= 4).length;
console.log(JSON.stringify({ fills, thick }));
"""


def test_viewer_javascript_draws_the_walls(tmp_path) -> None:
    """viewer.js run under node with a recording canvas: two filled polygons and one thick segment."""
    import shutil
    import subprocess

    node = shutil.which("node")
    if node is None:
        pytest.skip("node is not installed")
    counts = {}
    for name, smap in (("walls", CORRIDOR), ("open", None)):
        (tmp_path / f"{name}.html").write_text(episode_page(_walk(smap)))
        (tmp_path / "harness.js").write_text(NODE_HARNESS)
        out = subprocess.run([node, str(tmp_path / "harness.js"), str(tmp_path / f"{name}.html")],
                             capture_output=True, text=True, timeout=60)
        assert out.returncode == 0, out.stderr
        counts[name] = json.loads(out.stdout.strip().splitlines()[-1])
    assert counts["walls"] == {"fills": 2, "thick": 1}
    assert counts["open"] == {"fills": 0, "thick": 0}


def test_render_cli_map_scale(tmp_path, capsys) -> None:
    """--map-scale reads an SVG drawn in centimetres as `socialnav metrics` does."""
    plain = tmp_path / "plain.csv"
    write_trajectories(plain, [_walk(None)])
    (tmp_path / "map.yaml").write_text("rectangles: [{x: 1, y: -3, width: 0.2, height: 6}]\n")
    # the same side wall in cm; SVG y points down, so y = -300 .. 300 flips to 3 .. -3 m
    (tmp_path / "map.svg").write_text(
        '<svg xmlns="http://www.w3.org/2000/svg"><rect x="100" y="-300" width="20" height="600"/></svg>'
    )

    def walls(*argv: str) -> int:
        out = tmp_path / "out.png"
        assert main(["render", str(plain), *argv, "--out", str(out), "--quiet"]) == 0
        return _count(np.asarray(Image.open(out).convert("RGB")), WALL_FACE)

    open_floor, metres = walls(), walls("--map", str(tmp_path / "map.yaml"))
    assert metres > open_floor + 2000
    assert walls("--map", str(tmp_path / "map.svg"), "--map-scale", "0.01") == pytest.approx(metres, rel=0.01)
    # one unit per metre: the wall is 100 m away, beyond the view (the grey of a few anti-aliased pixels)
    assert walls("--map", str(tmp_path / "map.svg")) < open_floor + 500
    assert main(["render", str(plain), "--map", str(tmp_path / "map.yaml"), "--map-scale", "0.01"]) == 2
    assert capsys.readouterr().err.strip() == (
        f"socialnav render: error: {tmp_path / 'map.yaml'}: scale applies to SVG maps only (YAML maps state "
        "their 'units')"
    )
    assert main(["render", str(plain), "--map-scale", "0.01"]) == 2
    assert capsys.readouterr().err.strip() == "socialnav render: error: --map-scale needs --map"


ARC_HARNESS = NODE_HARNESS.replace(
    "const fills = calls",
    "const bad = calls.filter(([k, args]) => k === \"arc\" && !args.every(Number.isFinite));\n"
    "console.log(JSON.stringify({ arcs: calls.filter(([k]) => k === \"arc\").length, bad: bad.length }));\n"
    "const fills = calls")


def test_a_person_in_view_for_part_of_a_log_is_drawn_only_then(tmp_path) -> None:
    """A long-format log whose person comes into view at 1 s and leaves at 2 s: every format renders it."""
    import shutil
    import subprocess

    rows = ["t,agent,role,x,y,radius,gx,gy,v_pref,outcome"]
    for k in range(31):
        rows.append(f"{k / 10},0,robot,0.0,{-3 + 0.2 * k:.3f},0.3,0.0,3.0,1.0,success")
        if 10 <= k <= 20:
            rows.append(f"{k / 10},1,human,1.5,{-1 + 0.1 * (k - 10):.3f},0.3,,,,success")
    log = tmp_path / "late.csv"
    log.write_text("\n".join(rows) + "\n")
    for suffix in ("png", "svg", "html"):
        assert main(["render", str(log), "--out", str(tmp_path / f"late.{suffix}"), "--quiet"]) == 0, suffix
    page = (tmp_path / "late.html").read_text()
    data = json.loads(re.search(r'<script id="episode-data" type="application/json">(.*?)</script>', page,
                                re.S).group(1))
    pos = data["episodes"][0]["pos"]
    assert pos[2:4] == [None, None] and None not in pos[2 * 2 * 10: 2 * 2 * 10 + 4]  # out of view, then in
    node = shutil.which("node")
    if node is None:
        pytest.skip("node is not installed")
    (tmp_path / "harness.js").write_text(ARC_HARNESS)
    out = subprocess.run([node, str(tmp_path / "harness.js"), str(tmp_path / "late.html")],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    drawn = json.loads(out.stdout.strip().splitlines()[0])
    assert drawn["arcs"] > 0 and drawn["bad"] == 0  # no disc drawn at a position not in view

"""`socialnav metrics --map`: a log scored against a map file, and a log that carries its own map."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from socialnav.cli import main
from socialnav.maps.static_map import StaticMap
from socialnav.trajectory import Trajectory, write_trajectories
from tests._env import subprocess_env

MIN_KEY = "min_obstacle_clearance"
PROX_KEY = "obstacle_proximity.duration_s@threshold=0.2"


def _log(tmp_path: Path, smap: StaticMap | None = None, name: str = "log.csv") -> Path:
    """The robot (r = 0.3) walking up x = 0 from y = 0 to y = 0.8 in 0.2 m steps, a human far away."""
    ys = np.arange(5) * 0.2
    pos = np.zeros((5, 2, 2))
    pos[:, 0, 1] = ys
    pos[:, 1] = [20.0, 20.0]
    tr = Trajectory.from_positions(pos, 0.25, radii=0.3, v_pref=1.0, goals=pos[-1], outcome="success",
                                   static_map=smap)
    path = tmp_path / name
    write_trajectories(path, [tr])
    return path


def _json(capsys: pytest.CaptureFixture[str], argv: list[str]) -> dict:
    assert main(["metrics", *argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_map_file_scores_the_obstacle_metrics(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = _log(tmp_path)
    plain = _json(capsys, [str(log)])["episodes"][0]
    assert plain[MIN_KEY] is None  # NaN without a map (json_safe writes null)
    (tmp_path / "map.yaml").write_text("walls: [[[-5, 1.2], [5, 1.2]]]\n")
    row = _json(capsys, [str(log), "--map", str(tmp_path / "map.yaml")])["episodes"][0]
    # samples 1..4 at y = 0.2..0.8: distances 1.0, 0.8, 0.6, 0.4 m; clearances 0.7, 0.5, 0.3, 0.1 m
    assert row[MIN_KEY] == pytest.approx(0.1)
    assert row[PROX_KEY] == pytest.approx(0.25)  # one sample below 0.2 m, dt = 0.25 s
    for key, value in plain.items():  # the human metrics do not change
        if not key.startswith(("min_obstacle", "obstacle_", "wall_")):
            assert row[key] == value, key


def test_success_label_through_a_wall_is_said(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # the wall at y = 0.5 crosses the robot's path: at sample 3 (y = 0.6, t = 0.75 s) its centre is 0.1 m
    # past it, clearance 0.1 - 0.3 = -0.2 m; the worst sample is y = 0.4 or 0.6 (0.1 m away): the first
    (tmp_path / "map.yaml").write_text("walls: [[[-5, 0.5], [5, 0.5]]]\n")
    log = _log(tmp_path)
    # scored, and the contradiction makes the exit status 1 (as a person overlapped is)
    assert main(["metrics", str(log), "--map", str(tmp_path / "map.yaml"), "--json"]) == 1
    said = json.loads(capsys.readouterr().out)["warnings"]
    assert said == [f"{log}: episode 0: labelled 'success' but the robot overlaps an obstacle at t = 0.5 s "
                    "(clearance -0.2 m)"]
    assert main(["metrics", str(log), "--json"]) == 0  # without the map nothing contradicts the label
    assert json.loads(capsys.readouterr().out)["warnings"] == []


def test_log_carrying_its_map_and_replacement_note(tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    stored = StaticMap.from_polygons([[[-5, 1.0], [5, 1.0]]])
    log = _log(tmp_path, stored, "log.parquet")
    # the stored map has the robot's disc over the wall at its last sample: scored, and the 'success'
    # label contradicted (exit status 1)
    assert main(["metrics", str(log), "--json"]) == 1
    out = json.loads(capsys.readouterr().out)
    assert out["episodes"][0][MIN_KEY] == pytest.approx(-0.1)
    assert "labelled 'success' but the robot overlaps an obstacle at t = 1 s" in out["warnings"][0]
    (tmp_path / "map.svg").write_text('<svg xmlns="http://www.w3.org/2000/svg" data-scale="0.1">'
                                      '<line x1="-50" y1="-12" x2="50" y2="-12"/></svg>')  # y = +1.2 m
    out = _json(capsys, [str(log), "--map", str(tmp_path / "map.svg")])
    assert out["episodes"][0][MIN_KEY] == pytest.approx(0.1)
    assert any("replaces the static map stored with 1 episode" in n for n in out["notes"])


def test_bad_map_file_is_one_clear_line(tmp_path: Path) -> None:
    log = _log(tmp_path)
    bad = tmp_path / "map.yaml"
    bad.write_text("polygons: [[[0, 0], [1, 1], [1, 0], [0, 1]]]\n")
    proc = subprocess.run([sys.executable, "-m", "socialnav.cli", "metrics", str(log), "--map", str(bad)],
                          capture_output=True, text=True, env=subprocess_env(), timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [
        f"socialnav metrics: error: {bad}: polygons[0]: self-intersecting (edge 0-1 crosses edge 2-3)"
    ]


# a wall along y = 1.2 m drawn in centimetres (no data-scale): x from -5 m to 5 m at --map-scale 0.01
CM_SVG = '<svg xmlns="http://www.w3.org/2000/svg"><line x1="-500" y1="-120" x2="500" y2="-120"/></svg>'


def test_map_scale_reads_an_svg_in_other_units(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = _log(tmp_path)
    (tmp_path / "map.svg").write_text(CM_SVG)
    row = _json(capsys, [str(log), "--map", str(tmp_path / "map.svg"), "--map-scale", "0.01"])["episodes"][0]
    assert row[MIN_KEY] == pytest.approx(0.1)  # as the YAML map of the first test
    # one user unit per metre: the wall is 120 m away, the robot's nearest sample at y = 0.8 m
    row = _json(capsys, [str(log), "--map", str(tmp_path / "map.svg")])["episodes"][0]
    assert row[MIN_KEY] == pytest.approx(120 - 0.8 - 0.3)


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--map-scale", "0.01"], "--map-scale needs --map"),
        (["--map", "MAP", "--map-scale", "0"], "--map-scale must be a finite number > 0, got 0.0"),
        (["--map", "MAP", "--map-scale", "nan"], "--map-scale must be a finite number > 0, got nan"),
    ],
)
def test_map_scale_errors(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], message: str
) -> None:
    (tmp_path / "map.svg").write_text(CM_SVG)
    argv = [str(tmp_path / "map.svg") if a == "MAP" else a for a in argv]
    assert main(["metrics", str(_log(tmp_path)), *argv]) == 2
    assert capsys.readouterr().err.strip() == f"socialnav metrics: error: {message}"


def test_map_without_obstacles_is_an_error_not_nan(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # a drawing of clones only used to load as an empty map and score NaN clearances without a word
    (tmp_path / "use.svg").write_text('<svg xmlns="http://www.w3.org/2000/svg"><use href="#r" x="5"/></svg>')
    (tmp_path / "dots.svg").write_text('<svg xmlns="http://www.w3.org/2000/svg"><circle r="1"/></svg>')
    log = str(_log(tmp_path))
    assert main(["metrics", log, "--map", str(tmp_path / "use.svg")]) == 2
    assert "use.svg: <use> href='#r': not supported" in capsys.readouterr().err
    assert main(["metrics", log, "--map", str(tmp_path / "dots.svg")]) == 2
    assert "dots.svg: no obstacles" in capsys.readouterr().err

"""Inputs that used to give a silent or a bare result (issue #47): each is now refused, or reported, with
the file, the field and the value.

- a map with absurd coordinates (near 1e308): every distance to the walls came out NaN;
- ``socialnav replay`` ignored the map: a stored trajectory without its walls, or with every wall moved,
  replayed as "identical";
- a trajectory file whose metadata JSON was cut gave a bare ``JSONDecodeError`` message.
"""

from __future__ import annotations

import dataclasses
import re
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest

from socialnav.cli import TRACEBACK_ENV, main
from socialnav.maps.files import MapFileError, load_map
from socialnav.maps.static_map import MapError, StaticMap
from socialnav.trajectory import Trajectory, TrajectoryFormatError, read_trajectories, write_trajectories

SQUARE = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]
HEADER = "episode,t,agent,x,y,radius,gx,gy,v_pref,static_map"


@pytest.fixture(autouse=True)
def _one_line_errors(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(TRACEBACK_ENV, raising=False)


def _run_cli(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def _one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


# ------------------------------------------------------------------------ 1. absurd map coordinates
@pytest.mark.parametrize("value, axis", [(1e308, "x"), (-1e308, "y"), (1.5e6, "x"), (-2e7, "y")])
def test_static_map_refuses_coordinates_beyond_the_bound(value: float, axis: str) -> None:
    poly = [list(v) for v in SQUARE]
    poly[2][0 if axis == "x" else 1] = value
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # refused before any overflow in the geometry
        shown = re.escape(f"{value:g}")
        with pytest.raises(MapError, match=rf"^polygon 1: vertex 2 is out of range: {axis} = {shown} "
                                           r"\(map coordinates are limited to \|x\|, \|y\| <= 1,000,000 m\)"):
            StaticMap.from_polygons([SQUARE, poly])


def test_coordinates_at_the_bound_are_kept_and_their_distances_are_finite() -> None:
    far = 1e6  # socialnav.maps.static_map.MAX_COORDINATE
    smap = StaticMap.from_polygons([[[-far, -far], [far, -far], [far, far]], [[-far, far], [far, far]]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        d = smap.distance(np.array([[0.0, 0.0], [far, 0.0], [-far, far * 0.5]]))
    assert np.isfinite(d).all()
    assert d[1] == 0.0  # on the triangle's edge


def test_yaml_map_file_names_file_field_vertex_and_value(tmp_path: Path) -> None:
    path = tmp_path / "map.yaml"
    path.write_text("walls:\n  - [[0, 0], [1, 0]]\npolygons:\n  - [[0, 2], [1, 2], [1e308, 3]]\n")
    with pytest.raises(MapFileError, match=r"map\.yaml: polygons\[0\]: vertex 2 is out of range: "
                                           r"x = 1e\+308"):
        load_map(path)
    # the bound is on metres: 2e9 mm is 2000 km
    path.write_text("units: mm\nrectangles:\n  - {x: 0, y: 0, width: 2e9, height: 1}\n")
    with pytest.raises(MapFileError, match=r"map\.yaml: rectangles\[0\]: vertex 1 is out of range: "
                                           r"x = 2e\+06"):
        load_map(path)


def test_svg_map_file_names_file_element_vertex_and_value(tmp_path: Path) -> None:
    path = tmp_path / "map.svg"
    path.write_text('<svg xmlns="http://www.w3.org/2000/svg"><rect x="0" y="0" width="1" height="1"/>'
                    '<polygon id="far" points="0,0 1e308,0 1,1"/></svg>')
    with pytest.raises(MapFileError, match=r"map\.svg: <polygon> #2 id='far': vertex \d is out of range: "
                                           r"x = 1e\+308"):
        load_map(path)


def _csv_with_map(path: Path, cell: str) -> Path:
    rows = [HEADER, f"0,0,0,0,0,0.3,1,0,1,{cell}", "0,0,1,2,2,0.3,2,2,1,", "0,0.5,0,0.5,0,0.3,1,0,1,",
            "0,0.5,1,2,2,0.3,2,2,1,"]
    path.write_text("\n".join(rows) + "\n")
    return path


def test_trajectory_file_map_and_metrics_map_option_refuse_absurd_coordinates(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = _csv_with_map(tmp_path / "log.csv", '"{""polygons"": [[[3, -1], [3, 1]], [[0, 5], [1e308, 5]]]}"')
    with pytest.raises(TrajectoryFormatError, match=r"log\.csv: column 'static_map', row 1: polygon 1: "
                                                    r"vertex 1 is out of range: x = 1e\+308"):
        read_trajectories(log)
    code, _, err = _run_cli(["metrics", str(log), "--quiet"], capsys)
    assert code == 2 and "log.csv" in _one_line(err) and "polygon 1: vertex 1 is out of range" in err

    plain = _csv_with_map(tmp_path / "plain.csv", "")
    (tmp_path / "walls.yaml").write_text("walls:\n  - [[-1e308, 3], [1e308, 3]]\n")
    code, _, err = _run_cli(["metrics", str(plain), "--map", str(tmp_path / "walls.yaml"), "--quiet"], capsys)
    assert code == 2
    assert "walls.yaml: walls[0] segment 0: vertex 0 is out of range: x = -1e+308" in _one_line(err)


# ------------------------------------------------------------------------------ 2. replay and the map
@pytest.fixture(scope="module")
def walled_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from socialnav.evaluate.runner import run_protocol
    from socialnav.policies import make_policy
    from socialnav.presets import load_preset

    preset = load_preset("francis2023")
    preset = dataclasses.replace(preset, evaluation=dataclasses.replace(preset.evaluation, episodes=2,
                                                                          chunk_size=2))
    out = tmp_path_factory.mktemp("walled")
    run_protocol(make_policy("orca"), preset, out, scenarios=["narrow_doorway"], visibility="invisible",
                 progress=False, workers=0)
    return out


EPISODE = "narrow_doorway/invisible/1"


def _edited_run(walled_run: Path, tmp_path: Path, edit: object) -> tuple[Path, Trajectory]:
    """A copy of the run whose stored episode 1 has its map replaced by ``edit(map)``."""
    run = tmp_path / "run"
    shutil.copytree(walled_run, run)
    (path,) = (run / "trajectories").rglob("*.parquet")
    trajs = read_trajectories(path)
    assert [t.settings["episode"] for t in trajs] == ["narrow_doorway/invisible/0", EPISODE]
    assert trajs[1].static_map  # a walled scenario: the episode stores its map
    trajs[1] = dataclasses.replace(trajs[1], static_map=edit(trajs[1].static_map))  # type: ignore[operator]
    write_trajectories(path, trajs)
    return run, trajs[1]


def test_replay_of_the_untouched_walled_run_is_identical(walled_run: Path,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = _run_cli(["replay", str(walled_run), "--episode", EPISODE], capsys)
    assert code == 0 and "replay identical" in out and "max |difference| 0" in out


def test_replay_reports_a_removed_map(walled_run: Path, tmp_path: Path,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    run, stored = _edited_run(walled_run, tmp_path, lambda smap: None)
    assert stored.static_map is None
    code, out, _ = _run_cli(["replay", str(run), "--episode", EPISODE], capsys)
    assert code == 1 and "DIFFERS" in out
    assert "static_map: stored no map (open floor), replayed 6 polygon(s)" in out


def test_replay_reports_walls_moved_by_one_metre(walled_run: Path, tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    def shift(smap: StaticMap) -> StaticMap:
        return StaticMap.from_polygons([p + np.array([1.0, 0.0]) for p in smap.polygons])

    run, _ = _edited_run(walled_run, tmp_path, shift)
    code, out, _ = _run_cli(["replay", str(run), "--episode", EPISODE], capsys)
    assert code == 1 and "DIFFERS" in out and "max |difference| 1)" in out
    assert "static_map: polygon 0, vertex 0: stored" in out and "(max |difference| 1 over the map)" in out


# ------------------------------------------------------------------------- 3. cut trajectory metadata
def _cut_metadata(path: Path) -> None:
    """Rewrites a Parquet trajectory file with its metadata JSON cut in the middle."""
    import pyarrow.parquet as pq

    table = pq.read_table(path)
    meta = dict(table.schema.metadata)
    raw = meta[b"socialnav"]
    meta[b"socialnav"] = raw[: len(raw) // 2]
    pq.write_table(table.replace_schema_metadata(meta), path)


DAMAGED = r"the file's metadata \(Parquet key 'socialnav': the episodes' settings and maps\) is damaged: " \
          r"not valid JSON \(cut short\?\)"


def test_cut_metadata_names_the_file_reader_and_metrics(tmp_path: Path,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    rng = np.random.default_rng(0)
    pos = rng.normal(size=(5, 2, 2))
    traj = Trajectory(dt=0.25, positions=pos, velocities=np.zeros_like(pos), radii=[0.3, 0.3],
                      v_pref=[1.0, 1.0], goals=np.ones((2, 2)), roles=["robot", "human"], outcome="success",
                      static_map=StaticMap.from_polygons([SQUARE]), settings={"episode": 0})
    path = tmp_path / "log.parquet"
    write_trajectories(path, [traj])
    _cut_metadata(path)
    with pytest.raises(TrajectoryFormatError, match=rf"^{path}: {DAMAGED}"):
        read_trajectories(path)
    code, _, err = _run_cli(["metrics", str(path), "--quiet"], capsys)
    assert code == 2
    line = _one_line(err)
    assert line.startswith(f"socialnav metrics: error: {path}: the file's metadata") and "damaged" in line


def test_cut_metadata_names_the_file_replay(walled_run: Path, tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    run = tmp_path / "run"
    shutil.copytree(walled_run, run)
    (path,) = (run / "trajectories").rglob("*.parquet")
    _cut_metadata(path)
    code, _, err = _run_cli(["replay", str(run), "--episode", EPISODE], capsys)
    assert code == 2
    line = _one_line(err)
    assert f"{path.name}: the file's metadata" in line and "is damaged: not valid JSON" in line

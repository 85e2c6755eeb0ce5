"""Map files: YAML and the SVG subset (socialnav.map_files), and their errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from socialnav.map_files import MapFileError, load_map, map_from_svg, save_map
from socialnav.static_map import MapError, StaticMap

YAML_MAP = """\
name: test corridor
units: m
polygons:
  - [[0, 0], [0, 1], [1, 1], [1, 0]]     # clockwise: stored counter-clockwise
  - [[5, 5], [6, 5]]                     # a wall segment
walls:
  - [[-3, -1], [3, -1], [3, 2]]          # two segments
rectangles:
  - {x: 10, y: 0, width: 2, height: 0.5}
"""


def _write(tmp_path: Path, text: str, name: str = "map.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_yaml_map(tmp_path: Path) -> None:
    smap = load_map(_write(tmp_path, YAML_MAP))
    shapes = [p.tolist() for p in smap.polygons]
    assert shapes == [
        [[1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.0, 0.0]],
        [[5.0, 5.0], [6.0, 5.0]],
        [[-3.0, -1.0], [3.0, -1.0]], [[3.0, -1.0], [3.0, 2.0]],
        [[10.0, 0.0], [12.0, 0.0], [12.0, 0.5], [10.0, 0.5]],
    ]


def test_yaml_units_and_round_trip(tmp_path: Path) -> None:
    smap = load_map(_write(tmp_path, "units: cm\nwalls: [[[0, 0], [250, 0]]]\n"))
    assert smap.polygons[0].tolist() == [[0.0, 0.0], [2.5, 0.0]]
    odd = StaticMap.from_polygons([[[0.1, 0.2], [1 / 3, 0.7], [-0.123456789012345, 0.9]],
                                   [[1e-7, 2], [3, 4]]])
    save_map(tmp_path / "out.yaml", odd)
    assert load_map(tmp_path / "out.yaml") == odd  # bit for bit
    # StaticMap.to_dict() output is a map file too
    import json
    assert load_map(_write(tmp_path, json.dumps(odd.to_dict()), "m.json")) == odd


@pytest.mark.parametrize("text, match", [
    ("polygons: [[[0, 0], [1, 0]]\n  bad", r"map\.yaml: not valid YAML"),
    ("- 1\n- 2\n", r"map\.yaml: expected a mapping"),
    ("polygon: [[[0, 0], [1, 0]]]\n",
     r"map\.yaml: unknown field 'polygon' \(value \[\[\[0, 0\], \[1, 0\]\]\]\)"),
    ("units: ft\n", r"map\.yaml: field 'units': 'ft' is not one of m, cm, mm"),
    ("polygons: [[[0, 0], [1, 1], [1, 0], [0, 1]]]\n",
     r"map\.yaml: polygons\[0\]: self-intersecting \(edge 0-1 crosses edge 2-3\)"),
    ("polygons: [[[0, 0], [1, .nan], [1, 0]]]\n", r"map\.yaml: polygons\[0\]: vertex 1 is not finite"),
    ("walls: [[[0, 0], [1, 0], [1, 0]]]\n", r"map\.yaml: walls\[0\] segment 1: vertices 0 and 1 coincide"),
    ("walls: [[[0, 0]]]\n", r"map\.yaml: field 'walls\[0\]': needs at least 2 points, got 1"),
    ("polygons: [[[0, 0], [1, 'a']]]\n",
     r"map\.yaml: field 'polygons\[0\]': expected a list of \[x, y\] number"),
    ("polygons: {a: 1}\n", r"map\.yaml: field 'polygons': expected a list, got \{'a': 1\}"),
    ("rectangles: [{x: 0, y: 0, width: 1}]\n", r"map\.yaml: field 'rectangles\[0\]': expected \{x, y, width"),
    ("rectangles: [{x: 0, y: 0, width: -1, height: 1}]\n", r"rectangles\[0\]': width and height must be > 0"),
])
def test_yaml_errors_name_file_field_and_value(tmp_path: Path, text: str, match: str) -> None:
    with pytest.raises(MapFileError, match=match) as err:
        load_map(_write(tmp_path, text))
    assert isinstance(err.value, MapError) and isinstance(err.value, ValueError)


def test_file_level_errors(tmp_path: Path) -> None:
    with pytest.raises(MapFileError, match=r"nope\.yaml: no such map file"):
        load_map(tmp_path / "nope.yaml")
    with pytest.raises(MapFileError, match=r"map\.txt: unsupported map file suffix '\.txt'"):
        load_map(_write(tmp_path, "", "map.txt"))
    with pytest.raises(MapFileError, match=r"scale applies to SVG maps only"):
        load_map(_write(tmp_path, YAML_MAP), scale=2.0)


SVG = """<?xml version="1.0"?>
<svg xmlns="http://www.w3.org/2000/svg" xmlns:inkscape="http://www.inkscape.org/namespaces/inkscape"
     width="20" height="10" data-scale="0.5">
  <g inkscape:label="obstacles" transform="translate(2, 0)">
    <rect x="0" y="0" width="4" height="2"/>
    <path d="M 10 0 L 12 0 l 0 2 H 10 z"/>
    <path d="M 0 8 h 6 v 2"/>
  </g>
  <line x1="0" y1="0" x2="1" y2="1" id="wall_a"/>
  <polygon points="0,4 2,4 1,6" class="robot_spawn_zone"/>
  <circle cx="3" cy="3" r="1" inkscape:label="obstacle_round"/>
</svg>
"""


def test_svg_subset_with_labels_transform_scale_and_flip(tmp_path: Path) -> None:
    smap = load_map(_write(tmp_path, SVG, "map.svg"))
    shapes = [p.tolist() for p in smap.polygons]
    # x' = 0.5 (x + 2) for the group, y' = -0.5 y; the spawn zone is not an obstacle (labels are used);
    # a circle is not in the subset and is skipped
    box = [[1.0, 0.0], [3.0, 0.0], [3.0, -1.0], [1.0, -1.0]]  # clockwise after the flip ...
    assert shapes[0] == box[::-1][-1:] + box[::-1][:-1] or sorted(shapes[0]) == sorted(box)
    assert np.allclose(StaticMap((np.array(box),)).polygons[0], smap.polygons[0])  # ... stored CCW
    assert sorted(shapes[1]) == sorted([[6.0, 0.0], [7.0, 0.0], [7.0, -1.0], [6.0, -1.0]])
    assert shapes[2:4] == [[[1.0, -4.0], [4.0, -4.0]], [[4.0, -4.0], [4.0, -5.0]]]  # open path: segments
    assert shapes[4] == [[0.0, 0.0], [0.5, -0.5]]  # the line labelled wall_a, outside the group
    assert len(shapes) == 5
    # scale argument overrides data-scale
    assert load_map(tmp_path / "map.svg", scale=1.0).polygons[4].tolist() == [[0.0, 0.0], [1.0, -1.0]]


def test_unlabelled_svg_takes_every_shape(tmp_path: Path) -> None:
    text = ('<svg xmlns="http://www.w3.org/2000/svg"><g transform="scale(2) rotate(90)">'
            '<polyline points="0,0 1,0"/></g>'
            '<rect x="1" y="1" width="1" height="1" transform="matrix(1 0 0 1 1 1)"/></svg>')
    smap = map_from_svg(text)
    np.testing.assert_allclose(smap.polygons[0], [[0.0, 0.0], [0.0, -2.0]], atol=1e-12)
    assert sorted(smap.polygons[1].tolist()) == [[2.0, -3.0], [2.0, -2.0], [3.0, -3.0], [3.0, -2.0]]


@pytest.mark.parametrize("body, match", [
    ('<rect x="0" y="0" width="1" height="1"', r"map\.svg: not valid SVG/XML"),
    ('<path d="M 0 0 C 1 1 2 2 3 3"/>', r"map\.svg: <path> #1: attribute 'd': command 'C' is not supported"),
    ('<path d="M 0 0 L 1 1 L 1 0 L 0 1 Z"/>', r"map\.svg: <path> #1: self-intersecting"),
    ('<rect x="a" width="1" height="1"/>', r"map\.svg: <rect> #1: attribute 'x': 'a' is not a number"),
    ('<rect width="0" height="1" id="w"/>', r"map\.svg: <rect> #1 id='w': width and height must be > 0"),
    ('<polygon points="0,0 1"/>', r"attribute 'points' needs pairs of numbers"),
    ('<g transform="skewX(3)"><line x2="1"/></g>', r"<g> attribute 'transform': skewX\(3\) is not supported"),
])
def test_svg_errors_name_file_element_and_value(tmp_path: Path, body: str, match: str) -> None:
    path = _write(tmp_path, f'<svg xmlns="http://www.w3.org/2000/svg">{body}</svg>', "map.svg")
    with pytest.raises(MapFileError, match=match):
        load_map(path)


def test_svg_scale_must_be_positive(tmp_path: Path) -> None:
    path = _write(tmp_path, '<svg xmlns="http://www.w3.org/2000/svg" data-scale="x"/>', "map.svg")
    with pytest.raises(MapFileError, match=r"attribute 'data-scale' of <svg>: 'x' is not a number"):
        load_map(path)
    with pytest.raises(MapFileError, match=r"scale must be a finite number > 0, got -1"):
        load_map(path, scale=-1.0)
    assert len(load_map(_write(tmp_path, '<svg xmlns="http://www.w3.org/2000/svg"/>', "empty.svg"))) == 0

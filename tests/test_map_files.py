"""Map files: YAML and the SVG subset (socialnav.maps), and their errors."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from socialnav.maps.files import MapFileError, load_map, map_from_svg, save_map
from socialnav.maps.static_map import MapError, StaticMap

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
  <circle cx="3" cy="3" r="1" inkscape:label="single_ped_1"/>
  <text x="0" y="9">walls drawn over a floor plan</text>
  <image href="plan.png" width="20" height="10"/>
</svg>
"""


def test_svg_subset_with_labels_transform_scale_and_flip(tmp_path: Path) -> None:
    smap = load_map(_write(tmp_path, SVG, "map.svg"))
    shapes = [p.tolist() for p in smap.polygons]
    # x' = 0.5 (x + 2) for the group, y' = -0.5 y; the spawn zone, the pedestrian's circle, the text and
    # the unlabelled floor plan picture are not obstacles (labels are used)
    box = [[1.0, 0.0], [3.0, 0.0], [3.0, -1.0], [1.0, -1.0]]  # clockwise after the flip ...
    assert shapes[0] == box[::-1][-1:] + box[::-1][:-1] or sorted(shapes[0]) == sorted(box)
    assert np.allclose(StaticMap((np.array(box),)).polygons[0], smap.polygons[0])  # ... stored CCW
    assert sorted(shapes[1]) == sorted([[6.0, 0.0], [7.0, 0.0], [7.0, -1.0], [6.0, -1.0]])
    assert shapes[2:4] == [[[1.0, -4.0], [4.0, -4.0]], [[4.0, -4.0], [4.0, -5.0]]]  # open path: segments
    assert shapes[4] == [[0.0, 0.0], [0.5, -0.5]]  # the line labelled wall_a, outside the group
    assert len(shapes) == 5
    # scale argument overrides data-scale
    assert load_map(tmp_path / "map.svg", scale=1.0).polygons[4].tolist() == [[0.0, 0.0], [1.0, -1.0]]


def test_svg_layers_switched_off_are_not_obstacles() -> None:
    # Inkscape hides a layer with style="display:none"; SVG also has the display attribute
    text = ('<svg xmlns="http://www.w3.org/2000/svg">'
            '<g style="opacity:1; display : none"><rect x="0" y="0" width="1" height="1"/></g>'
            '<rect x="5" y="5" width="1" height="1" display="none"/>'
            '<g style="display:inline"><line x1="0" y1="0" x2="2" y2="0"/></g></svg>')
    smap = map_from_svg(text)
    assert [p.tolist() for p in smap.polygons] == [[[0.0, 0.0], [2.0, 0.0]]]


def test_svg_page_in_millimetres_without_a_scale_is_said(tmp_path: Path) -> None:
    page = ('<svg xmlns="http://www.w3.org/2000/svg" width="210mm" height="297mm" viewBox="0 0 210 297"{}>'
            '<rect x="0" y="0" width="10" height="5"/></svg>')
    with pytest.warns(UserWarning, match=r"map.svg: the page is 210mm wide for a viewBox 210 user units wide "
                      r"\(1 user unit = 0.001 m on paper\); the map reads 1 user unit as 1 m"):
        smap = load_map(_write(tmp_path, page.format(""), "map.svg"))
    assert smap.polygons[0].max() == 10.0  # read as said: metres
    with warnings.catch_warnings():  # a scale given, either way: nothing to say
        warnings.simplefilter("error")
        map_from_svg(page.format(' data-scale="0.1"'))
        map_from_svg(page.format(""), scale=0.05)
        map_from_svg(page.format("").replace('width="210mm"', 'width="210"'))  # user units: nothing to say


def test_unlabelled_svg_takes_every_shape(tmp_path: Path) -> None:
    text = ('<svg xmlns="http://www.w3.org/2000/svg"><g transform="scale(2) rotate(90)">'
            '<polyline points="0,0 1,0"/></g>'
            '<rect x="1" y="1" width="1" height="1" transform="matrix(1 0 0 1 1 1)"/></svg>')
    smap = map_from_svg(text)
    np.testing.assert_allclose(smap.polygons[0], [[0.0, 0.0], [0.0, -2.0]], atol=1e-12)
    assert sorted(smap.polygons[1].tolist()) == [[2.0, -3.0], [2.0, -2.0], [3.0, -3.0], [3.0, -2.0]]


@pytest.mark.parametrize(
    "body, match",
    [
        ('<rect x="0" y="0" width="1" height="1"', r"map\.svg: not valid SVG/XML"),
        (
            '<path d="M 0 0 C 1 1 2 2 3 3"/>',
            r"map\.svg: <path> #1: attribute 'd': command 'C' is not supported",
        ),
        ('<path d="M 0 0 L 1 1 L 1 0 L 0 1 Z"/>', r"map\.svg: <path> #1: self-intersecting"),
        ('<rect x="a" width="1" height="1"/>', r"map\.svg: <rect> #1: attribute 'x': 'a' is not a number"),
        ('<rect width="0" height="1" id="w"/>', r"map\.svg: <rect> #1 id='w': width and height must be > 0"),
        ('<polygon points="0,0 1"/>', r"attribute 'points' needs pairs of numbers"),
        (
            '<g transform="skewX(3)"><line x2="1"/></g>',
            r"<g> attribute 'transform': skewX\(3\) is not supported",
        ),
        (
            '<line x1="0" y1="0" x2="nan" y2="0"/>',
            r"map\.svg: <line> #1: attribute 'x2': 'nan' is not a finite number",
        ),
        (
            '<rect width="inf" height="1" id="w"/>',
            r"<rect> #1 id='w': attribute 'width': 'inf' is not a finite number",
        ),
        ('<rect height="1"/>', r"map\.svg: <rect> #1: attribute 'width' missing"),
        (
            '<line x2="1" transform="translate(nan, 1)"/>',
            r"<line> attribute 'transform': translate\(nan, 1\): 'nan, 1' is not a list of numbers",
        ),
        (
            '<line x2="1" transform="translate(1) flip"/>',
            r"<line> attribute 'transform': cannot parse 'translate",
        ),
    ],
)
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
    nan_scale = _write(tmp_path, '<svg xmlns="http://www.w3.org/2000/svg" data-scale="nan"/>', "nan.svg")
    with pytest.raises(
        MapFileError, match=r"nan\.svg: attribute 'data-scale' of <svg>: 'nan' is not a number > 0"
    ):
        load_map(nan_scale)


def _svg(body: str) -> str:
    return (
        '<svg xmlns="http://www.w3.org/2000/svg" xmlns:xlink="http://www.w3.org/1999/xlink" '
        f'xmlns:inkscape="http://www.inkscape.org/namespaces/inkscape">{body}</svg>'
    )


SPAWN = '<rect id="spawn" x="5" width="1" height="1"/>'


@pytest.mark.parametrize(
    "body, match",
    [
        # nothing labelled: everything drawn is an obstacle, so a clone or a picture cannot be skipped
        (
            '<defs><rect id="r" width="1" height="1"/></defs><use xlink:href="#r" x="5"/>',
            r"map\.svg: <use> href='#r': not supported \(it draws a copy of another element, which the "
            r"loader does not follow: .*\); in a drawing without 'obstacle' or 'wall' labels everything "
            r"drawn is an obstacle",
        ),
        (
            '<line x2="1"/><image href="plan.png" width="1" height="1"/>',
            r"map\.svg: <image> href='plan\.png': not supported \(a raster picture cannot be turned into "
            r"obstacles",
        ),
        # labelled: the clone is an obstacle, and the spawn zone must not become one instead
        (
            '<g id="walls"><use href="#x"/></g>' + SPAWN,
            r"map\.svg: <use> href='#x': not supported .*; it is labelled as an obstacle \(or in a group so "
            r"labelled\)",
        ),
        (
            '<g id="walls"><rect width="1" height="1"/><foreignObject id="f"/></g>' + SPAWN,
            r"map\.svg: <foreignObject> id='f': not supported \(its content cannot be turned into "
            r"obstacles\)",
        ),
        (
            '<circle r="1" inkscape:label="obstacle_round"/>' + SPAWN,
            r"map\.svg: <circle> inkscape:label='obstacle_round': not supported as an obstacle \(draw it "
            r"as a polygon or path\); it is labelled as an obstacle",
        ),
        (
            '<g class="walls"><ellipse rx="1" ry="2"/></g>',
            r"map\.svg: <ellipse>: not supported as an obstacle",
        ),
        (
            '<g class="walls layer"/><rect width="1" height="1"/>',
            r"map\.svg: <g> class='walls layer': labelled as obstacles, but holds no rect",
        ),
        (
            '<g inkscape:label="walls"><text>wall A</text></g>' + SPAWN,
            r"map\.svg: <g> inkscape:label='walls': labelled as obstacles, but holds no rect, polygon, "
            r"polyline, line, path element",
        ),
    ],
)
def test_svg_unsupported_elements_and_empty_labels_are_refused(tmp_path: Path, body: str, match: str) -> None:
    with pytest.raises(MapFileError, match=match):
        load_map(_write(tmp_path, _svg(body), "map.svg"))


def test_unsupported_elements_outside_the_labelled_obstacles_are_ignored() -> None:
    text = _svg(
        '<g id="walls"><line x2="1"/></g><use href="#ped"/><image href="plan.png" width="9" height="9"/>'
        '<circle r="1"/>' + SPAWN
    )
    assert [p.tolist() for p in map_from_svg(text).polygons] == [[[0.0, 0.0], [1.0, 0.0]]]


@pytest.mark.parametrize(
    "name, text, match",
    [
        (
            "empty.svg",
            '<svg xmlns="http://www.w3.org/2000/svg"/>',
            r"empty\.svg: no obstacles: the drawing has no rect, polygon, polyline, line, path element; an "
            r"open floor needs no map file",
        ),
        (
            "dots.svg",
            _svg('<circle r="1"/><ellipse rx="1" ry="1"/><text>x</text>'),
            r"dots\.svg: no obstacles: .* element \(circles and ellipses are not obstacles: 2 skipped\)",
        ),
        (
            "empty.yaml",
            "name: nothing yet\npolygons: []\n",
            r"empty\.yaml: no obstacles: 'polygons', 'walls' and 'rectangles' are missing or empty",
        ),
    ],
)
def test_a_map_file_without_obstacles_is_refused(tmp_path: Path, name: str, text: str, match: str) -> None:
    with pytest.raises(MapFileError, match=match):
        load_map(_write(tmp_path, text, name))


def test_save_map_refuses_the_empty_map_it_could_not_read_back(tmp_path: Path) -> None:
    with pytest.raises(MapFileError, match=r"out\.yaml: the map has no obstacles"):
        save_map(tmp_path / "out.yaml", StaticMap())
    assert not (tmp_path / "out.yaml").exists()


def test_closed_ring_repeating_its_first_vertex_is_accepted(tmp_path: Path) -> None:
    ring = "polygons: [[[0, 0], [2, 0], [2, 1], [0, 1], [0, 0]]]\n"  # counter-clockwise already
    assert load_map(_write(tmp_path, ring)).polygons[0].tolist() == [[0, 0], [2, 0], [2, 1], [0, 1]]
    svg = map_from_svg(_svg('<polygon points="0,0 2,0 2,1 0,1 0,0"/>'))  # flipped: clockwise, reversed
    assert svg.polygons[0].tolist() == [[0, -1], [2, -1], [2, 0], [0, 0]]


@pytest.mark.parametrize(
    "polygon, match",
    [
        (
            "[[0, 0], [2, 0], [2, 0], [0, 1]]",
            r"map\.yaml: polygons\[0\]: vertices 1 and 2 coincide \(\[2\.0, 0\.0\]\)",
        ),
        ("[[0, 0], [2, 0], [2, 1], [0, 0], [0, 0]]", r"polygons\[0\]: vertices 3 and 0 coincide"),  # twice
        ("[[0, 0], [2, 0], [0, 0]]", r"polygons\[0\]: vertices 2 and 0 coincide"),  # a segment, not a ring
    ],
)
def test_other_coincident_vertices_are_still_refused(tmp_path: Path, polygon: str, match: str) -> None:
    with pytest.raises(MapFileError, match=match):
        load_map(_write(tmp_path, f"polygons: [{polygon}]\n"))


@pytest.mark.parametrize("text, match", [
    ("walls: [[[0, 0], [1" + "0" * 400 + ", 0]]]\n",
     r"map\.yaml: field 'walls\[0\]': <an integer of 401 digits> is too large a number"),
    ("rectangles: [{x: 0, y: 0, width: 1" + "0" * 400 + ", height: 1}]\n",
     r"map\.yaml: field 'rectangles\[0\]\.width': <an integer of 401 digits> is too large a number"),
    ("units: [m]\nwalls: [[[0, 0], [1, 0]]]\n", r"map\.yaml: field 'units': \['m'\] is not one of m, cm, mm"),
    ("units: {a: 1}\nwalls: [[[0, 0], [1, 0]]]\n", r"map\.yaml: field 'units': \{'a': 1\} is not one of"),
    ("# only a comment\n", r"map\.yaml: the file is empty"),
])
def test_yaml_values_python_cannot_take_are_named_too(tmp_path: Path, text: str, match: str) -> None:
    with pytest.raises(MapFileError, match=match):
        load_map(_write(tmp_path, text))


def test_svg_rotation_about_a_point_and_transform_errors_name_the_element(tmp_path: Path) -> None:
    def svg(body: str) -> Path:
        return _write(tmp_path, f'<svg xmlns="http://www.w3.org/2000/svg">{body}</svg>', "map.svg")

    # rotate(90, 1, 0) maps (2, 0) to (1, 1); with the y flip the wall runs from (1, -1) to (1, 0)
    m = load_map(svg('<line x1="1" y1="0" x2="2" y2="0" transform="rotate(90, 1, 0)"/>'))
    np.testing.assert_allclose(m.polygons[0], [[1.0, 0.0], [1.0, -1.0]], atol=1e-12)
    with pytest.raises(MapFileError, match=r"<rect> id='door_frame' attribute 'transform': skewX\(3\)"):
        load_map(svg('<rect id="door_frame" width="1" height="1" transform="skewX(3)"/>'))
    with pytest.raises(MapFileError, match=r"<line> attribute 'transform': translate\(1e400\): a number "
                                           r"is too large"):
        load_map(svg('<line x2="1" transform="translate(1e400)"/>'))
    with pytest.raises(MapFileError, match=r"<svg> id='inner': a nested <svg> with x, viewBox is not "):
        load_map(svg('<svg id="inner" x="5" viewBox="0 0 1 1"><line x2="1"/></svg>'))

"""Map files: a :class:`~socialnav.static_map.StaticMap` from YAML (or JSON) or from an SVG drawing.

YAML (``.yaml``, ``.yml``, ``.json``), lengths in ``units`` (default metres)::

    units: m            # m, cm or mm
    polygons:           # solid polygons (k >= 3 vertices, either orientation) or 2-vertex wall segments
      - [[-5, 1], [5, 1], [5, 1.2], [-5, 1.2]]
    walls:              # polylines: each consecutive pair of points is one wall segment
      - [[-5, -1], [5, -1]]
    rectangles:         # axis-aligned solid boxes: lower-left corner and size
      - {x: -0.5, y: -0.3, width: 1.0, height: 0.6}

``StaticMap.to_dict()`` output (``{"polygons": ...}``) is a valid file. Any other top-level key (apart
from ``name`` and ``description``, free text) is an error, so that a misspelt key never silently
drops walls. A polygon may repeat its first vertex at the end (as GIS tools write rings): the repeat
is dropped, since polygons close implicitly.

SVG (``.svg``), the subset drawn by hand or by Inkscape (robot_sf's maps are an example): elements
``rect``, ``polygon``, ``polyline``, ``line`` and ``path`` with the commands M/m, L/l, H/h, V/v and
Z/z (a closed path is a solid polygon, an open one a chain of wall segments; curves are refused);
``transform`` attributes ``translate``, ``scale``, ``rotate`` (about the origin) and ``matrix`` on the
element and its groups. When any element or group is labelled (``inkscape:label``, ``id`` or
``class``) with a word starting with ``obstacle`` or ``wall``, only those (and every shape inside such
a group) are obstacles: spawn zones, routes and pedestrians drawn in the same file are ignored;
otherwise every shape is an obstacle. A labelled element or group without any of the shapes above is
an error. ``circle`` and ``ellipse`` (pedestrian markers) and ``text`` are not obstacles; a circle or
ellipse labelled as one is refused. ``use``, ``image`` and ``foreignObject`` are refused wherever they
would be obstacles (labelled, or anywhere in a drawing without labels). Lengths are SVG user units
times the scale, metres per unit: the ``scale`` argument, else the root's ``data-scale`` attribute,
else 1. The SVG y axis points down; the map flips it (world y = −scale·y) so that the drawing keeps
its orientation.

A file that yields no obstacle at all is refused (an open floor needs no map file). Every error is a
:class:`MapFileError` (a :class:`~socialnav.static_map.MapError`, hence a ``ValueError``) naming the
file, the field or element, and the value.
"""

from __future__ import annotations

import math
import re
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from socialnav._io import MAX_NESTING_DEPTH, load_yaml, short_repr
from socialnav.static_map import MapError, StaticMap

__all__ = ["MAP_SUFFIXES", "MapFileError", "load_map", "map_from_svg", "map_from_yaml", "save_map"]

MAP_SUFFIXES = (".yaml", ".yml", ".json", ".svg")
_UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001}
_YAML_KEYS = ("units", "polygons", "walls", "rectangles", "name", "description")


class MapFileError(MapError):
    """A map file cannot be read; the message starts with the file's path."""


def load_map(path: str | Path, *, scale: float | None = None) -> StaticMap:
    """Read a map file, choosing the format by its suffix.

    Args:
        path: ``.yaml``/``.yml``/``.json`` or ``.svg`` file.
        scale: SVG only: metres per SVG user unit (default: the root's ``data-scale``, else 1).

    Raises:
        MapFileError: Missing file, unknown suffix, unparsable text or an invalid polygon.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in MAP_SUFFIXES:
        raise MapFileError(
            f"{path}: unsupported map file suffix {path.suffix!r}; use one of {', '.join(MAP_SUFFIXES)}"
        )
    if not path.is_file():
        raise MapFileError(f"{path}: no such map file")
    try:
        text = path.read_text()
    except UnicodeDecodeError:
        raise MapFileError(f"{path}: not a text file") from None
    if suffix == ".svg":
        return map_from_svg(text, source=str(path), scale=scale)
    if scale is not None:
        raise MapFileError(f"{path}: scale applies to SVG maps only (YAML maps state their 'units')")
    return map_from_yaml(text, source=str(path))


def save_map(path: str | Path, smap: StaticMap) -> None:
    """Write ``smap`` as a YAML map file (atomically) that :func:`load_map` reads back exactly."""
    from socialnav._io import atomic_write_text

    path = Path(path)
    if path.suffix.lower() not in (".yaml", ".yml"):
        raise MapFileError(f"{path}: save_map writes YAML; use a .yaml or .yml suffix")
    if not smap:
        # load_map refuses a file without obstacles: do not write one it cannot read back
        raise MapFileError(f"{path}: the map has no obstacles; an open floor needs no map file")
    import yaml

    # PyYAML writes floats as their shortest repr: the map round-trips bit for bit
    text = yaml.safe_dump({"units": "m", **smap.to_dict()}, default_flow_style=None, sort_keys=False)
    atomic_write_text(path, text)


# ------------------------------------------------------------------------------------------- YAML
def map_from_yaml(text: str, *, source: str = "<map>") -> StaticMap:
    """Parse the YAML map format of this module's docstring; errors name ``source``."""
    import yaml

    try:
        data = load_yaml(text)
    except yaml.YAMLError as err:
        raise MapFileError(f"{source}: not valid YAML: {' '.join(str(err).split())}") from None
    if not isinstance(data, dict):
        raise MapFileError(f"{source}: expected a mapping with 'polygons', 'walls' or 'rectangles', "
                           f"got {type(data).__name__}")
    unknown = [k for k in data if k not in _YAML_KEYS]
    if unknown:
        raise MapFileError(f"{source}: unknown field {unknown[0]!r} (value {_short(data[unknown[0]])}); "
                           f"valid fields: {', '.join(_YAML_KEYS)}")
    units = data.get("units", "m")
    if units not in _UNITS:
        raise MapFileError(f"{source}: field 'units': {units!r} is not one of {', '.join(_UNITS)}")
    factor = _UNITS[units]
    polys: list[np.ndarray] = []
    names: list[str] = []
    for i, item in enumerate(_list(data, "polygons", source)):
        polys.append(_open_ring(_points(item, f"polygons[{i}]", source, at_least=2)) * factor)
        names.append(f"polygons[{i}]")
    for i, item in enumerate(_list(data, "walls", source)):
        pts = _points(item, f"walls[{i}]", source, at_least=2) * factor
        for j in range(len(pts) - 1):
            polys.append(pts[j : j + 2])
            names.append(f"walls[{i}] segment {j}")
    for i, item in enumerate(_list(data, "rectangles", source)):
        polys.append(_rectangle(item, f"rectangles[{i}]", source) * factor)
        names.append(f"rectangles[{i}]")
    if not polys:
        raise MapFileError(
            f"{source}: no obstacles: 'polygons', 'walls' and 'rectangles' are missing or "
            "empty (an open floor needs no map file)"
        )
    return _build(polys, names, source)


def _list(data: dict[str, Any], key: str, source: str) -> list[Any]:
    value = data.get(key)
    if value is None:
        return []
    if not isinstance(value, list):
        raise MapFileError(f"{source}: field '{key}': expected a list, got {_short(value)}")
    return value


def _points(item: Any, field: str, source: str, at_least: int) -> np.ndarray:
    if isinstance(item, list):
        item = [[_number(c) for c in p] if isinstance(p, list) else p for p in item]
    ok = isinstance(item, list) and all(
        isinstance(p, list) and len(p) == 2 and all(_is_number(c) for c in p) for p in item)
    if not ok:
        raise MapFileError(
            f"{source}: field '{field}': expected a list of [x, y] number pairs, got {_short(item)}"
        )
    if len(item) < at_least:
        raise MapFileError(f"{source}: field '{field}': needs at least {at_least} points, got {len(item)}")
    return np.array(item, dtype=np.float64)


def _rectangle(item: Any, field: str, source: str) -> np.ndarray:
    keys = ("x", "y", "width", "height")
    if isinstance(item, dict):
        item = {k: _number(v) for k, v in item.items()}
    if not isinstance(item, dict) or set(item) != set(keys) or not all(_is_number(item[k]) for k in keys):
        raise MapFileError(
            f"{source}: field '{field}': expected {{x, y, width, height}} numbers, got {_short(item)}"
        )
    x, y, w, h = (float(item[k]) for k in keys)
    if not (w > 0 and h > 0):
        raise MapFileError(f"{source}: field '{field}': width and height must be > 0, got {w} x {h}")
    return np.array([[x, y], [x + w, y], [x + w, y + h], [x, y + h]])


def _open_ring(pts: np.ndarray) -> np.ndarray:
    """The polygon without a closing vertex that repeats the first (rings as GIS tools write them).

    Polygons close implicitly, so the repeat would be a zero-length edge; three points are left as
    they are (dropping one would turn the polygon into a segment).
    """
    return pts[:-1] if len(pts) >= 4 and np.array_equal(pts[0], pts[-1]) else pts


def _number(v: Any) -> Any:
    """YAML 1.1 reads 1e-7 (no dot) as text: such text is taken as the number it spells."""
    if isinstance(v, str) and re.fullmatch(_NUMBER, v.strip()):
        return float(v)
    return v


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _short(value: Any) -> str:
    return short_repr(value, 80)


def _build(polys: list[np.ndarray], names: list[str], source: str) -> StaticMap:
    """The map, with a failing polygon named by where it came from in the file."""
    for poly, name in zip(polys, names, strict=True):
        try:
            StaticMap((poly,))
        except MapError as err:
            message = str(err).removeprefix("polygon 0: ")
            raise MapFileError(f"{source}: {name}: {message}") from None
    return StaticMap(tuple(polys))


# -------------------------------------------------------------------------------------------- SVG
_SVG_NS = "{http://www.w3.org/2000/svg}"
_LABEL = "{http://www.inkscape.org/namespaces/inkscape}label"
_XLINK_HREF = "{http://www.w3.org/1999/xlink}href"
_SHAPES = ("rect", "polygon", "polyline", "line", "path")
# never drawn, or drawn only through <use> or a fill; text is an annotation, never a wall
_NOT_DRAWN = (
    "defs",
    "clipPath",
    "mask",
    "symbol",
    "marker",
    "pattern",
    "metadata",
    "title",
    "desc",
    "style",
    "script",
    "text",
)
# robot_sf draws pedestrians as circles: not obstacles, unless labelled as such
_MARKERS = ("circle", "ellipse")
# drawn, but not convertible: refused where they would be obstacles rather than silently dropped
_UNSUPPORTED = {
    "use": "it draws a copy of another element, which the loader does not follow: replace the clone by "
    "the shape itself, e.g. Inkscape's Edit > Clone > Unlink Clone",
    "image": "a raster picture cannot be turned into obstacles: draw the walls as shapes",
    "foreignObject": "its content cannot be turned into obstacles",
}
_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_TRANSFORM = r"(\w+)\s*\(([^)]*)\)"
# metres per unit of the lengths a root's width may be given in (CSS absolute units)
_PAGE_UNITS = {"mm": 1e-3, "cm": 1e-2, "q": 2.5e-4, "in": 0.0254, "pt": 0.0254 / 72, "pc": 0.0254 / 6}


def map_from_svg(text: str, *, source: str = "<svg>", scale: float | None = None) -> StaticMap:
    """Parse the SVG subset of this module's docstring; errors name ``source`` and the element."""
    import xml.etree.ElementTree as ET

    try:
        root = ET.fromstring(text)
    except ET.ParseError as err:
        raise MapFileError(f"{source}: not valid SVG/XML ({err})") from None
    if _tag(root) != "svg":
        raise MapFileError(f"{source}: root element is <{_tag(root)}>, not <svg>")
    if scale is None:
        if root.get("data-scale") is None:
            _warn_page_size(root, source)
        raw = root.get("data-scale", "1")
        scale = float(raw) if re.fullmatch(_NUMBER, raw.strip()) else math.nan
        if not scale > 0:
            raise MapFileError(f"{source}: attribute 'data-scale' of <svg>: {raw!r} is not a number > 0")
    if not (math.isfinite(scale) and scale > 0):
        raise MapFileError(f"{source}: scale must be a finite number > 0, got {scale!r}")
    drawing = _Drawing()
    _collect(root, np.eye(3), False, drawing, source)
    labelled = bool(drawing.labelled)
    for elem, flag in drawing.others:
        tag = _tag(elem)
        if flag and tag in _MARKERS:
            raise MapFileError(
                f"{source}: {_describe(elem)}: not supported as an obstacle (draw it as a "
                "polygon or path); it is labelled as an obstacle (or in a group so labelled)"
            )
        if tag in _UNSUPPORTED and (flag or not labelled):
            where = (
                "it is labelled as an obstacle (or in a group so labelled)"
                if flag
                else "in a drawing without 'obstacle' or 'wall' labels everything drawn is an obstacle"
            )
            raise MapFileError(f"{source}: {_describe(elem)}: not supported ({_UNSUPPORTED[tag]}); {where}")
    for elem, has_shapes in drawing.labelled:
        if not has_shapes:
            # falling back to "every shape" would make the spawn zones and routes the obstacles
            raise MapFileError(
                f"{source}: {_describe(elem)}: labelled as obstacles, but holds no "
                f"{', '.join(_SHAPES)} element"
            )
    polys: list[np.ndarray] = []
    names: list[str] = []
    flip = np.diag([scale, -scale, 1.0])
    for n, (elem, transform, flag) in enumerate(drawing.shapes):
        if labelled and not flag:
            continue
        name = f"<{_tag(elem)}> #{n + 1}" + (f" id={elem.get('id')!r}" if elem.get("id") else "")
        for pts, closed in _shape_points(elem, name, source):
            world = _apply(flip @ transform, pts)
            if closed and len(world) >= 3:
                polys.append(world)
                names.append(name)
            else:
                for j in range(len(world) - 1):
                    polys.append(world[j : j + 2])
                    names.append(f"{name} segment {j}")
    if not polys:
        n_markers = len(drawing.others)  # without labels, only markers are left in others
        skipped = f" (circles and ellipses are not obstacles: {n_markers} skipped)" if n_markers else ""
        raise MapFileError(
            f"{source}: no obstacles: the drawing has no {', '.join(_SHAPES)} element"
            f"{skipped}; an open floor needs no map file"
        )
    return _build(polys, names, source)


class _Drawing:
    """What :func:`_collect` finds, in document order."""

    def __init__(self) -> None:
        self.shapes: list[tuple[Any, np.ndarray, bool]] = []  # (element, transform, obstacle by label)
        self.others: list[tuple[Any, bool]] = []  # markers and unsupported elements, (element, by label)
        self.labelled: list[tuple[Any, bool]] = []  # elements labelled themselves, (element, has shapes)


def _tag(elem: Any) -> str:
    return elem.tag.removeprefix(_SVG_NS) if isinstance(elem.tag, str) else ""


def _describe(elem: Any) -> str:
    """``<tag>`` with whatever names the element: id, Inkscape label, class, the target of a ``<use>``."""
    attrs = (
        ("id", "id"),
        ("inkscape:label", _LABEL),
        ("class", "class"),
        ("href", "href"),
        ("href", _XLINK_HREF),
    )
    named = [f"{key}={elem.get(attr)!r}" for key, attr in attrs if elem.get(attr)]
    return " ".join([f"<{_tag(elem)}>", *named])


def _is_obstacle_label(elem: Any) -> bool:
    words = " ".join(elem.get(a, "") for a in (_LABEL, "id", "class")).lower().replace("-", "_")
    return any(w.startswith(("obstacle", "wall")) for w in re.split(r"[\s_]+", words) if w)


def _warn_page_size(root: Any, source: str) -> None:
    """Warns where the root gives the page a physical size and no scale was given.

    Inkscape writes ``width="210mm"`` and a viewBox: one user unit is then a millimetre on paper, but
    the map reads it as one metre.
    """
    width, box = root.get("width", ""), root.get("viewBox", "").replace(",", " ").split()
    match = re.fullmatch(rf"\s*({_NUMBER})\s*([a-zA-Z]+)\s*", width)
    if not match or match.group(2).lower() not in _PAGE_UNITS or len(box) != 4:
        return
    try:
        per_unit = float(match.group(1)) * _PAGE_UNITS[match.group(2).lower()] / float(box[2])
    except (ValueError, ZeroDivisionError):
        return
    if math.isfinite(per_unit) and per_unit > 0:
        warnings.warn(
            f"{source}: the page is {width.strip()} wide for a viewBox {box[2]} user units wide (1 user unit "
            f"= {per_unit:.4g} m on paper); the map reads 1 user unit as 1 m: give the metres per user unit "
            "(scale=, --map-scale, or the root's data-scale) if the drawing is to another scale",
            UserWarning, stacklevel=4,
        )


def _hidden(elem: Any) -> bool:
    """``display="none"`` or ``style="display:none"``: not drawn (an Inkscape layer switched off)."""
    if elem.get("display", "").strip() == "none":
        return True
    style = re.sub(r"\s+", "", elem.get("style", "")).lower()
    return any(item == "display:none" for item in style.split(";"))


def _collect(elem: Any, transform: np.ndarray, inside: bool, drawing: _Drawing, source: str,
             depth: int = 1) -> None:
    tag = _tag(elem)
    if depth > MAX_NESTING_DEPTH:  # walked recursively: refused before Python's recursion limit
        raise MapFileError(f"{source}: {_describe(elem)}: nested too deep: more than {MAX_NESTING_DEPTH} "
                           "levels of elements")
    if tag in _NOT_DRAWN or _hidden(elem):
        return
    here = transform @ _parse_transform(elem.get("transform", ""), tag, source)
    own = _is_obstacle_label(elem)
    flag = inside or own
    n_shapes = len(drawing.shapes)
    if tag in _SHAPES:
        drawing.shapes.append((elem, here, flag))
    elif tag in _MARKERS or tag in _UNSUPPORTED:
        drawing.others.append((elem, flag))
    for child in elem:
        _collect(child, here, flag, drawing, source, depth + 1)
    if own:
        drawing.labelled.append((elem, len(drawing.shapes) > n_shapes))


def _parse_transform(text: str, tag: str, source: str) -> np.ndarray:
    if re.sub(_TRANSFORM, " ", text).replace(",", " ").strip():
        raise MapFileError(f"{source}: <{tag}> attribute 'transform': cannot parse {_short(text)}")
    m = np.eye(3)
    for name, args in re.findall(_TRANSFORM, text):
        if re.sub(_NUMBER, " ", args).replace(",", " ").strip():
            raise MapFileError(
                f"{source}: <{tag}> attribute 'transform': {name}({args.strip()}): "
                f"{args.strip()!r} is not a list of numbers"
            )
        v = [float(x) for x in re.findall(_NUMBER, args)]
        if name == "translate" and len(v) in (1, 2):
            t = np.array([[1, 0, v[0]], [0, 1, v[1] if len(v) == 2 else 0.0], [0, 0, 1]])
        elif name == "scale" and len(v) in (1, 2):
            t = np.diag([v[0], v[1] if len(v) == 2 else v[0], 1.0])
        elif name == "rotate" and len(v) == 1:
            c, s = math.cos(math.radians(v[0])), math.sin(math.radians(v[0]))
            t = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
        elif name == "matrix" and len(v) == 6:
            a, b, c, d, e, f = v
            t = np.array([[a, c, e], [b, d, f], [0, 0, 1]])
        else:
            raise MapFileError(f"{source}: <{tag}> attribute 'transform': {name}({args.strip()}) is not "
                               "supported (translate, scale, rotate(angle), matrix)")
        m = m @ t
    return m


def _apply(m: np.ndarray, pts: np.ndarray) -> np.ndarray:
    return pts @ m[:2, :2].T + m[:2, 2]


def _numbers(elem: Any, attr: str, name: str, source: str) -> list[float]:
    raw = elem.get(attr)
    if raw is None:
        raise MapFileError(f"{source}: {name}: attribute {attr!r} missing")
    nums = re.findall(_NUMBER, raw)
    rest = re.sub(_NUMBER, " ", raw).replace(",", " ").strip()
    if rest:
        raise MapFileError(f"{source}: {name}: attribute {attr!r}: {raw!r} is not a list of numbers")
    return [float(x) for x in nums]


def _length(elem: Any, attr: str, name: str, source: str, default: float | None = None) -> float:
    raw = elem.get(attr)
    if raw is None:
        if default is None:
            raise MapFileError(f"{source}: {name}: attribute {attr!r} missing")
        return default
    text = raw.strip().removesuffix("px")
    if re.fullmatch(_NUMBER, text):
        return float(text)
    if text.lower().lstrip("+-") in ("nan", "inf", "infinity"):
        why = "is not a finite number"
    else:
        why = "is not a number (units other than user units are not supported)"
    raise MapFileError(f"{source}: {name}: attribute {attr!r}: {raw!r} {why}")


def _shape_points(elem: Any, name: str, source: str) -> list[tuple[np.ndarray, bool]]:
    """Vertex lists of one element (in its own coordinates) and whether each is closed."""
    tag = _tag(elem)
    if tag == "rect":
        x, y = _length(elem, "x", name, source, 0.0), _length(elem, "y", name, source, 0.0)
        w, h = _length(elem, "width", name, source), _length(elem, "height", name, source)
        if not (w > 0 and h > 0):
            raise MapFileError(f"{source}: {name}: width and height must be > 0, got {w} x {h}")
        return [(np.array([[x, y], [x + w, y], [x + w, y + h], [x, y + h]]), True)]
    if tag == "line":
        coords = [_length(elem, a, name, source, 0.0) for a in ("x1", "y1", "x2", "y2")]
        return [(np.array(coords).reshape(2, 2), False)]
    if tag in ("polygon", "polyline"):
        v = _numbers(elem, "points", name, source)
        if len(v) % 2 or len(v) < 4:
            raise MapFileError(
                f"{source}: {name}: attribute 'points' needs pairs of numbers (>= 2 points), "
                f"got {len(v)} numbers"
            )
        pts = np.array(v).reshape(-1, 2)
        return [(_open_ring(pts), True)] if tag == "polygon" else [(pts, False)]
    return _path_points(elem.get("d", ""), name, source)


def _path_points(d: str, name: str, source: str) -> list[tuple[np.ndarray, bool]]:
    tokens = re.findall(r"[A-Za-z]|" + _NUMBER, d)
    leftover = re.sub(r"[A-Za-z]|" + _NUMBER, " ", d).replace(",", " ").strip()
    if leftover or not tokens:
        raise MapFileError(f"{source}: {name}: attribute 'd': cannot parse {_short(d)}")
    out: list[tuple[np.ndarray, bool]] = []
    current: list[list[float]] = []
    pos = np.zeros(2)
    start = np.zeros(2)
    cmd = ""
    i = 0

    def flush(closed: bool) -> None:
        if len(current) >= 2:
            out.append((np.array(current), closed))
        current.clear()

    while i < len(tokens):
        if tokens[i].isalpha():
            cmd = tokens[i]
            i += 1
            if cmd in "Zz":
                flush(True)
                pos = start.copy()
                continue
        if cmd not in "MmLlHhVv" or not cmd:
            raise MapFileError(f"{source}: {name}: attribute 'd': command {cmd or tokens[i]!r} is not "
                               "supported (M, L, H, V, Z and their relative forms)")
        need = 1 if cmd in "HhVv" else 2
        args = tokens[i : i + need]
        if len(args) < need or any(a.isalpha() for a in args):
            raise MapFileError(f"{source}: {name}: attribute 'd': command {cmd!r} needs {need} number(s)")
        vals = [float(a) for a in args]
        i += need
        rel = cmd.islower()
        if cmd in "Mm":
            flush(False)
            pos = (pos if rel else 0.0) + np.array(vals)
            start = pos.copy()
            current.append(pos.tolist())
            cmd = "l" if rel else "L"  # further pairs after a moveto are linetos
            continue
        if cmd in "Ll":
            pos = (pos if rel else 0.0) + np.array(vals)
        elif cmd in "Hh":
            pos = np.array([(pos[0] if rel else 0.0) + vals[0], pos[1]])
        else:
            pos = np.array([pos[0], (pos[1] if rel else 0.0) + vals[0]])
        if not current:
            current.append(start.tolist())
        current.append(pos.tolist())
    flush(False)
    # a closed path repeats its first vertex as the last one only when drawn so: drop the repeat
    return [(pts[:-1] if closed and len(pts) > 3 and np.allclose(pts[0], pts[-1]) else pts, closed)
            for pts, closed in out]

"""The SVG map format: a :class:`~socialnav.maps.static_map.StaticMap` from an SVG drawing.

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

A drawing that yields no obstacle at all is refused (an open floor needs no map file).
"""

from __future__ import annotations

import math
import re
import warnings
from typing import Any

import numpy as np

from socialnav._io import MAX_NESTING_DEPTH
from socialnav.maps.parsing import NUMBER, MapFileError, build_map, open_ring, short
from socialnav.maps.static_map import StaticMap

__all__ = ["map_from_svg"]

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
        scale = float(raw) if re.fullmatch(NUMBER, raw.strip()) else math.nan
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
    return build_map(polys, names, source)


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
    match = re.fullmatch(rf"\s*({NUMBER})\s*([a-zA-Z]+)\s*", width)
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
    if tag == "svg" and depth > 1:
        placed = [a for a in ("x", "y", "viewBox") if elem.get(a) is not None]
        if placed:  # its own viewport would move and scale what it holds, which is not read here
            raise MapFileError(f"{source}: {_describe(elem)}: a nested <svg> with {', '.join(placed)} is not "
                               "supported (use a <g> with a transform)")
    here = transform @ _parse_transform(elem.get("transform", ""), _describe(elem), source)
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


def _parse_transform(text: str, element: str, source: str) -> np.ndarray:
    """The matrix of a ``transform`` attribute; ``element`` names its element in a message."""
    if re.sub(_TRANSFORM, " ", text).replace(",", " ").strip():
        raise MapFileError(f"{source}: {element} attribute 'transform': cannot parse {short(text)}")
    m = np.eye(3)
    for name, args in re.findall(_TRANSFORM, text):
        if re.sub(NUMBER, " ", args).replace(",", " ").strip():
            raise MapFileError(
                f"{source}: {element} attribute 'transform': {name}({args.strip()}): "
                f"{args.strip()!r} is not a list of numbers"
            )
        v = [float(x) for x in re.findall(NUMBER, args)]
        if not all(math.isfinite(x) for x in v):
            raise MapFileError(f"{source}: {element} attribute 'transform': {name}({args.strip()}): a number "
                               "is too large (not finite)")
        if name == "translate" and len(v) in (1, 2):
            t = np.array([[1, 0, v[0]], [0, 1, v[1] if len(v) == 2 else 0.0], [0, 0, 1]])
        elif name == "scale" and len(v) in (1, 2):
            t = np.diag([v[0], v[1] if len(v) == 2 else v[0], 1.0])
        elif name == "rotate" and len(v) in (1, 3):
            c, s = math.cos(math.radians(v[0])), math.sin(math.radians(v[0]))
            t = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
            if len(v) == 3:  # about (cx, cy): translate(cx, cy) rotate(a) translate(-cx, -cy)
                cx, cy = v[1], v[2]
                to_origin = np.array([[1, 0, -cx], [0, 1, -cy], [0, 0, 1]])
                t = np.array([[1, 0, cx], [0, 1, cy], [0, 0, 1]]) @ t @ to_origin
        elif name == "matrix" and len(v) == 6:
            a, b, c, d, e, f = v
            t = np.array([[a, c, e], [b, d, f], [0, 0, 1]])
        else:
            raise MapFileError(f"{source}: {element} attribute 'transform': {name}({args.strip()}) is not "
                               "supported (translate, scale, rotate(angle[, cx, cy]), matrix)")
        m = m @ t
    return m


def _apply(m: np.ndarray, pts: np.ndarray) -> np.ndarray:
    return pts @ m[:2, :2].T + m[:2, 2]


def _numbers(elem: Any, attr: str, name: str, source: str) -> list[float]:
    raw = elem.get(attr)
    if raw is None:
        raise MapFileError(f"{source}: {name}: attribute {attr!r} missing")
    nums = re.findall(NUMBER, raw)
    rest = re.sub(NUMBER, " ", raw).replace(",", " ").strip()
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
    if re.fullmatch(NUMBER, text):
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
        return [(open_ring(pts), True)] if tag == "polygon" else [(pts, False)]
    return _path_points(elem.get("d", ""), name, source)


def _path_points(d: str, name: str, source: str) -> list[tuple[np.ndarray, bool]]:
    tokens = re.findall(r"[A-Za-z]|" + NUMBER, d)
    leftover = re.sub(r"[A-Za-z]|" + NUMBER, " ", d).replace(",", " ").strip()
    if leftover or not tokens:
        raise MapFileError(f"{source}: {name}: attribute 'd': cannot parse {short(d)}")
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

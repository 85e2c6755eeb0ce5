"""The YAML map format: a :class:`~socialnav.maps.static_map.StaticMap` from YAML (or JSON) text.

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

A file that yields no obstacle at all is refused (an open floor needs no map file).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from socialnav._io import load_yaml
from socialnav.maps.parsing import MapFileError, build_map, is_number, number_or_text, open_ring, short
from socialnav.maps.static_map import StaticMap

__all__ = ["map_from_yaml"]

_UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001}
_YAML_KEYS = ("units", "polygons", "walls", "rectangles", "name", "description")


def map_from_yaml(text: str, *, source: str = "<map>") -> StaticMap:
    """Parse the YAML map format of this module's docstring; errors name ``source``."""
    import yaml

    try:
        data = load_yaml(text)
    except yaml.YAMLError as err:
        raise MapFileError(f"{source}: not valid YAML: {' '.join(str(err).split())}") from None
    if data is None:
        raise MapFileError(f"{source}: the file is empty (expected a mapping with 'polygons', 'walls' or "
                           "'rectangles')")
    if not isinstance(data, dict):
        raise MapFileError(f"{source}: expected a mapping with 'polygons', 'walls' or 'rectangles', "
                           f"got {type(data).__name__}")
    unknown = [k for k in data if k not in _YAML_KEYS]
    if unknown:
        raise MapFileError(f"{source}: unknown field {unknown[0]!r} (value {short(data[unknown[0]])}); "
                           f"valid fields: {', '.join(_YAML_KEYS)}")
    units = data.get("units", "m")
    if not isinstance(units, str) or units not in _UNITS:
        raise MapFileError(f"{source}: field 'units': {units!r} is not one of {', '.join(_UNITS)}")
    factor = _UNITS[units]
    polys: list[np.ndarray] = []
    names: list[str] = []
    for i, item in enumerate(_list(data, "polygons", source)):
        polys.append(open_ring(_points(item, f"polygons[{i}]", source, at_least=2)) * factor)
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
    return build_map(polys, names, source)


def _list(data: dict[str, Any], key: str, source: str) -> list[Any]:
    value = data.get(key)
    if value is None:
        return []
    if not isinstance(value, list):
        raise MapFileError(f"{source}: field '{key}': expected a list, got {short(value)}")
    return value


def _points(item: Any, field: str, source: str, at_least: int) -> np.ndarray:
    if isinstance(item, list):
        item = [[number_or_text(c) for c in p] if isinstance(p, list) else p for p in item]
    ok = isinstance(item, list) and all(
        isinstance(p, list) and len(p) == 2 and all(is_number(c) for c in p) for p in item)
    if not ok:
        raise MapFileError(
            f"{source}: field '{field}': expected a list of [x, y] number pairs, got {short(item)}"
        )
    if len(item) < at_least:
        raise MapFileError(f"{source}: field '{field}': needs at least {at_least} points, got {len(item)}")
    return np.array([[_float(c, field, source) for c in p] for p in item], dtype=np.float64)


def _float(value: Any, field: str, source: str) -> float:
    """A coordinate as a float; an integer too large for one is named (float() overflows on it)."""
    try:
        return float(value)
    except OverflowError:
        raise MapFileError(f"{source}: field '{field}': {short(value)} is too large a number") from None


def _rectangle(item: Any, field: str, source: str) -> np.ndarray:
    keys = ("x", "y", "width", "height")
    if isinstance(item, dict):
        item = {k: number_or_text(v) for k, v in item.items()}
    if not isinstance(item, dict) or set(item) != set(keys) or not all(is_number(item[k]) for k in keys):
        raise MapFileError(
            f"{source}: field '{field}': expected {{x, y, width, height}} numbers, got {short(item)}"
        )
    x, y, w, h = (_float(item[k], f"{field}.{k}", source) for k in keys)
    if not (w > 0 and h > 0):
        raise MapFileError(f"{source}: field '{field}': width and height must be > 0, got {w} x {h}")
    return np.array([[x, y], [x + w, y], [x + w, y + h], [x, y + h]])

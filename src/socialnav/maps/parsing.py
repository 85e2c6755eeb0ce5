"""What the map file readers share: their error, number syntax, rings and the map they build.

Every error is a :class:`MapFileError` (a :class:`~socialnav.maps.static_map.MapError`, hence a
``ValueError``) whose message starts with the file (``source``) and names the field or element and
the value.
"""

from __future__ import annotations

import re
from typing import Any

import numpy as np

from socialnav._io import short_repr
from socialnav.maps.static_map import MapError, StaticMap

#: A decimal number as YAML text and SVG attributes write it (sign, digits, fraction, exponent).
NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"


class MapFileError(MapError):
    """A map file cannot be read; the message starts with the file's path."""


def number_or_text(v: Any) -> Any:
    """YAML 1.1 reads 1e-7 (no dot) as text: such text is taken as the number it spells."""
    if isinstance(v, str) and re.fullmatch(NUMBER, v.strip()):
        return float(v)
    return v


def is_number(v: Any) -> bool:
    """A number (int or float), never a bool."""
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def short(value: Any) -> str:
    """``value``'s repr, at most 80 characters, for a message."""
    return short_repr(value, 80)


def open_ring(pts: np.ndarray) -> np.ndarray:
    """The polygon without a closing vertex that repeats the first (rings as GIS tools write them).

    Polygons close implicitly, so the repeat would be a zero-length edge; three points are left as
    they are (dropping one would turn the polygon into a segment).
    """
    return pts[:-1] if len(pts) >= 4 and np.array_equal(pts[0], pts[-1]) else pts


def build_map(polys: list[np.ndarray], names: list[str], source: str) -> StaticMap:
    """The map, with a failing polygon named by where it came from in the file."""
    for poly, name in zip(polys, names, strict=True):
        try:
            StaticMap((poly,))
        except MapError as err:
            message = str(err).removeprefix("polygon 0: ")
            raise MapFileError(f"{source}: {name}: {message}") from None
    return StaticMap(tuple(polys))

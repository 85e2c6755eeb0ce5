"""Map files: a :class:`~socialnav.maps.static_map.StaticMap` read from, or written to, a file.

:func:`load_map` chooses the format by the suffix: YAML (``.yaml``, ``.yml``, ``.json``; the format is
described in :mod:`socialnav.maps.yaml_reader`) or an SVG drawing (``.svg``;
:mod:`socialnav.maps.svg_reader`). :func:`save_map` writes YAML that :func:`load_map` reads back exactly.

A file that yields no obstacle at all is refused (an open floor needs no map file). Every error is a
:class:`MapFileError` (a :class:`~socialnav.maps.static_map.MapError`, hence a ``ValueError``) naming the
file, the field or element, and the value.
"""

from __future__ import annotations

from pathlib import Path

from socialnav.maps.parsing import MapFileError
from socialnav.maps.static_map import StaticMap
from socialnav.maps.svg_reader import map_from_svg
from socialnav.maps.yaml_reader import map_from_yaml

__all__ = ["MAP_SUFFIXES", "MapFileError", "load_map", "map_from_svg", "map_from_yaml", "save_map"]

MAP_SUFFIXES = (".yaml", ".yml", ".json", ".svg")


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

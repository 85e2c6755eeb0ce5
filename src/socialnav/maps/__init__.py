"""Static maps: an episode's walls and obstacles as polygons, and the map files they are read from.

Example::

    from socialnav.maps import StaticMap, load_map

    corridor = StaticMap(([[-5.0, 1.0], [5.0, 1.0]], [[-5.0, -1.0], [5.0, -1.0]]))  # two wall segments
    drawn = load_map("floor.svg", scale=0.01)  # YAML (.yaml, .yml, .json) or SVG, by the suffix

:class:`StaticMap` (``static_map.py``) is the one representation of obstacles, shared by scenarios,
the world, trajectories and metrics; it depends on NumPy only. The map files (``files.py``: YAML in
``yaml_reader.py``, the SVG subset in ``svg_reader.py``) and the routes around a map's walls
(``routes.py``: ``plan_route``, ``route_distances``) load on first use of their names.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from socialnav._runtime import lazy_exports
from socialnav.maps.static_map import MAX_COORDINATE, MapError, MapStack, StaticMap

#: Public names whose module loads on first use (see ``lazy_exports``).
_EXPORTS = {
    "MAP_SUFFIXES": "socialnav.maps.files",
    "MapFileError": "socialnav.maps.files",
    "load_map": "socialnav.maps.files",
    "map_from_svg": "socialnav.maps.files",
    "map_from_yaml": "socialnav.maps.files",
    "save_map": "socialnav.maps.files",
    "Route": "socialnav.maps.routes",
    "plan_route": "socialnav.maps.routes",
    "route_distances": "socialnav.maps.routes",
}

__all__ = [
    "MAP_SUFFIXES",
    "MAX_COORDINATE",
    "MapError",
    "MapFileError",
    "MapStack",
    "Route",
    "StaticMap",
    "load_map",
    "map_from_svg",
    "map_from_yaml",
    "plan_route",
    "route_distances",
    "save_map",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

if TYPE_CHECKING:  # what type checkers and IDEs see; at run time the names load lazily
    from socialnav.maps.files import (
        MAP_SUFFIXES,
        MapFileError,
        load_map,
        map_from_svg,
        map_from_yaml,
        save_map,
    )
    from socialnav.maps.routes import Route, plan_route, route_distances

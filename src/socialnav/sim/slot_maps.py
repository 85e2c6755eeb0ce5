"""Each World slot's static map, kept in step with the native world's obstacles.

A world has one *fixed* map (its ``static_map`` argument or the scenario's) that the core's own refills
give every new episode; a scenario that generates a map per episode, or a caller of
``World.set_static_map``, can give a slot another one. Such slots are tracked, so that a native refill,
which knows only the fixed map, can restore it.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from socialnav import _core
from socialnav.maps.static_map import StaticMap
from socialnav.sim.observation import ObstacleArrays
from socialnav.sim.world_config import check_map_size


class SlotMaps:
    """The B slots' static maps and the flat form observations carry.

    Args:
        batch_size: Number of slots B.
        max_vertices: Vertices one map may have (``WorldSettings.max_obstacle_vertices``).
        fixed: The world's fixed map (None: an open floor). The slots start as open floors: the
            World gives them the fixed map once its native world exists.
    """

    def __init__(self, batch_size: int, max_vertices: int, fixed: StaticMap | None):
        """Starts every slot as an open floor (arguments: see the class)."""
        self.batch_size = batch_size
        self.max_vertices = max_vertices
        self.fixed = fixed
        #: (B,) each slot's static map (None: open floor); changed through :meth:`set` only.
        self.maps: list[StaticMap | None] = [None] * batch_size
        #: Slots whose map is not the fixed one.
        self.custom: set[int] = set()
        self._arrays: ObstacleArrays | None = None  # the flat form of maps, cached
        self._n_mapped = 0  # slots whose map is not None (open floors skip the O(B) scan per step)

    def set(self, core: _core.World, slot: int, static_map: StaticMap | None) -> None:
        """Gives ``slot`` the map ``static_map`` here and in the native world ``core``.

        Args:
            core: The native world whose obstacles follow the maps.
            slot: The slot, 0 <= slot < B.
            static_map: Its map, or None (or an empty map) for an open floor.

        Raises:
            TypeError: ``static_map`` is neither a StaticMap nor None.
            ValueError: The map has more than ``max_vertices`` vertices, or its copies in every slot
                would exceed the memory bound.
        """
        if static_map is not None and not isinstance(static_map, StaticMap):
            raise TypeError(f"a static map must be a StaticMap or None, got {type(static_map).__name__}")
        static_map = static_map if static_map else None
        if static_map is self.maps[slot]:
            self._note_custom(slot, static_map)
            return
        if static_map is not None and static_map.n_vertices > self.max_vertices:
            raise ValueError(
                f"the static map of slot {slot} has {static_map.n_vertices} vertices, more than "
                f"max_obstacle_vertices = {self.max_vertices} (raise that setting)"
            )
        if static_map is not None:
            check_map_size(static_map.n_vertices, self.batch_size)
        if static_map is None:
            vertices, offsets = np.zeros((0, 2)), np.zeros(1, np.int64)
        else:
            vertices, offsets = static_map.to_flat()
        core.set_obstacles(int(slot), vertices, offsets)
        self._n_mapped += (static_map is not None) - (self.maps[slot] is not None)
        self.maps[slot] = static_map
        self._arrays = None
        self._note_custom(slot, static_map)

    def restore_fixed(self, core: _core.World, slots: Iterable[int]) -> None:
        """Gives those of ``slots`` that hold another map the fixed one back.

        Args:
            core: The native world whose obstacles follow the maps.
            slots: Slots whose new episodes have the fixed map (the core's refills).
        """
        for b in slots:
            if int(b) in self.custom:
                self.set(core, int(b), self.fixed)

    @property
    def arrays(self) -> ObstacleArrays | None:
        """The slots' maps in flat form (None when every slot is an open floor)."""
        if self._arrays is None and self._n_mapped:
            self._arrays = ObstacleArrays.from_maps(self.maps)
        return self._arrays

    def _note_custom(self, slot: int, static_map: StaticMap | None) -> None:
        if static_map is self.fixed:
            self.custom.discard(int(slot))
        else:
            self.custom.add(int(slot))


def scenario_map(scenario: object) -> StaticMap | None:
    """The scenario's one map for all its episodes (its ``static_map`` attribute), if it has one.

    Args:
        scenario: The world's scenario.

    Returns:
        The map, or None where the scenario has none or an empty one.

    Raises:
        TypeError: The attribute is neither a StaticMap nor None.
    """
    fixed = getattr(scenario, "static_map", None)
    if fixed is not None and not isinstance(fixed, StaticMap):
        raise TypeError(
            f"scenario {type(scenario).__name__}.static_map must be a StaticMap or None, "
            f"got {type(fixed).__name__}"
        )
    return fixed if fixed else None

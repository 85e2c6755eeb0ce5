"""Compositions: the parts a consumer reads, by name, in one layout."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from socialnav.sim.parts.base import PartContext, PartInput
from socialnav.sim.parts.registry import UnknownObservationPartError, get_observation_part

__all__ = ["ObservationComposition", "check_part_names"]


class ObservationComposition:
    """The parts a consumer reads, by name, in one layout: their spaces and their arrays.

    Args:
        names: Part names, in the order their keys come.
        context: The layout (frame, units, dtype, slots).

    Raises:
        UnknownObservationPartError: A name no part has.
        ValueError: A name listed twice, two parts with the same key, or a frame a part lacks.
    """

    def __init__(self, names: Sequence[str], context: PartContext):
        names = tuple(names)
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:
            raise ValueError(f"observation part(s) listed twice: {', '.join(twice)}")
        self.names = names
        self.context = context
        self.parts = tuple(get_observation_part(n) for n in names)
        for part in self.parts:
            part.check_context(context)
        self._spaces: dict[str, Any] | None = None
        owner: dict[str, str] = {}
        for part in self.parts:
            for key in part.spaces(context):
                if key in owner:
                    raise ValueError(
                        f"observation parts {owner[key]!r} and {part.name!r} both give key {key!r}"
                    )
                owner[key] = part.name
        #: The parts that give keys in this layout (one without keys, such as obstacle_points without
        #: an encoding, is not asked to compute anything).
        self.active = tuple(p for p in self.parts if p.name in owner.values())
        #: Whether a part that gives keys reads the walls (``ObservationPart.reads_maps``): then the
        #: wrappers hand each episode's map to every call.
        self.reads_maps = any(p.reads_maps for p in self.active)
        #: Whether the keys show the walls (a part that reads the maps, or a sensor that sees them).
        self.shows_walls = any(p.reads_maps or p.sees_walls for p in self.active)
        #: The raw sensor keys the parts that give keys read (``ObservationPart.sensor_keys``).
        self.sensor_keys = tuple(dict.fromkeys(k for p in self.active for k in p.sensor_keys))

    def spaces(self) -> dict[str, Any]:
        """One episode's keys (in part order) and their Gymnasium spaces."""
        if self._spaces is None:
            out: dict[str, Any] = {}
            for part in self.parts:
                out.update(part.spaces(self.context))
            self._spaces = out
        return dict(self._spaces)

    def single_space(self) -> Any:
        """One episode's observation space (a ``gymnasium.spaces.Dict``)."""
        from gymnasium import spaces

        return spaces.Dict(self.spaces())

    def __call__(self, data: PartInput) -> dict[str, np.ndarray]:
        """Every part's (B, …) arrays of ``data``, one dict."""
        out: dict[str, np.ndarray] = {}
        ctx = self.context
        for part in self.active:
            out.update(part.compute(data, ctx))
        return out

    def agent_sets(self, data: PartInput) -> tuple[np.ndarray, np.ndarray, int]:
        """The agent-set parts as one set of agents, as the networks read them.

        Returns:
            (B, N + K…, 5) float64 rows in part order, their (B, …) bool mask, and how many trailing slots
            are static agents (parts that never move; they must come after the moving ones).

        Raises:
            ValueError: A part that is not an agent set (other than ``robot``, which the networks read as
                the robot's state), or a moving set after a static one.
        """
        sets, static, seen_static = [], 0, False
        for part in self.parts:
            if part.name == "robot":
                continue
            got = part.agents(data, self.context)
            if got is None:
                if not part.spaces(self.context):
                    continue
                raise ValueError(f"observation part {part.name!r} is not a set of agents: the networks read "
                                 "the robot's state and sets of agents only")
            if part.static:
                seen_static = True
                static += got[0].shape[1]
            elif seen_static:
                raise ValueError(f"observation part {part.name!r} moves and comes after a static one: static "
                                 "agents (obstacle points) must come last")
            sets.append(got)
        if not sets:
            b = data.batch_size
            return np.zeros((b, 0, 5)), np.zeros((b, 0), dtype=bool), 0
        if len(sets) == 1:
            return sets[0][0], sets[0][1], static
        return (np.concatenate([s[0] for s in sets], axis=1),
                np.concatenate([s[1] for s in sets], axis=1), static)

    def widths(self) -> dict[str, int]:
        """Each feature key's width (last axis) in this composition's frame."""
        return {key: part.width(key, self.context.frame) for part in self.parts for key in part.columns}


def check_part_names(value: Any, field: str, check: Callable[..., None]) -> tuple[str, ...]:
    """``value`` as a tuple of registered part names, refused with ``check`` (a ConfigError) otherwise."""
    ok = isinstance(value, tuple | list) and all(isinstance(v, str) for v in value)
    check(ok, field, value, "must be a list of observation part names")
    names = tuple(value)
    check(len(set(names)) == len(names), field, value, "must name each part once")
    for name in names:
        try:
            get_observation_part(name)
        except UnknownObservationPartError as err:
            check(False, field, value, f"must name registered observation parts: {err}")
    return names


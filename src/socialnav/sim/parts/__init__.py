"""Named observation parts, composed by name by every consumer of observations (docs/extending.md).

>>> from socialnav.sim.parts import ObservationComposition, PartContext, PartInput
>>> composition = ObservationComposition(("robot", "humans"), PartContext(frame="robot", human_slots=5))
>>> arrays = composition(PartInput.from_observation(world.observe()))

:mod:`socialnav.sim.parts.base` defines a part, its layout and its input; ``registry`` the registry
(built-ins, :func:`register_observation_part`, the entry point group ``socialnav.observations``);
``composition`` the parts a consumer reads; ``builtin`` the built-in parts (imported on the first lookup).
"""

from __future__ import annotations

from socialnav.sim.parts.base import BOUND, FRAMES, NETWORK_PARTS, ObservationPart, PartContext, PartInput
from socialnav.sim.parts.composition import ObservationComposition
from socialnav.sim.parts.registry import (
    ENTRY_POINT_GROUP,
    UnknownObservationPartError,
    get_observation_part,
    list_observation_parts,
    register_observation_part,
    unregister_observation_part,
)

__all__ = [
    "BOUND",
    "ENTRY_POINT_GROUP",
    "FRAMES",
    "NETWORK_PARTS",
    "ObservationComposition",
    "ObservationPart",
    "PartContext",
    "PartInput",
    "UnknownObservationPartError",
    "get_observation_part",
    "list_observation_parts",
    "register_observation_part",
    "unregister_observation_part",
]

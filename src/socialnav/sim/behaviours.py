"""Pedestrian behaviours: how the humans move, as registered components with declared parameters.

Every behaviour has a name (the value of ``WorldSettings.human_model``), a one-line description and its
parameters, each declared once (name, default, unit, description, bounds). The built-in ones (``orca``,
``social_force``, ``linear``) are native: each is a class in ``cpp/behaviours/`` that registers itself in
the core, and Python reads their declarations (``_core.human_behaviours()``) to build their settings
sections (``WorldSettings.orca``, ``WorldSettings.social_force``), the choices of ``human_model``,
``socialnav list`` and the docs table (docs/reference/behaviours.md).

A behaviour can also be written in Python, vectorised over the batch, and registered from outside the
package: subclass :class:`HumanBehaviour` (a frozen dataclass whose fields, declared with
:func:`~socialnav.settings.setting`, are its parameters), then call :func:`register_human_behaviour`
or name the class in an entry point of the group ``socialnav.behaviours``. The world calls it once per
step for the whole batch (:mod:`socialnav.sim.python_humans`), slower than a native one (docs/extending.md).

Both kinds answer the same two questions, kept apart: where does each human want to go (a preferred
velocity, towards its goal, or towards the next point of a route: the part a route among walls
supplies), and
how does it avoid the others (its new velocity).
"""

from __future__ import annotations

import dataclasses
import threading
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from socialnav import _core
from socialnav.plugins import load_entry_points
from socialnav.settings import Settings, setting

__all__ = [
    "ENTRY_POINT_GROUP",
    "HUMAN_MODELS",
    "HumanBehaviour",
    "HumanBehaviourInfo",
    "HumanState",
    "NativeParameters",
    "human_behaviour",
    "list_human_behaviours",
    "register_human_behaviour",
    "unregister_human_behaviour",
]

#: The entry-point group through which installed packages register pedestrian behaviours.
ENTRY_POINT_GROUP = "socialnav.behaviours"


@dataclass(frozen=True)
class HumanState:
    """The humans of B episode slots as a Python behaviour sees them (read-only views, N human slots).

    Attributes:
        position: (B, N, 2) float64 positions [m].
        velocity: (B, N, 2) float64 velocities applied in the last step [m/s].
        goal: (B, N, 2) float64 goals each human had at reset [m].
        radius: (B, N) float64 radii [m].
        v_pref: (B, N) float64 preferred speeds [m/s].
        mask: (B, N) bool humans to move: real humans of slots whose episode runs.
        robot_position: (B, 2) float64 the robot's position [m].
        robot_velocity: (B, 2) float64 its velocity in the last step [m/s].
        robot_radius: (B,) float64 its radius [m].
        robot_visible: Whether the humans see (react to) the robot.
        dt: The step [s].
        static_maps: (B,) each slot's static map (a StaticMap, or None for an open floor).
        time: (B,) float64 each slot's episode time [s] at this step (a behaviour keeps no state between
            calls: what depends on time reads it here, e.g. a person who stops 2 s in every 5).
        episode: (B,) int64 each slot's episode index (-1 for a slot without one).
    """

    position: np.ndarray
    velocity: np.ndarray
    goal: np.ndarray
    radius: np.ndarray
    v_pref: np.ndarray
    mask: np.ndarray
    robot_position: np.ndarray
    robot_velocity: np.ndarray
    robot_radius: np.ndarray
    robot_visible: bool
    dt: float
    static_maps: Sequence[Any]
    time: np.ndarray | None = None
    episode: np.ndarray | None = None


@dataclass(frozen=True)
class HumanBehaviour(Settings):
    """Base of a pedestrian behaviour written in Python, vectorised over the batch.

    Subclass it as a ``@dataclass(frozen=True)`` whose fields, declared with ``setting()``, are the
    behaviour's parameters (an instance holds their values, validated when built), set the class
    attributes ``name`` and ``description``, implement :meth:`velocities` (and, to head elsewhere than
    straight to the goal, :meth:`preferred_velocity`), and register the class with
    :func:`register_human_behaviour`. In a world, ``WorldSettings(human_model=name, human_params={...})``
    selects it; errors name the field as ``human_params.<parameter>``.

    Both methods must be functions of the state they are given (and the parameters): the world calls
    them once per step, and once more for an oracle's preview of the same state (``observe(oracle=True)``),
    which must see the velocities the step then applies. Randomness, if any, must be drawn from the
    state (e.g. seeded by positions), never from a generator advanced by each call.
    """

    section: ClassVar[str] = "human_params"
    #: The key of ``WorldSettings.human_model``.
    name: ClassVar[str] = ""
    #: One line for ``socialnav list`` (cite the model's paper).
    description: ClassVar[str] = ""

    def preferred_velocity(self, state: HumanState) -> np.ndarray:
        """Where each human wants to go: straight to its goal at v_pref, never passing it within a step.

        Args:
            state: The humans of the batch.

        Returns:
            (B, N, 2) float64 preferred velocities [m/s].
        """
        to_goal = state.goal - state.position
        distance = np.linalg.norm(to_goal, axis=-1)
        speed = np.minimum(distance / state.dt, state.v_pref)
        scale = np.divide(speed, distance, out=np.zeros_like(distance), where=distance > 1e-12)
        return to_goal * scale[..., None]

    def velocities(self, state: HumanState, preferred: np.ndarray) -> np.ndarray:
        """How each human avoids the others: its velocity for the next step.

        Args:
            state: The humans of the batch.
            preferred: (B, N, 2) float64 their preferred velocities [m/s] (:meth:`preferred_velocity`).

        Returns:
            (B, N, 2) float64 new velocities [m/s]; entries where ``state.mask`` is False are ignored.
        """
        raise NotImplementedError(f"{type(self).__name__} must implement velocities(state, preferred)")


@dataclass(frozen=True)
class HumanBehaviourInfo:
    """One registered pedestrian behaviour.

    Attributes:
        name: Its key (``WorldSettings.human_model``).
        description: One line.
        parameters: The settings class of its parameters (its fields, in declared order; for a Python
            behaviour, the behaviour class itself).
        native: Implemented in the core (cpp/behaviours/); else a :class:`HumanBehaviour` subclass.
    """

    name: str
    description: str
    parameters: type[Settings]
    native: bool

    @property
    def behaviour(self) -> type[HumanBehaviour] | None:
        """The Python class (None for a native behaviour)."""
        return None if self.native else self.parameters  # type: ignore[return-value]

    def describe(self) -> dict[str, Any]:
        """The record ``socialnav list`` prints: name, description, native, and its parameters' rows.

        Returns:
            Plain JSON data; each parameter row holds name, default, type, unit, doc and constraint.
        """
        rows = [{"name": p.name, "default": p.default, "type": p.type, "unit": p.unit, "doc": p.doc,
                 "constraint": p.constraint} for p in self.parameters.parameters()]
        return {"name": self.name, "description": self.description, "native": self.native, "parameters": rows}


class NativeParameters(Settings):
    """Base of the settings classes of the native behaviours' parameters (``OrcaSettings``, ...).

    Each subclass is a frozen dataclass built from the behaviour's declaration in the core, one field
    per parameter in declared order; type checkers see its fields as ``Any``.
    """

    if TYPE_CHECKING:  # the fields are made at run time from the core's declarations

        def __init__(self, **values: Any) -> None: ...

        def __getattr__(self, name: str) -> Any: ...


def _class_name(name: str) -> str:
    return "".join(part.capitalize() for part in name.split("_")) + "Settings"


def _native_settings(entry: dict[str, Any]) -> type[NativeParameters]:
    """The settings class of a native behaviour's parameters, built from its declaration in the core."""
    fields = []
    for p in entry["parameters"]:
        kind = int if p["type"] == "int" else float
        bounds = {k: p[k] for k in ("gt", "ge", "lt", "le") if p[k] is not None}
        declared = setting(kind(p["default"]), p["description"], unit=p["unit"], **bounds)
        fields.append((p["name"], kind, declared))
    name = entry["name"]
    doc = f"Parameters of the {name!r} pedestrian behaviour: {entry['description']}."
    cls = dataclasses.make_dataclass(_class_name(name), fields, bases=(NativeParameters,), frozen=True,
                                     namespace={"section": name, "__doc__": doc})
    cls.__module__ = __name__  # pickled by reference: the class is a name of this module
    return cls


_LOCK = threading.Lock()
_REGISTRY: dict[str, HumanBehaviourInfo] = {}
_PLUGINS_LOADED = False

for _entry in _core.human_behaviours():
    _cls = _native_settings(_entry)
    globals()[_cls.__name__] = _cls
    _REGISTRY[_entry["name"]] = HumanBehaviourInfo(_entry["name"], _entry["description"], _cls, native=True)


def native_settings(name: str) -> type[NativeParameters]:
    """The settings class of the built-in (native) behaviour ``name``'s parameters (``OrcaSettings``, ...).

    Raises:
        KeyError: No native behaviour has that name.
    """
    info = _REGISTRY[name]
    if not info.native or not issubclass(info.parameters, NativeParameters):
        raise KeyError(name)
    return info.parameters


def register_human_behaviour(cls: type[HumanBehaviour], *, replace: bool = False) -> type[HumanBehaviour]:
    """Registers a pedestrian behaviour written in Python under ``cls.name`` (usable as a decorator).

    Args:
        cls: A frozen-dataclass subclass of :class:`HumanBehaviour` with ``name`` and ``description``.
        replace: Replace a Python behaviour already registered under that name (never a built-in one).

    Returns:
        ``cls``.

    Raises:
        TypeError: ``cls`` is not a dataclass subclass of HumanBehaviour.
        ValueError: It has no name, or the name is taken (by a built-in one, or another class without
            ``replace``).
    """
    if not (isinstance(cls, type) and issubclass(cls, HumanBehaviour) and dataclasses.is_dataclass(cls)):
        raise TypeError("a pedestrian behaviour must be a @dataclass(frozen=True) subclass of "
                        f"HumanBehaviour, got {cls!r}")
    name = cls.name
    if not isinstance(name, str) or not name.isidentifier():
        raise ValueError(f"{cls.__name__}.name must be an identifier (the key of world.human_model), "
                         f"got {name!r}")
    with _LOCK:
        old = _REGISTRY.get(name)
        if old is not None and old.native:
            raise ValueError(f"pedestrian behaviour {name!r} is a built-in one")
        if old is not None and old.parameters is not cls and not replace:
            raise ValueError(f"pedestrian behaviour {name!r} is registered already "
                             f"({old.parameters.__qualname__}); pass replace=True to replace it")
        _REGISTRY[name] = HumanBehaviourInfo(name, str(cls.description), cls, native=False)
    return cls


def unregister_human_behaviour(name: str) -> None:
    """Removes the Python behaviour registered as ``name`` (e.g. after a test); absent names are ignored.

    Raises:
        ValueError: ``name`` is a built-in (native) behaviour.
    """
    with _LOCK:
        info = _REGISTRY.get(name)
        if info is not None and info.native:
            raise ValueError(f"pedestrian behaviour {name!r} is a built-in one")
        _REGISTRY.pop(name, None)


def _load_plugins() -> None:
    global _PLUGINS_LOADED
    if _PLUGINS_LOADED:
        return
    _PLUGINS_LOADED = True
    for ep, obj in load_entry_points(ENTRY_POINT_GROUP, "pedestrian behaviour"):
        try:
            register_human_behaviour(obj)
        except (TypeError, ValueError) as err:
            import warnings

            warnings.warn(f"pedestrian behaviour plugin {ep.name!r} ({ep.value}) not registered: {err}",
                          RuntimeWarning, stacklevel=3)


def list_human_behaviours() -> list[HumanBehaviourInfo]:
    """Every registered pedestrian behaviour: the built-in ones in the core's order, then the others."""
    _load_plugins()
    with _LOCK:
        return list(_REGISTRY.values())


def human_behaviour(name: str) -> HumanBehaviourInfo:
    """The behaviour registered as ``name``.

    Raises:
        ValueError: None is, naming the registered ones.
    """
    _load_plugins()
    info = _REGISTRY.get(name)
    if info is None:
        raise ValueError(f"unknown pedestrian behaviour {name!r}; registered: {', '.join(_REGISTRY)}")
    return info


class _BehaviourNames(Sequence[str]):
    """The registered behaviours' names, read from the registry at each use (``human_model``'s choices)."""

    def _names(self) -> tuple[str, ...]:
        _load_plugins()
        return tuple(_REGISTRY)

    def __getitem__(self, index: Any) -> Any:
        return self._names()[index]

    def __len__(self) -> int:
        return len(self._names())

    def __iter__(self) -> Iterator[str]:
        return iter(self._names())

    def __contains__(self, value: object) -> bool:
        return value in self._names()

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Sequence) and not isinstance(other, str) and tuple(self) == tuple(other)

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        return repr(self._names())


#: The registered behaviours' names, live (a behaviour registered later is in it): the built-in ones
#: ``orca``, ``social_force`` and ``linear`` first.
HUMAN_MODELS: Sequence[str] = _BehaviourNames()

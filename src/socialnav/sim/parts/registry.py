"""The registry of observation parts: built-ins, parts registered from outside, entry points."""

from __future__ import annotations

import importlib
import threading
from typing import Any

from socialnav.sim.parts.base import ObservationPart

__all__ = [
    "ENTRY_POINT_GROUP",
    "UnknownObservationPartError",
    "get_observation_part",
    "list_observation_parts",
    "register_observation_part",
    "unregister_observation_part",
]

#: Entry point group of observation parts from other packages.
ENTRY_POINT_GROUP = "socialnav.observations"
#: The modules defining the built-in parts (each registers its parts when imported, on the first lookup).
BUILTIN_MODULES = ("socialnav.sim.parts.builtin",)


class UnknownObservationPartError(KeyError, ValueError):
    """No observation part has this name (the message lists the registered ones)."""

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""


_REGISTRY: dict[str, ObservationPart] = {}
_LOCK = threading.RLock()
_builtins_loaded = False
_plugins_loaded = False


def register_observation_part(part: Any = None, *, replace: bool = False) -> Any:
    """Register an observation part under its ``name``: a class (built without arguments) or an instance.

    Usable as a decorator (``@register_observation_part``). Compositions then accept its name
    everywhere: the learner observation settings, the SB3 adapter, the Gymnasium envs' ``observation_parts``,
    ``socialnav list``.

    Args:
        part: An :class:`ObservationPart` subclass or instance.
        replace: Allow replacing a part registered under the same name by another class (the same class
            defined again, as a notebook cell run twice or a reloaded module defines it, replaces itself).

    Returns:
        ``part`` (so the decorator leaves the class in place).

    Raises:
        TypeError: Not an ObservationPart.
        ValueError: No name, or the name is taken (unless ``replace``).
    """
    if part is None:
        return lambda p: register_observation_part(p, replace=replace)
    instance = part() if isinstance(part, type) else part
    if not isinstance(instance, ObservationPart):
        raise TypeError(
            f"an observation part must derive from socialnav.sim.parts.ObservationPart, got {part!r}"
        )
    _load_builtins()  # built-ins first: a part registered from outside cannot take a built-in's name
    name = instance.name
    if not isinstance(name, str) or not name.isidentifier():
        raise ValueError(f"observation part {part!r}: name must be an identifier, got {name!r}")
    with _LOCK:
        taken = name in _REGISTRY and _qualified(type(_REGISTRY[name])) != _qualified(type(instance))
        if not replace and taken:
            # the same class defined again (a notebook cell run twice, importlib.reload) replaces itself
            raise ValueError(f"observation part name {name!r} is already registered to "
                             f"{_qualified(type(_REGISTRY[name]))} (pass replace=True to replace it)")
        _REGISTRY[name] = instance
    return part


def _qualified(cls: type) -> str:
    return f"{cls.__module__}.{cls.__qualname__}"


def unregister_observation_part(name: str) -> None:
    """Forget the part ``name`` (tests; a built-in comes back on the next lookup only if re-registered)."""
    with _LOCK:
        _REGISTRY.pop(name, None)


def _load_builtins() -> None:
    global _builtins_loaded
    if _builtins_loaded:
        return
    with _LOCK:
        if not _builtins_loaded:
            _builtins_loaded = True
            for module in BUILTIN_MODULES:
                importlib.import_module(module)


def _load_plugins() -> None:
    """Import the entry points of group ``socialnav.observations`` once.

    Each names an ObservationPart class (registered under its own name, or the entry point's where it has
    none) or a module whose import registers parts.
    """
    global _plugins_loaded
    if _plugins_loaded:
        return
    from socialnav.plugins import load_entry_points

    _load_builtins()
    _plugins_loaded = True
    for ep, obj in load_entry_points(ENTRY_POINT_GROUP, "observation part"):
        if isinstance(obj, type) and issubclass(obj, ObservationPart):
            if not obj.name:
                obj = type(obj.__name__, (obj,), {"name": ep.name, "__module__": obj.__module__})
            if obj.name not in _REGISTRY:
                register_observation_part(obj)


def get_observation_part(name: str) -> ObservationPart:
    """The registered part ``name`` (built-ins, then parts registered from outside, then entry points).

    Raises:
        UnknownObservationPartError: (a KeyError and a ValueError) listing the registered names.
    """
    _load_builtins()
    part = _REGISTRY.get(name)
    if part is None:
        _load_plugins()
        part = _REGISTRY.get(name)
    if part is None:
        raise UnknownObservationPartError(
            f"unknown observation part {name!r}; registered: {', '.join(sorted(_REGISTRY))} (register one "
            "with socialnav.sim.register_observation_part or the entry point group socialnav.observations)"
        )
    return part


def list_observation_parts() -> list[ObservationPart]:
    """Every registered part (built-ins first, then in registration order; entry points loaded)."""
    _load_plugins()
    return list(_REGISTRY.values())

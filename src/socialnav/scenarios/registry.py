"""Scenario registry: names → scenario classes, with their parameter tables.

Built-in scenarios register themselves where they are defined (``@register_scenario(name)``).
Other packages plug in through the entry-point group ``socialnav.scenarios``; each entry point
names either a `Scenario` subclass (registered under the entry point's name unless it already
registered itself) or a module whose import registers its scenarios. Entry points are loaded
lazily, the first time a name is looked up that is not built in, or the list is requested.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from typing import Any, TypeVar

from socialnav.plugins import load_entry_points
from socialnav.scenarios.base import ParamSpec, Scenario

__all__ = [
    "ENTRY_POINT_GROUP",
    "UnknownScenarioError",
    "get_scenario",
    "list_scenarios",
    "make_scenario",
    "register_scenario",
    "scenario_from_settings",
]

ENTRY_POINT_GROUP = "socialnav.scenarios"

_REGISTRY: dict[str, type[Scenario]] = {}
_plugins_loaded = False

S = TypeVar("S", bound=type[Scenario])


class UnknownScenarioError(KeyError, ValueError):
    """No scenario of that name. A KeyError (lookup) and a ValueError (bad setting) alike."""

    def __str__(self) -> str:
        """The message itself."""
        # KeyError's __str__ would print the repr of the message, quotes and escapes included.
        return str(self.args[0]) if self.args else ""


def register_scenario(name: str) -> Callable[[S], S]:
    """Class decorator registering a `Scenario` subclass under ``name``.

    The name is also stored on the class (``cls.name``): it salts the scenario's random numbers,
    so renaming a scenario changes its episodes.

    Args:
        name: Short snake_case name used in YAML (``type: name``) and on the command line.

    Returns:
        The decorator, which returns the class unchanged apart from ``name``.

    Raises:
        TypeError: The class is not a dataclass subclass of `Scenario`.
        ValueError: The name is taken by another class, or is not a valid identifier.
    """
    if not isinstance(name, str) or not name.isidentifier():
        raise ValueError(f"scenario name must be an identifier-like string, got {name!r}")

    def decorator(cls: S) -> S:
        if not (isinstance(cls, type) and issubclass(cls, Scenario)):
            raise TypeError(f"@register_scenario({name!r}) needs a Scenario subclass, got {cls!r}")
        if not dataclasses.is_dataclass(cls):
            raise TypeError(f"@register_scenario({name!r}): {cls.__name__} must be a dataclass")
        other = _REGISTRY.get(name)
        if other is not None and other.__qualname__ != cls.__qualname__:
            raise ValueError(
                f"scenario name {name!r} is already registered to "
                f"{other.__module__}.{other.__qualname__}"
            )
        cls.name = name
        _REGISTRY[name] = cls
        return cls

    return decorator


def _load_plugins() -> None:
    """Import the entry points of group ``socialnav.scenarios`` once."""
    global _plugins_loaded
    if _plugins_loaded:
        return
    _plugins_loaded = True
    for ep, obj in load_entry_points(ENTRY_POINT_GROUP, "scenario"):
        if isinstance(obj, type) and issubclass(obj, Scenario) and not obj.name:
            register_scenario(ep.name)(obj)


def get_scenario(name: str) -> type[Scenario]:
    """The scenario class registered under ``name``.

    Args:
        name: Registered name, e.g. "circle_crossing".

    Returns:
        The `Scenario` subclass.

    Raises:
        UnknownScenarioError: (a KeyError and a ValueError) listing the valid names.
    """
    cls = _REGISTRY.get(name)
    if cls is None:
        _load_plugins()
        cls = _REGISTRY.get(name)
    if cls is None:
        valid = ", ".join(sorted(_REGISTRY))
        raise UnknownScenarioError(f"unknown scenario {name!r}; valid scenarios: {valid}")
    return cls


def make_scenario(name: str, **params: Any) -> Scenario:
    """Instantiate a registered scenario with settings.

    Args:
        name: Registered name.
        **params: Settings (field names of the scenario's dataclass).

    Returns:
        The validated scenario.

    Raises:
        UnknownScenarioError: Unknown name.
        TypeError: Unknown parameter (named, with the valid ones listed) or badly typed value.
        ValueError: Out-of-range value (named).
    """
    cls = get_scenario(name)
    fields = [f.name for f in dataclasses.fields(cls)]
    unknown = [k for k in params if k not in fields]
    if unknown:
        raise TypeError(
            f"unknown parameter(s) {', '.join(map(repr, unknown))} for scenario {name!r}; "
            f"valid parameters: {', '.join(fields)}"
        )
    return cls(**params)


def scenario_from_settings(settings: Mapping[str, Any]) -> Scenario:
    """Instantiate a scenario from a settings mapping with a ``type`` key (the YAML form).

    Inverse of `Scenario.settings`: ``scenario_from_settings(sc.settings()) == sc``.

    Args:
        settings: ``{"type": name, **params}``.

    Returns:
        The validated scenario.
    """
    if "type" not in settings:
        raise ValueError(
            f"scenario settings need a 'type' key naming the scenario; got keys {sorted(settings)}"
        )
    params = dict(settings)
    return make_scenario(params.pop("type"), **params)


def list_scenarios() -> dict[str, tuple[ParamSpec, ...]]:
    """Every registered scenario (plugins included) with its parameter table, sorted by name."""
    _load_plugins()
    return {name: _REGISTRY[name].parameters() for name in sorted(_REGISTRY)}

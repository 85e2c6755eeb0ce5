"""Scenario registry: names → scenario classes, with their parameter tables.

Built-in scenarios register themselves where they are defined (``@register_scenario(name)``).
Other packages plug in through the entry-point group ``socialnav.scenarios``; each entry point
names either a `Scenario` subclass (registered under the entry point's name unless it already
registered itself) or a module whose import registers its scenarios.

**What loads when.** Importing ``socialnav.scenarios`` (or this module) imports none of the
modules defining the built-in scenarios (:data:`BUILTIN_MODULES`), so a module that needs only the
light names (``SPLIT_BASES``, ``Scenario``, ``EpisodeBatch``, ...) does not pay for them. They are
imported once, the first time anything needs the registry's contents: `get_scenario`,
`make_scenario`, `scenario_from_settings`, `list_scenarios`, and `register_scenario` too, so that
registering a name a built-in uses fails at once, as if the built-ins had always been there.
Importing one built-in module directly (``socialnav.scenarios.circle``, or unpickling one of its
scenarios in a worker process) registers all of them the same way, through its own
`register_scenario` calls. The built-ins always load before the entry points, which load lazily in
turn: the first time a name is looked up that is not built in, or the list is requested.
"""

from __future__ import annotations

import dataclasses
import importlib
import threading
from collections.abc import Callable, Mapping
from typing import Any, TypeVar

from socialnav.scenarios.base import ParamSpec, Scenario

__all__ = [
    "BUILTIN_MODULES",
    "ENTRY_POINT_GROUP",
    "UnknownScenarioError",
    "get_scenario",
    "list_scenarios",
    "make_scenario",
    "register_scenario",
    "scenario_from_settings",
]

ENTRY_POINT_GROUP = "socialnav.scenarios"

#: The modules whose import registers the built-in scenarios (docs/scenarios.md lists them).
BUILTIN_MODULES = (
    "socialnav.scenarios.circle",
    "socialnav.scenarios.circle_pillars",
    "socialnav.scenarios.francis",
    "socialnav.scenarios.single",
    "socialnav.scenarios.square",
)

_REGISTRY: dict[str, type[Scenario]] = {}
#: "unloaded", "loading" (by the thread holding _BUILTINS_LOCK) or "loaded".
_builtins_state = "unloaded"
#: Re-entrant: a built-in module registering itself re-enters _load_builtins in the loading thread,
#: while another thread's first lookup waits until the built-ins are all registered.
_BUILTINS_LOCK = threading.RLock()
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
    _load_builtins()  # a clash with a built-in's name is found now, not on the first lookup

    def decorator(cls: S) -> S:
        if not (isinstance(cls, type) and issubclass(cls, Scenario)):
            raise TypeError(f"@register_scenario({name!r}) needs a Scenario subclass, got {cls!r}")
        if not dataclasses.is_dataclass(cls):
            raise TypeError(f"@register_scenario({name!r}): {cls.__name__} must be a dataclass")
        other = _REGISTRY.get(name)
        # The same class defined again (a module reloaded) may take its name back; another may not.
        if other is not None and (other.__module__, other.__qualname__) != (cls.__module__, cls.__qualname__):
            raise ValueError(
                f"scenario name {name!r} is already registered to "
                f"{other.__module__}.{other.__qualname__}"
            )
        cls.name = name
        _REGISTRY[name] = cls
        return cls

    return decorator


def _load_builtins() -> None:
    """Import the modules defining the built-in scenarios once (they register themselves)."""
    global _builtins_state
    if _builtins_state == "loaded":
        return
    with _BUILTINS_LOCK:
        # "loading" here means this thread is importing them: each built-in module calls
        # register_scenario, hence this function, while it is being imported.
        if _builtins_state != "unloaded":
            return
        _builtins_state = "loading"
        try:
            for module in BUILTIN_MODULES:
                importlib.import_module(module)
        except BaseException:
            _builtins_state = "unloaded"  # the next lookup raises the same error, not "unknown scenario"
            raise
        _builtins_state = "loaded"


def _load_plugins() -> None:
    """Import the entry points of group ``socialnav.scenarios`` once."""
    global _plugins_loaded
    if _plugins_loaded:
        return
    # here, not at the top: importlib.metadata would cost every `import socialnav.scenarios` ~10 ms
    from socialnav.plugins import load_entry_points

    _load_builtins()  # built-ins first: a plugin cannot take a built-in's name
    _plugins_loaded = True
    for ep, obj in load_entry_points(ENTRY_POINT_GROUP, "scenario"):
        # registered itself: its own name (not one inherited from a built-in it derives from) maps to it
        own = obj.__dict__.get("name") if isinstance(obj, type) else None
        if isinstance(obj, type) and issubclass(obj, Scenario) and not (own and _REGISTRY.get(own) is obj):
            try:
                register_scenario(ep.name)(obj)
            except (TypeError, ValueError) as exc:  # a taken name: a warning, as for the other plugin kinds
                import warnings

                warnings.warn(f"could not register scenario plugin {ep.name!r} ({ep.value}): {exc}",
                              RuntimeWarning, stacklevel=2)


def get_scenario(name: str) -> type[Scenario]:
    """The scenario class registered under ``name``.

    Args:
        name: Registered name, e.g. "circle_crossing".

    Returns:
        The `Scenario` subclass.

    Raises:
        UnknownScenarioError: (a KeyError and a ValueError) listing the valid names.
    """
    _load_builtins()
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
    if not isinstance(name, str):
        raise TypeError(f"scenario must be a registered name, got a {type(name).__name__}: register the "
                        "class with @register_scenario('my_name') and pass 'my_name' (its settings as "
                        "parameters)")
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
    if not isinstance(settings, Mapping):
        raise TypeError(f"scenario settings must be a mapping such as {{'type': 'circle_crossing', "
                        f"'n_humans': 5}}, got {type(settings).__name__} {settings!r}")
    if "type" not in settings:
        raise ValueError(
            f"scenario settings need a 'type' key naming the scenario; got keys {sorted(settings)}"
        )
    params = dict(settings)
    return make_scenario(params.pop("type"), **params)


def list_scenarios() -> dict[str, tuple[ParamSpec, ...]]:
    """Every registered scenario (plugins included) with its parameter table, sorted by name."""
    _load_builtins()
    _load_plugins()
    return {name: _REGISTRY[name].parameters() for name in sorted(_REGISTRY)}

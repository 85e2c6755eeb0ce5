"""The policy protocol and the policy registry.

A policy maps a batch of observations to a batch of actions. It never holds the environment; the
information it receives about the future is a named setting (``information``) that is recorded with
every result.

Policies are found by name in the registry (built-in ones, ``@register_policy``, and the entry points
of group ``socialnav.policies``, loaded on the first unknown name), as ``module.path:Attribute``
naming a class or factory anywhere on the import path (docs/custom_policies.md), or as ``sb3:PATH``
naming a saved Stable-Baselines3 model (docs/train_your_own.md).
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import os
import sys
import warnings
from collections.abc import Callable
from typing import Any, Protocol, runtime_checkable

import numpy as np

from socialnav.plugins import load_entry_points
from socialnav.sim.observation import Observation

#: Keys a policy's ``describe()`` may hold for information only, which never change a result (the
#: native scorer's vector kernel: its kernels' values are bit-identical): a run's manifest records
#: them, resuming and replaying do not compare them.
RECORDED_ONLY: tuple[str, ...] = ("native_kernel",)


#: What a policy may know of the humans' future (docs/custom_policies.md): nothing, their current
#: velocity held, their exact next states (the runner adds them to the observation), or a learned
#: predictor's forecast.
INFORMATION: tuple[str, ...] = ("none", "constant_velocity", "oracle", "learned")


def policy_record(policy: Any) -> dict[str, Any]:
    """The policy's ``describe()``, checked: what a run's manifest records.

    Numpy scalars and arrays become plain numbers and lists; anything else that JSON cannot hold is
    refused, naming the key, so that no run starts with a manifest that cannot be written.

    Raises:
        ValueError: ``information`` is not one of :data:`INFORMATION`, ``describe()`` does not return a
            mapping, or one of its values is not plain data.
    """
    name = getattr(policy, "name", type(policy).__name__)
    information = getattr(policy, "information", None)
    if information not in INFORMATION:
        raise ValueError(f"policy {name!r}: information must be one of {', '.join(INFORMATION)}, got "
                         f"{information!r} (docs/custom_policies.md)")
    record = policy.describe()
    if not isinstance(record, dict):
        raise ValueError(f"policy {name!r}: describe() must return a dict, got a {type(record).__name__}")
    return {str(key): _plain(value, f"policy {name!r}: describe()[{key!r}]") for key, value in record.items()}


def _plain(value: Any, where: str) -> Any:
    if isinstance(value, np.generic | np.ndarray):
        return _plain(value.tolist(), where)
    if isinstance(value, float) and not np.isfinite(value):
        # JSON has no NaN: the manifest would hold null, and every resume would find the record changed
        raise ValueError(f"{where} is {value!r}; results record no NaN or infinity (JSON): describe it by "
                         "None or a string")
    if value is None or isinstance(value, bool | int | float | str):
        return value
    if isinstance(value, list | tuple):
        return [_plain(v, f"{where}[{i}]") for i, v in enumerate(value)]
    if isinstance(value, dict):
        return {str(k): _plain(v, f"{where}[{k!r}]") for k, v in value.items()}
    raise ValueError(f"{where} is a {type(value).__name__} ({value!r:.60}); describe() must return plain "
                     "data (strings, numbers, booleans, None, lists and dicts of them), which results record")


def missing_policy_members(policy: Any) -> list[str]:
    """Which of ``name``, ``act`` and ``describe`` (the :class:`Policy` protocol) ``policy`` lacks."""
    return [a for a in ("name", "act", "describe") if not hasattr(policy, a)]


class PolicyError(RuntimeError):
    """A policy failed while acting, or returned actions the world cannot take.

    The message names the policy, the scenario and visibility, and the episodes it was acting for.
    """


@runtime_checkable
class Policy(Protocol):
    """Anything with ``name``, ``information`` and ``act(observation) -> (B, 2) actions``."""

    name: str
    information: str

    def act(self, observation: Observation) -> np.ndarray:
        """Actions for a batch of episodes.

        Args:
            observation: What the policy may see of B episodes.

        Returns:
            (B, 2) float64 robot velocities [m/s] (the world's action set; holonomic or unicycle).
        """

    def describe(self) -> dict[str, Any]:
        """The policy's parameters, recorded with results (at least ``policy`` and ``information``)."""


@dataclasses.dataclass(frozen=True)
class PolicyEntry:
    """A registered policy.

    Attributes:
        name: The name it is built by (``make_policy(name)``).
        factory: Builds the policy from keyword parameters.
        description: One line shown by ``socialnav list``.
        learned: Whether it is built from a checkpoint.
        parameters: Its parameters and their defaults.
    """
    name: str
    factory: Callable[..., Policy]
    description: str
    learned: bool
    parameters: dict[str, Any]


_REGISTRY: dict[str, PolicyEntry] = {}
ENTRY_POINT_GROUP = "socialnav.policies"
_plugins_loaded = False


def register_policy(name: str, *, description: str, learned: bool = False,
                    parameters: dict[str, Any] | None = None) -> Callable:
    """Class/function decorator registering a policy factory under ``name``.

    ``parameters`` maps each keyword the factory accepts to its default (shown by ``socialnav list``;
    other keywords are refused). Left out, they are read from the factory's signature.
    """
    # names the command line reads otherwise: every shipped checkpoint, a module path, a saved SB3 model
    if not isinstance(name, str) or not name or name == "all" or ":" in name:
        raise ValueError(f"policy name {name!r} cannot be registered: `--policy` reads 'all' as every "
                         "shipped checkpoint and a name with ':' as module.path:Class or sb3:PATH")

    def decorator(factory: Callable[..., Policy]) -> Callable[..., Policy]:
        if name in _REGISTRY:
            raise ValueError(f"policy {name!r} is already registered")
        params = dict(parameters) if parameters is not None else _signature_parameters(factory)
        _REGISTRY[name] = PolicyEntry(name, factory, description, learned, params)
        return factory

    return decorator


def is_registered(name: str) -> bool:
    """Whether ``name`` is registered already (built-in, plugin or ``@register_policy``)."""
    return name in _REGISTRY


def list_policies() -> list[PolicyEntry]:
    """Every registered policy name, sorted.

    Built-in, learned and from the ``socialnav.policies`` entry-point group.
    """
    _load_builtin()
    _load_plugins()
    return [_REGISTRY[k] for k in sorted(_REGISTRY)]


def get_policy_entry(name: str) -> PolicyEntry:
    """The entry of a registered name, an entry-point name, or ``module.path:Attribute``."""
    _load_builtin()
    if name in _REGISTRY:
        return _REGISTRY[name]
    if name.startswith(SB3_PREFIX):
        return _sb3_entry(name)
    if name.startswith(EXEC_PREFIX):
        return _exec_entry(name)
    if ":" in name:
        return _entry_from_path(name)
    _load_plugins()
    if name not in _REGISTRY:
        # a learned policy a trainer plugin brings (its LearnedPolicySpec): import those, then the catalog
        from socialnav.policies import learned_loading

        _import_trainer_plugins()
        learned_loading.register_catalog()
    if name not in _REGISTRY:
        hint = f" (did you mean {name.lower()!r}? names are lower case)" if name.lower() in _REGISTRY else ""
        raise KeyError(
            f"unknown policy {name!r}{hint}; valid: {', '.join(sorted(_REGISTRY))}, or module.path:ClassName "
            f"(see docs/custom_policies.md), or sb3:PATH, a saved Stable-Baselines3 model "
            f"(docs/train_your_own.md), or exec:COMMAND, a planner program (docs/exec_protocol.md)"
        )
    return _REGISTRY[name]


_trainer_plugins_imported = False


def _import_trainer_plugins() -> None:
    """Imports the modules of the ``socialnav.trainers`` entry points once.

    A trainer plugin's learned policies register their records on import (the trainers themselves are
    socialnav.train's to register; this layer may not import it).
    """
    global _trainer_plugins_imported
    if _trainer_plugins_imported:
        return
    _trainer_plugins_imported = True
    from socialnav.plugins import load_entry_points

    for _ in load_entry_points("socialnav.trainers", "trainer"):
        pass


def make_policy(name: str, /, **params: Any) -> Policy:
    """Builds a registered policy; unknown parameters are refused with the valid ones listed.

    ``name`` is positional only, so a policy may have a parameter called ``name``.
    """
    entry = get_policy_entry(name)
    if entry.learned and params.get("checkpoint") is None:
        raise ValueError(f"policy {name!r} is learned: make_policy needs checkpoint=PATH (a file of "
                         f"`socialnav train`); build_policy({name!r}, preset) takes the checkpoint that "
                         "ships for a preset")
    if not name.startswith((SB3_PREFIX, EXEC_PREFIX)):
        from socialnav.policies.building import check_policy_parameters

        loading = ("checkpoint", "preset", "allow_preset_mismatch") if entry.learned else ()
        check_policy_parameters(name, entry, {k: v for k, v in params.items() if k not in loading})
    try:
        policy = entry.factory(**params)
    except TypeError as err:  # e.g. a required argument missing: the user's to fix, so no traceback
        raise ValueError(f"policy {name!r} could not be built with {params}: {err}") from None
    missing = missing_policy_members(policy)
    if missing:
        raise ValueError(
            f"policy {name!r} built a {type(policy).__name__} without {', '.join(missing)}: a policy needs "
            "name, information, act(observation) and describe() (docs/custom_policies.md)"
        )
    return policy


#: ``sb3:PATH`` names a saved Stable-Baselines3 model (socialnav.integrations.sb3_policy).
SB3_PREFIX = "sb3:"


def _sb3_entry(spec: str) -> PolicyEntry:
    def load(preset: Any = None, allow_preset_mismatch: bool = False, **params: Any) -> Policy:
        from socialnav.integrations.sb3_policy import load_sb3_policy

        if preset is None:
            raise ValueError(f"policy {spec}: an SB3 model is checked against the preset it runs under")
        return load_sb3_policy(spec, preset, allow_preset_mismatch=allow_preset_mismatch, **params)

    from socialnav.integrations.sb3_policy import PARAMETERS  # imports no SB3

    description = "a saved Stable-Baselines3 model, deterministic actions"
    return PolicyEntry(spec, load, description, False, dict(PARAMETERS))


#: ``exec:COMMAND`` names a planner program stepped over its stdin/stdout (socialnav.policies.exec_planner).
EXEC_PREFIX = "exec:"


def _exec_entry(spec: str) -> PolicyEntry:
    command = spec[len(EXEC_PREFIX):]

    def start(preset: Any = None, timeout: float = 10.0) -> Policy:
        from socialnav.policies.exec_planner import ExecPlanner

        world = getattr(preset, "world", None)
        kinematics, dt = getattr(world, "kinematics", "holonomic"), getattr(world, "dt", 0.25)
        limits: dict[str, Any] = {}
        if world is not None and kinematics != "holonomic":
            limits["rotation_limit"] = world.rotation_limit
        if world is not None and kinematics == "diff_drive":
            limits["diff_drive"] = world.diff_drive.to_dict()
        return ExecPlanner(command, timeout=float(timeout), kinematics=kinematics, dt=dt, robot_limits=limits)

    return PolicyEntry(spec, start, "a planner program stepped over its stdin/stdout (docs/exec_protocol.md)",
                       False, {"timeout": 10.0})


def _entry_from_path(spec: str) -> PolicyEntry:
    module_name, _, attr = spec.partition(":")
    if not module_name or not attr:
        raise ValueError(f"policy {spec!r}: expected module.path:ClassName")
    if module_name.endswith(".py") or "/" in module_name or os.sep in module_name:
        # A file path would be recorded in the run's manifest relative to wherever it was typed; a module
        # name is found again from the same directory or PYTHONPATH, which is what replay and resume need.
        folder, file = os.path.split(module_name)
        module = file.removesuffix(".py")
        where = f"from {folder!r} (or with it on PYTHONPATH)" if folder else "from the file's directory"
        raise ValueError(
            f"policy {spec!r}: give a module name, not a file path: run {where} with "
            f"--policy {module}:{attr or 'ClassName'}"
        )
    if os.getcwd() not in sys.path and "" not in sys.path:
        sys.path.append(os.getcwd())  # `socialnav evaluate --policy my_policy:X` finds ./my_policy.py
    try:
        module = importlib.import_module(module_name)
    except ImportError as err:
        raise ValueError(f"policy {spec!r}: cannot import module {module_name!r} ({err})") from None
    obj: Any = module
    for part in attr.split("."):
        if not hasattr(obj, part):
            raise ValueError(f"policy {spec!r}: module {module_name!r} has no attribute {attr!r}")
        obj = getattr(obj, part)
    if not callable(obj):
        raise ValueError(f"policy {spec!r}: {attr} is not a class or a factory function")
    doc = (inspect.getdoc(obj) or "").strip().splitlines()
    return PolicyEntry(spec, obj, doc[0] if doc else "", False, _signature_parameters(obj))


def _signature_parameters(factory: Callable) -> dict[str, Any]:
    try:
        sig = inspect.signature(factory)
    except (TypeError, ValueError):
        return {}
    return {
        p.name: (None if p.default is inspect.Parameter.empty else p.default)
        for p in sig.parameters.values()
        if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)
    }


def accepts_any_keyword(factory: Callable) -> bool:
    """Whether ``factory`` takes ``**kwargs`` (then its parameters are its own to check).

    Args:
        factory: A registered policy's factory.

    Returns:
        True when it has a ``**kwargs`` parameter (False when its signature cannot be read).
    """
    try:
        return any(p.kind is p.VAR_KEYWORD for p in inspect.signature(factory).parameters.values())
    except (TypeError, ValueError):
        return True


def _load_plugins() -> None:
    """Import the entry points of group ``socialnav.policies`` once.

    Each names a policy class or factory (registered under the entry point's name) or a module whose import
    registers policies.
    """
    global _plugins_loaded
    if _plugins_loaded:
        return
    _plugins_loaded = True
    for ep, obj in load_entry_points(ENTRY_POINT_GROUP, "policy"):
        if not callable(obj):  # a module whose import registered its policies
            continue
        if ep.name in _REGISTRY and _REGISTRY[ep.name].factory is not obj:
            warnings.warn(f"policy plugin {ep.name!r} ({ep.value}) is not registered: the name is taken by "
                          f"another policy ({_REGISTRY[ep.name].description}); give the entry point another "
                          "name", RuntimeWarning, stacklevel=3)
            continue
        if ep.name in _REGISTRY:
            continue
        doc = (inspect.getdoc(obj) or "").strip().splitlines()
        try:
            register_policy(ep.name, description=doc[0] if doc else f"plugin {ep.value}")(obj)
        except ValueError as err:
            warnings.warn(f"policy plugin {ep.name!r} ({ep.value}) is not registered: {err}", RuntimeWarning,
                          stacklevel=3)


def _load_builtin() -> None:
    # Native policies register on import; learned ones from their records in learned_catalog (their
    # factories, in learned_loading, import torch only when called). Records added since the last call
    # register now.
    from socialnav.policies import learned_loading, native  # noqa: F401

    learned_loading.register_catalog()

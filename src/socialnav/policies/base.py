"""The policy protocol and the policy registry.

A policy maps a batch of observations to a batch of actions. It never holds the environment; the
information it receives about the future is a named setting (``information``) that is recorded with
every result.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any, Protocol, runtime_checkable

import numpy as np

from socialnav.sim.observation import Observation


@runtime_checkable
class Policy(Protocol):
    """Anything with ``name``, ``information`` and ``act(observation) -> (B, 2) actions``."""

    name: str
    information: str

    def act(self, observation: Observation) -> np.ndarray: ...

    def describe(self) -> dict[str, Any]: ...


@dataclasses.dataclass(frozen=True)
class PolicyEntry:
    name: str
    factory: Callable[..., Policy]
    description: str
    learned: bool
    parameters: dict[str, Any]


_REGISTRY: dict[str, PolicyEntry] = {}


def register_policy(name: str, *, description: str, learned: bool = False,
                    parameters: dict[str, Any] | None = None) -> Callable:
    """Class/function decorator registering a policy factory under ``name``."""

    def decorator(factory: Callable[..., Policy]) -> Callable[..., Policy]:
        if name in _REGISTRY:
            raise ValueError(f"policy {name!r} is already registered")
        _REGISTRY[name] = PolicyEntry(name, factory, description, learned, dict(parameters or {}))
        return factory

    return decorator


def list_policies() -> list[PolicyEntry]:
    _load_builtin()
    return [_REGISTRY[k] for k in sorted(_REGISTRY)]


def get_policy_entry(name: str) -> PolicyEntry:
    _load_builtin()
    if name not in _REGISTRY:
        raise KeyError(f"unknown policy {name!r}; valid: {', '.join(sorted(_REGISTRY))}")
    return _REGISTRY[name]


def make_policy(name: str, **params: Any) -> Policy:
    """Builds a registered policy; unknown parameters are refused with the valid ones listed."""
    entry = get_policy_entry(name)
    if not entry.learned:
        unknown = sorted(set(params) - set(entry.parameters))
        if unknown:
            raise ValueError(f"policy {name!r} has no parameter(s) {', '.join(unknown)}; "
                             f"valid: {', '.join(sorted(entry.parameters)) or 'none'}")
    return entry.factory(**params)


def _load_builtin() -> None:
    # Native policies register on import; learned ones register lazily (they need torch).
    from socialnav.policies import learned_entries, native  # noqa: F401

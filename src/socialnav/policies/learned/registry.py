"""Registry of learned value networks, keyed by short policy names.

Each network module registers its factory where it is defined (``@register_learned("sarl")``);
importing :mod:`socialnav.policies.learned` populates the table. ``build(name, **kw)`` makes a fresh,
randomly initialised network (seed torch beforehand or pass ``generator``-seeded init yourself).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar

from torch import nn

__all__ = ["LEARNED_POLICIES", "ALIASES", "register_learned", "build", "canonical_name"]

LEARNED_POLICIES: dict[str, Callable[..., nn.Module]] = {}
# Names that denote the same network; the value is the name stored in checkpoints.
ALIASES: dict[str, str] = {"ga3c_cadrl": "lstm_rl"}

F = TypeVar("F", bound=Callable[..., nn.Module])


def register_learned(*names: str) -> Callable[[F], F]:
    """Decorator registering a network factory (a class or a function) under one or more names."""

    def deco(factory: F) -> F:
        for name in names:
            if name in LEARNED_POLICIES:
                raise ValueError(f"learned policy {name!r} is already registered")
            LEARNED_POLICIES[name] = factory
        return factory

    return deco


def canonical_name(name: str) -> str:
    """Canonical policy name (``ga3c_cadrl`` → ``lstm_rl``; others unchanged)."""
    return ALIASES.get(name, name)


def build(name: str, **kwargs: object) -> nn.Module:
    """Build a fresh value network by policy name.

    Args:
        name: one of ``LEARNED_POLICIES`` (cadrl, lstm_rl / ga3c_cadrl, sarl, om_sarl).
        **kwargs: keyword arguments of the network's constructor.

    Raises:
        KeyError: unknown name (the message lists the known ones).
    """
    import socialnav.policies.learned  # noqa: F401  (populates the registry)

    try:
        factory = LEARNED_POLICIES[name]
    except KeyError:
        raise KeyError(f"unknown learned policy {name!r}; known: {sorted(LEARNED_POLICIES)}") from None
    return factory(**kwargs)

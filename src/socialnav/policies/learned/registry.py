"""The learned networks by policy name.

Read from the registration records (:mod:`socialnav.policies.learned_catalog`).

``build(name, **kw)`` makes a fresh, randomly initialised network (seed torch beforehand).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping

from torch import nn

from socialnav.policies.learned_catalog import canonical_name, get_learned_spec, learned_policy_names

__all__ = ["LEARNED_POLICIES", "build", "canonical_name"]


class _NetworkFactories(Mapping[str, Callable[..., nn.Module]]):
    """Policy name (aliases included) → network factory, a live view of the registration records."""

    def __getitem__(self, name: str) -> Callable[..., nn.Module]:
        if name not in learned_policy_names():
            raise KeyError(name)
        return get_learned_spec(name).network_factory()

    def __iter__(self) -> Iterator[str]:
        return iter(learned_policy_names())

    def __len__(self) -> int:
        return len(learned_policy_names())


LEARNED_POLICIES: Mapping[str, Callable[..., nn.Module]] = _NetworkFactories()


def build(name: str, **kwargs: object) -> nn.Module:
    """Build a fresh network by policy name.

    Args:
        name: a learned policy's name or alias (``learned_policy_names()`` of
            :mod:`socialnav.policies.learned_catalog`).
        **kwargs: keyword arguments of the network's constructor.

    Raises:
        KeyError: unknown name (the message lists the known ones).
    """
    return get_learned_spec(name).network_factory()(**kwargs)

"""Entry-point plugins: load every entry point of a group, warning about (never failing on) broken ones."""

from __future__ import annotations

import importlib.metadata
import warnings
from collections.abc import Iterator
from typing import Any


def load_entry_points(group: str, kind: str) -> Iterator[tuple[Any, Any]]:
    """Yield ``(entry_point, loaded_object)`` for every entry point of ``group`` that imports.

    One that fails is reported as a RuntimeWarning naming the ``kind`` of plugin and skipped, so that a broken
    plugin cannot hide the built-in ones.
    """
    for ep in importlib.metadata.entry_points(group=group):
        try:
            obj = ep.load()
        except Exception as exc:
            warnings.warn(f"could not load {kind} plugin {ep.name!r} ({ep.value}): {exc!r}", RuntimeWarning,
                          stacklevel=4)
            continue
        yield ep, obj

"""The shipped presets (``<name>.yaml``; ``socialnav preset list``) and training configurations."""

from __future__ import annotations

from importlib import resources


def shipped_presets() -> list[str]:
    """The names of the presets shipped with the package, sorted.

    Here rather than in :mod:`socialnav.presets` so that the command line's help can list them without
    importing the settings classes.
    """
    return sorted(p.name[:-5] for p in resources.files(__name__).iterdir() if p.name.endswith(".yaml"))

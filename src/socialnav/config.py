"""Strict loading of settings from plain dicts / YAML (the names callers have always imported).

The mechanism lives in :mod:`socialnav.settings` (the one settings system); this module keeps its
older import path: ``from socialnav.config import ConfigError, check, from_dict, to_dict``.
"""

from __future__ import annotations

from socialnav.settings import ConfigError, check, from_dict, to_dict

__all__ = ["ConfigError", "check", "from_dict", "to_dict"]

"""Scenario settings: `param`, the scenarios' name for `socialnav.settings.setting`.

A scenario setting is a dataclass field whose metadata holds its doc, unit and constraints; that
one declaration drives validation, `list_scenarios()` tables, YAML and the docs, through the one
settings system (`socialnav.settings`).
"""

from __future__ import annotations

from typing import Any

from socialnav.settings import SettingSpec, setting

__all__ = ["ParamSpec", "param"]

#: One row of a scenario's parameter table (name, default, type, doc, unit, choices, constraint).
ParamSpec = SettingSpec


def param(
    default: Any,
    doc: str,
    *,
    unit: str = "",
    gt: float | None = None,
    ge: float | None = None,
    lt: float | None = None,
    le: float | None = None,
    choices: tuple[str, ...] | None = None,
) -> Any:
    """Declares a scenario setting: a dataclass field carrying its doc, unit and validator.

    Args:
        default: Default value (must be immutable: numbers, strings, tuples, None).
        doc: One-line description, used by `list_scenarios`, the CLI and the docs.
        unit: SI unit of the value.
        gt: The value must be strictly greater than this.
        ge: The value must be greater than or equal to this.
        lt: The value must be strictly less than this.
        le: The value must be less than or equal to this.
        choices: Allowed values of a string option.

    Returns:
        A `dataclasses.field` (see `socialnav.settings.setting`).
    """
    return setting(default, doc, unit=unit, gt=gt, ge=ge, lt=lt, le=le, choices=choices)

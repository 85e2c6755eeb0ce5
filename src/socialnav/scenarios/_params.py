"""Scenario settings: the `param` field helper, parameter tables and value validation.

A setting is a dataclass field whose metadata holds its doc, unit and constraints; that one
declaration drives validation (`check_value`), `list_scenarios()` tables, YAML and the docs.
"""

from __future__ import annotations

import math
import typing
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["ParamSpec", "check_value", "param", "type_name"]


@dataclass(frozen=True)
class ParamSpec:
    """One row of a scenario's parameter table.

    Attributes:
        name: Field name (the YAML / keyword name).
        default: Default value.
        type: Type as written in the annotation, e.g. "float" or "float | None".
        doc: One-line description.
        unit: SI unit, "" when dimensionless.
        choices: Allowed values for string options, else None.
    """

    name: str
    default: Any
    type: str
    doc: str
    unit: str = ""
    choices: tuple[str, ...] | None = None


def param(
    default: Any,
    doc: str,
    *,
    unit: str = "",
    gt: float | None = None,
    ge: float | None = None,
    choices: tuple[str, ...] | None = None,
) -> Any:
    """Declare a scenario setting: a dataclass field carrying its doc, unit and validator.

    Args:
        default: Default value (must be immutable: numbers, strings, tuples, None).
        doc: One-line description, used by `list_scenarios`, the CLI and the docs.
        unit: SI unit of the value.
        gt: The value must be strictly greater than this.
        ge: The value must be greater than or equal to this.
        choices: Allowed values of a string option.

    Returns:
        A `dataclasses.field`.
    """
    meta = {"doc": doc, "unit": unit, "gt": gt, "ge": ge, "choices": choices}
    return field(default=default, metadata=meta)


def _is_real(x: Any) -> bool:
    number = isinstance(x, (int, float, np.integer, np.floating))
    return number and not isinstance(x, (bool, np.bool_))


def type_name(tp: Any) -> str:
    if isinstance(tp, type):
        return tp.__name__
    return str(tp).replace("typing.", "")


def check_value(owner: str, name: str, value: Any, tp: Any, meta: Any) -> Any:
    """Check one setting against its annotation and constraints; return it normalised."""
    where = f"{owner}.{name}"
    args = typing.get_args(tp)
    origin = typing.get_origin(tp)
    optional = origin in (typing.Union, _UnionType) and type(None) in args
    if optional:
        if value is None:
            return value
        (tp,) = [a for a in args if a is not type(None)]
        origin, args = typing.get_origin(tp), typing.get_args(tp)
    if tp is bool:
        if not isinstance(value, (bool, np.bool_)):
            raise TypeError(f"{where} must be a bool, got {value!r}")
        return bool(value)
    if tp is int:
        if not isinstance(value, (int, np.integer)) or isinstance(value, (bool, np.bool_)):
            raise TypeError(f"{where} must be an int, got {value!r}")
        value = int(value)
    elif tp is float:
        if not _is_real(value):
            raise TypeError(f"{where} must be a number, got {value!r}")
        value = float(value)
        if not math.isfinite(value):
            raise ValueError(f"{where} must be finite, got {value!r}")
    elif tp is str:
        if not isinstance(value, str):
            raise TypeError(f"{where} must be a string, got {value!r}")
        choices = meta.get("choices")
        if choices and value not in choices:
            raise ValueError(
                f"{where} must be one of {', '.join(map(repr, choices))}; got {value!r}"
            )
        return value
    elif origin is tuple:
        if not isinstance(value, (tuple, list)) or len(value) != len(args):
            raise TypeError(f"{where} must be a sequence of {len(args)} numbers, got {value!r}")
        if not all(_is_real(v) and math.isfinite(float(v)) for v in value):
            raise ValueError(f"{where} must hold finite numbers, got {value!r}")
        return tuple(float(v) for v in value)
    gt, ge = meta.get("gt"), meta.get("ge")
    if gt is not None and not value > gt:
        raise ValueError(f"{where} must be > {gt}, got {value!r}")
    if ge is not None and not value >= ge:
        raise ValueError(f"{where} must be >= {ge}, got {value!r}")
    return value


_UnionType = type(int | None)

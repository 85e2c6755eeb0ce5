"""Validation of one setting's value against its annotation and `setting()` constraint.

The rules of a class's fields are prepared once per class (`rules_of`): scenario settings are built
on every world refill, so a check costs a few attribute reads in the common case.
"""

from __future__ import annotations

import dataclasses
import math
import typing
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from socialnav._io import short_repr
from socialnav.settings.errors import ConfigError, field_error

__all__ = ["Rule", "check_rule", "constraint_text", "rules_of", "type_hints", "type_name", "validate_value"]

_UnionType = type(int | None)


def type_name(tp: Any) -> str:
    """An annotation as text: ``float``, ``float | None``, ``tuple[float, float]``."""
    if isinstance(tp, type) and not typing.get_args(tp):
        return tp.__name__
    return str(tp).replace("typing.", "")


def constraint_text(meta: Mapping[str, Any]) -> str:
    """A field's constraint as the docs and errors say it: ``> 0``, ``in [0, 64]``, ``one of 'a', 'b'``."""
    if meta.get("choices"):
        return "one of " + ", ".join(map(repr, meta["choices"]))
    low = ("[", meta["ge"]) if meta.get("ge") is not None else ("(", meta.get("gt"))
    high = ("]", meta["le"]) if meta.get("le") is not None else (")", meta.get("lt"))
    if low[1] is not None and high[1] is not None:
        bounds = f"in {low[0]}{_number(low[1])}, {_number(high[1])}{high[0]}"
    elif low[1] is not None:
        bounds = f"{'>=' if low[0] == '[' else '>'} {_number(low[1])}"
    elif high[1] is not None:
        bounds = f"{'<=' if high[0] == ']' else '<'} {_number(high[1])}"
    else:
        bounds = ""
    extra = str(meta.get("requirement") or "").removeprefix("must be ").removeprefix("must ")
    return ", ".join(part for part in (bounds, extra) if part)


def _number(x: float) -> str:
    return "pi" if x == math.pi else repr(x)


_HINTS: dict[Any, dict[str, Any]] = {}


def type_hints(cls: Any) -> dict[str, Any]:
    """The resolved annotations of a class, computed once per class.

    Resolving them costs ≈ 0.5 ms a class, and scenario settings are built per world refill.

    Args:
        cls: A dataclass type.

    Returns:
        Field name → annotation.
    """
    hints = _HINTS.get(cls)
    if hints is None:
        hints = _HINTS[cls] = typing.get_type_hints(cls)
    return hints


def _is_real(x: Any) -> bool:
    number = isinstance(x, (int, float, np.integer, np.floating))
    return number and not isinstance(x, (bool, np.bool_))


class Rule(typing.NamedTuple):
    """One field's declaration, prepared once per class for validation."""

    name: str
    kind: str  # float, int, str, bool, section, tuple or other
    inner: Any  # the annotation without None
    optional: bool
    choices: tuple[Any, ...] | None
    gt: Any
    ge: Any
    lt: Any
    le: Any
    check: Callable[[Any], bool] | None
    requirement: str


def validate_value(owner: str, name: str, value: Any, tp: Any, meta: Mapping[str, Any]) -> Any:
    """Checks one value against its annotation and its :func:`setting` constraint.

    Args:
        owner: The section or class errors name (``orca``, ``CircleCrossing``), "" for none.
        name: The field's name.
        value: The value given.
        tp: The field's resolved annotation.
        meta: The field's metadata (empty for a plain field: only the type is checked).

    Returns:
        The value normalised (see `Settings.normalise`).

    Raises:
        ConfigError: A value out of its constraint (ConfigTypeError: of the wrong type).
    """
    return check_rule(owner, _rule(name, tp, meta), value)


def _rule(name: str, tp: Any, meta: Mapping[str, Any]) -> Rule:
    inner, optional = tp, False
    args = typing.get_args(tp)
    if typing.get_origin(tp) in (typing.Union, _UnionType) and type(None) in args:
        rest = [a for a in args if a is not type(None)]
        optional = True
        inner = rest[0] if len(rest) == 1 else tp
    if inner in (float, int, str, bool):
        kind = inner.__name__
    elif dataclasses.is_dataclass(inner):
        kind = "section"
    elif typing.get_origin(inner) is tuple:
        kind = "tuple"
    else:
        kind = "other"
    return Rule(name, kind, inner, optional, meta.get("choices"), meta.get("gt"), meta.get("ge"),
                 meta.get("lt"), meta.get("le"), meta.get("check"), str(meta.get("requirement") or ""))


_RULES: dict[Any, tuple[Rule, ...]] = {}


def rules_of(cls: Any) -> tuple[Rule, ...]:
    """The validation rules of every field of a dataclass, prepared once per class.

    Args:
        cls: A dataclass type.

    Returns:
        One rule per field, in field order.
    """
    rules = _RULES.get(cls)
    if rules is None:
        hints = type_hints(cls)
        rules = _RULES[cls] = tuple(_rule(f.name, hints[f.name], f.metadata) for f in dataclasses.fields(cls))
    return rules


def _refuse(owner: str, rule: Rule, detail: str, given: Any, type_error: bool = False) -> ConfigError:
    return field_error(owner, rule.name, f"{detail}, got {short_repr(given)}", type_error=type_error)


def check_rule(owner: str, r: Rule, value: Any) -> Any:
    """`validate_value` for a prepared rule."""
    given = value  # errors show the value as given, not as normalised
    kind = r.kind
    if value is None and r.optional:
        return value
    if kind == "float":
        if type(value) is not float or not math.isfinite(value):  # the common case costs one test
            if not _is_real(value):
                raise _refuse(owner, r, "must be a number", given, True)
            if not math.isfinite(float(value)):
                raise _refuse(owner, r, "must be finite", given)
            value = float(value)
    elif kind == "int":
        if type(value) is not int:
            if not isinstance(value, (int, np.integer)) or isinstance(value, (bool, np.bool_)):
                raise _refuse(owner, r, "must be an int", given, True)
            value = int(value)
    elif kind == "str":
        if not isinstance(value, str):
            raise _refuse(owner, r, "must be a string", given, True)
    elif kind == "bool":
        if not isinstance(value, (bool, np.bool_)):
            raise _refuse(owner, r, "must be a bool (true or false)", given, True)
        value = bool(value)
    elif kind == "section":
        if not isinstance(value, r.inner):
            raise _refuse(owner, r, f"must be a {r.inner.__name__} (a section of settings)", given, True)
        return value
    elif kind == "tuple":
        args = typing.get_args(r.inner)
        fixed = not (len(args) == 2 and args[1] is Ellipsis)
        if not isinstance(value, (tuple, list)) or (fixed and len(value) != len(args)):
            what = f"{len(args) if fixed else ''} {'numbers' if float in args else 'values'}".lstrip()
            raise _refuse(owner, r, f"must be a sequence of {what}", given, True)
        if float in args:
            if not all(_is_real(v) and math.isfinite(float(v)) for v in value):
                raise _refuse(owner, r, "must hold finite numbers", given)
            value = tuple(float(v) for v in value)
        else:
            value = tuple(value)
    else:
        return value  # a mapping, a list, a union of several types: the loader checked the type
    if r.choices and value not in r.choices:
        raise _refuse(owner, r, "must be one of " + ", ".join(map(repr, r.choices)), given)
    gt, ge, lt, le = r.gt, r.ge, r.lt, r.le
    if ((gt is not None and not value > gt) or (ge is not None and not value >= ge)
            or (lt is not None and not value < lt) or (le is not None and not value <= le)):
        raise _refuse(owner, r, "must be " + constraint_text({"gt": gt, "ge": ge, "lt": lt, "le": le}), given)
    if r.check is not None and not r.check(value):
        raise _refuse(owner, r, r.requirement, given)
    return value

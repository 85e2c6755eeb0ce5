"""Loading settings from plain mappings (parsed YAML): strict keys, coercion, dotted error paths.

Errors name the dotted path of the offending field (``world.orca.time_horizon``) and its value, so a
typo in a YAML file is reported (with the closest valid name) instead of silently ignored.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import re
import types
import typing
from collections.abc import Mapping
from typing import Any, TypeVar

from socialnav._io import short_repr
from socialnav.settings.errors import ConfigError
from socialnav.settings.validation import type_hints, type_name

__all__ = ["check", "from_dict", "to_dict"]

T = TypeVar("T")


def from_dict(cls: type[T], data: Mapping[str, Any] | None, path: str = "") -> T:
    """Builds the frozen dataclass ``cls`` from ``data``, recursing into nested dataclasses.

    Args:
        cls: A dataclass type (a :class:`Settings` subclass or a plain frozen dataclass).
        data: Field values; missing fields keep their defaults.
        path: Dotted prefix used in error messages (``world``).

    Returns:
        The instance.

    Raises:
        ConfigError: On unknown keys (the closest valid one suggested, the valid ones listed) or
            invalid values, naming the dotted field and the value.
    """
    if data is not None and not isinstance(data, Mapping):
        what = f"section {path}" if path else "the settings"
        raise ConfigError(f"{what} must be a mapping of settings, got {_kind(data)}")
    data = dict(data or {})
    fields = {f.name: f for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    where = f"{path}." if path else ""
    unknown = sorted(set(data) - set(fields), key=str)  # keys may be numbers too (YAML `1: x`)
    if unknown:
        named = []
        for key in unknown:
            text = key if isinstance(key, str) and len(key) <= 80 else short_repr(key, 80)
            close = difflib.get_close_matches(text, list(fields), n=1, cutoff=0.6)
            named.append(where + text + (f" (did you mean {where}{close[0]}?)" if close else ""))
        raise ConfigError(f"unknown setting(s) {', '.join(named)}; valid: {', '.join(sorted(fields))}")
    hints = type_hints(cls)
    kwargs: dict[str, Any] = {}
    for name, value in data.items():
        hint = hints.get(name)
        sub = f"{where}{name}"
        if dataclasses.is_dataclass(hint):
            kwargs[name] = from_dict(typing.cast(type, hint), value, sub)  # value None: the defaults
        else:
            kwargs[name] = _coerce(value, hint, sub)
    try:
        return cls(**kwargs)
    except ConfigError as err:
        if err.field is not None:  # raised by the instance: name it by its path in this mapping
            raise type(err)(f"{where}{err.field} {err.detail}") from None
        message = str(err)
        if path and message.startswith("unknown setting(s) "):  # its names, each put under this path
            names, sep, valid = message[len("unknown setting(s) "):].partition("; valid: ")
            names = re.sub(r"(^|, |did you mean )", lambda m: f"{m.group(1)}{path}.", names)
            raise type(err)(f"unknown setting(s) {names}{sep}{valid}") from None
        if path and not message.startswith(path):
            raise type(err)(f"{path}.{err}") from None
        raise


def to_dict(obj: Any) -> dict[str, Any]:
    """Plain-dict form of a settings dataclass (JSON/YAML serialisable; a Settings' own ``to_dict``)."""
    own = getattr(obj, "to_dict", None)
    return own() if callable(own) else dataclasses.asdict(obj)


def check(condition: bool, field: str, value: Any, requirement: str) -> None:
    """Raises a ConfigError naming ``field`` unless ``condition`` holds.

    Args:
        condition: What must hold.
        field: The (dotted) field named in the message.
        value: Its value.
        requirement: What it must satisfy (``must be > 0``).

    Raises:
        ConfigError: ``condition`` is false.
    """
    if not condition:
        raise ConfigError(f"{field} {requirement}, got {short_repr(value)}")


def _coerce(value: Any, hint: Any, path: str) -> Any:
    """Accepts ints for float fields (YAML writes ``25`` for ``25.0``); rejects other mismatches."""
    origin = typing.get_origin(hint)
    if origin is tuple:
        if not isinstance(value, list | tuple):
            raise ConfigError(f"{path} must be a list, got {_kind(value)}")
        item = typing.get_args(hint)[0] if typing.get_args(hint) else Any
        return tuple(_coerce(v, item, f"{path}[{i}]") for i, v in enumerate(value))
    if origin is dict or hint is dict:
        if not isinstance(value, Mapping):
            raise ConfigError(f"{path} must be a mapping, got {_kind(value)}")
        return dict(value)
    if origin is list or hint is list:
        if not isinstance(value, list | tuple):
            raise ConfigError(f"{path} must be a list, got {_kind(value)}")
        return list(value)
    if hint is float and isinstance(value, int) and not isinstance(value, bool):
        if abs(value) > 1e300:
            raise ConfigError(f"{path} must be a finite number, got {short_repr(value)}")
        return float(value)
    if hint is float and isinstance(value, str):
        # PyYAML reads 1e-3 and 1.0e9 as strings: accept exponent forms, and refuse other text,
        # quoted numbers included ("1.5"), as an int field refuses "20".
        if not _EXPONENT_FORM.fullmatch(value.strip()):
            hint_text = " (write the number without quotes)" if _is_number(value) else ""
            raise ConfigError(f"{path} must be a number, got the text {short_repr(value)}{hint_text}")
        value = float(value)
    if hint is float and isinstance(value, float) and not math.isfinite(value):
        raise ConfigError(f"{path} must be a finite number, got {value!r}")
    if hint is int and isinstance(value, str) and _is_number(value):
        number = float(value)
        if _EXPONENT_FORM.fullmatch(value.strip()) and number.is_integer():  # 1e7: YAML 1.1 keeps it as text
            raise ConfigError(
                f"{path} must be an integer, got {value.strip()} (write it in digits: {int(number)})"
            )
        raise ConfigError(
            f"{path} must be an integer, got the text {short_repr(value)} (write the number without quotes)"
        )
    if hint is int and isinstance(value, float) and math.isfinite(value) and value.is_integer():
        # 1e7 or 1.0e7 (YAML's float forms): the integer is what was meant, in digits
        raise ConfigError(f"{path} must be an integer, got {value!r} (write it in digits: {int(value)})")
    if hint in (float, int, str, bool) and not isinstance(value, hint):
        raise ConfigError(f"{path} must be of type {hint.__name__}, got {short_repr(value)}")
    if hint is int and isinstance(value, bool):
        raise ConfigError(f"{path} must be an integer, got {value!r}")
    if origin in (typing.Union, types.UnionType) and value is not None:
        options = [arg for arg in typing.get_args(hint) if arg is not type(None)]
        if len(options) == 1:  # an optional value: the type's own message
            return _coerce(value, options[0], path)
        for arg in options:
            try:
                return _coerce(value, arg, path)
            except ConfigError:
                continue
        kinds = " or ".join(_KINDS.get(typing.get_origin(a) or a, type_name(a)) for a in options)
        raise ConfigError(f"{path} must be {kinds}, got {_kind(value)}")
    return value


_KINDS = {dict: "a mapping", list: "a list", tuple: "a list", float: "a number", int: "an integer",
          str: "a text", bool: "true or false"}


#: What PyYAML (YAML 1.1) may leave as text although YAML 1.2 reads a number: exponent forms (1e-3,
#: 1.0e9); YAML 1.1 wants a dot and a signed exponent.
_EXPONENT_FORM = re.compile(r"[-+]?(\d+(\.\d*)?|\.\d+)[eE][-+]?\d+")


def _is_number(text: str) -> bool:
    """Whether the text spells a finite number (YAML's .nan and .inf are the non-finite ones, written so)."""
    try:
        return math.isfinite(float(text))
    except ValueError:
        return False


def _kind(value: Any) -> str:
    return f"{type(value).__name__} {short_repr(value, 40)}"

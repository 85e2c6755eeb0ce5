"""The one settings system: typed frozen dataclasses whose fields carry their own parameter table.

A settings class is a frozen dataclass deriving from :class:`Settings`; each field is declared once
with :func:`setting` (default, unit, description, constraint). That declaration drives:

- validation when an instance is built (``__post_init__``): the annotation's type and the
  constraint, with an error naming the section, the field and the value;
- loading from plain dicts / YAML (:meth:`Settings.from_dict`, :func:`from_dict`): unknown keys are
  refused with the closest valid name, wrong types are refused naming the file and dotted field;
- :meth:`Settings.to_dict` (plain, JSON-serialisable, in field order: run manifests hash it);
- the parameter table (:meth:`Settings.parameters`): name, type, default, unit, description and
  constraint of every field, read by ``socialnav list`` and the settings reference in the docs.

Rules between fields (``rl.batch_size <= rl.capacity``) go in :meth:`Settings.cross_check`.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import re
import types
import typing
from collections.abc import Callable, Mapping
from typing import Any, ClassVar, TypeVar

import numpy as np

__all__ = [
    "ConfigError",
    "ConfigTypeError",
    "SettingSpec",
    "Settings",
    "check",
    "from_dict",
    "parameter_table",
    "setting",
    "to_dict",
]

T = TypeVar("T")
_UnionType = type(int | None)


class ConfigError(ValueError):
    """A setting is unknown, of the wrong type or out of range.

    Attributes:
        field: For an error raised while an instance was built, the offending field's name
            relative to its settings class (``from_dict`` then prefixes the section's dotted path);
            None once the message is final.
        detail: The message after the field's name (``must be > 0, got -1``).
    """

    def __init__(self, message: str, *, field: str | None = None, detail: str = "") -> None:
        """Builds the error.

        Args:
            message: The full message.
            field: See the class attributes.
            detail: See the class attributes.
        """
        super().__init__(message)
        self.field = field
        self.detail = detail


class ConfigTypeError(ConfigError, TypeError):
    """A setting has a value of the wrong type (also a TypeError, as Python raises for bad arguments)."""


def setting(
    default: Any = dataclasses.MISSING,
    doc: str = "",
    *,
    unit: str = "",
    gt: float | None = None,
    ge: float | None = None,
    lt: float | None = None,
    le: float | None = None,
    choices: tuple[Any, ...] | None = None,
    check: Callable[[Any], bool] | None = None,
    requirement: str = "",
    default_factory: Callable[[], Any] | Any = dataclasses.MISSING,
) -> Any:
    """Declares one setting: a dataclass field carrying its description, unit and constraint.

    Args:
        default: Default value (immutable: numbers, strings, tuples, None); use
            ``default_factory`` for a nested settings section.
        doc: One-line description (``socialnav list``, the docs tables).
        unit: SI unit in brackets' form (``m``, ``m/s``, ``s``, ``rad``); "" when dimensionless.
        gt: The value must be > gt.
        ge: The value must be >= ge.
        lt: The value must be < lt.
        le: The value must be <= le.
        choices: The allowed values (string options).
        check: A predicate the value must satisfy besides the bounds (None values skip it).
        requirement: What ``check`` requires, as the error says it (``must be ...``).
        default_factory: Builds the default (nested sections).

    Returns:
        A ``dataclasses.field``.
    """
    if (check is None) != (not requirement):
        raise TypeError("setting(): give check= and requirement= together")
    meta = {"doc": doc, "unit": unit, "gt": gt, "ge": ge, "lt": lt, "le": le, "choices": choices,
            "check": check, "requirement": requirement}
    if default_factory is not dataclasses.MISSING:
        return dataclasses.field(default_factory=default_factory, metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


@dataclasses.dataclass(frozen=True)
class SettingSpec:
    """One row of a parameter table.

    Attributes:
        name: The field's (dotted, for a nested section's fields) YAML / keyword name.
        default: Default value (a nested section's default instance for a section row).
        type: The annotation as text ("float", "float | None"), or "section".
        doc: One-line description.
        unit: SI unit, "" when dimensionless.
        choices: Allowed values of an option, else None.
        constraint: The constraint as text ("> 0", "in [0, 64]", "one of 'a', 'b'"), "" if none.
    """

    name: str
    default: Any
    type: str
    doc: str
    unit: str = ""
    choices: tuple[Any, ...] | None = None
    constraint: str = ""

    @property
    def is_section(self) -> bool:
        """Whether the row heads a nested section (its fields follow with dotted names)."""
        return self.type == "section"


class Settings:
    """Base of the settings dataclasses (decorate subclasses with ``@dataclass(frozen=True)``).

    Class attributes:
        section: The dotted name of the section errors name when an instance is built directly
            (``orca`` gives ``orca.time_horizon must be > 0``); "" for a top-level one.
        normalise: Store values normalised (ints of float fields as floats, lists as tuples,
            NumPy scalars as Python ones) rather than as given.
    """

    section: ClassVar[str] = ""
    normalise: ClassVar[bool] = False

    def __post_init__(self) -> None:
        """Validates every field against its annotation and constraint, then `cross_check`."""
        owner = self.setting_owner()
        normalise = self.normalise
        for rule in _rules(type(self)):
            value = getattr(self, rule.name)
            new = _check(owner, rule, value)
            if normalise and new is not value:
                object.__setattr__(self, rule.name, new)
        self.cross_check()

    def cross_check(self) -> None:
        """Checks the rules between fields (override; raise with :meth:`refuse`)."""

    @classmethod
    def setting_owner(cls) -> str:
        """The name errors give the instance's section (``section``, or the class name if none)."""
        return cls.section

    def refuse(self, name: str, requirement: str, value: Any = dataclasses.MISSING, *,
               got: bool = True) -> typing.NoReturn:
        """Raises the ConfigError of field ``name`` (its path completed by `from_dict`).

        Args:
            name: The field.
            requirement: What it must satisfy (``must be <= rl.capacity (50)``).
            value: The value to show (default: the field's).
            got: End the message with ``, got <value>``; False: ``requirement`` is the whole
                message after the field's name.

        Raises:
            ConfigError: Always.
        """
        value = getattr(self, name) if value is dataclasses.MISSING else value
        detail = f"{requirement}, got {value!r}" if got else requirement
        raise _field_error(self.setting_owner(), name, detail)

    @classmethod
    def from_dict(cls: type[T], data: Mapping[str, Any] | None, *, source: str | None = None,
                  section: str = "") -> T:
        """Builds the settings from a mapping (the parsed YAML); missing fields keep their defaults.

        Args:
            data: Field values, nested mappings for nested sections; None: all defaults.
            source: Where the mapping comes from (a file path), named first in errors.
            section: Dotted path of the mapping in its file (``world``), named in errors.

        Returns:
            The settings.

        Raises:
            ConfigError: An unknown key (with the closest valid one), a wrong type or value.
        """
        try:
            return from_dict(cls, data, section)
        except ConfigError as err:
            if source is None:
                raise
            raise type(err)(f"{source}: {err}") from None

    def to_dict(self) -> dict[str, Any]:
        """Plain-dict form (JSON/YAML serialisable, nested sections as dicts, in field order)."""
        return dataclasses.asdict(self)  # type: ignore[call-overload]

    @classmethod
    def parameters(cls) -> tuple[SettingSpec, ...]:
        """The parameter table, nested sections flattened after a section row (see `parameter_table`)."""
        return tuple(parameter_table(cls))


def parameter_table(cls: type, prefix: str = "") -> list[SettingSpec]:
    """One row per field of the dataclass ``cls``; a nested section gets a row, then its fields.

    Works for any dataclass: fields declared without :func:`setting` have an empty description,
    unit and constraint.

    Args:
        cls: A dataclass type whose fields all have defaults.
        prefix: Dotted prefix of the names (``world.``).

    Returns:
        The rows in field order.
    """
    hints = _type_hints(cls)
    rows = []
    for f in dataclasses.fields(cls):
        if not f.init:
            continue
        default = f.default_factory() if f.default_factory is not dataclasses.MISSING else f.default
        name = f"{prefix}{f.name}"
        if dataclasses.is_dataclass(default):
            doc = f.metadata.get("doc") or (type(default).__doc__ or "").strip().split("\n\n")[0]
            rows.append(SettingSpec(name, default, "section", " ".join(doc.split())))
            rows += parameter_table(type(default), f"{name}.")
            continue
        meta = f.metadata
        rows.append(SettingSpec(name=name, default=default, type=type_name(hints[f.name]),
                                doc=meta.get("doc", ""), unit=meta.get("unit", ""),
                                choices=meta.get("choices"), constraint=constraint_text(meta)))
    return rows


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


def _type_hints(cls: Any) -> dict[str, Any]:
    # resolving annotations costs ≈ 0.5 ms a class, and scenario settings are built per world refill
    hints = _HINTS.get(cls)
    if hints is None:
        hints = _HINTS[cls] = typing.get_type_hints(cls)
    return hints


def _field_error(owner: str, name: str, detail: str, *, type_error: bool = False) -> ConfigError:
    where = f"{owner}.{name}" if owner else name
    kind = ConfigTypeError if type_error else ConfigError
    return kind(f"{where} {detail}", field=name, detail=detail)


def _is_real(x: Any) -> bool:
    number = isinstance(x, (int, float, np.integer, np.floating))
    return number and not isinstance(x, (bool, np.bool_))


class _Rule(typing.NamedTuple):
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
    return _check(owner, _rule(name, tp, meta), value)


def _rule(name: str, tp: Any, meta: Mapping[str, Any]) -> _Rule:
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
    return _Rule(name, kind, inner, optional, meta.get("choices"), meta.get("gt"), meta.get("ge"),
                 meta.get("lt"), meta.get("le"), meta.get("check"), str(meta.get("requirement") or ""))


_RULES: dict[Any, tuple[_Rule, ...]] = {}


def _rules(cls: Any) -> tuple[_Rule, ...]:
    # prepared once per class: scenario settings are built on every world refill
    rules = _RULES.get(cls)
    if rules is None:
        hints = _type_hints(cls)
        rules = _RULES[cls] = tuple(_rule(f.name, hints[f.name], f.metadata) for f in dataclasses.fields(cls))
    return rules


def _refuse(owner: str, rule: _Rule, detail: str, given: Any, type_error: bool = False) -> ConfigError:
    return _field_error(owner, rule.name, f"{detail}, got {given!r}", type_error=type_error)


def _check(owner: str, r: _Rule, value: Any) -> Any:
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


# -- loading from mappings ------------------------------------------------------------------------
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
    unknown = sorted(set(data) - set(fields))
    if unknown:
        named = []
        for key in unknown:
            close = difflib.get_close_matches(str(key), list(fields), n=1, cutoff=0.6)
            named.append(where + str(key) + (f" (did you mean {where}{close[0]}?)" if close else ""))
        raise ConfigError(f"unknown setting(s) {', '.join(named)}; valid: {', '.join(sorted(fields))}")
    hints = _type_hints(cls)
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
        if path and not str(err).startswith(path):
            raise type(err)(f"{path}.{err}") from None
        raise


def to_dict(obj: Any) -> dict[str, Any]:
    """Plain-dict form of a settings dataclass (JSON/YAML serialisable)."""
    return dataclasses.asdict(obj)


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
        raise ConfigError(f"{field} {requirement}, got {value!r}")


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
            raise ConfigError(f"{path} must be a finite number, got {value!r}")
        return float(value)
    if hint is float and isinstance(value, str):
        # PyYAML reads 1e-3 and 1.0e9 as strings: accept exponent forms, and refuse other text,
        # quoted numbers included ("1.5"), as an int field refuses "20".
        if not _EXPONENT_FORM.fullmatch(value.strip()):
            hint_text = " (write the number without quotes)" if _is_number(value) else ""
            raise ConfigError(f"{path} must be a number, got the text {value!r}{hint_text}")
        value = float(value)
    if hint is float and isinstance(value, float) and not math.isfinite(value):
        raise ConfigError(f"{path} must be a finite number, got {value!r}")
    if hint is int and isinstance(value, str) and _is_number(value):
        raise ConfigError(
            f"{path} must be an integer, got the text {value!r} (write the number without quotes)"
        )
    if hint in (float, int, str, bool) and not isinstance(value, hint):
        raise ConfigError(f"{path} must be of type {hint.__name__}, got {value!r}")
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
    try:
        float(text)
    except ValueError:
        return False
    return True


def _kind(value: Any) -> str:
    text = repr(value)
    return f"{type(value).__name__} {text if len(text) <= 40 else text[:37] + '...'}"

"""Declaring settings: the `setting()` field helper, the `Settings` base class, parameter tables."""

from __future__ import annotations

import dataclasses
import typing
from collections.abc import Callable, Mapping, Sequence
from typing import Any, ClassVar, TypeVar

from socialnav._io import short_repr
from socialnav.settings.errors import ConfigError, field_error
from socialnav.settings.loading import from_dict
from socialnav.settings.validation import check_rule, constraint_text, rules_of, type_hints, type_name

__all__ = ["SettingSpec", "Settings", "parameter_table", "setting"]

T = TypeVar("T")


def setting(
    default: Any = dataclasses.MISSING,
    doc: str = "",
    *,
    unit: str = "",
    gt: float | None = None,
    ge: float | None = None,
    lt: float | None = None,
    le: float | None = None,
    choices: Sequence[Any] | None = None,
    check: Callable[[Any], bool] | None = None,
    requirement: str = "",
    default_factory: Callable[[], Any] | Any = dataclasses.MISSING,
    record_default: bool = True,
) -> Any:
    """Declares one setting: a dataclass field carrying its description, unit and constraint.

    Args:
        default: Default value (immutable: numbers, strings, tuples, None); use
            ``default_factory`` for a nested settings section.
        doc: One-line description (``socialnav list``, the docs tables).
        unit: SI unit (``m``, ``m/s``, ``s``, ``rad``); "" when dimensionless.
        gt: The value must be > gt.
        ge: The value must be >= ge.
        lt: The value must be < lt.
        le: The value must be <= le.
        choices: The allowed values (string options; a live sequence, such as the registered
            pedestrian behaviours' names, is read at each check).
        check: A predicate the value must satisfy besides the bounds (None values skip it).
        requirement: What ``check`` requires, as the error says it (``must be ...``).
        default_factory: Builds the default (nested sections).
        record_default: False: `Settings.to_dict` leaves the field out while it holds its default, so
            that the records (run manifests, checkpoints) of settings that leave it alone are the ones
            made before it existed, fingerprints included.

    Returns:
        A ``dataclasses.field``.
    """
    if (check is None) != (not requirement):
        raise TypeError("setting(): give check= and requirement= together")
    meta = {"doc": doc, "unit": unit, "gt": gt, "ge": ge, "lt": lt, "le": le, "choices": choices,
            "check": check, "requirement": requirement, "record_default": record_default}
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
    choices: Sequence[Any] | None = None
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
        for rule in rules_of(type(self)):
            value = getattr(self, rule.name)
            new = check_rule(owner, rule, value)
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
        detail = f"{requirement}, got {short_repr(value)}" if got else requirement
        raise field_error(self.setting_owner(), name, detail)

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
        """Plain-dict form (JSON/YAML serialisable, nested sections as dicts, in field order).

        ``dataclasses.asdict``, less the fields declared with ``record_default=False`` that hold their
        default (in nested sections too).
        """
        return _drop_unrecorded(self, dataclasses.asdict(self))  # type: ignore[call-overload]

    @classmethod
    def parameters(cls) -> tuple[SettingSpec, ...]:
        """The parameter table, nested sections flattened after a section row (see `parameter_table`)."""
        return tuple(parameter_table(cls))


def _drop_unrecorded(obj: Any, data: dict[str, Any]) -> dict[str, Any]:
    """``data`` (``asdict(obj)``) less the fields of ``obj`` that are not recorded at their default.

    A settings class keeps some of them at their default too where its ``recorded_at_default()`` names
    them (WorldSettings: a differential drive's limits).
    """
    keep = obj.recorded_at_default() if hasattr(obj, "recorded_at_default") else ()
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        if not f.metadata.get("record_default", True) and f.name not in keep:
            default = f.default_factory() if f.default_factory is not dataclasses.MISSING else f.default
            if value == default:
                del data[f.name]
        elif dataclasses.is_dataclass(value) and isinstance(data.get(f.name), dict):
            _drop_unrecorded(value, data[f.name])
    return data


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
    hints = type_hints(cls)
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

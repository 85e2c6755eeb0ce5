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


from socialnav.settings.declare import Settings, SettingSpec, parameter_table, setting
from socialnav.settings.errors import ConfigError, ConfigTypeError
from socialnav.settings.loading import check, from_dict, to_dict
from socialnav.settings.validation import constraint_text, type_name, validate_value

__all__ = [
    "ConfigError",
    "ConfigTypeError",
    "SettingSpec",
    "Settings",
    "check",
    "constraint_text",
    "from_dict",
    "parameter_table",
    "setting",
    "to_dict",
    "type_name",
    "validate_value",
]

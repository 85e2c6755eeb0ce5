"""The errors of the settings system: a setting is unknown, of the wrong type or out of range."""

from __future__ import annotations

__all__ = ["ConfigError", "ConfigTypeError", "field_error"]


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


def field_error(owner: str, name: str, detail: str, *, type_error: bool = False) -> ConfigError:
    """The error of field ``name`` of a settings instance (``from_dict`` completes its path).

    Args:
        owner: The section or class the message names first ("" for none).
        name: The field.
        detail: The rest of the message (``must be > 0, got -1``).
        type_error: A wrong type (ConfigTypeError) rather than a wrong value.

    Returns:
        The error, with ``field`` and ``detail`` set.
    """
    where = f"{owner}.{name}" if owner else name
    kind = ConfigTypeError if type_error else ConfigError
    return kind(f"{where} {detail}", field=name, detail=detail)

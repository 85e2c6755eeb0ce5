"""Training config files, whichever trainer's settings they hold.

A config is a YAML file, the name of a config shipped in ``socialnav/configs/train`` (``--config
smoke``), or a run's own ``config.yaml`` (its ``train:`` section). Loading is strict: an unknown key is
refused with the closest valid name, a bad value naming the file and the dotted field, and a value
given on the command line naming its option instead of a file the user never wrote.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any, TypeVar

import yaml

from socialnav._io import load_yaml
from socialnav.settings import ConfigError, from_dict

#: What every trainer's ``device`` setting may be.
DEVICES = ("cpu", "cuda", "auto")
#: Keys of a run's record that name its trainer's checkpoint record (records written before the record
#: named its ``trainer``): the trainer each stands for.
LEGACY_RECORD_KEYS = {"value_policy": "value", "ppo_policy": "ppo"}

T = TypeVar("T")


def is_run_record(data: Mapping[str, Any]) -> bool:
    """Whether a config mapping is a run directory's ``config.yaml`` (a trainer's record of a run).

    It names its ``trainer`` (older records: a ``value_policy`` or ``ppo_policy``) beside its
    ``train`` settings, the policy and the preset.
    """
    return "trainer" in data or any(key in data for key in LEGACY_RECORD_KEYS)


def record_trainer(data: Mapping[str, Any]) -> str | None:
    """The trainer a run's record names (older records: read from their checkpoint record), else None."""
    named = data.get("trainer")
    if isinstance(named, str):
        return named
    return next((trainer for key, trainer in LEGACY_RECORD_KEYS.items() if key in data), None)


def settings_of(data: dict[str, Any]) -> dict[str, Any]:
    """The training settings of a config file: itself, or a run's record's ``train`` section.

    ``--config`` takes a run's ``config.yaml`` (what a refused resume points to) as its settings.
    """
    record = isinstance(data.get("train"), dict) and is_run_record(data)
    return dict(data["train"]) if record else data


def shipped_train_configs() -> list[str]:
    """Names of the training configs shipped in ``socialnav/configs/train`` (``smoke`` …)."""
    from importlib import resources

    folder = resources.files("socialnav.configs") / "train"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".yaml"))


def resolve_config_path(path: str | Path) -> Path:
    """A YAML path, or the name of a shipped training config (``--config smoke``).

    Raises:
        ConfigError: neither a file nor a shipped config's name (the shipped ones are listed).
    """
    p = Path(path)
    if p.exists():
        return p
    if p.suffix not in (".yaml", ".yml") and str(path) in shipped_train_configs():
        from importlib import resources

        return Path(str(resources.files("socialnav.configs") / "train" / f"{path}.yaml"))
    raise ConfigError(
        f"training config {p} does not exist (shipped configs: {', '.join(shipped_train_configs())})"
    )


def read_config(path: str | Path) -> dict[str, Any]:
    """The settings mapping of a config file (a run's record: its ``train`` section).

    Raises:
        ConfigError: the file is missing, a directory, not text, not YAML or not a mapping (named).
    """
    path = resolve_config_path(path)
    if path.is_dir():
        raise ConfigError(f"training config {path} is a directory, not a YAML file")
    try:
        data = load_yaml(path.read_text()) or {}
    except UnicodeDecodeError:
        raise ConfigError(f"training config {path} is not a text (YAML) file") from None
    except yaml.YAMLError as err:
        raise ConfigError(f"{path}: not valid YAML: {' '.join(str(err).split())}") from None
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: expected a mapping of settings, got {type(data).__name__}")
    return settings_of(data)


def _set_dotted(data: dict[str, Any], key: str, value: Any) -> None:
    """Sets a dotted key (``rl.episodes``) in nested mappings.

    A section that is not a mapping is left as it is, for the loader to refuse naming the file.
    """
    *sections, last = key.split(".")
    for section in sections:
        inner = data.setdefault(section, {})
        if not isinstance(inner, dict):
            return
        data = inner
    data[last] = value


def load_settings_file(cls: type[T], path: str | Path | None, overrides: dict[str, Any],
                       flags: Mapping[str, str] | None = None) -> T:
    """Settings of class ``cls`` from a YAML file, with ``overrides`` applied after it.

    Args:
        cls: The settings class.
        path: A YAML file or a shipped config's name; None: the defaults.
        overrides: Settings (dotted for nested ones, ``rl.episodes``); None values are ignored.
        flags: The command-line option of each override whose name differs from ``--<name>``
            (``n_envs``: ``--collection-batch``), to name it in an error.

    Returns:
        The settings.

    Raises:
        ConfigError: Naming the file and the field, or the option.
    """
    data: dict[str, Any] = {} if path is None else read_config(path)
    if path is not None:
        path = resolve_config_path(path)
    given = {k: v for k, v in overrides.items() if v is not None}
    for key, value in given.items():
        _set_dotted(data, key, value)
    try:
        return from_dict(cls, data)
    except ConfigError as err:
        # a value from the command line is the command line's error, not the file's
        named = [k for k in given if str(err).startswith(f"{k} ")]
        if named:
            option = (flags or {}).get(named[0], "--" + named[0].replace("_", "-"))
            raise ConfigError(f"{option}: {err}") from None
        raise ConfigError(f"{path}: {err}" if path is not None else str(err)) from None


def flat_diff(a: Any, b: Any, prefix: str = "") -> list[str]:
    """Dotted keys where two nested plain dicts differ."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in sorted(set(a) | set(b)):
            out += flat_diff(a.get(k), b.get(k), f"{prefix}{k}.")
        return out
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        a, b = list(a), list(b)
    return [] if a == b else [prefix.rstrip(".")]

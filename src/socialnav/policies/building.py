"""Builds the policy a command line, a preset or a sweep names, loading a checkpoint for learned ones.

:func:`build_policy` (the CLI, evaluation, replay and sweeps call it) takes a policy's parameters from
the preset and the caller, checks them (:func:`check_policy_parameters`, also behind ``make_policy``, a
preset's ``policies:`` section and a sweep's ``policy_args``), finds the shipped checkpoint of a learned
policy when none is given, and calls the policy's registry entry (for a learned one, its loader in
:mod:`socialnav.policies.learned_loading`).

Shipped checkpoints are described by ``socialnav/checkpoints/index.yaml`` (file, policy, preset, result
name, display label, variant, paper row, training command, seed, notes). A ``.pt`` file there without an
index entry is still recognised when it is named ``<policy>_<preset>.pt``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

from socialnav._io import load_yaml
from socialnav.policies.learned_catalog import (
    VALUE_INFORMATION,
    canonical_name,
    default_label,
    default_paper_row,
)
from socialnav.policies.native import NativePolicy
from socialnav.policies.registry import (
    EXEC_PREFIX,
    SB3_PREFIX,
    Policy,
    accepts_any_keyword,
    get_policy_entry,
    make_policy,
)
from socialnav.presets import Preset
from socialnav.settings import ConfigError

INDEX_FILE = "index.yaml"
VARIANTS = ("protocol", "original")


@dataclass(frozen=True)
class ShippedCheckpoint:
    """One entry of ``socialnav/checkpoints/index.yaml``."""

    file: str
    policy: str
    preset: str
    name: str
    label: str
    variant: str = "protocol"
    paper_row: str | None = None
    command: str | None = None
    seed: int | None = None
    notes: str = ""
    pending: bool = False

    @property
    def path(self) -> Path:
        """Where the checkpoint file is (or would be) in the package's checkpoint directory."""
        return checkpoint_dir() / self.file

    @property
    def exists(self) -> bool:
        """Whether the checkpoint file is present."""
        return self.path.is_file()


def build_policy(
    name: str,
    preset: Preset,
    checkpoint: str | Path | None = None,
    /,
    *,
    allow_preset_mismatch: bool = False,
    **overrides,
) -> Policy:
    """The policy ``name`` with the preset's defaults for it, overridden by ``overrides``.

    ``name``, ``preset`` and ``checkpoint`` are positional only: a policy may have parameters so called.

    Raises:
        KeyError: Unknown policy (the valid ones are listed).
        ValueError: A checkpoint given to a policy that does not learn, or missing for one that does;
            a checkpoint trained for another world than the preset's (unless ``allow_preset_mismatch``).
    """
    policy = _build(name, preset, checkpoint, allow_preset_mismatch, overrides)
    try:  # run_protocol then knows the preset's policies section was applied (or deliberately overridden)
        policy.built_for_preset = preset.name
    except AttributeError:  # a policy object that takes no new attributes
        pass
    return policy


def _build(name: str, preset: Preset, checkpoint: str | Path | None, allow_preset_mismatch: bool,
           overrides: dict[str, Any]) -> Policy:
    entry = get_policy_entry(name)
    params = {**preset.policy_params(name), **overrides}
    if name.startswith(SB3_PREFIX):
        if checkpoint is not None:
            raise ValueError(f"policy {name} names its model file itself and takes no --checkpoint")
        return entry.factory(preset=preset, allow_preset_mismatch=allow_preset_mismatch, **params)
    if name.startswith(EXEC_PREFIX):
        if checkpoint is not None:
            raise ValueError(f"policy {name} is a program and takes no --checkpoint")
        unknown = sorted(set(params) - set(entry.parameters))
        if unknown:
            raise ValueError(f"policy {name}: unknown parameter(s) {unknown}; an exec planner takes timeout")
        return entry.factory(preset=preset, **params)
    if not entry.learned:
        if checkpoint is not None:
            raise ValueError(f"policy {name!r} is not learned and takes no --checkpoint")
        policy = make_policy(name, **params)
        if isinstance(policy, NativePolicy):  # the robot's ORCA/social force as the preset's humans'
            policy.use_world(preset.world)
        return policy
    if checkpoint is None:
        checkpoint = shipped_checkpoint(name, preset.name)
        if checkpoint is None:
            raise ValueError(
                f"policy {name!r} is learned and no checkpoint of it ships for preset "
                f"{preset.name!r} (shipped: {', '.join(list_shipped_checkpoints()) or 'none'}): "
                "pass --checkpoint PATH (see `socialnav train`)"
            )
    check_policy_parameters(name, entry, params)
    return entry.factory(
        checkpoint=Path(checkpoint), preset=preset, allow_preset_mismatch=allow_preset_mismatch, **params
    )


def check_preset_policies(preset: Preset, source: str) -> None:
    """A preset's ``policies`` section: policy names and their parameters, named with the file and field.

    Args:
        preset: The preset.
        source: Where it was read from (its file, or a shipped preset's name), for the message.

    Raises:
        ConfigError: An unknown policy, or a parameter its policy does not have.
    """
    for name, params in preset.policies.items():
        try:
            entry = get_policy_entry(name)
        except KeyError as err:
            raise ConfigError(f"{source}: policies.{name}: {err.args[0] if err.args else err}") from None
        try:
            # a learned policy's device is checked when it is built (that needs PyTorch, which this run
            # may lack); its other settings now, as a native policy's
            check_policy_parameters(name, entry, params, check_device=False)
        except ValueError as err:
            raise ConfigError(f"{source}: policies.{name}: {err}") from None


def check_policy_parameters(
    name: str, entry: Any, params: dict[str, Any], *, check_device: bool = True
) -> None:
    """Refuse parameters a registered policy does not have, or values it cannot take.

    The one check behind ``make_policy``, ``build_policy``, a preset's ``policies:`` section and a
    sweep's ``policy_args``. A factory taking ``**kwargs`` checks its own arguments.

    Args:
        name: The policy.
        entry: Its registry entry.
        params: Its parameters (for a learned policy, the evaluation ones, not the checkpoint).
        check_device: Check that a learned policy's device exists on this machine (a sweep leaves it
            to the machine the job runs on).

    Raises:
        ValueError: An unknown parameter (the valid ones listed), or a value of the wrong type or range.
    """
    if entry.learned:
        given = params if check_device else {k: v for k, v in params.items() if k != "device"}
        check_learned_parameters(name, entry.parameters, given)
        return
    if accepts_any_keyword(entry.factory):
        return
    unknown = sorted(set(params) - set(entry.parameters))
    if unknown:
        raise ValueError(f"policy {name!r} has no parameter(s) {', '.join(unknown)}; "
                         f"valid: {', '.join(sorted(entry.parameters)) or 'none'}")
    for key, value in params.items():  # a value of its default's kind: a flag, an integer, a number, text
        default = entry.parameters[key]
        number = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
        whole = isinstance(value, int) and not isinstance(value, bool)
        if key == "threads" and not (whole and value >= 0):
            raise ValueError(f"policy {name!r}: threads must be an integer >= 0, got {value!r}")
        if isinstance(default, bool) and not isinstance(value, bool):
            raise ValueError(f"policy {name!r}: {key} must be true or false, got {value!r}")
        if isinstance(default, int) and not isinstance(default, bool) and not whole:
            raise ValueError(f"policy {name!r}: {key} must be an integer, got {value!r}")
        if isinstance(default, float) and not number:
            raise ValueError(f"policy {name!r}: {key} must be a finite number, got {value!r}")
        if isinstance(default, str) and not isinstance(value, str):
            raise ValueError(f"policy {name!r}: {key} must be text, got {value!r}")
        if key == "safety_space" and value < 0:  # a clearance: ORCA inflates radii by it
            raise ValueError(f"policy {name!r}: safety_space must be >= 0, got {value!r}")


#: The value-based policies' lookahead settings, which ``socialnav evaluate`` and sweep jobs take as keys of
#: their own (``--information``, ``information:``) beside the policy's parameters.
LOOKAHEAD_SETTINGS = ("information", "planning_depth", "planning_width")


def refuse_lookahead_setting(name: str, key: str, shown: str) -> None:
    """Refuses the lookahead setting ``key`` (given as ``shown``) for a policy that has no such setting.

    A module path's or ``sb3:`` model's settings are its own to check.

    Raises:
        ValueError: Naming ``shown``, the policy and the policies that take it.
    """
    if ":" not in name and key not in get_policy_entry(name).parameters:
        raise ValueError(f"{shown} applies to the value-based learned policies (CADRL, LSTM-RL, SARL, "
                         f"OM-SARL, RGL, MP-RGL); {name!r} has no {key} setting")


def check_learned_parameters(name: str, valid: dict[str, Any], params: dict[str, Any]) -> None:
    """Refuse evaluation parameters a learned policy does not have or cannot take.

    They are checked before the checkpoint is read, so that a typo is named as the user's, not blamed on
    a damaged checkpoint (the scorer is checked where it is chosen, with its own message).

    Args:
        name: The policy.
        valid: Its parameters with their defaults (the registry's).
        params: What the preset and the command line give it.

    Raises:
        ValueError: An unknown parameter (the valid ones listed), a value of the wrong type or range, or
            a device this machine does not have.
    """
    unknown = sorted(set(params) - set(valid))
    if unknown:
        raise ValueError(f"policy {name!r} has no parameter(s) {', '.join(unknown)}; "
                         f"valid: {', '.join(sorted(valid))}")
    for key, value in params.items():
        if value is None:
            continue
        if key == "deterministic" and not isinstance(value, bool):
            raise ValueError(f"policy {name!r}: deterministic must be true or false, got {value!r}")
        if key in ("planning_depth", "planning_width") and (
                isinstance(value, bool) or not isinstance(value, int) or value < 1):
            raise ValueError(f"policy {name!r}: {key} must be an integer >= 1, got {value!r}")
        if key == "information" and value not in VALUE_INFORMATION:
            raise ValueError(f"policy {name!r}: information must be one of {', '.join(VALUE_INFORMATION)}, "
                             f"got {value!r}")
        if key == "device":
            _check_device(name, value)


def _check_device(name: str, value: Any) -> None:
    import torch

    try:
        device = torch.device(value)
    except (RuntimeError, TypeError) as err:
        raise ValueError(f"policy {name!r}: device {value!r} is not a torch device ({err})") from None
    if device.type == "cuda" and not torch.cuda.is_available():
        raise ValueError(f"policy {name!r}: device {value!r}, but CUDA is not available on this machine "
                         "(a CPU-only PyTorch build, or no GPU); use device=cpu")
    if device.type == "mps" and not torch.backends.mps.is_available():
        raise ValueError(f"policy {name!r}: device {value!r}, but MPS is not available on this machine")


def checkpoint_dir() -> Path:
    """The directory of the shipped checkpoints (``socialnav/checkpoints``)."""
    return Path(str(resources.files("socialnav.checkpoints")))


def read_checkpoint_index() -> list[ShippedCheckpoint]:
    """Every entry of the index, including pending ones whose file is not shipped yet.

    Raises:
        ConfigError: The index is not valid (the entry and field are named).
    """
    import yaml

    source = checkpoint_dir() / INDEX_FILE
    if not source.is_file():
        return []
    try:
        data = load_yaml(source.read_text()) or {}
    except yaml.YAMLError as err:
        raise ConfigError(f"checkpoints/{INDEX_FILE}: not valid YAML: {err}") from None
    fields = {f.name for f in dataclasses.fields(ShippedCheckpoint)}
    entries = []
    for i, raw in enumerate(data.get("checkpoints") or []):
        where = f"checkpoints/{INDEX_FILE}: entry {i} ({raw.get('file') if isinstance(raw, dict) else raw!r})"
        if not isinstance(raw, dict):
            raise ConfigError(f"{where}: must be a mapping")
        unknown = sorted(set(raw) - fields)
        missing = sorted({"file", "policy", "preset", "name", "label"} - set(raw))
        if unknown or missing:
            raise ConfigError(f"{where}: unknown field(s) {unknown}, missing field(s) {missing}")
        entry = ShippedCheckpoint(**{k: ("" if k == "notes" and v is None else v) for k, v in raw.items()})
        if entry.variant not in VARIANTS:
            raise ConfigError(f"{where}: variant {entry.variant!r} must be one of {', '.join(VARIANTS)}")
        entries.append(entry)
    keys = [(e.preset, e.name) for e in entries]
    duplicates = sorted({k for k in keys if keys.count(k) > 1})
    if duplicates:
        raise ConfigError(f"checkpoints/{INDEX_FILE}: (preset, name) used twice: {duplicates}")
    return entries


def shipped_checkpoints(preset: str | None = None) -> list[ShippedCheckpoint]:
    """The checkpoints that ship (file present), for one preset or all, in index order.

    Files without an index entry named ``<policy>_<preset>.pt`` (a registered policy) are included
    with default labels, after the indexed ones.
    """
    indexed = read_checkpoint_index()
    out = [e for e in indexed if e.exists]
    known = {e.file for e in indexed}
    for path in sorted(checkpoint_dir().iterdir(), key=lambda p: p.name):
        if path.name.endswith(".pt") and path.name not in known:
            guess = _entry_from_name(path.name)
            if guess is not None:
                out.append(guess)
    return [e for e in out if preset is None or e.preset == preset]


def unindexed_checkpoint_files() -> list[str]:
    """``.pt`` files in ``socialnav/checkpoints`` that have no index entry."""
    known = {e.file for e in read_checkpoint_index()}
    return sorted(
        p.name
        for p in checkpoint_dir().iterdir()
        if p.name.endswith(".pt") and p.name not in known
    )


def _entry_from_name(filename: str) -> ShippedCheckpoint | None:
    from socialnav.policies.registry import list_policies

    stem = filename[:-3]
    for entry in sorted(list_policies(), key=lambda e: -len(e.name)):
        if entry.learned and stem.startswith(entry.name + "_"):
            preset = stem[len(entry.name) + 1 :]
            return ShippedCheckpoint(
                file=filename,
                policy=entry.name,
                preset=preset,
                name=entry.name,
                label=default_label(entry.name),
                paper_row=default_paper_row(entry.name),
                notes="no entry in checkpoints/index.yaml",
            )
    return None


def list_shipped_checkpoints() -> list[str]:
    """File stems of the checkpoints shipped in ``socialnav/checkpoints`` (e.g. ``sarl_wang2022``)."""
    return sorted(e.file[:-3] for e in shipped_checkpoints())


def shipped_checkpoint(policy: str, preset: str, variant: str = "protocol") -> Path | None:
    """The shipped checkpoint of ``policy`` (name or alias) for ``preset`` (``variant``: see the index)."""
    policy = canonical_name(policy)  # ga3c_cadrl's checkpoint is lstm_rl's
    for entry in shipped_checkpoints(preset):
        if entry.policy == policy and entry.variant == variant:
            return entry.path
    return None


def describe_checkpoint(entry: ShippedCheckpoint) -> dict[str, Any]:
    """The index entry as a plain dict (recorded in result manifests)."""
    return {k: v for k, v in dataclasses.asdict(entry).items() if k != "pending"}

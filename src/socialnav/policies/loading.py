"""Builds the policy a command line or a preset names, loading a checkpoint for learned ones.

Shipped checkpoints are described by ``socialnav/checkpoints/index.yaml`` (file, policy, preset, result
name, display label, variant, paper row, training command, seed, notes). A ``.pt`` file there without an
index entry is still recognised when it is named ``<policy>_<preset>.pt``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

from socialnav.config import ConfigError
from socialnav.policies.base import SB3_PREFIX, Policy, get_policy_entry, make_policy
from socialnav.policies.learned_catalog import get_learned_spec
from socialnav.presets import Preset

INDEX_FILE = "index.yaml"
VARIANTS = ("protocol", "original")


def default_label(policy: str) -> str:
    """The display name of a policy in tables: its record's label for a learned one, else its name."""
    try:
        return get_learned_spec(policy).label
    except KeyError:
        return policy


def default_paper_row(policy: str) -> str | None:
    """The row of Wang et al. 2022's tables a learned policy fills, if any (its record says)."""
    try:
        return get_learned_spec(policy).paper_row
    except KeyError:
        return None


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
    *,
    allow_preset_mismatch: bool = False,
    **overrides,
) -> Policy:
    """The policy ``name`` with the preset's defaults for it, overridden by ``overrides``.

    Raises:
        KeyError: Unknown policy (the valid ones are listed).
        ValueError: A checkpoint given to a policy that does not learn, or missing for one that does;
            a checkpoint trained for another world than the preset's (unless ``allow_preset_mismatch``).
    """
    entry = get_policy_entry(name)
    params = {**preset.policy_params(name), **overrides}
    if name.startswith(SB3_PREFIX):
        if checkpoint is not None:
            raise ValueError(f"policy {name} names its model file itself and takes no --checkpoint")
        return entry.factory(preset=preset, allow_preset_mismatch=allow_preset_mismatch, **params)
    if not entry.learned:
        if checkpoint is not None:
            raise ValueError(f"policy {name!r} is not learned and takes no --checkpoint")
        return make_policy(name, **params)
    if checkpoint is None:
        checkpoint = shipped_checkpoint(name, preset.name)
        if checkpoint is None:
            raise ValueError(
                f"policy {name!r} is learned and no checkpoint of it ships for preset "
                f"{preset.name!r} (shipped: {', '.join(list_shipped_checkpoints()) or 'none'}): "
                "pass --checkpoint PATH (see `socialnav train`)"
            )
    return entry.factory(
        checkpoint=Path(checkpoint), preset=preset, allow_preset_mismatch=allow_preset_mismatch, **params
    )


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
        data = yaml.safe_load(source.read_text()) or {}
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
    from socialnav.policies.base import list_policies

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
    """The shipped checkpoint of ``policy`` trained for ``preset`` (``variant``: see the index), if any."""
    for entry in shipped_checkpoints(preset):
        if entry.policy == policy and entry.variant == variant:
            return entry.path
    return None


def describe_checkpoint(entry: ShippedCheckpoint) -> dict[str, Any]:
    """The index entry as a plain dict (recorded in result manifests)."""
    return {k: v for k, v in dataclasses.asdict(entry).items() if k != "pending"}

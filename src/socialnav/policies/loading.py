"""Builds the policy a command line or a preset names, loading a checkpoint for learned ones."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from socialnav.policies.base import Policy, get_policy_entry, make_policy
from socialnav.presets import Preset


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


def list_shipped_checkpoints() -> list[str]:
    """Names ``<policy>_<preset>`` of the checkpoints shipped in ``socialnav/checkpoints``."""
    return sorted(
        p.name[:-3] for p in resources.files("socialnav.checkpoints").iterdir() if p.name.endswith(".pt")
    )


def shipped_checkpoint(policy: str, preset: str) -> Path | None:
    """The shipped checkpoint trained by `socialnav train` for (policy, preset), if any."""
    path = resources.files("socialnav.checkpoints") / f"{policy}_{preset}.pt"
    return Path(str(path)) if path.is_file() else None

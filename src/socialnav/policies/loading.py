"""Builds the policy a command line or a preset names, loading a checkpoint for learned ones."""

from __future__ import annotations

from pathlib import Path

from socialnav.policies.base import Policy, get_policy_entry, make_policy
from socialnav.presets import Preset


def build_policy(name: str, preset: Preset, checkpoint: str | Path | None = None, **overrides) -> Policy:
    """The policy ``name`` with the preset's defaults for it, overridden by ``overrides``.

    Raises:
        KeyError: Unknown policy (the valid ones are listed).
        ValueError: A checkpoint given to a policy that does not learn, or missing for one that does.
    """
    entry = get_policy_entry(name)
    params = {**preset.policy_params(name), **overrides}
    if not entry.learned:
        if checkpoint is not None:
            raise ValueError(f"policy {name!r} is not learned and takes no --checkpoint")
        return make_policy(name, **params)
    if checkpoint is None:
        raise ValueError(f"policy {name!r} is learned: pass --checkpoint PATH (see `socialnav train`)")
    return entry.factory(checkpoint=Path(checkpoint), preset=preset, **params)

"""Checkpoints of learned value networks: atomic save, safe (``weights_only``) load with checks.

A checkpoint is a plain dict (tensors, numbers, strings, lists, dicts only, so that
``torch.load(..., weights_only=True)`` can read it without executing code)::

    {"format": "socialnav.learned/1", "policy": "sarl", "input_dim": 13,
     "model_kwargs": {...constructor arguments...}, "state_dict": {...},
     "config": {...resolved settings...}, "extra": {...epoch, metrics...}, "torch_version": "2.x"}
"""

from __future__ import annotations

import dataclasses
import enum
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch
from torch import nn

from socialnav.policies.learned.registry import LEARNED_POLICIES, build, canonical_name

__all__ = [
    "FORMAT",
    "Checkpoint",
    "CheckpointError",
    "save_checkpoint",
    "load_checkpoint",
    "LEARNED_POLICIES",
    "build",
]

FORMAT = "socialnav.learned/1"


class CheckpointError(ValueError):
    """A checkpoint that cannot be used where it was asked for."""


@dataclass(frozen=True)
class Checkpoint:
    """A loaded checkpoint: the rebuilt network (eval mode) and what was saved with it."""

    policy: str
    input_dim: int
    model: nn.Module
    config: dict[str, Any]
    extra: dict[str, Any]


def _plain(x: Any, where: str) -> Any:
    """Convert to types ``weights_only`` loading accepts; refuse anything else."""
    if x is None or isinstance(x, torch.Tensor):
        return x
    for t in (bool, int, float, str):  # also turns subclasses (np.float64, IntEnum…) into builtins
        if isinstance(x, t) and not isinstance(x, enum.Enum):
            return t(x)
    if isinstance(x, enum.Enum):
        return _plain(x.value, where)
    if isinstance(x, os.PathLike):
        return os.fspath(x)
    if dataclasses.is_dataclass(x) and not isinstance(x, type):
        return {f.name: _plain(getattr(x, f.name), f"{where}.{f.name}") for f in dataclasses.fields(x)}
    if isinstance(x, dict):
        return {str(k): _plain(v, f"{where}.{k}") for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v, f"{where}[{i}]") for i, v in enumerate(x)]
    if hasattr(x, "item") and hasattr(x, "dtype"):  # NumPy scalar
        return x.item()
    if hasattr(x, "tolist"):  # NumPy array
        return x.tolist()
    raise TypeError(f"cannot store {type(x).__name__} at {where} in a checkpoint (plain data only)")


def save_checkpoint(
    path: str | os.PathLike[str],
    policy_name: str,
    model: nn.Module,
    config: dict[str, Any] | None = None,
    extra: dict[str, Any] | None = None,
) -> Path:
    """Save a network atomically (temporary file in the same folder, then ``os.replace``).

    Args:
        path: destination file.
        policy_name: registry name (``ga3c_cadrl`` is stored as ``lstm_rl``).
        model: the value network (must provide ``model_kwargs()`` and ``input_dim``).
        config: resolved settings (plain data; dataclasses are converted).
        extra: anything else worth keeping (epoch, validation metrics…), plain data.

    Returns:
        The path written.
    """
    name = canonical_name(policy_name)
    if name not in LEARNED_POLICIES:
        raise KeyError(f"unknown learned policy {policy_name!r}; known: {sorted(LEARNED_POLICIES)}")
    payload = {
        "format": FORMAT,
        "policy": name,
        "input_dim": int(model.input_dim),  # type: ignore[arg-type]
        "model_kwargs": _plain(model.model_kwargs(), "model_kwargs"),  # type: ignore[operator]
        "state_dict": {k: v.detach().cpu().clone() for k, v in model.state_dict().items()},
        "config": _plain(config or {}, "config"),
        "extra": _plain(extra or {}, "extra"),
        "torch_version": str(torch.__version__),
    }
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            torch.save(payload, f)
            f.flush()
            os.fsync(f.fileno())
        from socialnav.evaluate.files import default_file_mode

        os.chmod(tmp, default_file_mode())  # as open() would, not mkstemp's 0600
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


def load_checkpoint(
    path: str | os.PathLike[str],
    expected_policy: str,
    expected_input_dim: int | None = None,
    map_location: str | torch.device = "cpu",
) -> Checkpoint:
    """Load a checkpoint with ``torch.load(..., weights_only=True)`` and rebuild its network.

    Args:
        path: checkpoint file.
        expected_policy: the policy the caller wants (``ga3c_cadrl`` and ``lstm_rl`` are the same).
        expected_input_dim: per-human input size wanted; default: that of a freshly built
            ``expected_policy`` with default settings (13, or 61 for om_sarl).
        map_location: device for the tensors.

    Raises:
        CheckpointError: not a socialnav checkpoint, or it holds another policy or input size; the
            message names both, e.g. "checkpoint x.pt holds policy 'cadrl' (input 13), expected
            'sarl' (input 13)".
    """
    path = Path(path)
    payload = torch.load(path, map_location=map_location, weights_only=True)
    if not isinstance(payload, dict) or payload.get("format") != FORMAT:
        raise CheckpointError(f"{path} is not a socialnav learned-policy checkpoint (format {FORMAT!r})")
    want = canonical_name(expected_policy)
    if expected_input_dim is None:
        expected_input_dim = int(build(want).input_dim)  # type: ignore[arg-type]
    got, got_dim = str(payload["policy"]), int(payload["input_dim"])
    if got != want or got_dim != expected_input_dim:
        raise CheckpointError(
            f"checkpoint {path.name} holds policy {got!r} (input {got_dim}), "
            f"expected {expected_policy!r} (input {expected_input_dim})"
        )
    model = build(got, **payload["model_kwargs"])
    model.load_state_dict(payload["state_dict"], strict=True)
    model.to(map_location).eval()
    return Checkpoint(
        policy=got, input_dim=got_dim, model=model, config=payload["config"], extra=payload["extra"]
    )

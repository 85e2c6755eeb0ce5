"""Checkpoints of learned value networks: atomic save, safe (``weights_only``) load with checks.

A checkpoint is a plain dict (tensors, numbers, strings, lists, dicts only, so that
``torch.load(..., weights_only=True)`` can read it without executing code)::

    {"format": "socialnav.learned/1", "policy": "sarl", "input_dim": 13,
     "model_kwargs": {...constructor arguments...}, "state_dict": {...},
     "config": {...resolved settings...}, "extra": {...epoch, metrics...}, "torch_version": "2.x",
     "socialnav_version": "0.2.0", "predictor": None or {"model_kwargs": {...}, "state_dict": {...}}}

``predictor`` holds the learned state predictor (RGL's), saved with every network trained with the
``learned`` information setting (and always with ``mp_rgl``). ``socialnav_version`` is the release
that wrote the file (absent from checkpoints written before 0.2.0).
"""

from __future__ import annotations

import dataclasses
import enum
import os
import pickle
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch
from torch import nn

from socialnav import __version__
from socialnav._io import atomic_write
from socialnav.policies.learned.networks import LEARNED_POLICIES, build
from socialnav.policies.learned_catalog import canonical_name

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
    predictor: nn.Module | None = None  # the learned state predictor, when the run trained one
    socialnav_version: str | None = None  # the release that wrote it; None before 0.2.0 recorded it


def _recorded_version(payload: dict) -> str | None:
    version = payload.get("socialnav_version")
    return version if isinstance(version, str) else None


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
    predictor: nn.Module | None = None,
) -> Path:
    """Save a network atomically (temporary file in the same folder, then ``os.replace``).

    Args:
        path: destination file.
        policy_name: registry name (``ga3c_cadrl`` is stored as ``lstm_rl``).
        model: the value network (must provide ``model_kwargs()`` and ``input_dim``).
        config: resolved settings (plain data; dataclasses are converted).
        extra: anything else worth keeping (epoch, validation metrics…), plain data.
        predictor: the learned state predictor to store beside the network, if any.

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
        "socialnav_version": __version__,
        "predictor": None
        if predictor is None
        else {
            "model_kwargs": _plain(predictor.model_kwargs(), "predictor.model_kwargs"),  # type: ignore[operator]
            "state_dict": {k: v.detach().cpu().clone() for k, v in predictor.state_dict().items()},
        },
    }
    def write(tmp: str) -> None:
        with open(tmp, "wb") as f:
            torch.save(payload, f)
            f.flush()
            os.fsync(f.fileno())

    path = Path(path)
    atomic_write(path, write)
    return path


#: Fields of a checkpoint and the type each must have.
_FIELDS = {
    "policy": str,
    "input_dim": int,
    "model_kwargs": dict,
    "state_dict": dict,
    "config": dict,
    "extra": dict,
}


def _one_line(err: BaseException, limit: int = 300) -> str:
    text = " ".join(str(err).split()) or type(err).__name__
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _read_payload(path: Path, map_location: str | torch.device) -> dict[str, Any]:
    """The checkpoint's dict, its fields checked; every way a file can be unusable is a CheckpointError."""
    if path.is_dir():
        raise CheckpointError(f"checkpoint {path} is a directory, not a checkpoint file")
    if not path.exists():
        raise CheckpointError(f"checkpoint {path} does not exist")
    if path.stat().st_size == 0:
        raise CheckpointError(f"checkpoint {path} is empty")
    try:
        payload = torch.load(path, map_location=map_location, weights_only=True)
    except OSError as err:
        if Path(path).is_file():  # torch reads a truncated zip archive as an I/O error (Errno 22)
            raise CheckpointError(f"checkpoint {path} is damaged or truncated (reading it failed: "
                                  f"{_one_line(err)})") from None
        raise CheckpointError(f"checkpoint {path} cannot be read: {_one_line(err)}") from None
    except Exception as err:  # unpickling a damaged, foreign or crafted file fails in many ways
        if _saved_by_sb3(path):
            raise CheckpointError(
                f"checkpoint {path} is a Stable-Baselines3 model: evaluate it with --policy sb3:{path}"
            ) from None
        if not isinstance(err, pickle.UnpicklingError):
            raise CheckpointError(
                f"checkpoint {path} is damaged or not a torch file ({type(err).__name__}: {_one_line(err)})"
            ) from None
        # weights_only names the object it refused ("GLOBAL posix.system"); any other refusal (an opcode it
        # does not know) is a damaged file. torch's own message advises weights_only=False, which would run
        # whatever the file names: never repeat that advice.
        refused = re.search(r"GLOBAL ([\w.]+)", _one_line(err, limit=4000))
        if refused is None:
            raise CheckpointError(f"checkpoint {path} is damaged or not a torch file (it is not a pickle "
                                  "of tensors and plain values)") from None
        raise CheckpointError(
            f"checkpoint {path} is refused: it holds the object {refused.group(1)}, and socialnav loads only "
            "tensors and plain values from a checkpoint (an object could run code when read); it was not "
            "written by socialnav"
        ) from None
    if not isinstance(payload, dict) or payload.get("format") != FORMAT:
        if not isinstance(payload, dict):
            found = f"it holds a {type(payload).__name__}"
        else:
            found = f"its format is {payload['format']!r}" if "format" in payload else "it records no format"
        raise CheckpointError(f"{path} is not a socialnav learned-policy checkpoint: {found}, expected "
                              f"format {FORMAT!r}")
    for key, kind in _FIELDS.items():
        value = payload.get(key)
        if not isinstance(value, kind) or isinstance(value, bool):
            raise CheckpointError(
                f"checkpoint {path}: field {key!r} must be a {kind.__name__}, got {_describe(value)}"
            )
    return payload


def _saved_by_sb3(path: Path) -> bool:
    """Whether ``path`` is a zip archive as Stable-Baselines3's ``model.save`` writes (a ``data`` member)."""
    import zipfile

    try:
        with zipfile.ZipFile(path) as archive:
            return "data" in archive.namelist()
    except (OSError, zipfile.BadZipFile):
        return False


def _describe(value: Any) -> str:
    if value is None:
        return "nothing (missing)"
    return f"{type(value).__name__} {_one_line(Exception(repr(value)), 60)}"


def _require_finite_weights(path: Path, field: str, state_dict: dict) -> None:
    """Refuse a network with a NaN or infinite weight, naming the tensor.

    Such a network scores every action NaN and picks one arbitrarily: its evaluation would be a table of
    numbers with no meaning.
    """
    for name, tensor in state_dict.items():
        if torch.is_tensor(tensor) and tensor.is_floating_point() and not bool(torch.isfinite(tensor).all()):
            bad = int((~torch.isfinite(tensor)).sum())
            raise CheckpointError(
                f"checkpoint {path}: {field}[{name!r}] holds {bad} non-finite value(s) "
                f"(NaN or inf) of {tensor.numel()}; the training run that wrote it diverged"
            )


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
            ``expected_policy`` with default settings (13, or 61 for om_sarl); -1 accepts any size
            (networks whose input size is a constructor setting, e.g. crowdnav_pp's prediction steps).
        map_location: device for the tensors.

    Raises:
        CheckpointError: missing, empty, damaged or not a socialnav checkpoint (a field of the wrong
            type is named), or it holds another policy or input size; the
            message names both, e.g. "checkpoint x.pt holds policy 'cadrl', expected 'sarl' (load it
            as 'cadrl', e.g. --policy cadrl)".
    """
    path = Path(path)
    payload = _read_payload(path, map_location)
    want = canonical_name(expected_policy)
    if expected_input_dim is None:
        expected_input_dim = int(build(want).input_dim)  # type: ignore[arg-type]
    got, got_dim = payload["policy"], payload["input_dim"]
    if expected_input_dim == -1 and got == want:
        expected_input_dim = got_dim
    if got != want:
        raise CheckpointError(
            f"checkpoint {path} holds policy {got!r}, expected {expected_policy!r} (load it as {got!r}, "
            f"e.g. --policy {got})"
        )
    if got_dim != expected_input_dim:
        raise CheckpointError(
            f"checkpoint {path} holds policy {got!r} with input size {got_dim} per human, expected "
            f"{expected_input_dim}"
        )
    try:
        model = build(got, **payload["model_kwargs"])
        model.load_state_dict(payload["state_dict"], strict=True)
    except (TypeError, ValueError, KeyError, RuntimeError) as err:
        raise CheckpointError(
            f"checkpoint {path}: its network cannot be rebuilt ({_one_line(err)})"
        ) from None
    _require_finite_weights(path, "state_dict", payload["state_dict"])
    model.to(map_location).eval()
    predictor = None
    if payload.get("predictor") is not None:
        from socialnav.policies.learned.predictor import StatePredictor

        predictor = StatePredictor(**payload["predictor"]["model_kwargs"])
        predictor.load_state_dict(payload["predictor"]["state_dict"], strict=True)
        _require_finite_weights(path, "predictor.state_dict", payload["predictor"]["state_dict"])
        predictor.to(map_location).eval()
    return Checkpoint(
        policy=got,
        input_dim=got_dim,
        model=model,
        config=payload["config"],
        extra=payload["extra"],
        predictor=predictor,
        socialnav_version=_recorded_version(payload),
    )

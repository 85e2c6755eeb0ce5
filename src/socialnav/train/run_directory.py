"""A training run's directory: what every trainer does with it, kept once.

Every trainer's setup takes the same steps, in this order, so that a refused run leaves nothing behind:

1. build what the run needs (network, worlds) from its settings and seeds (:func:`derive_seeds`,
   :func:`run_device`), and its record (:func:`run_record`: trainer, policy, preset, settings, seeds);
2. :func:`open_run_directory`: refuse an evaluation's or a sweep's directory, create the directory,
   take its lock (a second run on it is refused), delete a killed writer's temporaries, refuse a
   directory holding another trainer's run, and check this run against the one found there: its
   ``last.pt`` (a training state of this policy, with the same settings but those the trainer lets
   change), or, for a run killed before its first ``last.pt``, its ``config.json``;
3. restore the state it found (the trainer's own business);
4. :func:`start_run_files`: write the record (``config.json``, ``config.yaml``), say where the run
   trains, and open ``curves.csv`` (trimmed to the resumed point).

Importing this module does not import torch.
"""

from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from socialnav._io import (
    DirectoryLock,
    atomic_write_json,
    atomic_write_text,
    make_output_dir,
    remove_orphan_temporaries,
)
from socialnav.evaluate.manifest import refuse_other_kind
from socialnav.settings import ConfigError
from socialnav.train.curves import Curves
from socialnav.train.settings_files import record_trainer

#: A run's record: its trainer, policy, preset, settings and seeds (also every checkpoint's ``config``).
RECORD = "config.json"


class RunFiles:
    """The files of a training run directory.

    A mixin: the run (a frozen dataclass) provides ``out``, the run directory.
    """

    out: Path

    @property
    def last_path(self) -> Path:
        """last.pt: the latest training state (resumption)."""
        return self.out / "last.pt"

    @property
    def best_path(self) -> Path:
        """best.pt: the best validation so far."""
        return self.out / "best.pt"

    @property
    def curves_path(self) -> Path:
        """curves.csv: one row per logged episode or update."""
        return self.out / "curves.csv"


def derive_seeds(seed: int) -> dict[str, int]:
    """Independent seeds for the parts of a run, derived from the master seed.

    ``scenario_start`` is the first training-episode index (disjoint ranges of 10 M episodes per
    master seed; validation uses the ``val`` split, indices 0..val_episodes-1, whatever the seed).
    """
    exploration, init, sampling = (
        int(x) for x in np.random.SeedSequence([int(seed), 0x50C1A1]).generate_state(3)
    )
    return {
        "scenario_start": int(seed) * 10_000_000,
        "exploration": exploration,
        "init": init,
        "sampling": sampling,
    }


def resolve_device(name: str) -> Any:
    """The torch device a training setting ``device`` names.

    Args:
        name: ``auto`` (CUDA when available, else CPU), ``cpu``, ``cuda`` or any torch device name.

    Returns:
        The ``torch.device``.

    Raises:
        RuntimeError: ``cuda`` was asked for and CUDA is not available.
    """
    import torch

    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if name == "cuda" and not torch.cuda.is_available():
        raise RuntimeError(
            "device 'cuda' requested but torch.cuda.is_available() is False (use --device cpu)"
        )
    return torch.device(name)


def run_device(settings: Any) -> Any:
    """The run's torch device (setting ``device``), torch's threads set (``threads``; 0: all cores, ≤ 8).

    Raises:
        RuntimeError: ``cuda`` was asked for and CUDA is not available.
    """
    import torch

    device = resolve_device(settings.device)
    torch.set_num_threads(settings.threads or max(1, min(os.cpu_count() or 1, 8)))
    return device


def plain(record: Any) -> Any:
    """``record`` as JSON-plain data (tuples as lists, anything else unknown as its ``str``)."""
    return json.loads(json.dumps(record, default=lambda v: list(v) if isinstance(v, tuple) else str(v)))


def run_record(trainer: str, checkpoint_record: Mapping[str, Any], policy: str, preset: Any, settings: Any,
               seeds: Mapping[str, int], **extra: Any) -> dict[str, Any]:
    """A run's record (``config.json``; every checkpoint's ``config``), as JSON-plain data.

    Args:
        trainer: the trainer's name.
        checkpoint_record: ``{kind: record}``, what loading the checkpoints reads (``value_policy``
            or ``ppo_policy``: the world and how the policy acts).
        policy: the policy trained (as asked: an alias is kept).
        preset: the preset trained under.
        settings: the trainer's settings (``train``).
        seeds: the derived seeds.
        **extra: more entries, after the seeds (humans per episode, stream offsets).

    Returns:
        The record: the checkpoint record, trainer, policy, preset, train, seeds, extra, kinematics.
    """
    return plain({
        **checkpoint_record,
        "trainer": trainer,
        "policy": policy,
        "preset": preset.to_dict(),
        "train": settings.to_dict(),
        "seeds": dict(seeds),
        **extra,
        "kinematics": preset.world.kinematics,
    })


def recorded_config(out: Path) -> dict[str, Any] | None:
    """The record a run wrote in ``<out>/config.json`` when it started, or None where there is none.

    A run killed before its first ``last.pt`` leaves only this record (and its trainer's early
    files): another run started into the directory must be checked against it, or it would
    overwrite that run.

    Raises:
        ConfigError: The record is not a JSON object.
    """
    path = out / RECORD
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError) as err:
        raise ConfigError(f"{path}: the run's record cannot be read ({err}); move the directory away or "
                          "use another --out") from None
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: the run's record is not a JSON object; use another --out")
    return data


def dotted(data: Any, key: str) -> Any:
    """The value at a dotted key (``train.seed``) of nested dicts, or None."""
    for part in key.split("."):
        data = data.get(part) if isinstance(data, dict) else None
    return data


def refuse_other_settings(saved: dict[str, Any], config: dict[str, Any], diff: list[str], out: Path) -> None:
    """Refuses a resume where ``diff`` (dotted keys) is not empty, naming each key's two values.

    The one message of every trainer; each decides which keys may change.

    Raises:
        ConfigError: ``diff`` names keys.
    """
    if diff:
        # what changes the training first (another policy, then the world and the robot), not the 6th of 30
        # behind the preset's name, description and evaluation settings
        def weight(key: str) -> int:
            if key == "policy":
                return 0
            if key.startswith(("preset.world.", "preset.robot.", "preset.training.", "train.")):
                return 1
            return 2 if key.startswith("preset.") else 1

        diff = sorted(diff, key=weight)  # (stable: each group keeps its order)
        changes = "; ".join(f"{k}: {dotted(saved, k)!r} -> {dotted(config, k)!r}" for k in diff[:6])
        raise ConfigError(
            f"{out} holds a run with other settings ({changes}"
            f"{f'; and {len(diff) - 6} more' if len(diff) > 6 else ''}); use another --out, or the run's own "
            f"settings: its config.yaml (--config) and the preset it was trained under (--preset)"
        )


def check_record(saved: dict[str, Any], config: dict[str, Any], out: Path,
                 diff: Callable[[dict[str, Any], dict[str, Any]], list[str]]) -> None:
    """Refuses to go on with a run directory whose record differs from this run's where ``diff`` says.

    A record written before records named their trainer is read as naming the one its checkpoint
    record stands for (``value_policy``: value, ``ppo_policy``: ppo).

    Args:
        saved: the run directory's record (``config.json`` or a checkpoint's ``config``).
        config: this run's record.
        out: the run directory.
        diff: the trainer's comparison: the dotted keys that differ and may not.

    Raises:
        ConfigError: another trainer's run, or other settings (each key named with both values).
    """
    if "trainer" not in saved and record_trainer(saved) is not None:
        saved = {**saved, "trainer": record_trainer(saved)}
    refuse_another_trainer(saved, config, out)
    refuse_other_settings(saved, config, diff(saved, config), out)


def refuse_another_trainer(saved: dict[str, Any], config: dict[str, Any], out: Path) -> None:
    """Refuses a run directory that holds another trainer's run, naming both trainers and its policy.

    Raises:
        ConfigError: its record names another trainer than this run's.
    """
    theirs, ours = record_trainer(saved), record_trainer(config)
    if theirs is not None and theirs != ours:
        raise ConfigError(f"{out} holds a run of the {theirs!r} trainer (policy {saved.get('policy')!r}), "
                          f"and {config.get('policy')!r} trains with the {ours!r} trainer: use another --out")


def load_resume_checkpoint(last_path: Path, policy: str, out: Path, **kwargs: Any) -> Any:
    """A run directory's ``last.pt``, refused naming the directory when it holds another policy's run.

    Args:
        last_path: The run's ``last.pt``.
        policy: The policy being trained.
        out: The run directory.
        **kwargs: Passed to :func:`~socialnav.policies.learned.load_checkpoint`.

    Returns:
        The checkpoint.

    Raises:
        ConfigError: The directory holds a run of another policy.
        CheckpointError: The file is damaged.
    """
    from socialnav.policies.learned import load_checkpoint
    from socialnav.policies.learned.checkpoint import CheckpointError

    try:
        return load_checkpoint(last_path, policy, **kwargs)
    except CheckpointError as err:
        if " holds policy " not in str(err):
            raise
        raise ConfigError(f"{out} holds a training run of another policy ({err}); train {policy!r} into "
                          "another --out, or move that run away") from None


@dataclass(frozen=True)
class Found:
    """What a run directory held: the checkpoint of the run to resume, or nothing to resume.

    Attributes:
        checkpoint: ``last.pt`` loaded, or None (a new run, or one killed before its first ``last.pt``).
        resume: its ``extra["resume"]`` record (the trainer's state), or None.
    """

    checkpoint: Any
    resume: dict[str, Any] | None


def open_run_directory(
    out: Path,
    config: dict[str, Any],
    stack: contextlib.ExitStack,
    *,
    policy: str,
    diff: Callable[[dict[str, Any], dict[str, Any]], list[str]],
    **load_kwargs: Any,
) -> Found:
    """Takes the run directory and checks this run against the one it holds.

    Nothing is written but the directory and its lock.

    Args:
        out: the run directory (created).
        config: this run's record (:func:`run_record`).
        stack: releases the lock when the training call ends.
        policy: the policy trained (its canonical name: what checkpoints store).
        diff: the trainer's comparison of a saved record with this one (:func:`check_record`).
        **load_kwargs: passed to :func:`~socialnav.policies.learned.load_checkpoint` (``map_location``).

    Returns:
        ``last.pt`` and its resume record, when the run goes on.

    Raises:
        ResumeMismatchError: an evaluation's or a sweep's directory.
        DirectoryLockedError: another training is writing to ``out``.
        ConfigError: another trainer's or policy's run, a ``last.pt`` that is not a training state, or
            a run with other settings.
    """
    refuse_other_kind(out, "training")  # an evaluation's or a sweep's directory: not written into
    make_output_dir(out)
    stack.enter_context(DirectoryLock(out, "training"))
    remove_orphan_temporaries(out)
    recorded = recorded_config(out)  # a run killed before its first last.pt: not to be overwritten
    if recorded is not None:
        refuse_another_trainer(recorded, config, out)
    last_path = out / "last.pt"
    if last_path.exists():
        ck = load_resume_checkpoint(last_path, policy, out, **load_kwargs)
        resume = ck.extra.get("resume")
        if not isinstance(resume, dict):
            raise ConfigError(
                f"{last_path} is not a training state (no 'resume' record); move it away to restart"
            )
        check_record(ck.config, config, out, diff)
        return Found(ck, resume)
    if recorded is not None:
        check_record(recorded, config, out, diff)
    return Found(None, None)


def start_run_files(
    out: Path,
    config: dict[str, Any],
    stack: contextlib.ExitStack,
    *,
    say: Callable[[str], None],
    banner: str,
    resumed_at: int | None,
    columns: tuple[str, ...] | None = None,
    key: str = "episode",
) -> Curves:
    """Writes the run's record, says where it trains, and opens its ``curves.csv``.

    ``config.yaml`` keeps the device as asked (``auto`` resumes anywhere); ``banner`` says which one
    runs.

    Args:
        out: the run directory (taken by :func:`open_run_directory`).
        config: the run's record.
        stack: closes the curves when the training call ends.
        say: where the line goes.
        banner: the line (``training sarl under preset 'wang2022' on cpu into runs/x``).
        resumed_at: the ``key`` value the run resumes at (rows past it are dropped), or None.
        columns: the curves' columns (default: the value-based trainer's).
        key: the column that counts the run's progress (``episode``, ``update``).

    Returns:
        The curves.
    """
    import yaml

    atomic_write_json(out / RECORD, config)
    atomic_write_text(out / "config.yaml", yaml.safe_dump(config, sort_keys=False))
    say(banner)
    shape = {} if columns is None else {"columns": columns}
    curves = Curves(out / "curves.csv", resumed_at, **shape, key=key)
    stack.callback(curves.close)
    if curves.dropped:
        say(f"{out / 'curves.csv'}: {curves.dropped} damaged row(s) left out")
    return curves

"""A run's manifest: what it consists of, its fingerprint, and whether a directory may be resumed.

``manifest.json`` records the preset, the policy (with the hashes of a user policy's sources), the
cells, the chunk and batch sizes and whether trajectories are kept. Its fingerprint
(:func:`manifest_stamp`) is stored in every chunk file. A directory is resumed only by a run with the
same identity (:func:`run_identity`: the manifest less what it records for information only); a
different one is refused with what differs (:func:`describe_differences`).
"""

from __future__ import annotations

import hashlib
import json
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from socialnav import __version__
from socialnav._io import atomic_write_json, file_sha256, remove_orphan_temporaries, short_repr
from socialnav.evaluate.chunks import (
    Chunk,
    ResumeMismatchError,
    chunk_done,
    chunk_path,
    has_results,
    refuse_foreign_chunks,
)
from socialnav.evaluate.plan import Cell
from socialnav.policies.registry import RECORDED_ONLY, Policy, policy_record
from socialnav.presets import Preset


def policy_sources(policy: Policy) -> dict[str, str]:
    """SHA-256 of what a policy from outside socialnav was built from.

    That is the source file of the module that defines its class, and every file it names in an
    optional ``source_files()`` method (a model file, say). They are in the manifest so that a resume
    never reuses the results of a policy whose code or model changed at the same path; socialnav's own
    policies are covered by the package version and their checkpoints' hashes.

    Args:
        policy: The robot policy.

    Returns:
        ``{"module": sha, <declared path>: sha, ...}``; empty for socialnav's own policies.

    Raises:
        ValueError: A declared source file does not exist.
    """
    out: dict[str, str] = {}
    module_sha = _outside_source(type(policy))  # by content: a script run and its import are one policy
    if module_sha:
        out["module"] = module_sha
    declared = getattr(policy, "source_files", None)
    for item in declared() if callable(declared) else ():
        item = Path(item)
        if not item.is_file():
            raise ValueError(
                f"policy {getattr(policy, 'name', type(policy).__module__)!r} declares source file {item}, "
                "which does not exist"
            )
        out[str(item)] = file_sha256(item)
    return out


def _outside_source(obj: Any) -> str | None:
    """SHA-256 of the source file of the module defining ``obj``, where that is outside socialnav."""
    module = getattr(obj, "__module__", None) or ""
    path = getattr(sys.modules.get(module), "__file__", None)
    if not path or module.split(".")[0] == "socialnav" or not Path(path).is_file():
        return None
    return file_sha256(path)


def extension_sources(preset: Preset, cells: list[Cell]) -> dict[str, str]:
    """SHA-256 of the modules outside socialnav that a run's humans, scenarios and metrics come from.

    Recorded in the manifest beside ``policy_sources`` so that a resume never mixes results of a pedestrian
    behaviour, scenario or metric of one's own whose code changed (or a metric added or removed: each
    registered metric from outside is a key); socialnav's own are covered by the package version.

    Returns:
        ``{"behaviour:<name>": sha, "scenario:<name>": sha, "metric:<name>": sha, ...}``; empty where
        everything is socialnav's.
    """
    from socialnav.metrics.registry import list_metrics
    from socialnav.scenarios import get_scenario
    from socialnav.sim.behaviours import human_behaviour

    out: dict[str, str] = {}
    behaviour = human_behaviour(preset.world.human_model).behaviour
    sha = None if behaviour is None else _outside_source(behaviour)
    if sha:
        out[f"behaviour:{preset.world.human_model}"] = sha
    for name in sorted({c.scenario for c in cells}):
        sha = _outside_source(get_scenario(name))
        if sha:
            out[f"scenario:{name}"] = sha
    for metric in list_metrics():
        sha = _outside_source(metric.fn)
        if sha:
            out[f"metric:{metric.name}"] = sha
    return out


def protocol_manifest(
    policy: Policy,
    preset: Preset,
    cells: list[Cell],
    label: str,
    batch_size: int,
    trajectories: bool,
    extra_manifest: dict | None = None,
) -> dict:
    """What a run consists of, as recorded in ``manifest.json`` and fingerprinted into every chunk file.

    A sweep builds the same manifest, so its job directories are ``socialnav evaluate``'s.

    Args:
        policy: The robot policy.
        preset: The protocol.
        cells: The run's cells.
        label: The policy's name in the results.
        batch_size: Episodes simulated in lockstep.
        trajectories: Whether trajectories are kept.
        extra_manifest: Extra fields (e.g. the checkpoint path and hash).

    Returns:
        The manifest, as plain JSON data.
    """
    sources = policy_sources(policy)
    extensions = extension_sources(preset, cells)
    return _normalised(
        {
            # information only (run_identity leaves it out): a run resumed by a newer release continues
            "socialnav_version": __version__,
            "preset": preset.to_dict(),
            "policy": {"label": label, **policy_record(policy)},
            **({"policy_sources": sources} if sources else {}),
            **({"extension_sources": extensions} if extensions else {}),
            "cells": [
                {"scenario": c.scenario, "visibility": c.visibility, "episodes": c.episodes} for c in cells
            ],
            "chunk_size": preset.evaluation.chunk_size,
            # replay re-simulates a whole chunk in batches of this size, so that a learned policy sees
            # the same batch composition as during the run
            "batch_size": batch_size,
            "trajectories": bool(trajectories),
            **(extra_manifest or {}),
        }
    )


def _normalised(manifest: dict) -> dict:
    return json.loads(json.dumps(manifest, default=list))


def run_identity(manifest: dict) -> dict:
    """The manifest less what it records for information only.

    That is the release that started the run and the policy's ``RECORDED_ONLY`` keys (e.g. the native
    scorer's vector kernel, whose values are bit-identical across kernels).

    Args:
        manifest: A run's manifest.

    Returns:
        What two runs must share for one to resume the other.
    """
    manifest = {k: v for k, v in manifest.items() if k != "socialnav_version"}
    policy = manifest.get("policy")
    if isinstance(policy, dict) and any(k in policy for k in RECORDED_ONLY):
        return {**manifest, "policy": {k: v for k, v in policy.items() if k not in RECORDED_ONLY}}
    return manifest


def manifest_stamp(manifest: dict) -> str:
    """Fingerprint of a run's manifest, stored in each of its chunk files.

    Args:
        manifest: A run's manifest.

    Returns:
        32 hex digits of the SHA-256 of its identity's canonical JSON.
    """
    text = json.dumps(run_identity(manifest), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:32]


def check_or_write_manifest(out: Path, manifest: dict) -> None:
    """Writes ``manifest.json``, or checks that the one there is this run's.

    The first run's record stands when the identities agree (a resume on another CPU or release
    changes no result). A different manifest without any result (e.g. a run refused right after
    starting) is replaced.

    Args:
        out: The result directory.
        manifest: This run's manifest.

    Raises:
        ResumeMismatchError: The directory holds results of a different run, or a damaged manifest.
    """
    path = out / "manifest.json"
    if path.exists():
        try:
            previous = json.loads(path.read_text())
        except (ValueError, UnicodeDecodeError) as err:
            raise ResumeMismatchError(f"{path} is damaged ({err}); use another --out or delete it") from None
        if not isinstance(previous, dict):
            raise ResumeMismatchError(f"{path} is damaged (not a JSON object but a "
                                      f"{type(previous).__name__}); use another --out or delete it")
        if run_identity(previous) == run_identity(manifest):
            return
        if has_results(out):
            differences = describe_differences(run_identity(previous), run_identity(manifest))
            if not differences:  # the same cells, listed in another order (the files are fingerprinted so)
                differences = (f"the order of the cells: {_cell_names(previous)} before, "
                               f"{_cell_names(manifest)} now; give --scenario in the previous order to "
                               "resume")
            raise ResumeMismatchError(
                f"{out} holds results of a different run (differs in: {differences}); "
                "use another --out directory or delete it" + _same_checkpoint_hint(previous, manifest)
            )
    atomic_write_json(path, manifest)


@dataclass(frozen=True)
class ResumePlan:
    """Which chunks of a run are finished and which are left, in cell and index order.

    Attributes:
        done: Chunks whose files exist (not yet read: the caller verifies them when it reads them).
        todo: Chunks to compute.
    """

    done: list[Chunk]
    todo: list[Chunk]


def resume_directory(
    out: Path, manifest: dict, cells: list[Cell], chunk_size: int, trajectories: bool
) -> ResumePlan:
    """Prepares a locked result directory for a run and decides what is left to compute.

    Removes the temporaries an interrupted write left, writes or checks the manifest, and refuses
    episode files of another run. Call it while holding the directory's lock.

    Args:
        out: The result directory (it exists).
        manifest: This run's manifest.
        cells: The run's cells.
        chunk_size: Episodes per chunk.
        trajectories: Whether the run keeps trajectories (a chunk lacking its trajectory file is left).

    Returns:
        The finished chunks and those left.

    Raises:
        ResumeMismatchError: The directory holds a different run's results.
    """
    remove_orphan_temporaries(out)
    check_or_write_manifest(out, manifest)
    expected = {chunk_path(out, c, a, b): (c, a, b) for c in cells for a, b in c.chunks(chunk_size)}
    refuse_foreign_chunks(out, expected)
    done: list[Chunk] = []
    todo: list[Chunk] = []
    for cell, a, b in expected.values():
        (done if chunk_done(out, cell, a, b, trajectories) else todo).append((cell, a, b))
    return ResumePlan(done, todo)


def _cell_names(manifest: dict) -> str:
    cells = manifest.get("cells") if isinstance(manifest, dict) else None
    if not isinstance(cells, list):
        return "?"
    return ", ".join(f"{c.get('scenario')}/{c.get('visibility')}" for c in cells if isinstance(c, dict))


#: What marks each kind of result directory: one policy's run, ``evaluate --policy all``'s, a
#: reproduction's.
_KIND_MARKS = {"one policy": "manifest.json", "several policies": "policies",
               "reproduction": "reproduction.json", "training": "curves.csv", "sweep": "sweep.json"}


def refuse_other_kind(out: Path, kind: str) -> None:
    """Refuses a result directory that holds another kind of run than ``kind`` (see :data:`_KIND_MARKS`).

    Their top-level files share names (summary.json, table2.md, ...): one kind's run would overwrite the
    other's conclusion without a word.

    Raises:
        ResumeMismatchError: ``out`` holds another kind of run, named.
    """
    for other, mark in _KIND_MARKS.items():
        if other != kind and (out / mark).exists():
            raise ResumeMismatchError(f"{out} holds the results of {_KIND_NAMES[other]} ({mark}); this is "
                                      f"{_KIND_NAMES[kind]}: use another --out")


_KIND_NAMES = {"one policy": "an evaluation of one policy", "several policies": "`evaluate --policy all`",
               "reproduction": "`socialnav reproduce`", "training": "a training run (`socialnav train`)",
               "sweep": "a sweep (`socialnav sweep`)"}


def _same_checkpoint_hint(previous: dict, manifest: dict) -> str:
    """Where only the checkpoint's path string differs and its content is the same: how to resume."""
    def without_paths(m: dict) -> dict:
        policy = {k: v for k, v in (m.get("policy") or {}).items() if k != "checkpoint"}
        return {**{k: v for k, v in run_identity(m).items() if k != "checkpoint"}, "policy": policy}

    same_file = previous.get("checkpoint_sha256") and previous.get("checkpoint_sha256") == manifest.get(
        "checkpoint_sha256")
    if not same_file or without_paths(previous) != without_paths(manifest):
        return ""
    return (f" - or resume it: the checkpoint is the same file (SHA-256 equal) given as another path; give "
            f"--checkpoint {previous.get('checkpoint')} as the run did")


def describe_differences(old: Any, new: Any, limit: int = 6) -> str:
    """What differs between two manifests, e.g. ``cells[circle_crossing/visible].episodes: 10 -> 20``.

    Args:
        old: The previous run's manifest (or a part of it).
        new: This run's.
        limit: At most this many differences are named; the rest are counted.

    Returns:
        The differences, separated by ``; ``.
    """
    found: list[str] = []
    _diff(old, new, "", found)
    shown = "; ".join(found[:limit])
    return shown + (f"; and {len(found) - limit} more" if len(found) > limit else "")


def _diff(old: Any, new: Any, where: str, found: list[str]) -> None:
    if isinstance(old, dict) and isinstance(new, dict):
        if where == "" or not _is_cells(old, new):
            for key in [*old, *(k for k in new if k not in old)]:
                sub = f"{where}.{key}" if where else str(key)
                if key not in new:
                    found.append(f"{sub} only in the previous run")
                elif key not in old:
                    found.append(f"{sub} only in this run")
                else:
                    _diff(old[key], new[key], sub, found)
            return
    if isinstance(old, list) and isinstance(new, list) and _is_cells(old, new):
        # cells are compared by (scenario, visibility), so a cell added or removed is named as such
        before = {f"{c['scenario']}/{c['visibility']}": c for c in old}
        after = {f"{c['scenario']}/{c['visibility']}": c for c in new}
        for key in [*before, *(k for k in after if k not in before)]:
            if key not in after:
                found.append(f"{where}: {key} only in the previous run")
            elif key not in before:
                found.append(f"{where}: {key} only in this run")
            else:
                _diff(before[key], after[key], f"{where}[{key}]", found)
        return
    if old != new:
        found.append(f"{where}: {_short(old)} -> {_short(new)}")


def _is_cells(old: Any, new: Any) -> bool:
    items = [*old, *new] if isinstance(old, list) and isinstance(new, list) else []
    return bool(items) and all(isinstance(c, dict) and {"scenario", "visibility"} <= set(c) for c in items)


def _short(value: Any) -> str:
    return short_repr(value, 60, json_style=True)

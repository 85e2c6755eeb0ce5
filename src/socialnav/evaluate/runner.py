"""The protocol runner: simulate every cell of a preset with one policy, score, aggregate, write.

Results live in an output directory:

    manifest.json                  what was run (preset, policy, cells); checked on resume
    episodes/<cell>/<a>-<b>.parquet  one row per episode (ids, outcome, every metric), atomic
    trajectories/<cell>/<a>-<b>.parquet  every episode's trajectory (docs/trajectory_format.md), unless
                                   trajectories=False; episode keys "<scenario>/<visibility>/<index>"
    summary.json / summary.csv     per (policy, scenario, visibility) and pooled aggregates
    table2.md / table2.tex         the paper's Table II layout (+ per-scenario tables)
    table3.md / table3.tex         the paper's Table III layout (M_VI side preference)

A chunk file is written only when all its episodes are scored, so an interrupted run resumes by
skipping the chunk files that exist: nothing finished is recomputed or lost. Every chunk file carries
the fingerprint of the manifest it was computed for and Parquet page checksums; a file of another
run, or a damaged one, is refused by name instead of being scored. A run holds ``.lock`` in the
directory while it writes there: a second run on the same directory is refused at once. With
trajectories, the trajectory file is written first and a chunk counts as done only when both files
exist; a chunk that has one without the other is simulated again (episodes are deterministic, so both
are rewritten identically).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import sys
import warnings
from collections import deque
from collections.abc import Sequence
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from socialnav import __version__
from socialnav._io import (
    DirectoryLock,
    atomic_write_json,
    atomic_write_rows_parquet,
    file_sha256,
    make_output_dir,
    read_parquet_verified,
    remove_orphan_temporaries,
)
from socialnav._runtime import forkserver_pool, main_module_reruns_call, one_blas_thread, worker_init
from socialnav.evaluate.plan import Cell, cell_scenario, cell_world_settings, plan_cells
from socialnav.evaluate.report import mismatch_caveats, render_reports, write_reports
from socialnav.evaluate.summary import summarize_episodes
from socialnav.metrics import score_episode, side_case_of_row
from socialnav.policies.base import RECORDED_ONLY, Policy, PolicyError
from socialnav.presets import Preset
from socialnav.sim.world import World, check_world_size
from socialnav.trajectory import Trajectory

#: Parquet metadata key of a chunk file: the fingerprint of the manifest of the run that wrote it.
CHUNK_STAMP_KEY = "socialnav.manifest"


class ResumeMismatchError(RuntimeError):
    """The output directory holds results of a different run configuration."""


@dataclass(frozen=True)
class ProtocolResult:
    out_dir: Path
    rows: list[dict[str, Any]]  # per-episode rows
    summary: list[dict[str, Any]]  # aggregate rows
    computed_episodes: int  # episodes simulated by this call (0 when everything was resumed)


def simulate_chunk(
    policy: Policy,
    preset: Preset,
    cell: Cell,
    start: int,
    stop: int,
    label: str,
    batch_size: int = 256,
    until: int | None = None,
) -> list[Trajectory]:
    """Simulates episodes [start, stop) of a cell; trajectories in index order.

    ``until``: stop as soon as the episode of this index has finished (replay of one episode).
    """
    settings = cell_world_settings(preset, cell)
    world = World(
        settings,
        cell_scenario(preset, cell),
        min(batch_size, stop - start),
        split=preset.evaluation.split,
        start=start,
        count=stop - start,
        tags={"policy": label, "information": getattr(policy, "information", "none")},
    )
    trajs: list[Trajectory] = []
    oracle = getattr(policy, "information", "none") == "oracle"
    with world:  # its native threads stop here, not when the cycle collector runs
        world.reset()
        while world.busy:
            obs = world.observe(oracle=oracle)
            trajs.extend(world.step(checked_actions(policy, obs, world, label, cell)).finished)
            if until is not None and any(t.settings["index"] == until for t in trajs):
                break
    return sorted(trajs, key=lambda t: t.settings["index"])


def checked_actions(policy: Policy, obs: Any, world: World, label: str, cell: Cell) -> np.ndarray:
    """``policy.act(obs)``, checked: an exception in the policy, or actions of the wrong shape or not
    finite where an episode runs, become a :class:`PolicyError` naming the policy, the cell and the
    episodes (a user's policy would otherwise fail with a bare NumPy or tensor error)."""

    def where(rows: np.ndarray | None = None) -> str:
        active = np.flatnonzero(obs.active) if rows is None else rows
        episodes = [int(i) for i in world.episode_index[active][:8]]
        more = f" and {len(active) - 8} more" if len(active) > 8 else ""
        t = float(obs.time.max()) if len(obs.time) else 0.0
        return f"{cell.scenario}/{cell.visibility}, episode(s) {episodes}{more} at t = {t:g} s"

    try:
        actions = policy.act(obs)
    except Exception as err:  # noqa: BLE001 - re-raised with where it happened
        raise PolicyError(f"policy {label!r} failed in {where()}: {type(err).__name__}: {err}") from err
    try:
        arr = np.asarray(actions, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise PolicyError(
            f"policy {label!r} returned actions that are not numbers in {where()}: {err}"
        ) from None
    if arr.shape != (len(obs.active), 2):
        raise PolicyError(
            f"policy {label!r} returned actions of shape {arr.shape} in {where()}; expected "
            f"({len(obs.active)}, 2), one (vx, vy) or (v, dtheta) row per episode of the batch"
        )
    bad = obs.active & ~np.isfinite(arr).all(axis=1)
    if bad.any():
        raise PolicyError(
            f"policy {label!r} returned non-finite actions (NaN or inf) in {where(np.flatnonzero(bad))}"
        )
    return arr


def score_trajectories(trajs: list[Trajectory], cell: Cell, label: str) -> list[dict[str, Any]]:
    """One result row per episode: identifiers, outcome and every metric (runs in worker processes)."""
    rows = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for traj in trajs:
            row = {
                "policy": label,
                "scenario": cell.scenario,
                "visibility": cell.visibility,
                "index": traj.settings["index"],
                "seed": traj.settings["seed"],
                "outcome": traj.outcome,
                "information": traj.settings["information"],
                **score_episode(traj),
            }
            if cell.single_human:
                row["side"] = "failed" if traj.outcome != "success" else side_case_of_row(row)
            rows.append(row)
    return rows, sorted({(w.category.__name__, str(w.message)) for w in caught})


def episode_id(scenario: str, visibility: str, index: int) -> str:
    """The id of an evaluated episode, e.g. ``passing/invisible/3`` (see evaluate/results.py)."""
    return f"{scenario}/{visibility}/{int(index)}"


def store_and_score(
    trajs: list[Trajectory], cell: Cell, label: str, traj_path: Path | None
) -> tuple[list[dict[str, Any]], list[tuple[str, str]]]:
    """Writes the chunk's trajectories (when ``traj_path`` is given), then scores them (in a worker)."""
    if traj_path is not None:
        from socialnav.trajectory_io import write_trajectories

        for traj in trajs:
            traj.settings["episode"] = episode_id(cell.scenario, cell.visibility, traj.settings["index"])
        write_trajectories(traj_path, trajs)
    return score_trajectories(trajs, cell, label)


def reissue_warnings(notes: list[tuple[str, str]]) -> None:
    """Re-raises here, where the caller sees them, the warnings ``(category, message)`` that
    :func:`store_and_score` collected in a worker process (categories of socialnav.metrics)."""
    import socialnav.metrics as metrics

    for category, message in notes:
        warnings.warn(message, getattr(metrics, category, UserWarning), stacklevel=3)


def run_protocol(
    policy: Policy,
    preset: Preset,
    out_dir: str | Path,
    *,
    label: str | None = None,
    scenarios: Sequence[str] | None = None,
    episodes: int | None = None,
    visibility: str | None = None,
    progress: bool = True,
    extra_manifest: dict | None = None,
    batch_size: int = 256,
    workers: int | None = None,
    trajectories: bool = True,
    simulate_in_workers: bool | None = None,
) -> ProtocolResult:
    """Runs (or resumes) the protocol of ``preset`` for ``policy`` and writes every result file.

    Args:
        policy: The robot policy.
        preset: The protocol (world, robot, scenarios, episode counts).
        out_dir: Result directory; an existing one with the same manifest is resumed.
        label: Policy name in the results (default ``policy.name``).
        scenarios: Only these scenarios (default: the preset's).
        episodes: Episodes per multi-human scenario (default: the preset's).
        visibility: ``invisible``, ``visible`` or ``both`` (default: the preset's).
        progress: Show a progress bar on stderr.
        extra_manifest: Extra fields recorded in the manifest (e.g. the checkpoint path).
        batch_size: Episodes simulated in lockstep.
        workers: Processes that score finished chunks while the next chunk is simulated (default:
            one per core, at most 4; 0 scores in this process). Called from the top level of a
            script without an ``if __name__ == "__main__":`` guard, scoring stays in this process
            (workers would re-run the script).
        trajectories: Keep every episode's trajectory under ``trajectories/`` (for ``socialnav
            replay``, ``render`` and ``report``).
        simulate_in_workers: Simulate chunks in the worker processes too, one torch thread each
            (default: when the policy can be pickled, i.e. learned policies). Each chunk is simulated
            exactly as in this process (same slots, same batches), so results are bit-identical; on
            few cores, one process per core beats intra-op threads on the small batches of a
            draining chunk (docs/protocol.md).

    Raises:
        ResumeMismatchError: ``out_dir`` holds a different run's results.
    """
    out = Path(out_dir)
    label = label or policy.name
    cells = plan_cells(preset, list(scenarios) if scenarios else None, episodes, visibility)
    chunk = preset.evaluation.chunk_size
    # Everything that can be refused is refused before the first file is written.
    validate_cells(preset, cells, batch_size)
    manifest = protocol_manifest(policy, preset, cells, label, batch_size, trajectories, extra_manifest)
    stamp = manifest_stamp(manifest)
    make_output_dir(out)
    # Worker processes are the parallelism; the bootstrap's small products need one BLAS thread
    # (socialnav/_runtime.py), and spinning BLAS threads would take CPU from the workers.
    with DirectoryLock(out, "evaluation"), one_blas_thread():
        remove_orphan_temporaries(out)
        check_or_write_manifest(out, manifest)
        expected = {
            chunk_path(out, cell, a, b): (cell, a, b) for cell in cells for a, b in cell.chunks(chunk)
        }
        refuse_foreign_chunks(out, expected)
        todo = []
        verified: dict[Path, list[dict[str, Any]]] = {}  # rows of finished chunks, read once
        for path, (cell, a, b) in expected.items():
            if chunk_done(out, cell, a, b, trajectories):
                # damaged or foreign files are refused now, before anything is computed
                verified[path] = _read_chunk(path, cell, a, b, label, stamp)
            else:
                todo.append((cell, a, b))
        computed = _simulate_and_score(
            policy, preset, out, todo, label, stamp, sum(c.episodes for c in cells), progress, batch_size,
            workers, trajectories, simulate_in_workers,
        )
        rows = read_episode_rows(out, cells, chunk, label, stamp, verified)
        summary = summarize_episodes(rows, multi_human=preset.evaluation.multi_human)
        write_reports(out, summary, rows, preset, mismatch_caveats(manifest["policy"]))
    return ProtocolResult(out, rows, summary, computed)


def policy_sources(policy: Policy) -> dict[str, str]:
    """SHA-256 of what a policy from outside socialnav was built from: the source file of the module
    that defines its class, and every file it names in an optional ``source_files()`` method (a model
    file, say). In the manifest, so that a resume never reuses the results of a policy whose code or
    model changed at the same path; socialnav's own policies are covered by the package version and
    their checkpoints' hashes."""
    out: dict[str, str] = {}
    module = type(policy).__module__
    path = getattr(sys.modules.get(module), "__file__", None)
    if path and module.split(".")[0] != "socialnav" and Path(path).is_file():
        out["module"] = file_sha256(path)  # by content: a script run and its import are one policy
    declared = getattr(policy, "source_files", None)
    for item in declared() if callable(declared) else ():
        item = Path(item)
        if not item.is_file():
            raise ValueError(f"policy {getattr(policy, 'name', module)!r} declares source file {item}, "
                             "which does not exist")
        out[str(item)] = file_sha256(item)
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
    """What a run consists of, as recorded in ``manifest.json`` and fingerprinted into every chunk file
    (a sweep builds the same manifest, so its directories are ``socialnav evaluate``'s)."""
    sources = policy_sources(policy)
    return _normalised(
        {
            # information only (run_identity leaves it out): a run resumed by a newer release continues
            "socialnav_version": __version__,
            "preset": preset.to_dict(),
            "policy": {"label": label, **policy.describe()},
            **({"policy_sources": sources} if sources else {}),
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


def _simulate_and_score(
    policy: Policy,
    preset: Preset,
    out: Path,
    todo: list[tuple[Cell, int, int]],
    label: str,
    stamp: str,
    total: int,
    progress: bool,
    batch_size: int,
    workers: int | None,
    trajectories: bool = True,
    simulate_in_workers: bool | None = None,
) -> int:
    """Simulates the chunks ``todo`` and writes one scored file per chunk; returns the episodes done."""
    chunk_meta = {CHUNK_STAMP_KEY: stamp}
    done = total - sum(b - a for _, a, b in todo)
    bar = episode_progress(total, done, progress)
    computed = 0
    workers = min(os.cpu_count() or 1, 4) if workers is None else workers
    if workers > 0 and main_module_reruns_call():
        workers = 0  # workers would re-run the calling script's top level (see socialnav/_runtime.py)
    payload = None
    if workers > 0 and len(todo) > 1 and simulate_in_workers is not False:
        payload = _policy_payload(policy, required=bool(simulate_in_workers))
    if payload is not None:
        pool = _simulation_pool(workers, payload, preset)
    else:
        pool = scoring_pool(workers) if workers > 0 and len(todo) > 1 else None
    pending: deque = deque()

    def finish_oldest() -> None:
        nonlocal computed
        cell, a, b, future = pending.popleft()
        try:
            rows, notes = future.result() if pool else future
        except BrokenProcessPool:
            raise RuntimeError(
                f"an evaluation worker process died while running {cell.scenario}/{cell.visibility} "
                f"episodes {a}-{b - 1} (a crash in native code, memory exhausted, or a policy module with "
                "code at its top level, which every worker runs again when it imports the module: put that "
                "code under `if __name__ == \"__main__\":`); finished chunks are kept: rerun to resume"
            ) from None
        reissue_warnings(notes)
        # A chunk lands whole or not at all, stamped with the run it belongs to.
        atomic_write_rows_parquet(chunk_path(out, cell, a, b), rows, chunk_meta)
        computed += b - a
        bar.update(b - a)

    try:
        for cell, a, b in todo:
            bar.set_description(f"{label} {cell.scenario} {cell.visibility}")
            traj_path = trajectory_path(out, cell, a, b) if trajectories else None
            if traj_path is not None:
                traj_path.parent.mkdir(parents=True, exist_ok=True)
            if payload is not None:
                job = pool.submit(
                    _simulate_store_and_score_in_worker, cell, a, b, label, batch_size, traj_path
                )
            else:
                trajs = simulate_chunk(policy, preset, cell, a, b, label, batch_size)
                job = (
                    pool.submit(store_and_score, trajs, cell, label, traj_path)
                    if pool
                    else store_and_score(trajs, cell, label, traj_path)
                )
            pending.append((cell, a, b, job))
            while len(pending) > (workers if pool else 0):
                finish_oldest()
        while pending:
            finish_oldest()
    except BaseException:
        # Interrupted while simulating: chunks already handed to scoring still land, so that a
        # resumed run recomputes nothing that was finished.
        while pending:
            try:
                finish_oldest()
            except BaseException:
                break
        raise
    finally:
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)
        bar.close()
    return computed


def read_episode_rows(
    out: Path, cells: list[Cell], chunk: int, label: str | None = None, stamp: str | None = None,
    verified: dict[Path, list[dict[str, Any]]] | None = None,
) -> list[dict[str, Any]]:
    """Every episode row of a run, in cell and index order; damaged or foreign chunk files are refused.
    ``verified`` holds chunks already read and checked in this run (by path), not read again."""
    rows: list[dict[str, Any]] = []
    known = verified or {}
    for cell in cells:
        for a, b in cell.chunks(chunk):
            path = chunk_path(out, cell, a, b)
            rows.extend(known[path] if path in known else _read_chunk(path, cell, a, b, label, stamp))
    return rows


def conclude_chunks(
    chunks: Sequence[tuple[Cell, int, int, str, bytes]],
    label: str | None,
    stamp: str | None,
    preset: Preset,
) -> tuple[int, list[dict[str, Any]], dict[str, str]]:
    """A finished run's conclusion from its chunk files' bytes, given in cell and index order as
    ``(cell, start, stop, path, bytes)`` (``path`` names a chunk in errors): the number of episodes,
    the summary rows and the text of every result file by name, exactly what :func:`run_protocol`
    writes. A sweep computes it in a worker, which may have no access to the result directory.

    Raises:
        ResumeMismatchError, CorruptFileError: A chunk is damaged or belongs to another run.
    """
    rows: list[dict[str, Any]] = []
    for cell, a, b, path, data in chunks:
        rows.extend(_read_chunk(Path(path), cell, a, b, label, stamp, data))
    summary = summarize_episodes(rows, multi_human=preset.evaluation.multi_human)
    return len(rows), summary, render_reports(summary, preset)


def run_identity(manifest: dict) -> dict:
    """The manifest less what it records for information only: the release that started the run and
    the policy's ``RECORDED_ONLY`` keys (e.g. the native scorer's vector kernel, whose values are
    bit-identical across kernels)."""
    manifest = {k: v for k, v in manifest.items() if k != "socialnav_version"}
    policy = manifest.get("policy")
    if isinstance(policy, dict) and any(k in policy for k in RECORDED_ONLY):
        return {**manifest, "policy": {k: v for k, v in policy.items() if k not in RECORDED_ONLY}}
    return manifest


def manifest_stamp(manifest: dict) -> str:
    """Fingerprint of a run's manifest, stored in each of its chunk files."""
    text = json.dumps(run_identity(manifest), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:32]


def _read_chunk(
    path: Path, cell: Cell, a: int, b: int, label: str | None, stamp: str | None, data: bytes | None = None
) -> list[dict]:
    """The rows of a chunk file (or of its bytes, ``data``), refused if damaged or not this run's."""
    table = read_parquet_verified(path, data=data)
    fix = "delete it to recompute those episodes"
    if stamp is not None:
        got = (table.schema.metadata or {}).get(CHUNK_STAMP_KEY.encode(), b"").decode(errors="replace")
        if got != stamp:
            raise ResumeMismatchError(
                f"{path} does not belong to this run (written for another configuration"
                f"{'' if got else ' or by an older socialnav'}); {fix}"
            )
    rows = table.to_pylist()
    indices = [r.get("index") for r in rows]
    bad = next(
        (
            (k, r.get(k), v)
            for r in rows
            for k, v in (("scenario", cell.scenario), ("visibility", cell.visibility), ("policy", label))
            if v is not None and r.get(k) != v
        ),
        None,
    )
    if bad is not None:
        raise ResumeMismatchError(f"{path} holds {bad[0]} {bad[1]!r}, expected {bad[2]!r}; {fix}")
    if indices != list(range(a, b)):
        raise ResumeMismatchError(f"{path} does not hold episodes {a}..{b - 1} in order; {fix}")
    return rows


def refuse_foreign_chunks(out: Path, expected: dict[Path, Any]) -> None:
    episodes = out / "episodes"
    if not episodes.is_dir():
        return
    foreign = sorted(p for p in episodes.rglob("*.parquet") if p not in expected)
    if foreign:
        more = f" and {len(foreign) - 1} more" if len(foreign) > 1 else ""
        raise ResumeMismatchError(
            f"{foreign[0]}{more} in {episodes} is not part of this run; move it away or use another --out"
        )


def chunk_path(out: Path, cell: Cell, a: int, b: int) -> Path:
    return out / "episodes" / cell.key / f"{a:05d}-{b:05d}.parquet"


def trajectory_path(out: Path, cell: Cell, a: int, b: int) -> Path:
    return out / "trajectories" / cell.key / f"{a:05d}-{b:05d}.parquet"


def chunk_done(out: Path, cell: Cell, a: int, b: int, trajectories: bool) -> bool:
    return chunk_path(out, cell, a, b).exists() and (
        not trajectories or trajectory_path(out, cell, a, b).exists()
    )


def validate_cells(preset: Preset, cells: list[Cell], batch_size: int) -> None:
    """Builds each cell's world settings and scenario and sizes its world, allocating nothing big."""
    if not isinstance(batch_size, int) or batch_size < 1:
        raise ValueError(f"batch size must be an integer >= 1, got {batch_size!r}")
    for cell in cells:
        settings = cell_world_settings(preset, cell)
        scenario = cell_scenario(preset, cell)
        check_world_size(settings, min(batch_size, cell.episodes), 1 + int(scenario.n_humans))


def _normalised(manifest: dict) -> dict:
    return json.loads(json.dumps(manifest, default=list))


def check_or_write_manifest(out: Path, manifest: dict) -> None:
    path = out / "manifest.json"
    if path.exists():
        try:
            previous = json.loads(path.read_text())
        except (ValueError, UnicodeDecodeError) as err:
            raise ResumeMismatchError(f"{path} is damaged ({err}); use another --out or delete it") from None
        if run_identity(previous) == run_identity(manifest):
            return  # the first run's record stands (a resume on another CPU changes no result)
        has_results = (out / "episodes").is_dir() and any((out / "episodes").rglob("*.parquet"))
        if has_results:
            raise ResumeMismatchError(
                f"{out} holds results of a different run "
                f"(differs in: {describe_differences(run_identity(previous), run_identity(manifest))}); "
                "use another --out directory or delete it"
            )
        # A manifest without any result (e.g. a run refused right after starting) blocks nothing.
    atomic_write_json(path, manifest)


def describe_differences(old: Any, new: Any, limit: int = 6) -> str:
    """What differs between two manifests, e.g. ``cells[circle_crossing/visible].episodes: 10 -> 20``."""
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
    text = json.dumps(value)
    return text if len(text) <= 60 else text[:57] + "..."


def scoring_pool(workers: int) -> Any:
    """A pool of ``workers`` processes for :func:`store_and_score` and other picklable work (the
    runner's and a sweep's local executor's).

    forkserver: workers start from a clean process, so native threads or torch in this one are safe.
    The forkserver and the workers die with this process, even on SIGKILL (socialnav/_runtime.py).
    """
    return forkserver_pool(workers)


def _policy_payload(policy: Policy, required: bool) -> bytes | None:
    """The pickled policy for simulation workers, or None when it cannot travel (native policies,
    whose simulation is cheap anyway)."""
    import pickle

    device = str(getattr(getattr(policy, "value_policy", None), "device", "cpu"))
    if device != "cpu" and not required:
        return None  # one GPU serves one process best; workers would each hold a copy of the network
    try:
        return pickle.dumps(policy)
    except Exception as err:
        if required:
            raise ValueError(f"policy {policy.name!r} cannot be simulated in workers: {err}") from None
        return None


def _simulation_pool(workers: int, payload: bytes, preset: Preset):
    # Same lifetime guarantees as the scoring pool (socialnav/_runtime.py); each worker holds the
    # policy, unpickled once.
    # One native thread per world in a worker: the workers already use every core.
    worker_preset = dataclasses.replace(preset, world=dataclasses.replace(preset.world, threads=1))
    return forkserver_pool(workers, _init_simulation_worker, (payload, worker_preset))


_WORKER: dict[str, Any] = {}


def _init_simulation_worker(payload: bytes, preset: Preset) -> None:
    import pickle

    worker_init()
    try:
        import torch

        torch.set_num_threads(1)  # parallelism comes from the processes; results do not depend on it
    except ImportError:
        pass
    _WORKER["policy"] = pickle.loads(payload)
    _WORKER["preset"] = preset


def _simulate_store_and_score_in_worker(
    cell: Cell, start: int, stop: int, label: str, batch_size: int, traj_path: Path | None
):
    trajs = simulate_chunk(_WORKER["policy"], _WORKER["preset"], cell, start, stop, label, batch_size)
    return store_and_score(trajs, cell, label, traj_path)


def episode_progress(total: int, initial: int, enabled: bool) -> Any:
    """The progress bar of a run counting episodes, on stderr (``enabled`` False: silent)."""
    from tqdm.auto import tqdm

    return tqdm(
        total=total,
        initial=initial,
        unit="ep",
        disable=not enabled,
        file=sys.stderr,
        leave=False,
        dynamic_ncols=True,
    )

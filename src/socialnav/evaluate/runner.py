"""The protocol runner: simulate every cell of a preset with one policy, score, aggregate, write.

Results live in an output directory:

    manifest.json                  what was run (preset, policy, cells); checked on resume
    episodes/<cell>/<a>-<b>.parquet  one row per episode (ids, outcome, every metric), atomic
    summary.json / summary.csv     per (policy, scenario, visibility) and pooled aggregates
    table2.md / table2.tex         the paper's Table II layout (+ per-scenario tables)
    table3.md / table3.tex         the paper's Table III layout (M_VI side preference)

A chunk file is written only when all its episodes are scored, so an interrupted run resumes by
skipping the chunk files that exist: nothing finished is recomputed or lost.
"""

from __future__ import annotations

import dataclasses
import os
import sys
import warnings
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from socialnav.evaluate.files import atomic_write_json, atomic_write_rows_parquet
from socialnav.evaluate.plan import Cell, cell_scenario, cell_world_settings, plan_cells
from socialnav.evaluate.report import write_reports
from socialnav.evaluate.summary import summarize_episodes
from socialnav.metrics import score_episode
from socialnav.policies.base import Policy
from socialnav.presets import Preset
from socialnav.sim.world import World
from socialnav.trajectory import Trajectory

SIDE_LABEL = {1.0: "left", -1.0: "right", 0.0: "unlabelled"}
SIDE_KEY = "m6_side_preference.sign@frame=world"


class ResumeMismatchError(RuntimeError):
    """The output directory holds results of a different run configuration."""


@dataclass(frozen=True)
class ProtocolResult:
    out_dir: Path
    rows: list[dict[str, Any]]  # per-episode rows
    summary: list[dict[str, Any]]  # aggregate rows
    computed_episodes: int  # episodes simulated by this call (0 when everything was resumed)


def simulate_chunk(
    policy: Policy, preset: Preset, cell: Cell, start: int, stop: int, label: str, batch_size: int = 256
) -> list[Trajectory]:
    """Simulates episodes [start, stop) of a cell; trajectories in index order."""
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
    world.reset()
    trajs: list[Trajectory] = []
    oracle = getattr(policy, "information", "none") == "oracle"
    while world.busy:
        trajs.extend(world.step(policy.act(world.observe(oracle=oracle))).finished)
    return sorted(trajs, key=lambda t: t.settings["index"])


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
                sign = row.get(SIDE_KEY, np.nan)
                row["side"] = "failed" if traj.outcome != "success" else SIDE_LABEL.get(sign, "unlabelled")
            rows.append(row)
    return rows, sorted({(w.category.__name__, str(w.message)) for w in caught})


def _reissue(notes: list[tuple[str, str]]) -> None:
    # Warnings raised while scoring in a worker are re-raised here, where the caller can see them.
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
    simulate_in_workers: bool | None = None,
) -> ProtocolResult:
    """Runs (or resumes) the protocol of ``preset`` for ``policy`` and writes every result file.

    Args:
        policy: The robot policy.
        preset: The protocol (world, robot, scenarios, episode counts).
        out_dir: Result directory; an existing one with the same manifest is resumed.
        label: Policy name in the results (default ``policy.name``).
        scenarios, episodes, visibility: Overrides of the preset's evaluation settings.
        progress: Show a progress bar on stderr.
        extra_manifest: Extra fields recorded in the manifest (e.g. the checkpoint path).
        batch_size: Episodes simulated in lockstep.
        workers: Processes that score finished chunks while the next chunk is simulated (default:
            one per core, at most 4; 0 scores in this process).
        simulate_in_workers: Simulate chunks in the worker processes too, one torch thread each
            (default: when the policy can be pickled, i.e. learned policies). Each chunk is simulated
            exactly as in this process (same slots, same batches), so results are bit-identical; on
            few cores, one process per core beats intra-op threads on the small batches of a
            draining chunk (docs/reproduction.md).

    Raises:
        ResumeMismatchError: ``out_dir`` holds a different run's results.
    """
    out = Path(out_dir)
    label = label or policy.name
    cells = plan_cells(preset, list(scenarios) if scenarios else None, episodes, visibility)
    chunk = preset.evaluation.chunk_size
    manifest = {
        "preset": preset.to_dict(),
        "policy": {"label": label, **policy.describe()},
        "cells": [
            {"scenario": c.scenario, "visibility": c.visibility, "episodes": c.episodes} for c in cells
        ],
        "chunk_size": chunk,
        **(extra_manifest or {}),
    }
    _check_or_write_manifest(out, manifest)

    todo = [
        (cell, a, b)
        for cell in cells
        for a, b in cell.chunks(chunk)
        if not _chunk_path(out, cell, a, b).exists()
    ]
    total = sum(c.episodes for c in cells)
    done = total - sum(b - a for _, a, b in todo)
    bar = _progress(total, done, progress)
    computed = 0
    workers = min(os.cpu_count() or 1, 4) if workers is None else workers
    payload = None
    if workers > 0 and len(todo) > 1 and simulate_in_workers is not False:
        payload = _policy_payload(policy, required=bool(simulate_in_workers))
    if payload is not None:
        pool = _simulation_pool(workers, payload, preset)
    else:
        pool = _scoring_pool(workers) if workers > 0 and len(todo) > 1 else None
    pending: deque = deque()

    def finish_oldest() -> None:
        nonlocal computed
        cell, a, b, future = pending.popleft()
        rows, notes = future.result() if pool else future
        _reissue(notes)
        atomic_write_rows_parquet(_chunk_path(out, cell, a, b), rows)  # a chunk lands whole or not at all
        computed += b - a
        bar.update(b - a)

    try:
        for cell, a, b in todo:
            bar.set_description(f"{label} {cell.scenario} {cell.visibility}")
            if payload is not None:
                job = pool.submit(_simulate_and_score, cell, a, b, label, batch_size)
            else:
                trajs = simulate_chunk(policy, preset, cell, a, b, label, batch_size)
                job = (
                    pool.submit(score_trajectories, trajs, cell, label)
                    if pool
                    else score_trajectories(trajs, cell, label)
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
            except Exception:
                break
        raise
    finally:
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)
        bar.close()

    rows = read_episode_rows(out, cells, chunk)
    summary = summarize_episodes(rows, multi_human=preset.evaluation.multi_human)
    write_reports(out, summary, rows, preset)
    return ProtocolResult(out, rows, summary, computed)


def read_episode_rows(out: Path, cells: list[Cell], chunk: int) -> list[dict[str, Any]]:
    import pyarrow.parquet as pq

    rows: list[dict[str, Any]] = []
    for cell in cells:
        for a, b in cell.chunks(chunk):
            rows.extend(pq.read_table(_chunk_path(out, cell, a, b)).to_pylist())
    return rows


def _chunk_path(out: Path, cell: Cell, a: int, b: int) -> Path:
    return out / "episodes" / cell.key / f"{a:05d}-{b:05d}.parquet"


def _check_or_write_manifest(out: Path, manifest: dict) -> None:
    import json

    path = out / "manifest.json"
    normalised = json.loads(json.dumps(manifest, default=list))
    if path.exists():
        previous = json.loads(path.read_text())
        if previous != normalised:
            changed = sorted(
                k for k in set(previous) | set(normalised) if previous.get(k) != normalised.get(k)
            )
            raise ResumeMismatchError(
                f"{out} holds results of a different run (differs in: {', '.join(changed)}); "
                "use another --out directory or delete it"
            )
        return
    atomic_write_json(path, normalised)


def _scoring_pool(workers: int):
    # forkserver: workers start from a clean process, so native threads or torch in this one are safe.
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    return ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("forkserver"))


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
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    # One native thread per world in a worker: the workers already use every core.
    worker_preset = dataclasses.replace(preset, world=dataclasses.replace(preset.world, threads=1))
    return ProcessPoolExecutor(
        max_workers=workers,
        mp_context=multiprocessing.get_context("forkserver"),
        initializer=_init_simulation_worker,
        initargs=(payload, worker_preset),
    )


_WORKER: dict[str, Any] = {}


def _init_simulation_worker(payload: bytes, preset: Preset) -> None:
    import pickle

    try:
        import torch

        torch.set_num_threads(1)  # parallelism comes from the processes; results do not depend on it
    except ImportError:
        pass
    _WORKER["policy"] = pickle.loads(payload)
    _WORKER["preset"] = preset


def _simulate_and_score(cell: Cell, start: int, stop: int, label: str, batch_size: int):
    trajs = simulate_chunk(_WORKER["policy"], _WORKER["preset"], cell, start, stop, label, batch_size)
    return score_trajectories(trajs, cell, label)


def _progress(total: int, initial: int, enabled: bool):
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

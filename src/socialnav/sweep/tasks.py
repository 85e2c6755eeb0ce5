"""What a sweep's workers run: one evaluation chunk, an evaluation job's conclusion, or one training run.

Both run in a worker process (local executor) or a Ray task, so their arguments and results are plain
data. An evaluation chunk returns its scored rows and its trajectories as Parquet bytes; the driver
alone writes result files, so a worker on another machine needs no shared file system, and a task run
twice (a retry after its worker died) writes nothing twice.
"""

from __future__ import annotations

import dataclasses
import os
import socket
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from socialnav._io import json_safe
from socialnav.evaluate.plan import Cell, preset_for_scenarios
from socialnav.presets import Preset

#: Policies a worker has built, by job key: a worker runs many chunks of one job.
_POLICIES: dict[str, Any] = {}


#: Presets a worker has parsed, by name or path and the file's modification time (a Ray worker
#: outlives one sweep: an edited preset file is parsed again).
_PRESETS: dict[tuple[str, int], Preset] = {}


def _load_preset_once(name: str) -> Preset:
    from socialnav.presets import load_preset

    try:
        stamp = os.stat(name).st_mtime_ns if os.path.isfile(name) else 0
    except OSError:
        stamp = 0
    key = (name, stamp)
    if key not in _PRESETS:
        _PRESETS[key] = load_preset(name)
    return _PRESETS[key]


def job_preset(params: dict[str, Any], threads: int | None = None) -> Preset:
    """The job's preset with its ``human_model`` override.

    In a worker, also ``threads`` native threads per world: parallelism comes from the workers; results do not
    depend on it.
    """
    preset = _load_preset_once(str(params["preset"]))
    world = preset.world
    if params.get("human_model") is not None:
        world = dataclasses.replace(world, human_model=params["human_model"])
    if threads is not None:
        world = dataclasses.replace(world, threads=threads)
    return dataclasses.replace(preset, world=world)


def policy_overrides(params: dict[str, Any]) -> dict[str, Any]:
    """``socialnav evaluate``'s ``--policy-arg``, ``--information`` and ``--planning-*`` of a job."""
    from socialnav.policies.building import LOOKAHEAD_SETTINGS

    overrides = dict(params.get("policy_args") or {})
    for key in LOOKAHEAD_SETTINGS:
        if params.get(key) is not None:
            overrides[key] = params[key]
    return overrides


def build_job_policy(
    params: dict[str, Any], preset: Preset, checkpoint: str | None, threads: int | None = None
):
    """The job's policy.

    ``threads`` (in a worker): the native threads of a policy that has them (linear, ORCA, social force),
    unless the job sets them. Without it such a policy would start a thread per core in every worker, and on a
    machine whose cores the workers already fill, each of its calls would wake a thread that has no core to
    run on (results do not depend on it).
    """
    from socialnav.policies.building import build_policy
    from socialnav.policies.registry import get_policy_entry

    name = str(params["policy"])
    overrides = policy_overrides(params)
    if threads is not None and "threads" not in overrides and "threads" in get_policy_entry(name).parameters:
        overrides["threads"] = threads
    return build_policy(
        name,
        preset_for_scenarios(preset, params.get("scenarios")),  # the job's scenarios, as evaluate's
        checkpoint,
        allow_preset_mismatch=bool(params.get("allow_preset_mismatch", False)),
        **overrides,
    )


def evaluate_chunk(
    payload: bytes | None,
    job_key: str,
    params: dict[str, Any],
    checkpoint: str | None,
    cell: Cell,
    start: int,
    stop: int,
    label: str,
    batch_size: int,
    trajectories: bool,
    threads: int,
    stamp: str,
) -> dict[str, Any]:
    """Simulates and scores episodes [start, stop) of ``cell`` exactly as ``socialnav evaluate`` does.

    ``payload`` is the pickled policy built by the driver (None for policies that do not pickle; they
    are rebuilt here from ``params``). The chunk's rows come back as the bytes of its Parquet file,
    stamped with the run's ``stamp`` (``rows_parquet``), so that the driver only stores them.
    """
    from socialnav._runtime import one_blas_thread_for_good
    from socialnav.evaluate.chunks import chunk_file_bytes
    from socialnav.evaluate.execution import simulate_chunk, store_and_score

    one_blas_thread_for_good()  # a worker (local or Ray): processes are the parallelism
    t0 = time.perf_counter()
    preset = job_preset(params, threads=threads)
    policy = _POLICIES.get(job_key)
    if policy is None:
        if payload is not None:
            import pickle

            policy = pickle.loads(payload)
        else:
            policy = build_job_policy(params, preset, checkpoint, threads=threads)
        _POLICIES.clear()  # one job's policy at a time: a worker's memory stays that of one network
        _POLICIES[job_key] = policy
    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(threads)
    trajs = simulate_chunk(policy, preset, cell, start, stop, label, batch_size)
    traj_bytes = None
    if trajectories:
        with tempfile.TemporaryDirectory(prefix="socialnav-sweep-") as tmp:
            path = Path(tmp) / "chunk.parquet"
            rows, notes = store_and_score(trajs, cell, label, path)
            traj_bytes = path.read_bytes()
    else:
        rows, notes = store_and_score(trajs, cell, label, None)
    return {
        "rows_parquet": chunk_file_bytes(rows, stamp),
        "notes": notes,
        "trajectories": traj_bytes,
        "where": where_am_i(),
        "seconds": round(time.perf_counter() - t0, 4),
    }


def conclude_job(
    _payload: None,
    params: dict[str, Any],
    chunks: list[tuple[Cell, int, int, str, bytes]],
    label: str,
    stamp: str,
) -> dict[str, Any]:
    """An evaluation job's conclusion (summary rows, tables) from its chunk files' bytes.

    Chunks are taken in cell and index order: what ``socialnav evaluate`` writes when a run ends, computed
    here so that the driver only stores the files (its serial share stays small however many workers there
    are).
    """
    import warnings

    from socialnav._runtime import one_blas_thread_for_good
    from socialnav.evaluate.runner import conclude_chunks

    one_blas_thread_for_good()
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the chunks' warnings were re-issued when they landed
        episodes, summary, files = conclude_chunks(chunks, label, stamp, job_preset(params))
    return {
        "episodes": episodes,
        "summary": summary,
        "files": files,
        "where": where_am_i(),
        "seconds": round(time.perf_counter() - t0, 4),
    }


def train_job(_payload: None, params: dict[str, Any], out_dir: str, threads: int,
              label: str | None = None) -> dict[str, Any]:
    """Run (or resume, from ``last.pt``) one training job of a sweep into ``out_dir``.

    ``_payload`` is unused; every task takes one. The trainer's lines go to stderr, each starting with
    ``label`` (the job: several train at once), or nowhere when ``label`` is None (``--quiet``).
    """
    from socialnav.train.registry import OPTIONS, trainer_for_policy

    def log(line: str) -> None:
        if label is not None:
            print(f"{label}: {line}", file=sys.stderr, flush=True)

    t0 = time.perf_counter()
    policy = str(params["policy"])
    trainer = trainer_for_policy(policy)
    settings = trainer.load_settings(
        params.get("config"), policy=policy, seed=params.get("seed"), device=params.get("device"),
        **{k: params.get(k) for k in OPTIONS if k in trainer.options},
    )
    settings = dataclasses.replace(settings, threads=threads)
    result = trainer.run(policy, job_preset(params), out_dir, settings, progress=False, log=log)
    summary = trainer.summary(result)
    counters = {k: summary[k] for k in trainer.counters}
    return {
        "best_checkpoint": summary["best_checkpoint"],
        **counters,
        "counters": counters,
        "best_val": json_safe(summary["best_val"]),  # NaN (no validation yet) as None
        "resumed": summary["resumed"],
        "where": where_am_i(),
        "seconds": round(time.perf_counter() - t0, 3),
    }


def where_am_i() -> dict[str, Any]:
    """Host, process and (in a Ray task) node of the worker, recorded in the sweep's log."""
    where: dict[str, Any] = {"host": socket.gethostname(), "pid": os.getpid()}
    ray = sys.modules.get("ray")
    if ray is not None and ray.is_initialized():
        where["node"] = ray.get_runtime_context().get_node_id()
    return where

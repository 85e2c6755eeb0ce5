"""Runs a sweep: training jobs, then evaluation jobs split into episode chunks, on an executor.

Result directory::

    sweep.json                    the resolved jobs and the executor of the last run
    train/<job>/                  ``socialnav train``'s run directory (resumes from last.pt)
    evaluate/<job>/               ``socialnav evaluate``'s result directory (manifest, chunk files,
                                  trajectories, summary, tables), labelled with the job's name
    summary.json/.csv, table2.*, table3.*   every evaluation job's summary rows and tables
    jobs.json                     per job: done or failed, its directory, what this run computed
    failures.json                 every job or chunk that failed, with its error (empty when none)
    sweep_log.jsonl               one line per finished task: where it ran, how long it took

Only this process writes result files; each chunk lands atomically, stamped with its job's manifest,
exactly as ``socialnav evaluate`` writes it. When a job's last chunk has landed, its conclusion (summary,
confidence intervals, tables) is computed by a worker from the chunks' bytes and stored here, so the
driver's serial share stays small however many workers run. Chunks are handed out longest first
(episodes x agents), so the workers finish together. Rerunning the same command after a kill
recomputes no finished chunk and duplicates none: a chunk is a file named by its episode range.
Results are the same, bit for bit, whatever the executor, the number of workers or the order chunks
finish in, because each chunk is simulated on its own exactly as ``socialnav evaluate`` simulates it.
"""

from __future__ import annotations

import json
import pickle
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from socialnav import __version__
from socialnav._io import (
    DirectoryLock,
    atomic_write_json,
    atomic_write_text,
    file_sha256,
    make_output_dir,
    remove_orphan_temporaries,
)
from socialnav._runtime import one_blas_thread
from socialnav.evaluate.chunks import ResumeMismatchError, chunk_path, store_chunk_files
from socialnav.evaluate.execution import episode_progress, reissue_warnings, validate_cells
from socialnav.evaluate.manifest import manifest_stamp, protocol_manifest, refuse_other_kind, resume_directory
from socialnav.evaluate.plan import plan_cells
from socialnav.sweep.executors import Task, TaskFailed
from socialnav.sweep.spec import TRAIN_REFERENCE, Job, SweepSpec, job_record
from socialnav.sweep.tasks import build_job_policy, conclude_job, evaluate_chunk, job_preset, train_job


@dataclass
class SweepResult:
    """What :func:`run_sweep` returns.

    Attributes:
        out_dir: The sweep's result directory.
        summary: Every evaluation job's summary rows.
        jobs: Each job's status by ``"<kind>/<name>"`` (as in ``jobs.json``).
        failures: Every job or chunk that failed, with its error (as in ``failures.json``).
    """

    out_dir: Path
    summary: list[dict[str, Any]]
    jobs: dict[str, dict[str, Any]]
    failures: list[dict[str, Any]] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        """Whether every job finished."""
        return not self.failures


@dataclass
class _EvalJob:
    job: Job
    dir: Path
    policy: Any
    preset: Any
    checkpoint: str | None
    cells: list
    stamp: str
    extra: dict[str, Any]
    todo: list
    lock: Any = None  # the job directory's DirectoryLock, held while chunks and the conclusion land
    computed: int = 0
    failed: list[str] = field(default_factory=list)
    # the chunk files this run computed, by (cell key, first episode): the conclusion's input
    chunk_bytes: dict[tuple[str, int], bytes] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.pending = len(self.todo)

    def release(self) -> None:
        if self.lock is not None:
            self.lock.__exit__(None, None, None)
            self.lock = None


def run_sweep(
    spec: SweepSpec,
    out_dir: str | Path,
    executor: Any,
    *,
    progress: bool = True,
    log: Callable[[str], None] | None = None,
) -> SweepResult:
    """Runs (or resumes) every job of ``spec`` into ``out_dir`` on ``executor``.

    Args:
        spec: The sweep's jobs.
        out_dir: Its result directory (an existing one is resumed).
        executor: Where tasks run (:class:`~socialnav.sweep.executors.LocalExecutor` or
            :class:`~socialnav.sweep.executors.RayExecutor`).
        progress: Show a progress bar on stderr.
        log: Called with one line per event (a job started, finished or failed).

    Returns:
        The summary rows, each job's status and the failures.

    Raises:
        DirectoryLockedError: Another sweep is writing to ``out_dir``.
    """
    out = Path(out_dir)
    say = log or (lambda line: None)
    refuse_other_kind(out, "sweep")
    make_output_dir(out)
    with DirectoryLock(out, "sweep"):
        remove_orphan_temporaries(out)
        atomic_write_json(
            out / "sweep.json",
            {
                "socialnav_version": __version__,
                "source": spec.source,
                "executor": executor.describe(),
                "threads": spec.threads,
                "jobs": [job_record(j) for j in spec.jobs],
            },
        )
        statuses: dict[str, dict[str, Any]] = {}
        failures: list[dict[str, Any]] = []
        # the workers are the parallelism: the driver's summaries get one BLAS thread (socialnav/_runtime.py)
        with open(out / "sweep_log.jsonl", "a", encoding="utf-8") as task_log, one_blas_thread():
            _run_training(spec, out, executor, statuses, failures, task_log, say, quiet=log is None)
            summary = _run_evaluations(spec, out, executor, statuses, failures, task_log, progress, say)
        from socialnav.evaluate.report import remove_reports, write_reports

        names = {job.name for job in spec.evaluate_jobs}
        others = sorted(d.name for d in (out / "evaluate").glob("*/") if d.is_dir() and d.name not in names)
        if others:  # e.g. the jobs of an earlier grid: kept, but not this sweep's
            say(f"evaluate/{{{', '.join(others)}}}: not jobs of this sweep file, left out of the combined "
                "tables")

        if summary:
            reported = {r["policy"] for r in summary}
            presets = {job.name: job_preset(job.params) for job in spec.evaluate_jobs if job.name in reported}
            first = job_preset(spec.evaluate_jobs[0].params)
            write_reports(out, summary, [], first, presets_by_policy=presets)
        else:  # no job has rows: an earlier call's combined tables would be taken for this call's
            removed = remove_reports(out)
            if removed:
                say(f"no evaluation job has results: the earlier combined {', '.join(removed)} removed")
        atomic_write_json(out / "jobs.json", statuses)
        atomic_write_json(out / "failures.json", failures)
    return SweepResult(out, summary, statuses, failures)


def _log_task(task_log, task: Task, result: Any) -> None:
    line = {"task": task.key, "time": round(time.time(), 3)}
    if isinstance(result, TaskFailed):
        line.update(error=result.message, attempts=result.attempts)
    else:
        line.update(where=result.get("where"), seconds=result.get("seconds"))
    task_log.write(json.dumps(line) + "\n")
    task_log.flush()


def _run_training(spec, out, executor, statuses, failures, task_log, say, quiet: bool = False) -> None:
    tasks = []
    for job in spec.train_jobs:
        run_dir = out / "train" / job.name
        run_dir.parent.mkdir(parents=True, exist_ok=True)
        label = None if quiet else f"train/{job.name}"
        tasks.append(Task(f"train/{job.name}", train_job, (job.params, str(run_dir), spec.threads, label),
                          meta={"job": job}))
    if tasks:
        say(f"training: {len(tasks)} job(s) on {executor.name}")
    for task, result in executor.run(tasks):
        _log_task(task_log, task, result)
        job = task.meta["job"]
        key = f"train/{job.name}"
        if isinstance(result, TaskFailed):
            statuses[key] = {"status": "failed", "dir": f"train/{job.name}", "error": result.message}
            failures.append(
                {"job": key, "task": task.key, "error": result.message, "attempts": result.attempts}
            )
            say(f"{key}: FAILED: {result.message}")
        else:
            counters = result.get("counters") or {}  # the trainer's own: episodes, updates, ...
            statuses[key] = {
                "status": "done",
                "dir": f"train/{job.name}",
                **counters,
                **{k: result[k] for k in ("best_val", "resumed", "seconds")},
            }
            done = ", ".join(f"{value} {name}" for name, value in counters.items())
            say(f"{key}: done ({done}; best validation {result['best_val']})")


def _run_evaluations(
    spec, out, executor, statuses, failures, task_log, progress, say
) -> list[dict[str, Any]]:
    jobs: list[_EvalJob] = []
    tasks: deque[Task] = deque()  # the executor takes tasks from it as it goes: conclusions join later
    summaries: dict[str, list[dict[str, Any]]] = {}
    try:
        for job in spec.evaluate_jobs:
            key = f"evaluate/{job.name}"
            try:
                ev = _prepare(job, out, statuses)
            except _JobRefused as err:
                statuses[key] = {"status": "failed", "dir": f"evaluate/{job.name}", "error": str(err)}
                failures.append({"job": key, "task": key, "error": str(err), "attempts": 0})
                say(f"{key}: FAILED: {err}")
                continue
            jobs.append(ev)
            tasks.extend(_chunk_tasks(ev, spec))
        # Longest first (episodes x agents): the last chunks to finish are short ones, so the workers
        # end together instead of one finishing a long chunk alone (stable: job order among equals).
        tasks = deque(sorted(tasks, key=lambda t: -t.meta["cost"]))
        total = sum(t.meta["b"] - t.meta["a"] for t in tasks)
        say(
            f"evaluation: {len(jobs)} job(s), {len(tasks)} chunk(s) ({total} episodes) to compute "
            f"on {executor.name}"
        )
        for ev in jobs:
            if not ev.todo:  # resumed whole: only its conclusion is left
                _queue_conclusion(ev, tasks, statuses, failures, say)
        bar = episode_progress(total, 0, progress)
        bar.set_description("sweep")
        try:
            for task, result in executor.run(tasks):
                ev = task.meta["ev"]
                if task.meta.get("conclusion"):
                    _log_task(task_log, task, result)
                    summaries[ev.job.name] = _store_conclusion(ev, task, result, statuses, failures, say)
                    continue
                cell, a, b = task.meta["cell"], task.meta["a"], task.meta["b"]
                if isinstance(result, TaskFailed):
                    _log_task(task_log, task, result)
                    ev.failed.append(task.key)
                    failures.append(
                        {
                            "job": f"evaluate/{ev.job.name}",
                            "task": task.key,
                            "error": result.message,
                            "attempts": result.attempts,
                        }
                    )
                    say(f"{task.key}: FAILED: {result.message}")
                else:
                    reissue_warnings(result["notes"])
                    store_chunk_files(ev.dir, cell, a, b, result["rows_parquet"], result["trajectories"])
                    ev.chunk_bytes[(cell.key, a)] = result["rows_parquet"]
                    # logged after the chunk landed: a logged chunk is never computed again
                    _log_task(task_log, task, result)
                    ev.computed += b - a
                    bar.update(b - a)
                ev.pending -= 1
                if ev.pending == 0:
                    # The job's conclusion runs next on a worker while the others go on with other jobs.
                    _queue_conclusion(ev, tasks, statuses, failures, say)
        finally:
            bar.close()
    finally:
        for ev in jobs:
            ev.release()
    return [row for ev in jobs for row in summaries.get(ev.job.name, [])]


def _queue_conclusion(ev: _EvalJob, tasks: deque[Task], statuses, failures, say) -> None:
    """Queues the conclusion of a job whose chunks all came back, at the front.

    A job with a failed chunk has none (it is marked failed).
    """
    key = f"evaluate/{ev.job.name}"
    if ev.failed:
        _mark_failed(ev, f"{len(ev.failed)} chunk(s) failed (failures.json); rerun to retry them", statuses)
        return
    chunks = []
    try:
        for cell in ev.cells:
            for a, b in cell.chunks(ev.preset.evaluation.chunk_size):
                path = chunk_path(ev.dir, cell, a, b)
                data = ev.chunk_bytes.get((cell.key, a))
                chunks.append((cell, a, b, str(path), data if data is not None else path.read_bytes()))
    except OSError as err:  # a finished chunk file vanished or cannot be read since the job started
        message = f"cannot read {err.filename}: {err.strerror}"
        _mark_failed(ev, message, statuses)
        failures.append({"job": key, "task": f"{key}/conclusion", "error": message, "attempts": 0})
        say(f"{key}: FAILED: {message}")
        return
    ev.chunk_bytes.clear()
    tasks.appendleft(
        Task(
            f"{key}/conclusion",
            conclude_job,
            (ev.job.params, chunks, ev.job.name, ev.stamp),
            meta={"ev": ev, "conclusion": True},
        )
    )


def _store_conclusion(ev: _EvalJob, task: Task, result: Any, statuses, failures, say) -> list[dict[str, Any]]:
    """Writes a job's summary and tables computed by a worker; its summary rows (none if it failed)."""
    key = f"evaluate/{ev.job.name}"
    if isinstance(result, TaskFailed):
        _mark_failed(ev, f"its conclusion failed: {result.message}", statuses)
        failures.append({"job": key, "task": task.key, "error": result.message, "attempts": result.attempts})
        say(f"{task.key}: FAILED: {result.message}")
        return []
    for name, text in result["files"].items():
        atomic_write_text(ev.dir / name, text)
    ev.release()
    statuses[key] = {
        "status": "done",
        "dir": f"evaluate/{ev.job.name}",
        "episodes_computed": ev.computed,
        "episodes": result["episodes"],
    }
    return result["summary"]


def _mark_failed(ev: _EvalJob, error: str, statuses: dict[str, dict[str, Any]]) -> None:
    ev.release()
    statuses[f"evaluate/{ev.job.name}"] = {
        "status": "failed",
        "dir": f"evaluate/{ev.job.name}",
        "error": error,
        "episodes_computed": ev.computed,
    }


class _JobRefused(Exception):
    """An evaluation job that cannot start (its training failed, its checkpoint is refused …)."""


def _prepare(job: Job, out: Path, statuses: dict[str, dict[str, Any]]) -> _EvalJob:
    """Builds the job's policy, writes or checks its manifest and lists the chunks still to compute."""
    checkpoint = job.get("checkpoint")
    if checkpoint is not None and str(checkpoint).startswith(TRAIN_REFERENCE):
        trainer = str(checkpoint)[len(TRAIN_REFERENCE) :]
        if statuses.get(f"train/{trainer}", {}).get("status") == "failed":
            # an earlier call's best.pt may still be there, but it is not this sweep's training
            raise _JobRefused(f"its checkpoint {checkpoint}: the training job train/{trainer} failed in this "
                              "call (see failures.json)")
        trained = out / "train" / trainer / "best.pt"
        if not trained.is_file():
            raise _JobRefused(
                f"its checkpoint {checkpoint} ({trained}) does not exist: the training job "
                "failed or has not finished"
            )
        checkpoint = str(trained)
    batch_size = int(job.get("batch_size", 256))
    trajectories = bool(job.get("trajectories", True))
    try:
        # the job's preset too: a grid axis (another human_model, say) can make a preset its values refuse
        preset = job_preset(job.params)
        policy = build_job_policy(job.params, preset, checkpoint)
        cells = plan_cells(preset, job.get("scenarios"), job.get("episodes"), job.get("visibility"))
        validate_cells(preset, cells, batch_size)
    except (ValueError, KeyError, RuntimeError) as err:
        message = str(err.args[0] if err.args else err)
        # the command line's flag is a key of the job here
        raise _JobRefused(message.replace("--allow-preset-mismatch", "allow_preset_mismatch: true")) from None
    extra: dict[str, Any] = {"checkpoint": checkpoint}
    if checkpoint is not None:
        extra["checkpoint_sha256"] = file_sha256(checkpoint)
    manifest = protocol_manifest(policy, preset, cells, job.name, batch_size, trajectories, extra)
    job_dir = out / "evaluate" / job.name
    make_output_dir(job_dir)
    lock = DirectoryLock(job_dir, "evaluation").__enter__()
    try:
        try:
            plan = resume_directory(job_dir, manifest, cells, preset.evaluation.chunk_size, trajectories)
        except ResumeMismatchError as err:
            raise _JobRefused(str(err)) from None
    except BaseException:
        lock.__exit__(None, None, None)
        raise
    return _EvalJob(
        job, job_dir, policy, preset, checkpoint, cells, manifest_stamp(manifest), extra, plan.todo, lock
    )


def _chunk_tasks(ev: _EvalJob, spec: SweepSpec) -> list[Task]:
    try:
        payload = pickle.dumps(ev.policy)
    except Exception:
        payload = None  # rebuilt in the worker from the job's settings
    batch_size = int(ev.job.get("batch_size", 256))
    trajectories = bool(ev.job.get("trajectories", True))
    job_key = f"{ev.job.name}/{ev.stamp}"

    def humans(cell) -> int:
        return 1 if cell.single_human else ev.preset.evaluation.n_humans

    return [
        Task(
            f"evaluate/{ev.job.name}/{cell.key}/{a}-{b}",
            evaluate_chunk,
            (
                job_key,
                ev.job.params,
                ev.checkpoint,
                cell,
                a,
                b,
                ev.job.name,
                batch_size,
                trajectories,
                spec.threads,
                ev.stamp,
            ),
            payload,
            meta={"ev": ev, "cell": cell, "a": a, "b": b, "cost": (b - a) * (1 + humans(cell))},
        )
        for cell, a, b in ev.todo
    ]

"""Computing a run's chunks: simulation, scoring and storing, in this process or in worker processes.

A chunk is always simulated the same way (same world slots, same batches), wherever it runs, so
results are bit-identical whether it is simulated here, in a pool worker or in a sweep's worker. Three
ways to run a list of chunks (:func:`compute_chunks`):

- in this process (``workers=0``, or a single chunk);
- simulated here, scored and stored by a pool of worker processes while the next chunk is simulated;
- simulated, scored and stored by the workers, each holding a pickled copy of the policy (learned
  policies: on few cores one process per core beats intra-op threads on a draining chunk's small
  batches, docs/protocol.md).
"""

from __future__ import annotations

import dataclasses
import os
import pickle
import warnings
from collections import deque
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any

import numpy as np

from socialnav._progress import progress_bar
from socialnav._runtime import forkserver_pool, main_module_reruns_call, worker_init
from socialnav.evaluate.chunks import Chunk, trajectory_path, write_chunk
from socialnav.evaluate.plan import Cell, cell_scenario, cell_world_settings
from socialnav.metrics import score_episode, side_case_of_row
from socialnav.metrics.score import fill_missing_keys
from socialnav.policies.registry import Policy, PolicyError
from socialnav.presets import Preset
from socialnav.sim.world import World, check_world_size
from socialnav.trajectory import Trajectory

#: Warnings a worker caught while scoring, as ``(category name, message)``.
Notes = list[tuple[str, str]]


def validate_cells(preset: Preset, cells: list[Cell], batch_size: int) -> None:
    """Builds each cell's world settings and scenario and sizes its world, allocating nothing big.

    Everything that can be refused is refused this way before the first result file is written.

    Args:
        preset: The protocol.
        cells: The run's cells.
        batch_size: Episodes simulated in lockstep.

    Raises:
        ValueError: ``batch_size`` is not a positive integer, or a cell's world is too large.
    """
    if not isinstance(batch_size, int) or batch_size < 1:
        raise ValueError(f"batch size must be an integer >= 1, got {batch_size!r}")
    for cell in cells:
        settings = cell_world_settings(preset, cell)
        scenario = cell_scenario(preset, cell)
        check_world_size(settings, min(batch_size, cell.episodes), 1 + int(scenario.n_humans))


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
    """Simulates episodes ``[start, stop)`` of a cell.

    Args:
        policy: The robot policy.
        preset: The protocol.
        cell: The cell.
        start: The first episode index.
        stop: One past the last episode index.
        label: The policy's name in the results (a tag of every trajectory).
        batch_size: Episodes simulated in lockstep.
        until: Stop as soon as the episode of this index has finished (replay of one episode).

    Returns:
        The trajectories, in index order.

    Raises:
        PolicyError: The policy failed or returned unusable actions (:func:`checked_actions`).
    """
    # a policy reading a sensor the world lacks (its lidar) brings it (docs/perception.md)
    settings = cell_world_settings(preset, cell).with_sensors(getattr(policy, "sensors", None))
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
    """``policy.act(obs)``, checked.

    An exception in the policy, or actions of the wrong shape or not finite where an episode runs,
    become a :class:`PolicyError` naming the policy, the cell and the episodes (a user's policy would
    otherwise fail with a bare NumPy or tensor error).

    Args:
        policy: The robot policy.
        obs: The batch's observation.
        world: The world it came from (for the episodes' indices in errors).
        label: The policy's name in errors.
        cell: The cell, named in errors.

    Returns:
        The actions, shape (B, 2), float64.

    Raises:
        PolicyError: As above.
    """

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


def score_trajectories(trajs: list[Trajectory], cell: Cell, label: str) -> tuple[list[dict[str, Any]], Notes]:
    """One result row per episode: identifiers, outcome and every metric.

    Args:
        trajs: The chunk's trajectories, in index order.
        cell: Their cell.
        label: The policy's name in the results.

    Returns:
        The rows, and the warnings scoring raised (to re-issue with :func:`reissue_warnings` where the
        caller sees them, since this may run in a worker process).
    """
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
    # one set of columns per chunk, also where some of its episodes have a static map and some not
    return fill_missing_keys(rows), sorted({(w.category.__name__, str(w.message)) for w in caught})


def episode_id(scenario: str, visibility: str, index: int) -> str:
    """The id of an evaluated episode, e.g. ``passing/invisible/3`` (see evaluate/results.py).

    Args:
        scenario: The scenario's name.
        visibility: ``invisible`` or ``visible``.
        index: The episode's index.

    Returns:
        ``"<scenario>/<visibility>/<index>"``.
    """
    return f"{scenario}/{visibility}/{int(index)}"


def store_and_score(
    trajs: list[Trajectory], cell: Cell, label: str, traj_path: Path | None
) -> tuple[list[dict[str, Any]], Notes]:
    """Writes the chunk's trajectories (when ``traj_path`` is given), then scores them.

    Args:
        trajs: The chunk's trajectories, in index order (their ``episode`` setting is set here).
        cell: Their cell.
        label: The policy's name in the results.
        traj_path: The chunk's trajectory file, or None to keep no trajectories.

    Returns:
        As :func:`score_trajectories`.
    """
    if traj_path is not None:
        from socialnav.trajectory_io import write_trajectories

        for traj in trajs:
            traj.settings["episode"] = episode_id(cell.scenario, cell.visibility, traj.settings["index"])
        write_trajectories(traj_path, trajs)
    return score_trajectories(trajs, cell, label)


def reissue_warnings(notes: Notes) -> None:
    """Re-raises here, where the caller sees them, the warnings a worker collected.

    Args:
        notes: ``(category name, message)`` pairs from :func:`store_and_score` (categories of
            socialnav.metrics; any other becomes a ``UserWarning``).
    """
    import socialnav.metrics as metrics

    for category, message in notes:
        warnings.warn(message, getattr(metrics, category, UserWarning), stacklevel=3)


def scoring_pool(workers: int) -> Any:
    """A pool of worker processes for :func:`store_and_score` and other picklable work.

    The runner's and a sweep's local executor's pool. forkserver: workers start from a clean process,
    so native threads or torch in this one are safe. The forkserver and the workers die with this
    process, even on SIGKILL (socialnav/_runtime.py).

    Args:
        workers: Number of processes.

    Returns:
        A ``concurrent.futures.ProcessPoolExecutor``.
    """
    return forkserver_pool(workers)


def compute_chunks(
    policy: Policy,
    preset: Preset,
    out: Path,
    todo: list[Chunk],
    label: str,
    stamp: str,
    total: int,
    progress: bool,
    batch_size: int,
    workers: int | None,
    trajectories: bool = True,
    simulate_in_workers: bool | None = None,
) -> int:
    """Simulates the chunks ``todo`` and writes each chunk's files as soon as it is scored.

    A chunk lands whole or not at all. Interrupted, the chunks already handed to scoring still land,
    so that a resumed run recomputes nothing that was finished.

    Args:
        policy: The robot policy.
        preset: The protocol.
        out: The result directory.
        todo: The chunks to compute, in order.
        label: The policy's name in the results.
        stamp: The run's manifest fingerprint, stored in every chunk file.
        total: Episodes of the whole run (for the progress bar).
        progress: Show a progress bar on stderr.
        batch_size: Episodes simulated in lockstep.
        workers: Worker processes (None: one per core, at most 4; 0: everything in this process).
        trajectories: Keep every episode's trajectory.
        simulate_in_workers: Simulate in the workers too (None: when the policy can be pickled).

    Returns:
        The number of episodes computed.

    Raises:
        RuntimeError: A worker process died.
        ValueError: ``simulate_in_workers`` is True and the policy cannot be pickled.
    """
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
        write_chunk(out, cell, a, b, rows, stamp)
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


def episode_progress(total: int, initial: int, enabled: bool) -> Any:
    """The progress bar of a run counting episodes, on stderr (:mod:`socialnav._progress`).

    Args:
        total: Episodes of the whole run.
        initial: Episodes already done.
        enabled: False: a silent bar.

    Returns:
        A ``tqdm`` bar.
    """
    return progress_bar(total, initial, unit="ep", enabled=enabled, leave=False)


def _policy_payload(policy: Policy, required: bool) -> bytes | None:
    """The pickled policy for simulation workers, or None when it cannot travel.

    Native policies cannot, and their simulation is cheap anyway; a policy that says
    ``simulates_in_process`` (an exec planner: its work runs in a program of its own) stays here unless
    ``required``.
    """
    if getattr(policy, "simulates_in_process", False) and not required:
        return None
    device = str(getattr(getattr(policy, "value_policy", None), "device", "cpu"))
    if device != "cpu" and not required:
        return None  # one GPU serves one process best; workers would each hold a copy of the network
    try:
        return pickle.dumps(policy)
    except Exception as err:
        if required:
            raise ValueError(f"policy {policy.name!r} cannot be simulated in workers: {err}") from None
        return None


def _simulation_pool(workers: int, payload: bytes, preset: Preset) -> Any:
    # Same lifetime guarantees as the scoring pool (socialnav/_runtime.py); each worker holds the
    # policy, unpickled once.
    # One native thread per world in a worker: the workers already use every core.
    worker_preset = dataclasses.replace(preset, world=dataclasses.replace(preset.world, threads=1))
    return forkserver_pool(workers, _init_simulation_worker, (payload, worker_preset))


_WORKER: dict[str, Any] = {}


def _init_simulation_worker(payload: bytes, preset: Preset) -> None:
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
) -> tuple[list[dict[str, Any]], Notes]:
    trajs = simulate_chunk(_WORKER["policy"], _WORKER["preset"], cell, start, stop, label, batch_size)
    return store_and_score(trajs, cell, label, traj_path)

"""Where a sweep's tasks run: worker processes on this machine, or a Ray cluster.

Both take the same tasks and yield ``(task, result)`` as tasks finish, in any order; a task that
could not be run yields a :class:`TaskFailed` instead of a result. Given a ``deque``, an executor takes
its tasks from it as it goes, so the caller may add tasks while it iterates (a sweep's driver adds an
evaluation job's conclusion when the job's last chunk has come back; added on the left, it runs next).
A task whose *worker died* (killed, out of memory, its machine lost) is run again, up to ``retries``
times; a task that raised an error is not (the same inputs would raise it again) and is reported with
its message.
"""

from __future__ import annotations

import os
import time
import warnings
from collections import Counter, deque
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any


@dataclass(frozen=True)
class Task:
    """One unit of work: ``fn(payload, *args)``.

    Attributes:
        key: The task's name in logs and failures, unique in a sweep.
        fn: A picklable module-level function.
        args: Its arguments after ``payload`` (plain data).
        payload: Bytes shared by many tasks (a pickled policy): Ray stores them once in its object
            store.
        meta: The caller's bookkeeping; never sent to a worker.
    """

    key: str
    fn: Callable[..., Any]
    args: tuple = ()
    payload: bytes | None = None
    meta: dict[str, Any] = field(default_factory=dict, compare=False)


@dataclass(frozen=True)
class TaskFailed:
    """The result of a task that could not be run.

    Attributes:
        message: Its error, on one line.
        attempts: How many times it was run.
    """

    message: str
    attempts: int


def _one_line(err: BaseException) -> str:
    text = " ".join(str(err).split()) or type(err).__name__
    return f"{type(err).__name__}: {text}"


class LocalExecutor:
    """Worker processes on this machine (forkserver; they die with the sweep, see socialnav/_runtime.py)."""

    name = "local"

    def __init__(self, workers: int | None = None, retries: int = 3) -> None:
        """Describes the pool; no process starts before :meth:`run`.

        Args:
            workers: Worker processes (default: one per core).
            retries: Times a task whose worker died is run again, alone.
        """
        self.workers = max(1, workers or (os.cpu_count() or 1))
        self.retries = retries

    def describe(self) -> dict[str, Any]:
        """The executor's settings, as recorded in ``sweep.json``.

        Returns:
            Its name, workers and retries.
        """
        return {"executor": self.name, "workers": self.workers, "retries": self.retries}

    def run(self, tasks: Iterable[Task]) -> Iterator[tuple[Task, Any]]:
        """Runs the tasks on a pool of worker processes.

        Tasks in flight when a worker dies are *suspects*: each is run again alone, so that a death
        is charged to the task that caused it, never to the ones that shared the pool with it.

        Args:
            tasks: The tasks; a ``deque`` is consumed as it goes (the caller may add to it).

        Yields:
            ``(task, result)`` as tasks finish, a :class:`TaskFailed` as the result of one that failed.
        """
        from concurrent.futures import FIRST_COMPLETED, wait
        from concurrent.futures.process import BrokenProcessPool

        queue = tasks if isinstance(tasks, deque) else deque(tasks)
        suspects: deque[Task] = deque()
        attempts: Counter[str] = Counter()
        pending: dict[Any, Task] = {}
        solo: Task | None = None  # the suspect running alone, if any
        if not queue:
            return  # nothing to run: no pool to start
        pool = _process_pool(self.workers)
        try:
            while queue or suspects or pending:
                broken = False
                try:
                    # A task leaves its queue only once submitted: submit raises on a broken pool.
                    if suspects and not pending:
                        solo = suspects[0]
                        future = pool.submit(solo.fn, solo.payload, *solo.args)
                        pending[future] = suspects.popleft()
                    elif not suspects:
                        # A few tasks in flight per worker: a dying worker takes only those with it.
                        while queue and len(pending) < 2 * self.workers:
                            task = queue[0]
                            future = pool.submit(task.fn, task.payload, *task.args)
                            pending[future] = queue.popleft()
                except BrokenProcessPool:  # a worker died while tasks were being handed out
                    broken = True
                    solo = None
                done, _ = wait(pending, return_when=FIRST_COMPLETED) if pending else (set(), set())
                for future in done:
                    task = pending.pop(future)
                    try:
                        result = future.result()
                    except BrokenProcessPool:
                        broken = True
                        if task is solo:
                            attempts[task.key] += 1
                            if attempts[task.key] > self.retries:
                                yield task, TaskFailed(
                                    f"its worker process died {attempts[task.key]} times, run alone",
                                    attempts[task.key],
                                )
                            else:
                                suspects.appendleft(task)
                        else:
                            suspects.append(task)
                    except Exception as err:
                        yield task, TaskFailed(_one_line(err), attempts[task.key] + 1)
                    else:
                        yield task, result
                    if task is solo:
                        solo = None
                if broken:
                    # Every task still in the broken pool fails too: they become suspects, then the
                    # pool starts afresh.
                    for future in list(pending):
                        task = pending.pop(future)
                        try:
                            result = future.result()
                        except BrokenProcessPool:
                            suspects.append(task)
                        except Exception as err:
                            yield task, TaskFailed(_one_line(err), attempts[task.key] + 1)
                        else:
                            yield task, result
                    if suspects:
                        warnings.warn(f"a worker process died: {len(suspects)} task(s) in flight are run "
                                      "again, one at a time, so that a death is charged to the task that "
                                      "causes it (retries counts the deaths of a task running alone)",
                                      RuntimeWarning, stacklevel=2)
                    discard_broken_pool(pool)
                    pool = _process_pool(self.workers)
        except BaseException:
            # Interrupted (Ctrl-C, SIGTERM, an error in the caller): do not wait for running tasks (a
            # training job takes hours); the workers die with this process (socialnav/_runtime.py) and
            # a rerun resumes. A generator closed early (GeneratorExit) lands here too.
            pool.shutdown(wait=False, cancel_futures=True)
            raise
        else:
            pool.shutdown(wait=True)


def discard_broken_pool(pool: Any, poll_s: float = 0.05, give_up_s: float = 60.0) -> None:
    """Shut a broken process pool down without waiting forever on a worker that outlived it.

    When a worker dies, CPython's pool (3.11, 3.12) sends SIGTERM to its other workers and then joins
    them all. A worker that ``submit()`` started while the pool was breaking, or one that does not
    stop on SIGTERM, is never ended and that join blocks, and ``shutdown(wait=True)`` with it (seen as
    a sweep that hung after a worker was killed). Here the pool is told to shut down without waiting
    and every one of its workers still alive is killed until its manager thread has finished. The
    pool's workers and manager thread are private attributes: where they are missing (another Python),
    this is a plain ``shutdown(wait=True)``. A manager thread still running after ``give_up_s`` with
    no worker left alive is left behind with a warning, so the sweep goes on.
    """
    thread = getattr(pool, "_executor_manager_thread", None)
    processes = getattr(pool, "_processes", None)
    if thread is None or processes is None:
        pool.shutdown(wait=True, cancel_futures=True)
        return
    pool.shutdown(wait=False, cancel_futures=True)
    deadline = time.monotonic() + give_up_s
    while True:
        workers = _snapshot(processes)
        for process in workers:
            if process.is_alive():
                process.kill()
        thread.join(timeout=poll_s)
        if not thread.is_alive():
            break
        if time.monotonic() > deadline:
            warnings.warn(
                f"the broken worker pool's manager thread did not stop within {give_up_s:.0f} s after its "
                "workers were killed; it is left behind and a new pool is started",
                RuntimeWarning,
                stacklevel=2,
            )
            return
    for process in _snapshot(processes):
        process.join(timeout=5.0)


def _snapshot(processes: dict[int, Any]) -> list[Any]:
    # The manager thread may add or drop an entry while we copy: copy again.
    for _ in range(100):
        try:
            return list(processes.values())
        except RuntimeError:
            continue
    return []


def _process_pool(workers: int) -> Any:
    # The evaluation runner's pool: forkserver workers that die with this process (socialnav/_runtime.py).
    from socialnav.evaluate.execution import scoring_pool

    return scoring_pool(workers)


class RayExecutor:
    """Tasks on a Ray cluster (``address``), or on a Ray instance started here with ``workers`` CPUs.

    Each task asks for ``cpus_per_task`` CPUs; Ray re-runs a task whose worker or node died up to
    ``retries`` times (``max_retries``) and reports one that raised.
    """

    name = "ray"

    def __init__(
        self,
        address: str | None = None,
        workers: int | None = None,
        retries: int = 3,
        cpus_per_task: float = 1,
    ) -> None:
        """Describes the cluster; Ray is started or joined by :meth:`run`.

        Args:
            address: A Ray cluster's address (None: a Ray instance for this machine).
            workers: CPUs of a Ray instance started here (default: all).
            retries: Times Ray re-runs a task whose worker or node died.
            cpus_per_task: CPUs each task asks for.

        Raises:
            RuntimeError: Ray is not installed.
        """
        # No usage report to Ray's servers from a research tool's sweep (set the variable to 1 to send one).
        os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
        try:
            import ray  # noqa: F401
        except ImportError:
            raise RuntimeError(
                "the ray executor needs Ray: pip install 'socialnav[ray]' (Ray >= 2.9)"
            ) from None
        self.address = address
        self.workers = workers
        self.retries = retries
        self.cpus_per_task = cpus_per_task

    def describe(self) -> dict[str, Any]:
        """The executor's settings, as recorded in ``sweep.json``.

        Returns:
            Its name, address, workers, retries and CPUs per task.
        """
        return {
            "executor": self.name,
            "address": self.address,
            "workers": self.workers,
            "retries": self.retries,
            "cpus_per_task": self.cpus_per_task,
        }

    def run(self, tasks: Iterable[Task]) -> Iterator[tuple[Task, Any]]:
        """Runs the tasks as Ray tasks (starting Ray here if it is not running).

        Args:
            tasks: The tasks; a ``deque`` is consumed as it goes (the caller may add to it).

        Yields:
            ``(task, result)`` as tasks finish, a :class:`TaskFailed` as the result of one that failed.
        """
        import ray

        started_here = not ray.is_initialized()
        if started_here:
            init_ray(self.address, self.workers)
        # SPREAD: chunks go to every node from the start, rather than filling the driver's node first
        # (Ray's default prefers the local node, so short chunks may all finish there while the other
        # nodes are still starting their workers)
        remote = ray.remote(_call).options(
            num_cpus=self.cpus_per_task, max_retries=self.retries, retry_exceptions=False,
            scheduling_strategy="SPREAD",
        )
        stored: dict[int, Any] = {}
        refs: dict[Any, Task] = {}
        queue = tasks if isinstance(tasks, deque) else deque(tasks)
        try:
            while queue or refs:
                while queue:  # everything queued is submitted: Ray schedules it
                    task = queue.popleft()
                    payload = task.payload
                    if payload is not None:
                        if id(payload) not in stored:
                            stored[id(payload)] = ray.put(payload)
                        payload = stored[id(payload)]
                    refs[remote.remote(task.fn, payload, *task.args)] = task
                ready, _ = ray.wait(list(refs), num_returns=1)
                for ref in ready:
                    task = refs.pop(ref)
                    try:
                        result = ray.get(ref)
                    except ray.exceptions.RayTaskError as err:
                        cause = err.cause if getattr(err, "cause", None) is not None else err
                        yield task, TaskFailed(_one_line(cause), 1)
                    except ray.exceptions.RayError as err:
                        yield (
                            task,
                            TaskFailed(f"{_one_line(err)} (after {self.retries} retries)", self.retries + 1),
                        )
                    else:
                        yield task, result
        finally:
            for ref in refs:
                ray.cancel(ref, force=True)
            if started_here:
                ray.shutdown()


def init_ray(address: str | None = None, cpus: int | None = None) -> None:
    """Connects this process to a Ray cluster, or starts a Ray instance for this machine alone.

    A Ray instance started here listens on loopback, reachable from nowhere else, its workers at
    normal priority (Ray's default, nice 15, lets any other process, this driver included, starve the
    sweep's own work). No dashboard, no usage report to Ray's servers (set
    ``RAY_USAGE_STATS_ENABLED=1`` to send one), no worker logs echoed to the driver.

    Args:
        address: The cluster's address (None: start an instance here).
        cpus: CPUs of an instance started here (default: all).
    """
    if address is not None:
        _check_reachable(address)
    import ray

    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    kwargs: dict[str, Any] = {"include_dashboard": False, "logging_level": "ERROR", "log_to_driver": False}
    if address is None:
        kwargs.update(num_cpus=cpus or (os.cpu_count() or 1), _node_ip_address="127.0.0.1")
        os.environ.setdefault("RAY_worker_niceness", "0")
    ray.init(address=address, **kwargs)


def _check_reachable(address: str, timeout_s: float = 10.0) -> None:
    """Refuses a cluster address nothing answers at, before ``ray.init`` waits on it for minutes.

    ``HOST:PORT`` and ``ray://HOST:PORT`` are probed with one TCP connection; other forms (``auto``)
    are Ray's to resolve.

    Raises:
        ConnectionError: Nothing accepts a connection there within ``timeout_s``.
    """
    import socket

    host, sep, port = address.removeprefix("ray://").rpartition(":")
    if not sep or not host or not port.isdigit():
        return
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=timeout_s):
            pass
    except OSError as err:
        raise ConnectionError(
            f"--address {address}: no Ray cluster answers there ({err.strerror or type(err).__name__}); "
            "start one with `ray start --head` on that machine, or leave --address out to run Ray here"
        ) from None


def _call(fn: Callable[..., Any], payload: Any, *args: Any) -> Any:
    return fn(payload, *args)


def make_executor(
    name: str, *, workers: int | None = None, retries: int = 3, address: str | None = None
) -> LocalExecutor | RayExecutor:
    """The executor ``socialnav sweep --executor`` names.

    Args:
        name: ``local`` or ``ray``.
        workers: Worker processes (local) or CPUs of a Ray instance started here.
        retries: Times a task whose worker died is run again.
        address: A Ray cluster's address (ray only).

    Returns:
        The executor.

    Raises:
        ValueError: An unknown name, or an address for the local executor.
        ConnectionError: Nothing answers at ``address``.
    """
    if name == "local":
        if address is not None:
            raise ValueError("--address is for the ray executor (the local one runs on this machine)")
        return LocalExecutor(workers, retries)
    if name == "ray":
        if address is not None:
            _check_reachable(address)  # before the sweep writes anything
        return RayExecutor(address, workers, retries)
    raise ValueError(f"executor must be local or ray, got {name!r}")

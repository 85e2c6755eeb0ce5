"""A native policy built in a sweep worker gets the worker's thread count, not one thread per core.

Workers already fill the cores; a policy pool of one thread per core in each of them woke threads that
had no core to run on (measured: every task ≈ 10 % slower with two workers on two cores).
"""

from __future__ import annotations

import pyarrow as pa
import pyarrow.parquet as pq

from socialnav.evaluate.plan import Cell
from socialnav.policies.registry import get_policy_entry
from socialnav.sim.settings import WorldSettings
from socialnav.sweep import tasks
from socialnav.sweep.tasks import build_job_policy, evaluate_chunk, job_preset

PARAMS = {"policy": "orca", "preset": "wang2022"}
CELL = Cell("circle_crossing", "invisible", 6, False)


def _chunk(params: dict, threads: int) -> list[dict]:
    result = evaluate_chunk(
        None, f"job-{threads}-{sorted(params)}", params, None, CELL, 0, 6, "orca", 6, False, threads, "s"
    )
    # An Arrow buffer, not io.BytesIO: Arrow's threads must not hold a Python file object at exit.
    rows = pq.read_table(pa.BufferReader(result["rows_parquet"])).to_pylist()
    return [{k: repr(v) for k, v in row.items()} for row in rows]  # NaN-aware equality


def test_worker_policy_takes_the_workers_threads() -> None:
    rows = _chunk(PARAMS, threads=1)
    (policy,) = tasks._POLICIES.values()
    assert policy._pool.size == 1
    # The job's own setting wins; the results do not depend on the thread count.
    explicit = {**PARAMS, "policy_args": {"threads": 2}}
    assert _chunk(explicit, threads=1) == rows
    (policy,) = tasks._POLICIES.values()
    assert policy._pool.size == 2


def test_driver_side_build_keeps_the_policys_default() -> None:
    preset = job_preset(PARAMS)
    default = WorldSettings(threads=get_policy_entry("orca").parameters["threads"]).resolved_threads
    assert build_job_policy(PARAMS, preset, None)._pool.size == default
    assert build_job_policy(PARAMS, preset, None, threads=1)._pool.size == 1


def test_a_learned_policy_is_built_in_a_worker_without_a_threads_argument() -> None:
    # Learned policies take no `threads` (torch's threads are set apart): the override only goes to
    # factories that declare it, so a worker still builds them.
    params = {"policy": "sarl", "preset": "wang2022"}
    assert "threads" not in get_policy_entry("sarl").parameters
    policy = build_job_policy(params, job_preset(params, threads=1), None, threads=1)
    assert policy.name == "sarl"

"""Sweeps: the sweep file, the local executor, resumption after a killed driver or worker, and equality
with ``socialnav evaluate`` (the Ray executor is tested in test_ray.py)."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pyarrow.parquet as pq
import pytest
import yaml

from socialnav.cli import main
from socialnav.evaluate.runner import run_protocol
from socialnav.policies.building import build_policy
from socialnav.presets import load_preset
from socialnav.settings import ConfigError
from socialnav.sweep.driver import run_sweep
from socialnav.sweep.executors import LocalExecutor
from socialnav.sweep.spec import load_sweep, parse_sweep
from tests._env import subprocess_env
from tests.cli.test_faults import alive, descendants

ROOT = Path(__file__).resolve().parents[2]
POLICIES = "tests.sweep.fault_policy"


def small_preset(tmp_path: Path, chunk_size: int = 4) -> str:
    """wang2022 with small chunks, so that a few episodes make several tasks."""
    data = load_preset("wang2022").to_dict()
    data["evaluation"]["chunk_size"] = chunk_size
    path = tmp_path / "small.yaml"
    path.write_text(yaml.safe_dump(data))
    return str(path)


def write_sweep(tmp_path: Path, data: dict, name: str = "sweep.yaml") -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data))
    return path


def episode_rows(directory: Path) -> list[dict]:
    """Every episode row under a result directory, in a canonical order, NaN made comparable."""
    rows = []
    for f in sorted(directory.glob("episodes/*/*.parquet")):
        rows.extend(pq.read_table(f).to_pylist())
    for row in rows:
        for k, v in row.items():
            if isinstance(v, float) and math.isnan(v):
                row[k] = "nan"
    return sorted(rows, key=lambda r: (r["scenario"], r["visibility"], r["index"]))


def trajectory_tables(directory: Path) -> dict[str, object]:
    return {
        str(f.relative_to(directory)): pq.read_table(f) for f in sorted(directory.glob("trajectories/*/*"))
    }


# --- the sweep file -----------------------------------------------------------------------------------


def test_grid_expands_to_named_jobs_with_defaults(tmp_path):
    spec = parse_sweep(
        {
            "defaults": {"preset": "wang2022", "episodes": 5, "config": "smoke"},
            "grid": [
                {"kind": "evaluate", "policy": ["linear", "orca"], "human_model": ["orca", "social_force"]},
                {"kind": "train", "policy": "sarl", "seed": [0, 1], "name": "sarl-s{seed}"},
            ],
            "jobs": [
                {
                    "kind": "evaluate",
                    "policy": "sarl",
                    "checkpoint": "train:sarl-s{seed}",
                    "seed": [0, 1],
                    "name": "sarl-s{seed}",
                }
            ],
        }
    )
    names = [(j.kind, j.name) for j in spec.jobs]
    assert names == [
        ("evaluate", "linear-human_model=orca"),
        ("evaluate", "linear-human_model=social_force"),
        ("evaluate", "orca-human_model=orca"),
        ("evaluate", "orca-human_model=social_force"),
        ("train", "sarl-s0"),
        ("train", "sarl-s1"),
        ("evaluate", "sarl-s0"),
        ("evaluate", "sarl-s1"),
    ]
    # defaults go only where the job's kind takes them
    assert spec.jobs[0].params["episodes"] == 5 and "config" not in spec.jobs[0].params
    assert spec.train_jobs[0].params["config"] == "smoke" and "episodes" not in spec.train_jobs[0].params
    assert spec.evaluate_jobs[-1].params["checkpoint"] == "train:sarl-s1"


@pytest.mark.parametrize(
    ("data", "message"),
    [
        (
            {"jobs": [{"kind": "evaluate", "policy": "orca", "episodez": 3}]},
            r"jobs\[0\]: unknown setting\(s\) episodez \(did you mean episodes\?\)",
        ),
        ({"jobs": [{"kind": "evaluate", "policy": "nope"}]}, r"jobs\[0\].*unknown policy 'nope'"),
        (
            {"jobs": [{"kind": "evaluate", "policy": "sarl", "checkpoint": "missing.pt"}]},
            r"jobs\[0\].*checkpoint missing.pt does not exist",
        ),
        (
            {"jobs": [{"kind": "evaluate", "policy": "sarl", "checkpoint": "train:x"}]},
            r"jobs\[0\].*'train:x' names no training job",
        ),
        (
            {"grid": {"kind": "evaluate", "policy": ["orca", "orca"]}},
            r"grid\[0\]\{policy=orca\}.*job name 'orca' is also the name of another job of the same entry",
        ),
        ({"jobs": [{"kind": "evaluate", "policy": "orca", "preset": "nope"}]}, r"jobs\[0\].*unknown preset"),
        ({"jobs": [{"kind": "evaluate", "policy": "orca", "scenarios": ["nope"]}]}, r"jobs\[0\].*nope"),
        ({"jobs": [{"kind": "evaluate", "policy": "orca", "human_model": "rvo"}]}, r"jobs\[0\]: human_model"),
        ({"jobs": [{"kind": "evaluate", "policy": "orca", "episodes": 0}]}, r"jobs\[0\]: episodes must be"),
        ({"jobs": [{"kind": "train", "policy": "orca"}]}, r"jobs\[0\]: policy 'orca' does not learn"),
        ({"jobs": [{"kind": "train", "policy": "sarl", "config": "nope.yaml"}]}, r"jobs\[0\]: config"),
        ({"jobs": [{"kind": "fly", "policy": "orca"}]}, r"jobs\[0\]: kind must be"),
        ({"jobs": [{"kind": "evaluate", "policy": "orca", "name": "{nope}"}]}, r"name template"),
        ({"jobs": [{"kind": "evaluate", "policy": "orca"}], "executor": "slurm"}, r"executor must be"),
        (
            {"jobs": [{"kind": "evaluate", "policy": "orca"}], "wokers": 2},
            r"unknown setting.*wokers \(did you mean workers\?\)",
        ),
        ({"grid": {"kind": "evaluate", "policy": []}}, r"policy is an empty list"),
        ({"jobs": [{"kind": "evaluate"}]}, r"jobs\[0\]: an evaluate job needs policy:"),
        (
            {"jobs": [{"kind": "evaluate", "policy": "orca", "name": "../../escape"}]},
            r"job name '../../escape' \(as a directory: '.._.._escape'\) may hold only",
        ),
        (
            {"jobs": [{"kind": "evaluate", "policy": "orca", "policy_args": {"safety_space": 0.1},
                       "name": "slow-{policy_args}"}]},
            r"name template 'slow-\{policy_args\}': policy_args is a list or mapping, which a name cannot",
        ),
        (
            {"grid": {"kind": "evaluate", "policy": "orca", "scenarios": []}},
            r"grid\[0\]: scenarios is an empty list; leave the key out to run the preset's scenarios",
        ),
        (
            {"jobs": [{"kind": "evaluate", "policy": "orca", "scenarios": ["passing", "passing"]}]},
            r"jobs\[0\]: scenarios: passing given more than once",
        ),
        (
            {"jobs": [{"kind": "evaluate", "policy": "orca", "information": "oracle"}]},
            r"jobs\[0\]: information applies to the value-based learned policies .* 'orca' has no informat",
        ),
        (
            {"jobs": [{"kind": "evaluate", "policy": "orca", "policy_args": {"safety_spaec": 0.1}}]},
            r"jobs\[0\]: policy_args: policy 'orca' has no parameter\(s\) safety_spaec; valid: safety_space",
        ),
        (
            {"jobs": [{"kind": "evaluate", "policy": "sarl", "policy_args": {"planning_depth": 0}}]},
            r"jobs\[0\]: policy_args: policy 'sarl': planning_depth must be an integer >= 1",
        ),
        ({}, r"no jobs"),
    ],
)
def test_bad_sweep_is_refused_naming_the_entry(data, message):
    with pytest.raises(ConfigError, match=message):
        parse_sweep(data, source="s.yaml")


def test_bad_sweep_file_from_the_cli_is_one_line_and_starts_nothing(tmp_path, capsys):
    path = write_sweep(
        tmp_path,
        {
            "jobs": [
                {"kind": "evaluate", "policy": "orca", "episodes": 2},
                {"kind": "evaluate", "policy": "sarl", "checkpoint": "gone.pt"},
            ]
        },
    )
    code = main(["sweep", str(path), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and "jobs[1]" in err[0] and "gone.pt does not exist" in err[0]
    assert not (tmp_path / "out").exists()  # the valid first job did not start either


# --- running ------------------------------------------------------------------------------------------


def test_local_sweep_equals_socialnav_evaluate_bit_for_bit(tmp_path):
    preset = small_preset(tmp_path)
    scenarios = ["circle_crossing", "passing"]
    path = write_sweep(
        tmp_path,
        {
            "defaults": {"preset": preset, "episodes": 10, "scenarios": scenarios},
            "grid": {
                "kind": "evaluate",
                "policy": ["orca", f"{POLICIES}:StraightToGoal"],
                "human_model": ["orca", "social_force"],
            },
        },
    )
    spec = load_sweep(path)
    one = run_sweep(spec, tmp_path / "w1", LocalExecutor(1), progress=False)
    two = run_sweep(spec, tmp_path / "w2", LocalExecutor(2), progress=False)
    assert one.ok and two.ok and len(one.jobs) == 4
    # one reference per job from the runner itself (what `socialnav evaluate` runs)
    for job in spec.jobs:
        p = load_preset(preset)
        if job.get("human_model") == "social_force":
            import dataclasses

            p = dataclasses.replace(p, world=dataclasses.replace(p.world, human_model="social_force"))
        ref = run_protocol(
            build_policy(job.get("policy"), p),
            p,
            tmp_path / "ref" / job.name,
            label=job.name,
            scenarios=scenarios,
            episodes=10,
            progress=False,
            workers=0,
        )
        for run in (one, two):
            got = run.out_dir / "evaluate" / job.name
            assert episode_rows(got) == episode_rows(ref.out_dir)
            assert trajectory_tables(got).keys() == trajectory_tables(ref.out_dir).keys()
            assert all(
                a.equals(b)
                for a, b in zip(trajectory_tables(got).values(), trajectory_tables(ref.out_dir).values(),
                                strict=True)
            )
            assert (
                json.loads((got / "summary.json").read_text())["rows"]
                == json.loads((ref.out_dir / "summary.json").read_text())["rows"]
            )
            # the conclusion computed by a worker writes the very files the runner writes
            for name in ("summary.json", "summary.csv", "table2.md", "table2.tex", "table3.md", "table3.tex"):
                assert (got / name).read_text() == (ref.out_dir / name).read_text(), name
    # one set of tables over every job, and every finished chunk logged once
    summary = json.loads((one.out_dir / "summary.json").read_text())["rows"]
    assert {r["policy"] for r in summary} == {j.name for j in spec.jobs}
    assert "orca-human_model=social_force" in (one.out_dir / "table2.md").read_text()
    log = [json.loads(x) for x in (one.out_dir / "sweep_log.jsonl").read_text().splitlines()]
    assert len(log) == len({x["task"] for x in log}) == 4 * 3 * 3 + 4  # 3 cells x 3 chunks, 1 conclusion
    # each job's conclusion (summary, CIs, tables) ran in a worker process, after the job's chunks
    conclusions = [x for x in log if x["task"].endswith("/conclusion")]
    assert {x["task"] for x in conclusions} == {f"evaluate/{j.name}/conclusion" for j in spec.jobs}
    assert all(x["where"]["pid"] != os.getpid() for x in conclusions)
    for x in conclusions:
        job = x["task"][: -len("/conclusion")]
        assert max(y["time"] for y in log if y["task"].startswith(job + "/") and y is not x) <= x["time"]
    # a rerun computes nothing and changes nothing
    before = (one.out_dir / "summary.json").read_text()
    again = run_sweep(spec, tmp_path / "w1", LocalExecutor(2), progress=False)
    assert all(s["episodes_computed"] == 0 for s in again.jobs.values())
    assert (again.out_dir / "summary.json").read_text() == before


def test_a_killed_worker_is_retried_and_results_equal_an_undisturbed_run(tmp_path):
    preset = small_preset(tmp_path)
    marker = tmp_path / "died"

    def sweep(cls: str, out: str):
        data = {
            "jobs": [
                {
                    "kind": "evaluate",
                    "policy": f"{POLICIES}:{cls}",
                    "name": "straight",
                    "preset": preset,
                    "episodes": 12,
                    "scenarios": ["circle_crossing"],
                    "policy_args": {"marker": str(marker)},
                }
            ]
        }
        return run_sweep(parse_sweep(data), tmp_path / out, LocalExecutor(2, retries=2), progress=False)

    with pytest.warns(RuntimeWarning, match=r"a worker process died: \d+ task\(s\) in flight are run again"):
        faulty = sweep("DiesOnce", "faulty")
    assert marker.exists(), "the worker did not die: the test tested nothing"
    clean = sweep("StraightToGoal", "clean")
    assert faulty.ok, faulty.failures
    assert episode_rows(faulty.out_dir / "evaluate/straight") == episode_rows(
        clean.out_dir / "evaluate/straight"
    )
    episodes = [(r["visibility"], r["index"]) for r in episode_rows(faulty.out_dir / "evaluate/straight")]
    assert len(set(episodes)) == len(episodes) == 24  # invisible + visible, no duplicates


@pytest.mark.filterwarnings("ignore:a worker process died")
@pytest.mark.parametrize("workers", [1, 2])
def test_local_executor_charges_a_death_to_its_task_only_and_loses_nothing(workers):
    from socialnav.sweep.executors import Task, TaskFailed
    from tests.sweep.fault_policy import value_or_death

    deadly = (2, 5)
    tasks = [Task(f"t{i}", value_or_death, (i, deadly)) for i in range(8)]
    got = {task.key: result for task, result in LocalExecutor(workers, retries=1).run(tasks)}
    assert sorted(got) == sorted(t.key for t in tasks)  # every task comes back, once
    for i in range(8):
        if i in deadly:
            assert isinstance(got[f"t{i}"], TaskFailed) and got[f"t{i}"].attempts == 2
            assert "died 2 times, run alone" in got[f"t{i}"].message
        else:  # shared the pool with a dying task, yet never charged for it
            assert got[f"t{i}"] == i


def test_a_broken_pool_is_discarded_even_when_one_of_its_workers_outlives_sigterm():
    """CPython's broken pool SIGTERMs its workers, then joins them all: one that survives (a worker
    started by a submit() racing the breakage, here one that ignores SIGTERM) blocks that join, and
    shutdown(wait=True) with it. The executor's discard must end it and return."""
    import multiprocessing
    import threading
    from concurrent.futures.process import BrokenProcessPool

    from socialnav.sweep.executors import _process_pool, discard_broken_pool
    from tests.sweep.fault_policy import ignore_sigterm_and_sleep, value_or_death

    pool = _process_pool(1)
    assert pool.submit(value_or_death, None, 1, ()).result(timeout=60) == 1  # manager thread running
    ctx = multiprocessing.get_context("forkserver")
    ready = ctx.Event()
    stray = ctx.Process(target=ignore_sigterm_and_sleep, args=(ready,), daemon=True)
    stray.start()
    try:
        assert ready.wait(60)
        pool._processes[stray.pid] = stray  # as if submit() had started it while the pool broke
        with pytest.raises(BrokenProcessPool):
            pool.submit(value_or_death, None, 2, (2,)).result(timeout=60)
        manager = pool._executor_manager_thread
        manager.join(timeout=1.0)
        assert manager.is_alive(), "the pool's own shutdown did not hang: the test tested nothing"
        assert stray.is_alive()
        done = threading.Thread(target=discard_broken_pool, args=(pool,), daemon=True)
        done.start()
        done.join(timeout=60)
        assert not done.is_alive(), "discard_broken_pool hung"
        assert not manager.is_alive() and not stray.is_alive()
    finally:
        if stray.is_alive():
            stray.kill()
            stray.join(5)


def test_discarding_a_pool_whose_manager_never_stops_warns_and_returns():
    import threading

    from socialnav.sweep.executors import discard_broken_pool

    release = threading.Event()

    class StuckPool:  # a manager thread blocked on something other than a live worker
        def __init__(self):
            self._processes = {}
            self._executor_manager_thread = threading.Thread(target=release.wait, daemon=True)
            self._executor_manager_thread.start()
            self.shutdown_calls = []

        def shutdown(self, wait=True, cancel_futures=False):
            self.shutdown_calls.append((wait, cancel_futures))

    pool = StuckPool()
    try:
        with pytest.warns(RuntimeWarning, match="did not stop within"):
            discard_broken_pool(pool, poll_s=0.01, give_up_s=0.2)
        assert pool.shutdown_calls == [(False, True)]  # never a shutdown that waits
    finally:
        release.set()


def test_a_task_that_keeps_failing_is_reported_not_dropped(tmp_path, capsys):
    preset = small_preset(tmp_path)
    path = write_sweep(
        tmp_path,
        {
            "retries": 1,
            "jobs": [
                {
                    "kind": "evaluate",
                    "policy": "orca",
                    "preset": preset,
                    "episodes": 4,
                    "scenarios": ["circle_crossing"],
                },
                # a policy whose worker dies every time: marker path that can never be created
                {
                    "kind": "evaluate",
                    "policy": f"{POLICIES}:DiesOnce",
                    "name": "dies",
                    "preset": preset,
                    "episodes": 4,
                    "scenarios": ["circle_crossing"],
                    "policy_args": {"marker": str(tmp_path / "no" / "such" / "dir")},
                },
            ],
        },
    )
    code = main(["sweep", str(path), "--out", str(tmp_path / "out"), "--quiet", "--workers", "1"])
    err = capsys.readouterr().err
    assert code == 1
    jobs = json.loads((tmp_path / "out/jobs.json").read_text())
    failures = json.loads((tmp_path / "out/failures.json").read_text())
    assert jobs["evaluate/orca"]["status"] == "done"
    assert jobs["evaluate/dies"]["status"] == "failed"
    assert failures and all(f["job"] == "evaluate/dies" for f in failures)
    assert "error: evaluate/dies/" in err


def test_a_damaged_chunk_fails_its_job_by_name_and_the_other_jobs_conclude(tmp_path):
    preset = small_preset(tmp_path)
    spec = parse_sweep(
        {
            "defaults": {"preset": preset, "episodes": 8, "scenarios": ["circle_crossing"]},
            "grid": {"kind": "evaluate", "policy": ["linear", "orca"]},
        }
    )
    first = run_sweep(spec, tmp_path / "out", LocalExecutor(2), progress=False)
    assert first.ok
    damaged = sorted((tmp_path / "out/evaluate/orca/episodes").glob("*/*.parquet"))[0]
    damaged.write_bytes(damaged.read_bytes()[:100])  # truncated after it landed
    again = run_sweep(spec, tmp_path / "out", LocalExecutor(2), progress=False)
    assert not again.ok
    assert again.jobs["evaluate/linear"]["status"] == "done"
    failed = again.jobs["evaluate/orca"]
    assert failed["status"] == "failed" and str(damaged) in failed["error"]
    assert [f["task"] for f in again.failures] == ["evaluate/orca/conclusion"]
    assert str(damaged) in again.failures[0]["error"] and "damaged" in again.failures[0]["error"]
    # the other job's summary is still there, the damaged file is kept for the user to look at
    assert {r["policy"] for r in again.summary} == {"linear"}
    assert damaged.stat().st_size == 100


def test_a_foreign_chunk_refuses_its_job_by_name_and_the_other_jobs_conclude(tmp_path):
    # The sweep decides what to resume exactly as `socialnav evaluate` does (evaluate.manifest): a
    # chunk file that is not part of the job's run refuses that job before anything is computed.
    preset = small_preset(tmp_path)
    spec = parse_sweep(
        {
            "defaults": {"preset": preset, "episodes": 4, "scenarios": ["circle_crossing"]},
            "grid": {"kind": "evaluate", "policy": ["linear", "orca"]},
        }
    )
    foreign = tmp_path / "out/evaluate/orca/episodes/circle_crossing__invisible/00004-00008.parquet"
    foreign.parent.mkdir(parents=True)
    foreign.write_bytes(b"not this run's")
    result = run_sweep(spec, tmp_path / "out", LocalExecutor(1), progress=False)
    assert result.jobs["evaluate/linear"]["status"] == "done"
    refused = result.jobs["evaluate/orca"]
    assert refused["status"] == "failed" and str(foreign) in refused["error"]
    assert "not part of this run" in refused["error"]
    assert [f["job"] for f in result.failures] == ["evaluate/orca"]
    assert not (foreign.parent / "00000-00004.parquet").exists()  # nothing computed for it


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM], ids=["SIGKILL", "SIGTERM"])
def test_a_killed_driver_resumes_without_recomputing_or_duplicating(tmp_path, sig):
    preset = small_preset(tmp_path, chunk_size=25)
    path = write_sweep(
        tmp_path,
        {
            "workers": 1,
            "jobs": [
                {
                    "kind": "evaluate",
                    "policy": "orca",
                    "preset": preset,
                    "episodes": 200,
                    "scenarios": ["circle_crossing", "random"],
                    "visibility": "invisible",
                }
            ],
        },
    )
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "socialnav.cli", "sweep", str(path), "--out", str(out), "--quiet"]
    env = subprocess_env(ROOT)
    proc = subprocess.Popen(cmd, env=env, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    chunks = out / "evaluate" / "orca" / "episodes"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and len(list(chunks.glob("*/*.parquet"))) < 2:
        time.sleep(0.05)
    tree = descendants(proc.pid)  # forkserver, resource tracker, worker
    assert tree, "the sweep had no worker process"
    proc.send_signal(sig)
    _, stderr = proc.communicate(timeout=60)  # returns only once nobody holds its stderr
    if sig == signal.SIGTERM:
        assert proc.returncode == 143 and b"terminated (SIGTERM)" in stderr
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline and any(alive(p) for p in tree):
        time.sleep(0.1)
    assert not [p for p in tree if alive(p)], "a process of the killed sweep is still running"
    before = {f: f.stat().st_mtime_ns for f in chunks.glob("*/*.parquet")}
    assert 2 <= len(before) < 16, "the driver was not killed mid-run"
    subprocess.run(cmd, env=env, cwd=ROOT, check=True, timeout=300)
    after = {f: f.stat().st_mtime_ns for f in chunks.glob("*/*.parquet")}
    assert len(after) == 16 and all(after[f] == t for f, t in before.items())  # nothing finished redone
    log = [json.loads(x)["task"] for x in (out / "sweep_log.jsonl").read_text().splitlines()]
    assert len(log) == len(set(log)), "a chunk that had landed was computed again"
    reference = run_sweep(load_sweep(path), tmp_path / "ref", LocalExecutor(2), progress=False)
    rows = episode_rows(out / "evaluate/orca")
    assert rows == episode_rows(reference.out_dir / "evaluate/orca")
    assert len({(r["scenario"], r["index"]) for r in rows}) == len(rows) == 400


def test_training_then_evaluating_its_checkpoint(tmp_path):
    preset = small_preset(tmp_path)
    path = write_sweep(
        tmp_path,
        {
            "defaults": {"preset": preset},
            "jobs": [
                {
                    "kind": "train",
                    "policy": "sarl",
                    "seed": 3,
                    "config": "smoke",
                    "rl_episodes": 8,
                    "name": "sarl-s{seed}",
                },
                {
                    "kind": "evaluate",
                    "policy": "sarl",
                    "checkpoint": "train:sarl-s{seed}",
                    "seed": 3,
                    "name": "sarl-s{seed}",
                    "episodes": 4,
                    "scenarios": ["circle_crossing"],
                    "visibility": "invisible",
                },
            ],
        },
    )
    result = run_sweep(load_sweep(path), tmp_path / "out", LocalExecutor(1), progress=False,
                       log=lambda _: None)
    assert result.ok, result.failures
    assert result.jobs["train/sarl-s3"]["episodes"] == 8
    manifest = json.loads((tmp_path / "out/evaluate/sarl-s3/manifest.json").read_text())
    assert manifest["checkpoint"] == str(tmp_path / "out/train/sarl-s3/best.pt")
    assert len(episode_rows(tmp_path / "out/evaluate/sarl-s3")) == 4
    assert (tmp_path / "out/summary.json").is_file()
    # The training changed: refused on resume. Its evaluation must not run on the earlier best.pt, and
    # the earlier combined tables, of which no job has rows now, must not stay as this call's.
    data = yaml.safe_load(path.read_text())
    data["jobs"][0]["collection_batch"] = 8
    path.write_text(yaml.safe_dump(data))
    again = run_sweep(load_sweep(path), tmp_path / "out", LocalExecutor(1), progress=False)
    assert again.jobs["train/sarl-s3"]["status"] == "failed"
    assert again.jobs["evaluate/sarl-s3"]["status"] == "failed"
    assert "the training job train/sarl-s3 failed in this call" in again.jobs["evaluate/sarl-s3"]["error"]
    assert not (tmp_path / "out/summary.json").exists() and not (tmp_path / "out/table2.md").exists()


def test_a_checkpoint_of_another_preset_names_the_sweep_key_that_allows_it(tmp_path):
    pytest.importorskip("torch")
    from socialnav.policies.building import shipped_checkpoint

    crowdnav_sarl = str(shipped_checkpoint("sarl", "crowdnav"))
    path = write_sweep(tmp_path, {"jobs": [{"kind": "evaluate", "policy": "sarl", "checkpoint": crowdnav_sarl,
                                            "preset": "wang2022", "episodes": 1, "scenarios": ["passing"]}]})
    result = run_sweep(load_sweep(path), tmp_path / "out", LocalExecutor(1), progress=False)
    error = result.jobs["evaluate/sarl"]["error"]
    assert "allow_preset_mismatch: true" in error and "--allow-preset-mismatch" not in error


def test_jobs_of_several_presets_say_so_in_the_combined_summary(tmp_path):
    path = write_sweep(
        tmp_path,
        {
            "defaults": {"episodes": 2, "scenarios": ["circle_crossing"], "visibility": "invisible"},
            "jobs": [
                {"kind": "evaluate", "policy": "orca", "preset": "wang2022", "name": "orca-wang"},
                {"kind": "evaluate", "policy": "orca", "preset": "crowdnav", "name": "orca-crowdnav"},
            ],
        },
    )
    result = run_sweep(load_sweep(path), tmp_path / "out", LocalExecutor(1), progress=False)
    assert result.ok, result.failures
    summary = json.loads((tmp_path / "out/summary.json").read_text())
    assert summary["preset"] == "wang2022, crowdnav"
    assert summary["presets"] == {"orca-wang": "wang2022", "orca-crowdnav": "crowdnav"}
    assert any(n.startswith("wang2022 (orca-wang): robot v_pref 1.5 m/s") for n in summary["notes"])
    assert any(n.startswith("crowdnav (orca-crowdnav): robot v_pref 1 m/s") for n in summary["notes"])
    assert "rows of different presets do not compare: wang2022: orca-wang; crowdnav: orca-crowdnav" in (
        tmp_path / "out/table2.md").read_text()
    data = yaml.safe_load(path.read_text())
    del data["jobs"][1]  # the grid edited: the other job's directory stays, and the log says so
    path.write_text(yaml.safe_dump(data))
    lines: list[str] = []
    run_sweep(load_sweep(path), tmp_path / "out", LocalExecutor(1), progress=False, log=lines.append)
    assert ("evaluate/{orca-crowdnav}: not jobs of this sweep file, left out of the combined tables"
            in lines), lines
    assert json.loads((tmp_path / "out/summary.json").read_text())["preset"] == "wang2022"
    # an evaluation does not write its tables over a sweep's, nor a sweep over an evaluation's
    evaluate = ["evaluate", "--policy", "orca", "--episodes", "1", "--scenario", "passing", "--no-progress"]
    assert main([*evaluate, "--out", str(tmp_path / "out")]) == 2
    with pytest.raises(RuntimeError, match=r"holds the results of an evaluation of one policy \(manifest"):
        run_sweep(load_sweep(path), tmp_path / "out/evaluate/orca-wang", LocalExecutor(1), progress=False)


@pytest.mark.parametrize("label, said", [("train/sarl-s3", "train/sarl-s3: after imitation: 0.5\n"),
                                          (None, "")])
def test_a_training_jobs_lines_name_the_job_or_are_silenced(tmp_path, capsys, monkeypatch, label, said):
    from types import SimpleNamespace

    import socialnav.train.value.trainer as trainer
    from socialnav.sweep.tasks import train_job

    # the trainer's log, not its work
    def fake_train(policy, preset, out, settings, progress, stop_after, log):
        log("after imitation: 0.5")
        return SimpleNamespace(out_dir=out, best_checkpoint=out, episodes=0, gradient_steps=0, best_val={},
                               wall_time=0.0, resumed=False)

    monkeypatch.setattr(trainer, "train", fake_train)
    train_job(None, {"policy": "sarl", "preset": "wang2022"}, str(tmp_path), 1, label)
    assert capsys.readouterr().err == said  # several jobs train at once: each line says whose it is


def test_a_ppo_training_job_then_evaluating_its_checkpoint(tmp_path):
    # crowdnav_pp trains with PPO (its own settings: ppo_smoke, env_steps), as `socialnav train` does
    preset = small_preset(tmp_path)
    jobs = [
        {"kind": "train", "policy": "crowdnav_pp", "config": "ppo_smoke", "env_steps": 128, "name": "pp"},
        {"kind": "evaluate", "policy": "crowdnav_pp", "checkpoint": "train:pp", "name": "pp", "episodes": 2,
         "scenarios": ["circle_crossing"], "visibility": "invisible"},
    ]
    path = write_sweep(tmp_path, {"defaults": {"preset": preset}, "jobs": jobs})
    result = run_sweep(load_sweep(path), tmp_path / "out", LocalExecutor(1), progress=False)
    assert result.ok, result.failures
    assert result.jobs["train/pp"]["status"] == "done"
    assert (tmp_path / "out/train/pp/best.pt").is_file()
    assert len(episode_rows(tmp_path / "out/evaluate/pp")) == 2
    # the value-based trainer's settings are refused for a PPO job, and the other way round
    with pytest.raises(ConfigError, match=r"rl_episodes: not a setting of the PPO trainer of 'crowdnav_pp'"):
        parse_sweep({"jobs": [{"kind": "train", "policy": "crowdnav_pp", "rl_episodes": 3}]})
    with pytest.raises(ConfigError, match=r"env_steps: not a setting of the value-based trainer of 'sarl'"):
        parse_sweep({"jobs": [{"kind": "train", "policy": "sarl", "env_steps": 3}]})
    with pytest.raises(ConfigError, match=r"config: .*unknown"):
        parse_sweep({"jobs": [{"kind": "train", "policy": "ppo_mlp", "config": "smoke"}]})


def test_evaluation_of_a_failed_training_is_reported(tmp_path):
    preset = small_preset(tmp_path)
    bad_config = tmp_path / "bad_train.yaml"
    bad_config.write_text("rl:\n  episodes: 4\n")
    spec = parse_sweep(
        {
            "defaults": {"preset": preset},
            "jobs": [
                {"kind": "train", "policy": "sarl", "config": str(bad_config), "device": "cuda", "name": "t"},
                {"kind": "evaluate", "policy": "sarl", "checkpoint": "train:t", "episodes": 2, "name": "e"},
            ],
        }
    )
    import torch

    if torch.cuda.is_available():
        pytest.skip("this test needs a machine without CUDA to make the training fail")
    result = run_sweep(spec, tmp_path / "out", LocalExecutor(1), progress=False)
    assert result.jobs["train/t"]["status"] == "failed"
    assert result.jobs["evaluate/e"]["status"] == "failed"
    assert "train:t" in result.jobs["evaluate/e"]["error"]


def test_the_html_report_reads_a_sweeps_job_directories(tmp_path):
    pytest.importorskip("matplotlib")
    path = write_sweep(
        tmp_path,
        {
            "defaults": {"preset": small_preset(tmp_path), "episodes": 4, "scenarios": ["circle_crossing"]},
            "grid": {"kind": "evaluate", "policy": ["orca", "linear"]},
        },
    )
    result = run_sweep(load_sweep(path), tmp_path / "out", LocalExecutor(1), progress=False)
    assert result.ok
    html = tmp_path / "report.html"
    jobs = sorted((tmp_path / "out" / "evaluate").iterdir())
    assert main(["report", *map(str, jobs), "--out", str(html), "--quiet"]) in (0, None)
    table = html.read_text().split("<h3>Table II, circle_crossing")[1].split("</table>")[0]
    assert "<td>orca</td>" in table and "<td>linear</td>" in table


def test_a_job_whose_preset_its_grid_values_refuse_is_a_failed_job_not_a_crash(tmp_path):
    # human_params of a behaviour of one's own, and a grid axis that switches to ORCA (whose parameters
    # live in world.orca): that job is refused by name; the sweep reports it and goes on
    from socialnav.sim.behaviours import register_human_behaviour, unregister_human_behaviour
    from tests.sim.test_behaviour_registry import _plugin_module

    register_human_behaviour(_plugin_module(tmp_path).HalfSpeed)  # "dummy", speed_factor
    try:
        data = load_preset("wang2022").to_dict()
        data["world"]["human_model"] = "dummy"
        data["world"]["human_params"] = {"speed_factor": 0.5}
        (tmp_path / "pacer.yaml").write_text(yaml.safe_dump(data))
        path = write_sweep(tmp_path, {"jobs": [{"kind": "evaluate", "policy": "linear",
                                                "preset": str(tmp_path / "pacer.yaml"), "episodes": 1,
                                                "scenarios": ["passing"], "human_model": ["orca"]}]})
        result = run_sweep(load_sweep(path), tmp_path / "out", LocalExecutor(1), progress=False)
    finally:
        unregister_human_behaviour("dummy")
    (name,) = result.jobs
    assert result.jobs[name]["status"] == "failed"
    assert "human_params" in result.jobs[name]["error"]

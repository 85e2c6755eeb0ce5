"""The Ray executor: same results as the local one, a killed worker retried, jobs spread over a head
and a worker node (two raylet processes on loopback). Skipped where Ray is not installed (it is in
the test extra)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from socialnav.sweep.driver import run_sweep
from socialnav.sweep.executors import LocalExecutor, RayExecutor, init_ray
from socialnav.sweep.spec import parse_sweep
from tests._env import subprocess_env
from tests.sweep.test_sweep import POLICIES, episode_rows, small_preset, trajectory_tables

os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")  # no report to Ray's servers from the tests
ray = pytest.importorskip("ray")
ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def local_ray():
    """One Ray instance (2 CPUs, loopback) for the module, started as the Ray executor starts one:
    starting Ray costs seconds."""
    init_ray(cpus=2)
    yield
    ray.shutdown()


def test_ray_executor_gives_the_local_executors_results_bit_for_bit(tmp_path, local_ray):
    preset = small_preset(tmp_path)
    spec = parse_sweep(
        {
            "defaults": {"preset": preset, "episodes": 10, "scenarios": ["circle_crossing", "passing"]},
            "grid": {
                "kind": "evaluate",
                "policy": ["orca", f"{POLICIES}:StraightToGoal"],
                "human_model": ["orca", "social_force"],
            },
        }
    )
    local = run_sweep(spec, tmp_path / "local", LocalExecutor(2), progress=False)
    remote = run_sweep(spec, tmp_path / "ray", RayExecutor(retries=1), progress=False)
    assert local.ok and remote.ok
    for job in spec.jobs:
        a, b = local.out_dir / "evaluate" / job.name, remote.out_dir / "evaluate" / job.name
        assert episode_rows(a) == episode_rows(b) and len(episode_rows(a)) == 30
        ta, tb = trajectory_tables(a), trajectory_tables(b)
        assert ta.keys() == tb.keys() and all(ta[k].equals(tb[k]) for k in ta)
    assert (local.out_dir / "table2.md").read_text() == (remote.out_dir / "table2.md").read_text()
    where = [json.loads(x)["where"] for x in (remote.out_dir / "sweep_log.jsonl").read_text().splitlines()]
    assert all("node" in w for w in where)  # the tasks really ran as Ray tasks


def test_ray_retries_a_killed_worker_and_results_equal_an_undisturbed_run(tmp_path, local_ray):
    preset = small_preset(tmp_path)
    marker = tmp_path / "died"

    def sweep(cls: str, out: str, executor):
        data = {
            "jobs": [
                {
                    "kind": "evaluate",
                    "policy": f"{POLICIES}:{cls}",
                    "name": "straight",
                    "preset": preset,
                    "episodes": 12,
                    "scenarios": ["circle_crossing"],
                    "visibility": "invisible",
                    "policy_args": {"marker": str(marker)},
                }
            ]
        }
        return run_sweep(parse_sweep(data), tmp_path / out, executor, progress=False)

    faulty = sweep("DiesOnce", "faulty", RayExecutor(retries=2))
    assert marker.exists(), "no Ray worker died: the test tested nothing"
    assert faulty.ok, faulty.failures
    clean = sweep("StraightToGoal", "clean", LocalExecutor(1))
    rows = episode_rows(faulty.out_dir / "evaluate/straight")
    assert rows == episode_rows(clean.out_dir / "evaluate/straight")
    assert sorted(r["index"] for r in rows) == list(range(12))  # nothing lost, nothing twice


def test_ray_reports_a_task_whose_worker_always_dies(tmp_path, local_ray):
    preset = small_preset(tmp_path)
    data = {
        "jobs": [
            {
                "kind": "evaluate",
                "policy": f"{POLICIES}:DiesOnce",
                "name": "dies",
                "preset": preset,
                "episodes": 4,
                "scenarios": ["circle_crossing"],
                "visibility": "invisible",
                "policy_args": {"marker": str(tmp_path / "no" / "such" / "dir")},
            }
        ]
    }
    result = run_sweep(parse_sweep(data), tmp_path / "out", RayExecutor(retries=1), progress=False)
    assert not result.ok and result.jobs["evaluate/dies"]["status"] == "failed"
    assert result.failures[0]["task"] == "evaluate/dies/circle_crossing__invisible/0-4"


TWO_NODES = textwrap.dedent("""
    import json, sys
    from pathlib import Path
    import ray._private.services as services
    # Joining a cluster, Ray rewrites 127.0.0.1 to the machine's outward address; keep to loopback.
    services.get_node_ip_address = lambda address=None: "127.0.0.1"
    from ray.cluster_utils import Cluster
    from socialnav.sweep.driver import run_sweep
    from socialnav.sweep.executors import RayExecutor
    from socialnav.sweep.spec import load_sweep

    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1, "node_ip_address": "127.0.0.1",
                                                            "include_dashboard": False})
    cluster.add_node(num_cpus=1, node_ip_address="127.0.0.1")
    cluster.wait_for_nodes()  # both nodes registered before the first task is placed
    try:
        result = run_sweep(load_sweep(sys.argv[1]), Path(sys.argv[2]), RayExecutor(address=cluster.address),
                           progress=False)
        print(json.dumps({"ok": result.ok, "nodes": len(cluster.list_all_nodes())}))
    finally:
        cluster.shutdown()
""")


def test_jobs_run_on_a_head_and_a_worker_node(tmp_path):
    preset = small_preset(tmp_path, chunk_size=5)
    sweep = tmp_path / "sweep.yaml"
    sweep.write_text(
        json.dumps(
            {
                "jobs": [
                    {
                        "kind": "evaluate",
                        "policy": "orca",
                        "preset": preset,
                        # 64 chunks: the sweep outlasts the second node's worker start-up
                        "episodes": 160,
                        "scenarios": ["circle_crossing", "random"],
                        "visibility": "invisible",
                    }
                ]
            }
        )
    )
    script = tmp_path / "two_nodes.py"
    script.write_text(TWO_NODES)
    out = tmp_path / "out"
    proc = subprocess.run(
        [sys.executable, str(script), str(sweep), str(out)],
        env=subprocess_env(ROOT),
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert json.loads(proc.stdout.strip().splitlines()[-1]) == {"ok": True, "nodes": 2}
    nodes = {json.loads(x)["where"]["node"] for x in (out / "sweep_log.jsonl").read_text().splitlines()}
    assert len(nodes) == 2, "every chunk ran on one node"
    assert len(episode_rows(out / "evaluate/orca")) == 320


def test_an_address_nothing_answers_at_is_refused_before_anything_is_written(tmp_path, capsys):
    import socket

    from socialnav.cli import main

    with socket.socket() as free:  # a port bound and closed: nothing listens there
        free.bind(("127.0.0.1", 0))
        port = free.getsockname()[1]
    sweep = tmp_path / "s.yaml"
    sweep.write_text("jobs:\n  - {kind: evaluate, policy: orca, episodes: 1, scenarios: [passing]}\n")
    out = tmp_path / "out"
    argv = ["sweep", str(sweep), "--executor", "ray", "--address", f"127.0.0.1:{port}", "--out", str(out)]
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2 and f"--address 127.0.0.1:{port}: no Ray cluster answers there" in err, err
    assert "Traceback" not in err and not out.exists()

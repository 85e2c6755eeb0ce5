"""A metric registered from outside the package, through the entry-point group ``socialnav.metrics``,
is listed and scored everywhere the built-in metrics are: ``socialnav list``, ``socialnav evaluate``'s
results and ``socialnav metrics`` on a log."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from tests._env import subprocess_env

PLUGIN = '''
import numpy as np
from socialnav.metrics import register_metric


@register_metric("final_goal_gap", unit="m", direction="lower", outputs={"value": "m"},
                 reference="a test plugin")
def final_goal_gap(traj):
    """Distance from the robot's last position to its goal."""
    return {"value": float(np.linalg.norm(traj.positions[-1, 0] - traj.goals[0]))}
'''


def _site(tmp_path: Path, metric: str = "final_goal_gap", module: str = "final_gap_metric",
          source: str = PLUGIN) -> Path:
    """A site folder holding the plugin module and the dist-info whose entry point names it."""
    site = tmp_path / "site"
    info = site / f"{module}-0.1.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {module.replace('_', '-')}\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(f"[socialnav.metrics]\n{metric} = {module}\n")
    (site / f"{module}.py").write_text(source)
    return site


def _run(args: list[str], tmp_path: Path) -> subprocess.CompletedProcess:
    site = tmp_path / "site" if (tmp_path / "site").exists() else _site(tmp_path)
    return subprocess.run([sys.executable, "-m", "socialnav.cli", *args], capture_output=True, text=True,
                          env=subprocess_env(site), cwd=tmp_path, timeout=600)


def test_a_plugin_metric_is_listed_and_scored_by_evaluate_and_metrics(tmp_path):
    listed = _run(["list", "--json"], tmp_path)
    assert listed.returncode == 0, listed.stderr
    metric = next(m for m in json.loads(listed.stdout)["metrics"] if m["name"] == "final_goal_gap")
    assert metric["unit"] == "m" and metric["direction"] == "lower"

    out = tmp_path / "run"
    run = _run(["evaluate", "--policy", "linear", "--preset", "crowdnav", "--episodes", "4",
                "--out", str(out), "--json", "--no-progress"], tmp_path)
    assert run.returncode == 0, run.stderr
    row = json.loads(run.stdout)["rows"][0]
    # the linear robot reaches its goal or stops on a collision short of it: a finite gap either way
    assert row["final_goal_gap.n"] == 4 and 0.0 <= row["final_goal_gap.mean"] < 20.0

    log = subprocess.run([sys.executable, "-c", "import socialnav.logs as l; print(l.example_log())"],
                         capture_output=True, text=True, env=subprocess_env()).stdout.strip()
    scored = _run(["metrics", log, "--ego", "all", "--json"], tmp_path)
    assert scored.returncode in (0, 1), scored.stderr  # 1: the example log's data warnings
    assert "final_goal_gap" in scored.stdout


def test_without_the_plugin_nothing_changes(tmp_path):
    listed = subprocess.run([sys.executable, "-m", "socialnav.cli", "list", "--json"], capture_output=True,
                            text=True, env=subprocess_env(), cwd=tmp_path)
    assert listed.returncode == 0, listed.stderr
    assert "final_goal_gap" not in {m["name"] for m in json.loads(listed.stdout)["metrics"]}


FRAGILE = '''
from socialnav.metrics import register_metric


@register_metric("fragile", unit="1", direction="none", outputs={"value": "1"}, reference="a test plugin")
def fragile(traj):
    """Fails on every episode."""
    return {"value": 1.0 / 0.0}
'''


def test_a_plugin_metric_that_raises_is_named_with_the_episode(tmp_path):
    _site(tmp_path, "fragile", "fragile_metric", FRAGILE)
    run = _run(["evaluate", "--policy", "linear", "--preset", "crowdnav", "--episodes", "2",
                "--out", str(tmp_path / "run"), "--no-progress"], tmp_path)
    assert run.returncode == 2, run.stderr
    assert "metric 'fragile' failed on episode" in run.stderr
    assert "ZeroDivisionError: float division by zero" in run.stderr
    assert "Traceback" not in run.stderr
    log = subprocess.run([sys.executable, "-c", "import socialnav.logs as l; print(l.example_log())"],
                         capture_output=True, text=True, env=subprocess_env()).stdout.strip()
    scored = _run(["metrics", log, "--ego", "all", "--json"], tmp_path)
    assert scored.returncode == 2 and "metric 'fragile' failed on episode" in scored.stderr, scored.stderr


def test_a_resume_after_a_plugin_metrics_code_changed_is_refused(tmp_path):
    # chunks scored by two versions of one metric would be averaged together: the module's hash is recorded
    argv = ["evaluate", "--policy", "linear", "--preset", "crowdnav", "--episodes", "2", "--out",
            str(tmp_path / "run"), "--no-progress", "--quiet"]
    first = _run(argv, tmp_path)
    assert first.returncode == 0, first.stderr
    manifest = json.loads((tmp_path / "run" / "manifest.json").read_text())
    assert set(manifest["extension_sources"]) == {"metric:final_goal_gap"}
    again = _run(argv, tmp_path)
    assert again.returncode == 0, again.stderr  # unchanged: resumed (nothing to do)
    module = tmp_path / "site" / "final_gap_metric.py"
    module.write_text(module.read_text().replace("traj.goals[0]", "traj.goals[0] * 1.0"))
    changed = _run(argv, tmp_path)
    assert changed.returncode == 2
    assert "extension_sources.metric:final_goal_gap" in changed.stderr, changed.stderr

"""Faults around `socialnav evaluate`: kills, Ctrl-C, two runs on one directory, damaged files.

These run the real command line in subprocesses: what is checked is what a scheduler, a terminal or a
second user sees (exit codes, stderr, the processes left, the files on disk).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests._env import subprocess_env

ROOT = Path(__file__).resolve().parents[2]
PRESET = (
    "name: fault\n"
    "evaluation: {multi_human: [circle_crossing], single_human: [], chunk_size: 25, visibility: invisible}\n"
)


def _env() -> dict[str, str]:
    return subprocess_env()


LONG_PRESET = PRESET.replace(
    "multi_human: [circle_crossing]",
    "multi_human: [circle_crossing, random, parallel_traffic, perpendicular_traffic]",
)


def evaluate(
    tmp_path: Path, out: Path, episodes: int, *extra: str, preset_text: str = PRESET, **kw
) -> subprocess.Popen:
    preset = tmp_path / "fault.yaml"
    preset.write_text(preset_text)
    argv = [
        sys.executable,
        "-m",
        "socialnav.cli",
        "evaluate",
        "--preset",
        str(preset),
        "--episodes",
        str(episodes),
        "--out",
        str(out),
        "--no-progress",
        *extra,
    ]
    return subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=_env(), **kw)


def _children() -> dict[int, list[int]]:
    tree: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                stat = Path(f"/proc/{entry}/stat").read_text()
            except OSError:
                continue
            ppid = int(stat.rsplit(")", 1)[1].split()[1])
            tree.setdefault(ppid, []).append(int(entry))
    return tree


def descendants(pid: int) -> set[int]:
    tree, out, todo = _children(), set(), [pid]
    while todo:
        for child in tree.get(todo.pop(), []):
            if child not in out:
                out.add(child)
                todo.append(child)
    return out


def alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"  # a zombie has exited (only its exit status waits for a reaper)


def wait_for_chunks(out: Path, n: int, proc: subprocess.Popen, timeout: float = 60) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if len(list(out.glob("episodes/*/*.parquet"))) >= n:
            return
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.05)
    raise AssertionError("no chunk file appeared")


def wait_for_workers(pid: int, at_least: int, timeout: float = 30) -> set[int]:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        tree = descendants(pid)
        if len(tree) >= at_least:
            return tree
        time.sleep(0.05)
    raise AssertionError(f"the run never had {at_least} descendants: {descendants(pid)}")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG is Linux's")
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM])
def test_killed_evaluate_leaves_no_process_of_its_tree(tmp_path, sig):
    out = tmp_path / "out"
    # a long run to kill: 2000 episodes, more than the test split's 1000, from the training split
    long_split = PRESET.replace("visibility: invisible}", "visibility: invisible, split: train}")
    proc = evaluate(tmp_path, out, 2000, preset_text=long_split)
    wait_for_chunks(out, 1, proc)
    # forkserver + resource tracker + at least one scoring worker
    tree = wait_for_workers(proc.pid, 3)
    proc.send_signal(sig)
    stdout, stderr = proc.communicate(timeout=60)  # returns only once nobody holds its stdout
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline and any(alive(p) for p in tree):
        time.sleep(0.1)
    assert not [p for p in tree if alive(p)], f"still running: {[p for p in tree if alive(p)]}"
    if sig == signal.SIGTERM:
        assert proc.returncode == 143
        lines = stderr.strip().splitlines()
        assert lines == [
            "socialnav evaluate: terminated (SIGTERM); finished results are kept; "
            "re-run the same command to resume"
        ], stderr
    else:
        assert proc.returncode == -signal.SIGKILL
    assert not list(out.rglob(".*.tmp")) or sig == signal.SIGKILL  # SIGKILL may cut a write short...
    # ...and the next run removes such a leftover and resumes from the chunk files that landed.
    done = len(list(out.glob("episodes/*/*.parquet")))
    assert done >= 1


def test_ctrl_c_prints_one_line_and_the_run_resumes(tmp_path):
    out = tmp_path / "out"
    # Enough work (4 scenarios x 40 chunks, episodes one at a time) that the run is still going when
    # the signal lands, however fast the machine.
    episodes = 1000
    slow = ("--batch-size", "1")
    # A foreground job in a terminal has SIGINT at its default; a test run started in the background
    # of a non-interactive shell inherits it ignored, so restore it as a terminal would have it.
    proc = evaluate(
        tmp_path,
        out,
        episodes,
        *slow,
        preset_text=LONG_PRESET,
        start_new_session=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    wait_for_chunks(out, 2, proc)
    wait_for_workers(proc.pid, 3)
    os.killpg(proc.pid, signal.SIGINT)  # what a terminal sends: to the run and every process of its group
    _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130
    assert stderr.strip().splitlines() == [
        "socialnav evaluate: interrupted; finished results are kept; re-run the same command to resume"
    ], stderr
    kept = sum(
        int(p.stem.split("-")[1]) - int(p.stem.split("-")[0]) for p in out.glob("episodes/*/*.parquet")
    )
    assert 0 < kept < 4 * episodes
    (out / "episodes" / "circle_crossing__invisible" / ".00000-00025.parquet.x1.tmp").write_text("partial")
    again = evaluate(tmp_path, out, episodes, *slow, "--json", preset_text=LONG_PRESET)
    stdout, stderr = again.communicate(timeout=120)
    assert again.returncode == 0, stderr
    summary = json.loads(stdout)
    pooled = [r for r in summary["rows"] if r["scenario"] == "circle_crossing"][0]
    assert pooled["episodes"] == episodes
    assert not list(out.rglob(".*.tmp"))  # the orphan left by a killed writer is gone


def test_two_evaluations_on_one_directory_one_is_refused(tmp_path):
    out = tmp_path / "out"
    # One episode at a time: the winner still holds the lock when the other starts, on any machine.
    first = evaluate(tmp_path, out, 600, "--label", "first", "--json", "--batch-size", "1")
    second = evaluate(tmp_path, out, 600, "--label", "second", "--json", "--batch-size", "1")
    (o1, e1), (o2, e2) = first.communicate(timeout=120), second.communicate(timeout=120)
    results = {"first": (first.returncode, o1, e1), "second": (second.returncode, o2, e2)}
    winners = [k for k, (code, _, _) in results.items() if code == 0]
    assert len(winners) == 1, results
    loser = "second" if winners == ["first"] else "first"
    code, _, err = results[loser]
    assert code == 2 and "in use by another evaluation" in err and "Traceback" not in err, err
    summary = json.loads((out / "summary.json").read_text())
    assert {r["policy"] for r in summary["rows"]} == {winners[0]}
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["policy"]["label"] == winners[0]

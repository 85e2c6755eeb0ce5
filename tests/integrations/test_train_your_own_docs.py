"""docs/train_your_own.md runs as written, with a short budget: the wrappers snippet, SB3 PPO on the
adapter (fewer training steps), its evaluation through ``socialnav evaluate --policy sb3:`` (fewer
episodes), and the hand-written PyTorch policy (fewer evaluation episodes)."""

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from tests._env import subprocess_env

ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / "docs" / "train_your_own.md"
# small networks: one PyTorch thread is fastest and does not slow to a crawl when the machine is busy
ONE_THREAD = subprocess_env(OMP_NUM_THREADS="1")


def blocks() -> list[str]:
    return re.findall(r"```python\n(.*?)```", PAGE.read_text(), re.S)


def run(code: str, cwd: Path) -> subprocess.CompletedProcess:
    (cwd / "snippet.py").write_text(code)
    return subprocess.run([sys.executable, "snippet.py"], cwd=cwd, capture_output=True, text=True,
                          env=ONE_THREAD, timeout=600)


def shortened(code: str, name: str, value: str) -> str:
    pattern = rf"^{name} = [\d_]+"
    assert re.search(pattern, code, re.M), f"docs/train_your_own.md: no {name} = ... line to shorten"
    return re.sub(pattern, f"{name} = {value}", code, count=1, flags=re.M)


def test_page_has_the_three_examples():
    assert len(blocks()) == 3


def test_wrappers_snippet(tmp_path):
    result = run(blocks()[0] + "\nprint(env.reset(seed=0)[0]['humans'].shape, venv.num_envs)\n", tmp_path)
    assert result.returncode == 0, result.stderr[-3000:]
    assert result.stdout.strip() == "(5, 7) 64"


def test_sb3_example_then_cli_evaluation(tmp_path):
    pytest.importorskip(
        "stable_baselines3", reason="stable-baselines3 is not installed (pip install 'socialnav[sb3]')"
    )
    result = run(shortened(blocks()[1], "STEPS", "2_048"), tmp_path)
    assert result.returncode == 0, result.stderr[-3000:]
    page = PAGE.read_text()
    argv = re.search(r"```\n(socialnav evaluate --policy sb3:\S+ --preset wang2022)\n```", page).group(1)
    argv = argv.split()[1:]
    cli = subprocess.run(
        [sys.executable, "-m", "socialnav.cli", *argv, "--scenario", "circle_crossing", "passing",
         "--episodes", "2", "--no-progress", "--json", "--out", "out"],
        cwd=tmp_path, capture_output=True, text=True, env=ONE_THREAD, timeout=600,
    )
    assert cli.returncode == 0, cli.stderr[-3000:]
    assert {r["scenario"] for r in json.loads(cli.stdout)["rows"]} >= {"circle_crossing", "passing"}


def test_hand_written_torch_policy_example(tmp_path):
    pytest.importorskip("torch", reason="torch (the learn extra) is not installed")
    result = run(shortened(blocks()[2], "EPISODES", "2"), tmp_path)
    assert result.returncode == 0, result.stderr[-3000:]
    assert re.search(r"circle_crossing invisible success \d\.\d\d", result.stdout), result.stdout
    assert re.search(r"passing invisible success \d\.\d\d", result.stdout), result.stdout

"""The README's Python snippet and the custom-policy example run as scripts (real subprocesses):
``run_protocol`` at a script's top level must not be re-run by its worker processes."""

import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from tests._env import subprocess_env

from socialnav._runtime import main_module_reruns_call

ROOT = Path(__file__).resolve().parents[2]


def python_block_after(text: str, marker: str) -> str:
    start = text.index(marker)
    return re.search(r"```python\n(.*?)```", text[start:], re.S).group(1)


def run_script(tmp_path: Path, code: str, timeout: int = 300) -> subprocess.CompletedProcess:
    script = tmp_path / "snippet.py"
    script.write_text(code)
    env = subprocess_env()
    return subprocess.run(
        [sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True, timeout=timeout, env=env
    )


def test_readme_python_snippet_runs_as_a_script(tmp_path):
    code = python_block_after((ROOT / "README.md").read_text(), "From Python:")
    assert "run_protocol(" in code and "__main__" not in code
    # The snippet as written, plus a check of what it produced.
    result = run_script(tmp_path, code + "\nprint('EPISODES', len(result.rows))\n")
    assert result.returncode == 0, result.stderr[-3000:]
    assert "EPISODES 4060" in result.stdout
    assert (tmp_path / "runs" / "orca-python" / "summary.json").exists()


def test_guarded_script_still_scores_in_worker_processes(tmp_path):
    code = textwrap.dedent(
        """
        import dataclasses
        import socialnav.evaluate.execution as execution
        import socialnav.evaluate.runner as runner
        from socialnav.policies import make_policy
        from socialnav.presets import load_preset

        pools = []
        original = execution.scoring_pool
        execution.scoring_pool = lambda n: pools.append(n) or original(n)

        if __name__ == "__main__":
            preset = load_preset("crowdnav")
            preset = dataclasses.replace(
                preset, evaluation=dataclasses.replace(preset.evaluation, chunk_size=10))
            result = runner.run_protocol(make_policy("orca"), preset, "out", episodes=30,
                                         progress=False, workers=2)
            print("POOLS", pools, len(result.rows))
        """
    )
    result = run_script(tmp_path, code)
    assert result.returncode == 0, result.stderr[-3000:]
    assert "POOLS [2] 30" in result.stdout  # 3 chunks of 10 episodes, scored by 2 workers


def _classify(tmp_path: Path, body: str) -> str:
    code = textwrap.dedent(
        """
        from socialnav._runtime import main_module_reruns_call

        def ask():
            return main_module_reruns_call()
        """
    ) + textwrap.dedent(body)
    result = run_script(tmp_path, code, timeout=60)
    assert result.returncode == 0, result.stderr
    return result.stdout.strip()


@pytest.mark.parametrize(
    "body, expected",
    [
        ("print(ask())\n", "True"),
        ("def main():\n    print(ask())\nmain()\n", "True"),
        ("if __name__ == '__main__':\n    print(ask())\n", "False"),
        ("if '__main__' == __name__:\n    x = 1\n    print(ask())\n", "False"),
        ("def main():\n    print(ask())\nif __name__ == '__main__':\n    main()\n", "False"),
    ],
)
def test_main_guard_detection(tmp_path, body, expected):
    assert _classify(tmp_path, body) == expected


def test_no_main_file_means_no_rerun():
    # Under pytest __main__ is pytest's entry; from python -c there is no file at all.
    code = "from socialnav._runtime import main_module_reruns_call as f; print(f())"
    env = subprocess_env()
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert out.stdout.strip() == "False", out.stderr
    assert main_module_reruns_call() in (True, False)

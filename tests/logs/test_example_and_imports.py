"""The shipped example log scores from Python and the CLI; socialnav.logs imports light."""

from __future__ import annotations

import json
import subprocess
import sys
import warnings

from socialnav.logs import example_log, score_file


def test_example_log_is_shipped_and_scores() -> None:
    path = example_log()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scores = score_file(path, ego="all")
    assert len(scores.rows) == 8 and not scores.warnings
    assert any("radius 0.3" in n for n in scores.notes)  # the assumed radius is stated


def test_cli_json_on_example(capsys) -> None:
    from socialnav.cli import main

    code = main(["metrics", example_log(), "--ego", "104", "--json"])
    data = json.loads(capsys.readouterr().out)
    assert code == 0 and len(data["episodes"]) == 1 and data["episodes"][0]["ego"] == "104"
    assert data["notes"] and data["warnings"] == []
    assert data["summaries"][0]["scope"] == "scene"


def test_logs_import_without_torch_or_pyarrow() -> None:
    code = ("import sys, socialnav.logs, socialnav.logs.command\n"
            "assert 'torch' not in sys.modules and 'pyarrow' not in sys.modules, sorted(sys.modules)\n")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr

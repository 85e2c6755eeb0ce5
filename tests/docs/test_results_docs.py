"""README.md's results and speed tables and benchmarks/results/README.md are generated from the committed
result files (tools/update_results_docs.py): a test fails when one is stale, so the README cannot
contradict the results."""

import importlib.util
import json
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
TOOL = ROOT / "tools" / "update_results_docs.py"
_spec = importlib.util.spec_from_file_location("update_results_docs", TOOL)
tool = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(tool)


def test_generated_blocks_are_current():
    assert tool.main(["--check"]) == 0, "run python tools/update_results_docs.py"


def test_every_benchmark_result_is_in_the_results_log_with_command_date_and_machine():
    log = (ROOT / "benchmarks" / "results" / "README.md").read_text()
    for path in sorted((ROOT / "benchmarks" / "results").glob("bench_*.json")):
        data = json.loads(path.read_text())
        assert data.get("date") and data.get("machine"), f"{path.name}: no date or machine recorded"
        (row,) = [line for line in log.splitlines() if line.startswith(f"| `{path.name}` |")]
        assert data["date"] in row and data["machine"] in row


def test_the_results_block_is_the_seed_mean_of_the_summary_files(tmp_path):
    # hand-computed: SARL's pooled success over its three seeds' summary files
    values = [tool.pooled(p)["success_rate"] * 100 for p in tool.seed_summaries("sarl")]
    assert len(values) == 3
    mean = sum(values) / 3
    std = (sum((v - mean) ** 2 for v in values) / 2) ** 0.5
    readme = (ROOT / "README.md").read_text()
    (row,) = [line for line in readme.splitlines() if line.startswith("| SARL | 3 |")]
    assert f"{mean:.2f} ± {std:.2f} / –" in row


def test_a_changed_result_makes_the_readme_stale(monkeypatch):
    original = tool.load

    def faster(name):
        data = original(name)
        if name == "bench_world.json":
            return {**data, "env_steps_per_s": data["env_steps_per_s"] * 2}
        return data

    monkeypatch.setattr(tool, "load", faster)
    assert tool.main(["--check"]) == 1

"""Benchmark histories: `benchmarks/_machine.py` keeps each recorded run (current figure + one JSON line
of history), and tools/update_results_docs.py reads them back into benchmarks/results/README.md."""

import argparse
import importlib.util
import json
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "benchmarks" / "results"


def _load(name: str, path: Path):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


machine = _load("bench_machine", ROOT / "benchmarks" / "_machine.py")
tool = _load("update_results_docs_history", ROOT / "tools" / "update_results_docs.py")


def test_a_recorded_run_is_the_current_figure_and_one_more_history_line(tmp_path):
    first = {"date": "2026-11-20", "machine": "CPU A, 2 cores", "seconds": 2.5}
    second = {"date": "2026-11-21", "machine": "CPU B, 16 cores", "seconds": 1.25}
    machine.record_result("bench_x", first, "python benchmarks/bench_x.py", "busy", results_dir=tmp_path)
    history = machine.record_result("bench_x", second, "python benchmarks/bench_x.py --fast",
                                    results_dir=tmp_path)
    assert history == tmp_path / "history" / "bench_x.jsonl"
    current = json.loads((tmp_path / "bench_x.json").read_text())
    assert current == {"command": "python benchmarks/bench_x.py --fast", **second}
    runs = [json.loads(line) for line in history.read_text().splitlines()]
    assert runs == [
        {"date": "2026-11-20", "machine": "CPU A, 2 cores", "command": "python benchmarks/bench_x.py",
         "result": first, "notes": "busy"},
        {"date": "2026-11-21", "machine": "CPU B, 16 cores", "command": "python benchmarks/bench_x.py --fast",
         "result": second, "notes": ""},
    ]
    assert tool.load_history(history) == runs  # what the results log reads back


def test_a_history_whose_last_line_lost_its_newline_still_gets_whole_lines(tmp_path):
    history = tmp_path / "history" / "bench_x.jsonl"
    history.parent.mkdir()
    old = {"date": "2026-11-19", "machine": "m", "command": "c", "result": {}, "notes": ""}
    history.write_text(json.dumps(old))  # no trailing newline
    machine.record_result("bench_x", {"date": "2026-11-20", "machine": "m"}, "c", results_dir=tmp_path)
    dates = [json.loads(line)["date"] for line in history.read_text().splitlines()]
    assert dates == ["2026-11-19", "2026-11-20"]


@pytest.mark.parametrize("name", ["", "../bench_x", "bench_x.json", "sub/bench_x"])
def test_a_record_name_that_is_not_a_file_stem_is_refused(tmp_path, name):
    with pytest.raises(ValueError, match="file stem"):
        machine.record_result(name, {}, "c", results_dir=tmp_path)
    assert not any(tmp_path.iterdir())


def test_the_command_kept_is_the_benchmark_command_without_record_and_notes():
    script = str(ROOT / "benchmarks" / "bench_world.py")
    argv = [script, "--obstacles", "--record", "bench_world_obstacles", "--notes", "quiet", "--threads", "1"]
    assert machine.command_line(argv) == "python benchmarks/bench_world.py --obstacles --threads 1"
    assert machine.command_line([script, "--record", "--threads", "1"]) == \
        "python benchmarks/bench_world.py --threads 1"
    assert machine.command_line([script, "--record=x", "--notes=a b"]) == "python benchmarks/bench_world.py"


def test_emit_prints_the_json_line_last_and_records_only_when_asked(tmp_path, monkeypatch, capsys):
    parser = argparse.ArgumentParser()
    machine.add_record_arguments(parser, "bench_x")
    monkeypatch.setattr(machine, "RESULTS", tmp_path)
    monkeypatch.setattr(sys, "argv", ["benchmarks/bench_x.py"])
    result = {"date": "2026-11-20", "machine": "m", "seconds": 1.0}
    machine.emit(result, parser.parse_args([]))
    assert not any(tmp_path.iterdir())
    machine.emit(result, parser.parse_args(["--record", "--notes", "quiet"]))
    out = capsys.readouterr().out.splitlines()
    assert [json.loads(line) for line in out] == [result, result]
    (run,) = tool.load_history(tmp_path / "history" / "bench_x.jsonl")
    assert run["notes"] == "quiet" and run["result"] == result


@pytest.mark.parametrize("line, problem", [
    ("{not json", "not a JSON object"),
    ("[1, 2]", "not a JSON object"),
    ('{"date": "2026-11-20", "machine": "m", "command": "c", "result": {}}', "no notes"),
    ('{"date": "yesterday", "machine": "m", "command": "c", "result": {}, "notes": ""}', "not YYYY-MM-DD"),
])
def test_a_malformed_history_line_is_an_error_naming_the_file_and_line(tmp_path, line, problem):
    path = tmp_path / "bench_x.jsonl"
    good = '{"date": "2026-11-20", "machine": "m", "command": "c", "result": {}, "notes": ""}'
    path.write_text(good + "\n" + line + "\n")
    with pytest.raises(SystemExit, match=rf"bench_x\.jsonl:2: .*{problem}"):
        tool.load_history(path)


def test_an_empty_history_is_an_error_naming_it(tmp_path, monkeypatch):
    (tmp_path / "bench_x.jsonl").write_text("\n")
    monkeypatch.setattr(tool, "HISTORY", tmp_path)
    with pytest.raises(SystemExit, match=r"bench_x\.jsonl: no runs"):
        tool.history_cell("bench_x")


def test_every_committed_history_is_well_formed_and_linked_from_the_results_log():
    log = (RESULTS / "README.md").read_text()
    histories = sorted((RESULTS / "history").glob("*.jsonl"))
    assert histories
    for path in histories:
        runs = tool.load_history(path)
        assert runs, path.name
        assert [r["date"] for r in runs] == sorted(r["date"] for r in runs), f"{path.name}: not in date order"
        (row,) = [line for line in log.splitlines() if line.startswith(f"| `{path.stem}.json` |")]
        assert f"[{len(runs)} run" in row and f"(history/{path.name})" in row


def test_every_current_figure_is_also_a_run_of_its_history():
    for path in sorted((RESULTS / "history").glob("*.jsonl")):
        current = json.loads((RESULTS / f"{path.stem}.json").read_text())
        results = [run["result"] for run in tool.load_history(path)]
        kept = current["runs"] if isinstance(current.get("runs"), list) else [
            {k: v for k, v in current.items() if k not in ("command", "note")}]
        for run in kept:
            assert run in results, f"{path.stem}.json: its run is not in {path.name}"

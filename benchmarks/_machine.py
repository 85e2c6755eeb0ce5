"""What the benchmarks report about the machine they ran on, and where their results are kept.

Every benchmark prints one JSON object as its last line, starting with :func:`run_record` (date and
machine). Run with ``--record`` (:func:`add_record_arguments`), it also keeps that object: as the current
figure, ``benchmarks/results/<name>.json``, and as one more line of the benchmark's history,
``benchmarks/results/history/<name>.jsonl`` (one JSON object per run: date, machine, command, the JSON
line as ``result``, notes). ``tools/update_results_docs.py`` builds ``benchmarks/results/README.md``
from both.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import shlex
import sys
from pathlib import Path
from typing import Any

RESULTS = Path(__file__).resolve().parent / "results"
HISTORY = RESULTS / "history"


def cpu_model() -> str:
    """The CPU's model name (Linux: /proc/cpuinfo), else what the platform module says."""
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def run_record() -> dict[str, str]:
    """What every benchmark's JSON line starts with: the date (UTC) and the machine it ran on.

    tools/update_results_docs.py reads both into benchmarks/results/README.md.
    """
    return {
        "date": datetime.datetime.now(datetime.timezone.utc).date().isoformat(),
        "machine": f"{cpu_model()}, {os.cpu_count()} cores",
    }


def add_record_arguments(parser: argparse.ArgumentParser, default_name: str) -> None:
    """Add ``--record [NAME]`` and ``--notes TEXT`` to a benchmark's command line.

    Args:
        parser: The benchmark's parser.
        default_name: The result's name when ``--record`` is given without one (the script's stem).
    """
    parser.add_argument(
        "--record", nargs="?", const=default_name, default=None, metavar="NAME",
        help=f"keep the JSON line as benchmarks/results/NAME.json and append it to "
        f"benchmarks/results/history/NAME.jsonl (NAME default: {default_name})",
    )
    parser.add_argument("--notes", default="", help="conditions of the run, kept with it in the history")


def history_entry(result: dict[str, Any], command: str, notes: str = "") -> dict[str, Any]:
    """One line of a benchmark's history: date, machine, command, the JSON line, notes."""
    record = run_record()
    return {
        "date": result.get("date", record["date"]),
        "machine": result.get("machine", record["machine"]),
        "command": command,
        "result": result,
        "notes": notes,
    }


def record_result(name: str, result: dict[str, Any], command: str, notes: str = "",
                  results_dir: Path | None = None) -> Path:
    """Keep ``result`` as the current figure ``<name>.json`` and append it to ``history/<name>.jsonl``.

    Both files are rewritten atomically (socialnav's helper): a run killed while writing leaves the
    previous files whole.

    Args:
        name: The result's name, e.g. ``bench_world_obstacles``.
        result: The benchmark's JSON line.
        command: The command line that produced it.
        notes: The conditions of the run (machine load, what changed).
        results_dir: Where the results live (default ``benchmarks/results``).

    Returns:
        The history file.

    Raises:
        ValueError: ``name`` is not a plain file stem.
    """
    from socialnav._io import atomic_write_text

    results_dir = RESULTS if results_dir is None else results_dir
    if not name or Path(name).name != name or name.endswith((".json", ".jsonl")):
        raise ValueError(f"--record: the name must be a file stem such as bench_world, got {name!r}")
    current = {"command": command, **result} if "command" not in result else dict(result)
    atomic_write_text(results_dir / f"{name}.json", json.dumps(current, indent=2) + "\n")
    history = results_dir / "history" / f"{name}.jsonl"
    history.parent.mkdir(parents=True, exist_ok=True)
    old = history.read_text() if history.exists() else ""
    if old and not old.endswith("\n"):
        old += "\n"
    line = json.dumps(history_entry(result, command, notes), ensure_ascii=False)
    atomic_write_text(history, old + line + "\n")
    return history


def command_line(argv: list[str] | None = None) -> str:
    """The command that ran this benchmark, as a user would type it (``--record``/``--notes`` left out)."""
    argv = list(sys.argv if argv is None else argv)
    kept: list[str] = []
    skip = False
    for i, arg in enumerate(argv):
        if skip:
            skip = False
            continue
        if arg == "--notes" or (arg == "--record" and i + 1 < len(argv) and not argv[i + 1].startswith("-")):
            skip = True
            continue
        if arg == "--record" or arg.startswith(("--record=", "--notes=")):
            continue
        kept.append(arg)
    script = kept[0] if kept else "benchmark"
    try:
        script = str(Path(script).resolve().relative_to(RESULTS.parents[1]))
    except ValueError:
        pass
    return "python " + " ".join(shlex.quote(a) for a in [script, *kept[1:]])


def emit(result: dict[str, Any], args: argparse.Namespace | None = None) -> None:
    """Print the benchmark's JSON line (its output's last line); keep it where ``--record`` asks.

    Args:
        result: The benchmark's JSON object (starting with :func:`run_record`).
        args: The parsed command line, with the arguments of :func:`add_record_arguments`.
    """
    name = getattr(args, "record", None)
    if name:
        record_result(name, result, command_line(), getattr(args, "notes", ""))
    print(json.dumps(result), flush=True)

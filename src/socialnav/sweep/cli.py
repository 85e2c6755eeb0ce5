"""`socialnav sweep SWEEP.yaml` (argument parsing kept free of torch and Ray imports)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from socialnav._progress import warnings_said_once


def add_sweep_parser(sub: argparse._SubParsersAction) -> None:
    """Add the ``sweep`` subcommand to ``sub``."""
    sw = sub.add_parser(
        "sweep",
        help="a grid of evaluation and training jobs (policies x seeds x crowd models …) on this machine "
        "or a Ray cluster; resumable",
        description="Runs every job of a sweep file (docs/sweeps.md). Evaluation jobs are split into "
        "episode chunks spread over the workers; results land in one directory in `socialnav evaluate`'s "
        "format, with one set of tables. Rerun the same command to resume. Exit status 0 when every job "
        "finished, 1 when some failed (failures.json names them), 2 for a bad sweep file.",
    )
    sw.add_argument("sweep", help="sweep YAML file")
    sw.add_argument(
        "--executor", choices=["local", "ray"], help="where jobs run (default: the file's, local)"
    )
    sw.add_argument("--address", help="Ray cluster address (ray executor; default: start Ray here)")
    sw.add_argument("--workers", type=int, help="worker processes or Ray CPUs here (default: one per core)")
    sw.add_argument("--retries", type=int, help="re-runs of a task whose worker died (default 3)")
    sw.add_argument("--out", help="result directory (default: the file's out:, else runs/sweep/<file name>)")
    sw.add_argument("--json", action="store_true", help="print one JSON object last (jobs, failures, rows)")
    sw.add_argument("--quiet", action="store_true", help="no progress bar, no tables (errors still print)")
    sw.set_defaults(run=cmd_sweep)


def cmd_sweep(args: argparse.Namespace) -> int:
    """``socialnav sweep``: run (or resume) a sweep file's jobs here or on a Ray cluster.

    Args:
        args: The parsed command line.

    Returns:
        The exit status.
    """
    from socialnav._io import json_safe
    from socialnav.sweep.driver import run_sweep
    from socialnav.sweep.executors import make_executor
    from socialnav.sweep.spec import load_sweep

    spec = load_sweep(args.sweep)
    for flag, value in (("--workers", args.workers), ("--retries", args.retries)):
        if value is not None and value < (1 if flag == "--workers" else 0):
            raise ValueError(f"{flag} must be >= {1 if flag == '--workers' else 0}, got {value}")
    executor = make_executor(
        args.executor or spec.executor,
        workers=args.workers or spec.workers,
        retries=spec.retries if args.retries is None else args.retries,
        address=args.address or spec.address,
    )
    out = Path(args.out or spec.out or f"runs/sweep/{Path(args.sweep).stem}")
    log = None if (args.json or args.quiet) else (lambda line: print(line, file=sys.stderr))
    with warnings_said_once():
        result = run_sweep(spec, out, executor, progress=not (args.quiet or args.json), log=log)
    if args.json:
        print(
            json.dumps(
                json_safe(
                    {
                        "out": str(out),
                        "jobs": result.jobs,
                        "failures": result.failures,
                        "rows": result.summary,
                    }
                )
            )
        )
    elif not args.quiet:
        from socialnav.evaluate.report import table2, table3

        for table in (table2(result.summary, "md"), table3(result.summary, "md")):
            if table:
                print(table)
        done = sum(1 for s in result.jobs.values() if s["status"] == "done")
        print(
            f"{done} of {len(result.jobs)} jobs done; results in {out}/ (jobs.json, failures.json, "
            "summary.json/csv, tables; evaluate/<job>/, train/<job>/)"
        )
    for failure in result.failures:
        print(f"error: {failure['task']}: {failure['error']}", file=sys.stderr)
    return 0 if result.ok else 1

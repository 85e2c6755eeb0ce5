"""What the benchmarks report about the machine they ran on."""

from __future__ import annotations

import datetime
import os
import platform


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
    """What every benchmark's JSON line starts with: the date (UTC) and the machine it ran on, read by
    tools/update_results_docs.py into benchmarks/results/README.md."""
    return {
        "date": datetime.datetime.now(datetime.timezone.utc).date().isoformat(),
        "machine": f"{cpu_model()}, {os.cpu_count()} cores",
    }

"""Time and size of the HTML report of a full `wang2022` evaluation of one policy (ORCA).

Runs the full protocol once (4060 episodes, trajectories stored; not timed), then times
`write_report` on it, and, in the same run, the report without the episode viewer as the reference
for the viewer's share. Goal: <= 60 s on 2 cores and <= 20 MB. Prints one JSON object last.

    python benchmarks/bench_report.py
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
import warnings
from pathlib import Path

from socialnav.evaluate.runner import run_protocol
from socialnav.policies import make_policy
from socialnav.presets import load_preset
from socialnav.viz.report import write_report

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _machine import add_record_arguments, emit, run_record  # noqa: E402  (benchmarks/ is not a package)

TARGET_SECONDS = 60.0
TARGET_MB = 20.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    add_record_arguments(parser, "bench_report")
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    preset = load_preset("wang2022")
    policy = make_policy("orca", **preset.policy_params("orca"))
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "orca"
        start = time.perf_counter()
        run_protocol(policy, preset, out, progress=False)
        evaluate_s = time.perf_counter() - start
        start = time.perf_counter()
        info = write_report(out, out / "report.html")
        seconds = time.perf_counter() - start
        start = time.perf_counter()
        bare = write_report(out, out / "bare.html", viewer_episodes=0, figure_files=False)
        bare_s = time.perf_counter() - start
    mb = info["bytes"] / 1e6
    print(
        f"report of the wang2022 ORCA evaluation: {seconds:.1f} s, {mb:.2f} MB, {info['viewer_episodes']} "
        f"episodes in the viewer, {info['figures']} figures (without the viewer and figure files: "
        f"{bare_s:.1f} s, {bare['bytes'] / 1e6:.2f} MB; the evaluation itself {evaluate_s:.1f} s); "
        f"targets <= {TARGET_SECONDS:.0f} s, <= {TARGET_MB:.0f} MB"
    )
    emit(
        run_record()
        | {
            "seconds": round(seconds, 2),
            "report_mb": round(mb, 3),
            "viewer_episodes": info["viewer_episodes"],
            "figures": info["figures"],
            "seconds_without_viewer": round(bare_s, 2),
            "ratio_to_without_viewer": round(seconds / bare_s, 2),
            "evaluation_seconds": round(evaluate_s, 2),
            "target_seconds": TARGET_SECONDS,
            "target_mb": TARGET_MB,
            "meets_target": seconds <= TARGET_SECONDS and mb <= TARGET_MB,
        },
        args,
    )


if __name__ == "__main__":
    main()

"""Regenerates tests/evaluate/checkpoint_expectations.json from the checkpoints that ship now.

Run it after adding, replacing or retraining a checkpoint in src/socialnav/checkpoints/ (and after a
deliberate change of the simulator or the metrics that alters a shipped policy's behaviour), review
the diff, and commit the file with the change:

    source .venv/bin/activate && PYTHONPATH=src python tools/update_checkpoint_expectations.py
    PYTHONPATH=src python tools/update_checkpoint_expectations.py --only cadrl_wang2022.pt  # one file

The test tests/evaluate/test_checkpoint_expectations.py fails for a shipped checkpoint without an
entry, for a checkpoint whose SHA-256 differs from the stored one, and for any change of behaviour.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from socialnav._io import atomic_write_text
from socialnav.evaluate.expectations import EPISODES, METRICS, TOLERANCE, fingerprint
from socialnav.evaluate.multi import file_sha256
from socialnav.policies.building import shipped_checkpoints

PATH = Path(__file__).resolve().parents[1] / "tests" / "evaluate" / "checkpoint_expectations.json"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", help="update only these checkpoint files (others are kept)")
    parser.add_argument("--out", type=Path, default=PATH, help=f"expectations file (default {PATH})")
    args = parser.parse_args(argv)
    entries = shipped_checkpoints()
    known = {e.file for e in entries}
    unknown = sorted(set(args.only or ()) - known)
    if unknown:
        shipped = ", ".join(sorted(known))
        print(f"error: not shipped: {', '.join(unknown)} (shipped: {shipped})", file=sys.stderr)
        return 2
    old = json.loads(args.out.read_text())["checkpoints"] if args.out.exists() else {}
    checkpoints = {}
    for entry in entries:
        if args.only and entry.file not in args.only and entry.file in old:
            checkpoints[entry.file] = old[entry.file]
            continue
        t0 = time.perf_counter()
        episodes = fingerprint(entry)
        checkpoints[entry.file] = {
            "policy": entry.policy,
            "preset": entry.preset,
            "sha256": file_sha256(entry.path),
            "episodes": episodes,
        }
        outcomes = [e["outcome"] for e in episodes]
        print(f"{entry.file}: {len(episodes)} episodes ({outcomes.count('success')} success) "
              f"in {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    data = {
        "about": "behaviour of each shipped checkpoint on fixed test episodes; "
        "regenerate with tools/update_checkpoint_expectations.py",
        "episodes_per_scenario": EPISODES,
        "metrics": list(METRICS),
        "tolerance": TOLERANCE,
        "checkpoints": checkpoints,
    }
    atomic_write_text(args.out, json.dumps(data, indent=1) + "\n")
    print(f"wrote {args.out} ({len(checkpoints)} checkpoints)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())

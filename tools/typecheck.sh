#!/usr/bin/env bash
# mypy on the public API: every package's __init__ (its __all__ names must resolve to typed
# definitions) and the modules below every package (I/O, runtime, learned-policy records), which are
# checked in full. Settings: [tool.mypy] in pyproject.toml; mypy is pinned in constraints.txt.
set -euo pipefail
cd "$(dirname "$0")/.."
python -m mypy --no-incremental \
  -p socialnav._io -p socialnav._runtime -p socialnav.settings -p socialnav.policies.learned_catalog \
  -m socialnav -m socialnav.sim -m socialnav.evaluate -m socialnav.train -m socialnav.sweep \
  -m socialnav.metrics -m socialnav.policies -m socialnav.logs -m socialnav.scenarios

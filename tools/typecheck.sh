#!/usr/bin/env bash
# mypy on the public API: every package's __init__ (its __all__ names must resolve to typed
# definitions) and the modules below every package (I/O, runtime, learned-policy records), which are
# checked in full; and, in full against the compiled core's stub (src/socialnav/_core.pyi, written by
# tools/gen_core_stub.sh), every module that calls the core: the world and its parts, the envs, the
# ORCA single step, the worker pools, the recorder and observations, native scenario generation, the
# native robot policies and the native SARL scorer.
# Settings: [tool.mypy] in pyproject.toml; mypy is pinned in constraints.txt.
set -euo pipefail
cd "$(dirname "$0")/.."
python -m mypy --no-incremental \
  -p socialnav._io -p socialnav._runtime -p socialnav.settings -p socialnav.policies.learned_catalog \
  -m socialnav -m socialnav.sim -m socialnav.evaluate -m socialnav.train -m socialnav.sweep \
  -m socialnav.metrics -m socialnav.policies -m socialnav.logs -m socialnav.scenarios -m socialnav.maps \
  -m socialnav.sim.world -m socialnav.sim.world_config -m socialnav.sim.slot_maps \
  -m socialnav.sim.step_result -m socialnav.sim.episode_stream -m socialnav.envs.single \
  -m socialnav.envs.vector -m socialnav.envs.config \
  -m socialnav.sim.orca_solver -m socialnav.sim.pool -m socialnav.sim.recorder -m socialnav.sim.observation \
  -m socialnav.scenarios.native -m socialnav.policies.native -m socialnav.policies.learned.native_scoring

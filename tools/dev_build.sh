#!/usr/bin/env bash
# Developer build: compiles the native core into src/socialnav/ so that `PYTHONPATH=src` (or a .pth
# file) runs the working tree directly. Users install with `pip install .` instead.
#
# Needs a C++17 compiler, and nanobind, CMake and Ninja for the active `python` (the `dev` extra:
# `pip install -e ".[dev]"`); those three are pip-installed into it first when missing.
# `tools/dev_build.sh --deps-only` only checks/installs them.
set -euo pipefail
cd "$(dirname "$0")/.."
missing=()
python -c "import nanobind" 2>/dev/null || missing+=("nanobind>=2.0")
command -v cmake >/dev/null 2>&1 || missing+=("cmake>=3.18")
command -v ninja >/dev/null 2>&1 || missing+=("ninja")
if ((${#missing[@]})); then
  echo "dev_build: installing the build requirements ${missing[*]} into $(command -v python)" >&2
  python -m pip install "${missing[@]}"
fi
if [[ "${1:-}" == "--deps-only" ]]; then
  exit 0
fi
python -m nanobind --cmake_dir >/dev/null
cmake -S . -B build/dev -G Ninja -DCMAKE_BUILD_TYPE=Release -DPython_EXECUTABLE="$(command -v python)" >/dev/null
cmake --build build/dev
cp build/dev/_core*.so src/socialnav/

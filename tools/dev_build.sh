#!/usr/bin/env bash
# Developer build: compiles the native core into src/socialnav/ so that `PYTHONPATH=src` (or a .pth
# file) runs the working tree directly. Users install with `pip install .` instead.
set -euo pipefail
cd "$(dirname "$0")/.."
python -m nanobind --cmake_dir >/dev/null
cmake -S . -B build/dev -G Ninja -DCMAKE_BUILD_TYPE=Release -DPython_EXECUTABLE="$(command -v python)" >/dev/null
cmake --build build/dev
cp build/dev/_core*.so src/socialnav/

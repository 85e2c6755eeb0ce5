#!/usr/bin/env bash
# The pictures of docs/walls_maps.md's scenario gallery: the first test episode (invisible robot) of every
# francis2023 scenario driven by the shipped wall-aware RGL, each drawn by `socialnav render`.
# Run from the repository root: bash tools/render_wall_scenarios.sh [out_dir]
set -euo pipefail
out=${1:-docs/img/walls}
runs=$(mktemp -d)
trap 'rm -rf "$runs"' EXIT
export PYTHONPATH=${PYTHONPATH:-src}
python -m socialnav.cli evaluate --policy rgl --preset francis2023 --episodes 1 --visibility invisible \
  --out "$runs/francis2023-rgl" --quiet
mkdir -p "$out"
for scenario in frontal_approach pedestrian_obstruction intersection blind_corner narrow_hallway \
    narrow_doorway entering_room exiting_room circle_crossing_obstacles; do
  python -m socialnav.cli render "$runs/francis2023-rgl" --episode "$scenario/invisible/0" \
    --out "$out/$scenario.png" --quiet
done

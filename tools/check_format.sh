#!/usr/bin/env bash
# Checks that the C++ core (cpp/) is formatted as .clang-format says (clang-format's check mode: it
# changes nothing, prints each difference and fails). Fix with `clang-format -i` on the files named.
# clang-format is the pip package of the `test` extra, pinned in constraints.txt (releases format
# differently). `.ci/run` calls this.
set -euo pipefail
cd "$(dirname "$0")/.."
# Not checked yet: the files another branch was changing for speed while cpp/ was first formatted
# (formatting them then would have conflicted). They get formatted after that merge, and this list
# goes away with it.
not_yet=(obstacles.cpp obstacles.hpp orca.cpp orca.hpp world.cpp world.hpp robot_policies.cpp robot_policies.hpp)
files=()
for f in cpp/*.cpp cpp/*.hpp; do
  skip=0
  for n in "${not_yet[@]}"; do [[ $f == "cpp/$n" ]] && skip=1; done
  ((skip)) || files+=("$f")
done
if ! command -v clang-format >/dev/null 2>&1; then
  echo "check_format: clang-format is missing: pip install -c constraints.txt clang-format" >&2
  exit 1
fi
clang-format --dry-run -Werror "${files[@]}"
echo "check_format: ${#files[@]} files formatted ($(clang-format --version))"

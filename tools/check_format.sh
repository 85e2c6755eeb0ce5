#!/usr/bin/env bash
# Checks that the C++ core (cpp/, cpp/behaviours/) is formatted as .clang-format says (clang-format's check mode: it
# changes nothing, prints each difference and fails). Fix with `clang-format -i` on the files named.
# clang-format is the pip package of the `test` extra, pinned in constraints.txt (releases format
# differently). `.ci/run` calls this.
set -euo pipefail
cd "$(dirname "$0")/.."
files=(cpp/*.cpp cpp/*.hpp cpp/behaviours/*.cpp cpp/behaviours/*.hpp)
if ! command -v clang-format >/dev/null 2>&1; then
  echo "check_format: clang-format is missing: pip install -c constraints.txt clang-format" >&2
  exit 1
fi
clang-format --dry-run -Werror "${files[@]}"
echo "check_format: ${#files[@]} files formatted ($(clang-format --version))"

#!/usr/bin/env bash
# clang-format check and clang-tidy over src/ (warnings are errors). Usage: bash scripts/lint.sh
set -euo pipefail
cd "$(dirname "$0")/.."
files=$(git ls-files 'src/*.cpp' 'src/*.hpp' 'tests/*.cpp' 'tests/*.hpp' 'python/*.cpp')
clang-format --dry-run --Werror $files
cmake -S . -B build/lint -DCMAKE_EXPORT_COMPILE_COMMANDS=ON -DCRUSHDEM_TESTS=OFF >/dev/null
for f in $(git ls-files 'src/*.cpp'); do clang-tidy -p build/lint --quiet "$f"; done
echo "lint: clean"

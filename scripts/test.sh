#!/usr/bin/env bash
# Builds crushdem and runs every test: the C++ suite (GoogleTest via CTest) and the Python
# suite (pytest on the pip-installed package, the notebooks included), then the docs site
# (scripts/docs.sh). Installs what it needs on a fresh Debian 12 machine.
# Usage: bash scripts/test.sh            (from the repository root)
# Env: JOBS (build parallelism, default nproc). The study-scale validation runs are opt-in
#      (hours): CRUSHDEM_VALIDATION_DIR=DIR .venv/bin/python -m pytest tests/python/test_validation.py
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/deps.sh
ensure_build_deps
JOBS=${JOBS:-$(nproc)}

echo "== C++: configure, build (warnings are errors), test"
cmake -S . -B build/test -DCMAKE_BUILD_TYPE=Release -DCRUSHDEM_WERROR=ON -DCRUSHDEM_TESTS=ON >/dev/null
cmake --build build/test -j "$JOBS"
(cd build/test && ctest --output-on-failure -j "$JOBS")

echo "== C++: install, then build and run a project that uses find_package(crushdem)"
cmake --install build/test --prefix build/test/install >/dev/null
# -march=native is for this project's own binaries: the installed package must not pass it on.
targets=(build/test/install/lib*/cmake/crushdem/crushdemTargets*.cmake)
[ -f "${targets[0]}" ] || { echo "no crushdemTargets.cmake installed" >&2; exit 1; }
if grep -n -- "-march" "${targets[@]}"; then
  echo "the installed crushdem CMake package passes -march to its consumers" >&2
  exit 1
fi
cmake -S tests/consumer -B build/consumer -DCMAKE_PREFIX_PATH="$PWD/build/test/install" >/dev/null
cmake --build build/consumer -j "$JOBS" >/dev/null
build/consumer/crushdem_consumer

echo "== Python: install the package into .venv, run pytest"
ensure_venv
.venv/bin/python -m pip install --quiet ".[test]"
.venv/bin/python -m pytest tests/python -q

echo "== Docs: the site, strict (the notebooks ran in pytest above: test_notebooks.py)"
bash scripts/docs.sh

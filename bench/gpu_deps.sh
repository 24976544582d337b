#!/usr/bin/env bash
# Gathers, on this machine, what bench/gpu_check.sh needs on a GPU machine that can reach no
# network and has no Debian packages: the toml++ and CLI11 headers, the peer reference packing,
# the study's REV sample and crushdem's REV relaxation configurations pointing at it. Writes
# DEPS (default build/gpu-deps, an ignored path: carry it with the call).
#
#   bash bench/gpu_deps.sh [REPRODUCE_DIR [DEPS]]
#
# REPRODUCE_DIR: a study-scale `crushdem-sand reproduce` directory (its sample/sample.txt and the
# config.toml of its oedometric and triaxial relaxations, the latter for its stop_q), needed by
# the parts scaling, oedometric and triaxial only; without it DEPS serves the others.
set -euo pipefail
cd "$(dirname "$0")/.."
REPRO=${1:-}
DEPS=${2:-build/gpu-deps}
mkdir -p "$DEPS/include"
cp -r /usr/include/toml++ "$DEPS/include/"
cp -r /usr/include/CLI "$DEPS/include/"
cp bench/peers/common/packing.txt.gz "$DEPS/packing.txt.gz"
if [ -z "$REPRO" ]; then
  echo "gpu_deps: no REPRODUCE_DIR: DEPS serves the parts build, tests, bench, chamber and pile" >&2
  du -sh "$DEPS"
  exit 0
fi
cp "$REPRO/sample/sample.txt" "$DEPS/sample_rev.txt"
for run in oedometric_relaxation triaxial_relaxation; do
  [ -f "$REPRO/$run/config.toml" ] || { echo "gpu_deps: no $REPRO/$run/config.toml" >&2; continue; }
  # The particle file is named relative to the configuration (both in DEPS).
  sed -E 's|^file = ".*"|file = "sample_rev.txt"|' "$REPRO/$run/config.toml" > "$DEPS/${run}_rev.toml"
done
du -sh "$DEPS"

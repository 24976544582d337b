#!/usr/bin/env bash
# The reference runs: results that a change of structure must leave byte for byte as they were.
#   bash bench/reference_runs.sh run CRUSHDEM_BINARY OUT_DIR     # every run into OUT_DIR
#   bash bench/reference_runs.sh compare DIR_A DIR_B             # every result file compared
# The runs (bench/reference/*.toml, each on the CPU backend and, where marked below, also on
# the emulated device): a crushing creep with crack growth and off-DEM ageing, a triaxial shear
# with rolling resistance, viscous damping, wall friction and crack growth, a sample prepared from
# a grading curve and loaded with crushing, a smooth-Hertz compression with wall friction, and
# the repository's small isotropic compression
# (examples/compression_small.toml). Only timing.json (wall-clock seconds) is left out of the
# comparison. One thread per run; results do not depend on it.
set -euo pipefail
cd "$(dirname "$0")/.."
mode=${1:?usage: reference_runs.sh run BINARY OUT | compare A B}
case "$mode" in
  run)
    bin=${2:?binary}; out=${3:?output directory}
    mkdir -p "$out"
    runs=(bench/reference/creep_ageing.toml bench/reference/triaxial_rolling_crack.toml
          bench/reference/sample_prep.toml bench/reference/compression_hertz.toml
          examples/compression_small.toml)
    emulated=(bench/reference/creep_ageing.toml bench/reference/compression_hertz.toml)
    for cfg in "${runs[@]}"; do
      name=$(basename "$cfg" .toml)
      start=$(date +%s)
      "$bin" run "$cfg" --out "$out/$name" --threads 1 --quiet --overwrite
      echo "$name: $(( $(date +%s) - start )) s"
    done
    for cfg in "${emulated[@]}"; do
      name=$(basename "$cfg" .toml)_emulated
      start=$(date +%s)
      "$bin" run "$cfg" --out "$out/$name" --threads 1 --quiet --overwrite --backend emulated
      echo "$name: $(( $(date +%s) - start )) s"
    done
    ;;
  compare)
    a=${2:?first directory}; b=${3:?second directory}
    status=0
    for run in "$a"/*/; do
      name=$(basename "$run")
      if [ ! -d "$b/$name" ]; then echo "$name: missing in $b"; status=1; continue; fi
      # summary.json names the build's commit and version; every other file must be equal.
      if diff -rq --exclude=timing.json --exclude=summary.json "$a/$name" "$b/$name" >/dev/null &&
         diff <(grep -v 'crushdem_commit\|crushdem_version\|seconds' "$a/$name/summary.json") \
              <(grep -v 'crushdem_commit\|crushdem_version\|seconds' "$b/$name/summary.json") >/dev/null; then
        echo "$name: identical ($(find "$a/$name" -type f ! -name timing.json | wc -l) files)"
      else
        echo "$name: DIFFERENT"
        diff -rq --exclude=timing.json "$a/$name" "$b/$name" || true
        status=1
      fi
    done
    exit $status
    ;;
  *) echo "unknown mode $mode" >&2; exit 2 ;;
esac

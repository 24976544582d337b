#!/usr/bin/env bash
# The main job: installs crushdem (pip, into .venv) and runs the default experiment, a small
# oedometric stress relaxation (sample preparation, loading to 7.5 MPa with crushing, one day of
# off-DEM ageing), then draws its figures. Results in runs/relaxation_small/.
# Usage: bash scripts/main.sh [CONFIG.toml] [OUT_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/deps.sh
ensure_build_deps
ensure_venv
.venv/bin/python -m pip install --quiet ".[plot]"  # crushdem-sand plot draws the figures
CONFIG=${1:-examples/relaxation_small.toml}
OUT=${2:-runs/$(basename "$CONFIG" .toml)}
if [ -f "$OUT/summary.json" ]; then
  # Run before: the finished result stays as it is; its figures are drawn again.
  echo "main job: $OUT holds the finished run (summary.json); its figures are drawn again." \
    "For a new run, remove $OUT or pass another OUT_DIR: bash scripts/main.sh $CONFIG runs/NEW"
elif [ -f "$OUT/checkpoint.bin" ] || [ -f "$OUT/manifest.json" ]; then
  echo "main job: $OUT holds a stopped run: resuming it"
  .venv/bin/crushdem-sand resume "$OUT"
else
  .venv/bin/crushdem-sand run "$CONFIG" --out "$OUT"
fi
.venv/bin/crushdem-sand plot "$OUT"
echo "main job: results and figures in $OUT (relaxation.png: the relaxation curve)"

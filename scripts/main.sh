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
.venv/bin/python -m pip install --quiet ".[plot]"  # crushdem plot draws the figures
CONFIG=${1:-examples/relaxation_small.toml}
OUT=${2:-runs/$(basename "$CONFIG" .toml)}
.venv/bin/crushdem run "$CONFIG" --out "$OUT"
.venv/bin/crushdem plot "$OUT"

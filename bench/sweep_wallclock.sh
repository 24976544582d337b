#!/usr/bin/env bash
# Wall-clock of a 4-variant ageing sweep (n_break x v0 of a small oedometric relaxation):
# branched from one loaded state against 4 full runs, each on 1 and 2 Dask workers.
#
#   bash bench/sweep_wallclock.sh [OUT_DIR]        # about 8 minutes on 2 cores
#   COUNT=500 MIN_CYCLES=20000 bash bench/sweep_wallclock.sh
#
# The base is examples/relaxation_small.toml with sample.count = COUNT grains (n_break and
# min_cycles as given); the loaded state is one full run of it, whose wall-clock the branched
# sweeps are charged with. Background crushdem jobs are stopped (SIGSTOP) while it runs.
# Prints one line per measurement and writes OUT_DIR/sweep_wallclock.csv.
set -euo pipefail
# shellcheck source=bench/lib.sh
source "$(dirname "$0")/lib.sh"
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
OUT="${1:-$ROOT/runs/sweep_wallclock}"
COUNT="${COUNT:-500}"
MIN_CYCLES="${MIN_CYCLES:-20000}"
CRUSHDEM="${CRUSHDEM:-$ROOT/.venv/bin/crushdem-sand}"
if [ -e "$OUT" ]; then
  echo "bench/sweep_wallclock.sh: $OUT exists; give a new directory" >&2
  exit 2
fi
pause_background_jobs
mkdir -p "$OUT"
sed -e "s/^count = 1500/count = $COUNT/" -e "s/^n_break = 4/n_break = 2/" \
  -e "s/^min_cycles = 20000/min_cycles = $MIN_CYCLES/" -e "s/^progress_seconds = 30/progress_seconds = 0/" \
  "$ROOT/examples/relaxation_small.toml" >"$OUT/base.toml"
vary='[vary]
"stage.relaxation.n_break" = [2, 4]
"crushing.v0" = [0.05, 0.1]'
printf 'base = "base.toml"\n%s\n' "$vary" >"$OUT/full.toml"
printf 'base = "base.toml"\nfrom = "loaded:relaxation"\n%s\n' "$vary" >"$OUT/branched.toml"

seconds() { # seconds COMMAND...: wall-clock of the command, to the centisecond
  local t0=$EPOCHREALTIME
  "$@" >/dev/null
  awk -v a="$t0" -v b="$EPOCHREALTIME" 'BEGIN { printf "%.2f", b - a }'
}
echo "what,workers,wall_s" >"$OUT/sweep_wallclock.csv"
loaded=$(seconds "$CRUSHDEM" run "$OUT/base.toml" --out "$OUT/loaded" --threads 1 --quiet)
echo "loaded state (one full run, 1 thread): $loaded s"
echo "loaded_state,1,$loaded" >>"$OUT/sweep_wallclock.csv"
for workers in 1 2; do
  for kind in full branched; do
    s=$(seconds "$CRUSHDEM" sweep "$OUT/$kind.toml" --out "$OUT/${kind}_$workers" \
      --workers "$workers" --threads-per-run 1)
    echo "$kind sweep of 4 variants on $workers worker(s): $s s"
    echo "${kind}_sweep,$workers,$s" >>"$OUT/sweep_wallclock.csv"
  done
done
echo "(a branched sweep's total cost is its wall-clock plus the loaded state's, paid once)"

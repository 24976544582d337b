#!/usr/bin/env bash
# crushdem against LAMMPS gran/hertz/history, interleaved: each round runs LAMMPS and then
# crushdem on the same process/thread count, back to back, and the ratio is taken per round.
#
#   bash bench/interleaved_peers.sh                 # 5 rounds of 1 and 2 threads (about 8 min)
#   ROUNDS=7 THREADS_LIST="1 2" bash bench/interleaved_peers.sh
#   ROUGH=1 bash bench/interleaved_peers.sh        # also rough against Hertz, settled, 1 thread
#   ROUGH=1 SETTLE=300000 bash bench/interleaved_peers.sh   # settling steps (the default)
#
# Why: run_all.sh (bench/run_peers.sh) runs all LAMMPS repeats, then all crushdem repeats. On a
# shared host whose speed drifts by 20-30 % over minutes, the two medians then come from
# different host states and their ratio moves by as much. Pairs made a minute apart see nearly
# the same host; the median of the per-round ratios is the figure to compare builds with. The
# problem, protocol and LAMMPS input are the shared ones (bench/peers), unchanged.
# Background `crushdem-sand run`/`resume` jobs are stopped (SIGSTOP) while it runs and continued after.
set -euo pipefail
# shellcheck source=bench/lib.sh
source "$(dirname "$0")/lib.sh"
bench_setup
ROUNDS="${ROUNDS:-5}"
THREADS_LIST="${THREADS_LIST:-1 2}"
STEPS="${STEPS:-10000}"
WARM="${WARM:-500}"

cmake -S "$ROOT" -B "$ROOT/build/bench" -DCMAKE_BUILD_TYPE=Release -DCRUSHDEM_TESTS=OFF >/dev/null
cmake --build "$ROOT/build/bench" -j "$(nproc)" >/dev/null
BIN="$ROOT/build/bench/crushdem-sand"

WORK="$(mktemp -d)"
BENCH_ON_EXIT="rm -rf '$WORK'"
pause_background_jobs
lammps() { # nprocs -> particle-steps/s
  NPROCS_LIST=$1 REPEATS=1 STEPS=$STEPS WARM=$WARM LAMMPS_PAIR=hertz_history WORK="$WORK" \
    bash "$PEER_DIR/lammps/run.sh" 2>"$WORK/lammps.err" | tail -1 | sed 's/^particle_steps_per_s=//'
}
engine() { # threads [extra bench args] -> particle-steps/s
  local t=$1
  shift
  crushdem_rate "$BIN" "$t" "$STEPS" "$@"
}

echo "# host: $(lscpu | grep -m1 'Model name' | sed 's/.*: *//'); nproc=$(nproc)"
echo "# crushdem $(git -C "$ROOT" rev-parse --short HEAD)$(git -C "$ROOT" diff --quiet || echo '+changes'); steps=$STEPS warm=$WARM"
declare -A RATIOS ENG PEER
for r in $(seq 1 "$ROUNDS"); do
  for t in $THREADS_LIST; do
    l=$(lammps "$t") || { tail -20 "$WORK/lammps.err" >&2; echo "LAMMPS run failed" >&2; exit 1; }
    e=$(engine "$t")
    ratio=$(awk -v e="$e" -v l="$l" 'BEGIN{printf "%.3f", e/l}')
    echo "round $r threads $t lammps_hh=$l crushdem=$e ratio=$ratio"
    RATIOS[$t]+=" $ratio"
    ENG[$t]+=" $e"
    PEER[$t]+=" $l"
  done
done
for t in $THREADS_LIST; do
  # shellcheck disable=SC2086  # one argument per figure
  echo "threads $t: median ratio $(median ${RATIOS[$t]}) (ratios:${RATIOS[$t]});" \
    "medians crushdem $(median ${ENG[$t]}), lammps_hh $(median ${PEER[$t]})"
done

if [ "${ROUGH:-0}" = 1 ]; then
  # The rough law on its own state at rest (bench/README.md, "--settle"), against Hertz settled
  # the same way, one after the other in each round. Each law is settled once, on every core
  # (the settled state does not depend on the thread count), and kept in a file that every
  # round reads (--settled-state). 300,000 steps bring the rough box to rest: kinetic energy
  # 2.0e-12 J (Hertz: 1.7e-13 J). After 100,000 it still relaxes (1.5e-11 J, 62 pruned-list
  # rebuilds in 3,000 steps against 22, a fifth of the contacts on the exact path), and after
  # 20,000 (1e-9 J) 59 % of the contact evaluations take the exact path (bench/README.md).
  SETTLE="${SETTLE:-300000}"
  for law in hertz rough; do
    "$BIN" bench --packing "$PACKING" --steps 1 --warm 0 --threads "$(nproc)" --law "$law" \
      --settle "$SETTLE" --settled-state "$WORK/settled_$law.bin" | grep '^settled' | sed "s/^/# $law /"
  done
  SLOW=""
  SLOWT=""
  for r in $(seq 1 "$ROUNDS"); do
    h=$(engine 1 --settle "$SETTLE" --settled-state "$WORK/settled_hertz.bin" --law hertz)
    g=$(engine 1 --settle "$SETTLE" --settled-state "$WORK/settled_rough.bin" --law rough)
    # Slower as lower throughput (1 - rough/hertz) and as longer time (hertz/rough - 1).
    s=$(awk -v h="$h" -v g="$g" 'BEGIN{printf "%.1f", 100*(1-g/h)}')
    st=$(awk -v h="$h" -v g="$g" 'BEGIN{printf "%.1f", 100*(h/g-1)}')
    echo "round $r settled 1 thread: hertz=$h rough=$g throughput_lower_pct=$s time_longer_pct=$st"
    SLOW+=" $s"
    SLOWT+=" $st"
  done
  # shellcheck disable=SC2086  # one argument per figure
  echo "rough against hertz (settled, 1 thread): throughput $(median $SLOW) % lower," \
    "time $(median $SLOWT) % longer (medians; per round:$SLOW /$SLOWT)"
fi

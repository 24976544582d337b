#!/usr/bin/env bash
# Two or more crushdem builds timed in alternation on the peer reference problem, for telling
# whether a change is faster on a host whose speed drifts (bench/README.md):
#
#   bash bench/alternate.sh THREADS LAW REPS BIN [BIN ...]
#   STEPS=3000 bash bench/alternate.sh 1 hertz 6 /tmp/crushdem_before build/bench/crushdem-sand
#   EXTRA="--settle 20000" bash bench/alternate.sh 1 rough 4 /tmp/before build/bench/crushdem-sand
#
# Each round runs every binary once, in the order given; per binary it prints the median, the
# range and every figure. Copy the old binary aside before rebuilding. Background `crushdem
# run`/`resume` jobs are paused (SIGSTOP) while it runs and continued after.
set -euo pipefail
if [ $# -lt 4 ]; then
  echo "usage: bash bench/alternate.sh THREADS LAW REPS BIN [BIN ...]" >&2
  exit 2
fi
threads=$1 law=$2 reps=$3
shift 3
# shellcheck source=bench/lib.sh
source "$(dirname "$0")/lib.sh"
bench_setup
for b in "$@"; do
  [ -x "$b" ] || { echo "alternate.sh: '$b' is not an executable" >&2; exit 2; }
done
pause_background_jobs

declare -A FIG
for r in $(seq 1 "$reps"); do
  for b in "$@"; do
    # shellcheck disable=SC2086  # EXTRA holds several bench arguments
    v=$(crushdem_rate "$b" "$threads" "${STEPS:-2000}" --law "$law" ${EXTRA:-})
    echo "round $r $b $v"
    FIG[$b]+=" $v"
  done
done
for b in "$@"; do
  read -r med lo hi n <<<"$(echo "${FIG[$b]}" | stats)"
  echo "$b median=$med min=$lo max=$hi n=$n"
done

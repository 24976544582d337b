#!/usr/bin/env bash
# Two or more crushdem builds timed in alternation on the peer reference problem, for telling
# whether a change is faster on a host whose speed drifts (bench/README.md):
#
#   bash bench/alternate.sh THREADS LAW REPS BIN [BIN ...]
#   STEPS=3000 bash bench/alternate.sh 1 hertz 6 /tmp/crushdem_before build/bench/crushdem
#   EXTRA="--settle 20000" bash bench/alternate.sh 1 rough 4 /tmp/before build/bench/crushdem
#
# Each round runs every binary once, in the order given; per binary it prints the median, the
# range and every figure. Copy the old binary aside before rebuilding. Background `crushdem
# run`/`resume` jobs are paused (SIGSTOP) while it runs and continued after.
set -euo pipefail
if [ $# -lt 4 ]; then
  echo "usage: bash bench/alternate.sh THREADS LAW REPS BIN [BIN ...]" >&2
  exit 2
fi
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
PEER_DIR="${PEER_DIR:-$ROOT/../shared/bench-peers}"
threads=$1 law=$2 reps=$3
shift 3
# shellcheck source=/dev/null
source "$PEER_DIR/common/lib.sh"
ensure_packing
export RHO G_SHEAR NU YOUNG MU REST DT SKIN
for b in "$@"; do
  [ -x "$b" ] || { echo "alternate.sh: '$b' is not an executable" >&2; exit 2; }
done

BG=$(pgrep -f "crushdem[^ ]* (run|resume) " | tr '\n' ' ' || true)
if [ -n "$BG" ]; then
  # shellcheck disable=SC2086  # one word per process id
  kill -STOP $BG
  trap 'kill -CONT $BG' EXIT
fi

declare -A FIG
for r in $(seq 1 "$reps"); do
  for b in "$@"; do
    # shellcheck disable=SC2086
    v=$("$b" bench --packing "$PACKING" --steps "${STEPS:-2000}" --threads "$threads" \
      --law "$law" ${EXTRA:-} | tail -1 | sed 's/^particle_steps_per_s=//')
    echo "round $r $b $v"
    FIG[$b]+=" $v"
  done
done
for b in "$@"; do
  echo "${FIG[$b]}" | tr ' ' '\n' | grep -v '^$' | sort -g |
    awk -v b="$b" '{v[NR]=$1} END{m=(NR%2)?v[(NR+1)/2]:(v[NR/2]+v[NR/2+1])/2;
      printf "%s median=%.3e min=%.3e max=%.3e n=%d\n", b, m, v[1], v[NR], NR}'
done

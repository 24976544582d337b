# shellcheck shell=bash
# Helpers shared by the benchmark scripts that time crushdem repeatedly on the peer reference
# problem (alternate.sh, interleaved_peers.sh). Sourced, not run.

# The peer problem's constants (bench/peers/common/lib.sh: PACKING, DT, SKIN, ...),
# exported for `crushdem-sand bench`, which reads them from the environment as the peers do.
bench_setup() {
  ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
  PEER_DIR="${PEER_DIR:-$ROOT/bench/peers}"
  # shellcheck source=/dev/null
  source "$PEER_DIR/common/lib.sh"
  ensure_packing
  export RHO G_SHEAR NU YOUNG MU REST DT SKIN
}

# Pauses background `crushdem-sand run`/`resume`/`reproduce`/`sensitivity` jobs (SIGSTOP) until the script exits; a timing
# made beside them measures the sharing, not the build. Extra cleanup commands may be appended
# to BENCH_ON_EXIT before exit.
BENCH_ON_EXIT=":"
pause_background_jobs() {
  BG=$(pgrep -f "crushdem[^ ]* (run|resume|reproduce|sensitivity) " | tr '\n' ' ' || true)
  if [ -n "$BG" ]; then
    echo "# stopping background crushdem jobs: $BG" >&2
    # shellcheck disable=SC2086  # one word per process id
    kill -STOP $BG
  fi
  trap '[ -n "$BG" ] && kill -CONT $BG; eval "$BENCH_ON_EXIT"' EXIT
}

# crushdem_rate BIN THREADS STEPS [bench args...] -> particle-steps/s of one `crushdem-sand bench`.
crushdem_rate() {
  local bin=$1 threads=$2 steps=$3
  shift 3
  "$bin" bench --packing "$PACKING" --steps "$steps" --threads "$threads" "$@" | tail -1 |
    sed 's/^particle_steps_per_s=//'
}

# stats: the median, smallest and largest of the numbers on stdin (any whitespace between them).
# (The median of arguments alone is the peers' median(), from their lib.sh.)
stats() {
  tr ' ' '\n' | grep -v '^$' | sort -g |
    awk '{v[NR]=$1} END{printf "%.4g %.4g %.4g %d\n",
      (NR%2)?v[(NR+1)/2]:(v[NR/2]+v[NR/2+1])/2, v[1], v[NR], NR}'
}

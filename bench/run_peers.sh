#!/usr/bin/env bash
# crushdem beside LAMMPS, LIGGGHTS and YADE on the peer reference problem, in one run:
#   bash bench/run_peers.sh                # all peers + crushdem (about 12 minutes)
#   PEERS=lammps_hh bash bench/run_peers.sh  # only the fastest peer + crushdem
# Prints the per-code medians and the crushdem/peer ratios (see bench/peers/README.md).
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
PEER_DIR="${PEER_DIR:-$ROOT/bench/peers}"
cmake -S "$ROOT" -B "$ROOT/build/bench" -DCMAKE_BUILD_TYPE=Release -DCRUSHDEM_TESTS=OFF >/dev/null
cmake --build "$ROOT/build/bench" -j "$(nproc)" >/dev/null
ENGINE_CMD="bash $ROOT/bench/peer_adapter.sh" bash "$PEER_DIR/run_all.sh"

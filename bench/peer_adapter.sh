#!/usr/bin/env bash
# ENGINE_CMD for bench/peers/run_all.sh: runs `crushdem-sand bench` on the reference
# problem with the harness's environment (PACKING DT STEPS WARM THREADS RHO G_SHEAR NU MU REST
# SKIN STATE_OUT are read by `crushdem-sand bench` itself). Law: CRUSHDEM_LAW (hertz | rough).
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
BIN="$ROOT/build/bench/crushdem-sand"
if [ ! -x "$BIN" ]; then
  cmake -S "$ROOT" -B "$ROOT/build/bench" -DCMAKE_BUILD_TYPE=Release -DCRUSHDEM_TESTS=OFF >&2
  cmake --build "$ROOT/build/bench" -j "$(nproc)" >&2
fi
exec "$BIN" bench --law "${CRUSHDEM_LAW:-hertz}"

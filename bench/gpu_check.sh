#!/usr/bin/env bash
# Every device check in one call, for a machine with an NVIDIA GPU and 16 CPU cores (about
# 8 minutes on an H200): build with CUDA, the device tests, the throughput figures, the CPU's
# thread scaling on the REV, and the study-scale relaxations on the GPU. Logs and result
# directories go to $OUT (default gpu_check_out); a table of the figures is printed last.
#
#   bash bench/gpu_deps.sh runs/reproduce_rev          # here, once: build/gpu-deps to carry
#   OUT=... bash bench/gpu_check.sh                    # there (PARTS to run some parts only)
#
# PARTS (default all): build tests bench scaling oedometric triaxial chamber pile. Each part has
# a time limit, so a slow one cannot eat the lease; what it wrote up to then is kept in $OUT.
#   tests       crushdem_cuda_kernel_test (contact kernels = host bits) and crushdem_device_test
#               (tests/device_checks.hpp on the GPU, then the GPU's bits against the emulation);
#   bench       `crushdem-sand bench --backend cuda` on the peer reference packing (11,500 grains,
#               Hertz and rough) and tiled 5 x 5 x 5 (1.44 million), with device bytes per grain;
#   scaling     the CPU backend on the REV sample, 1 to 16 threads (rough law);
#   oedometric  the REV oedometric relaxation of `crushdem-sand reproduce` on the GPU (wall-clock);
#   triaxial    the REV triaxial relaxation on the GPU for a fixed time: seconds per dynamic
#               phase from events.csv, and the projected total;
#   chamber     examples/chamber_cpt.toml (the study-scale CPT, 76,000 grains) on the GPU for
#               CHAMBER_LIMIT seconds: the preparation's and the push's steps/s, how far it got
#               and q_c by travel (bench/run_progress.py);
#   pile        examples/pile_chamber.toml (the study-scale pile, 590,000 grains) for PILE_LIMIT
#               seconds: the preparation's steps/s at that size.
# Last, $OUT/results.tar.gz holds every part's logs and small result files (no checkpoints).
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-gpu_check_out}
DEPS=${DEPS:-build/gpu-deps}
PARTS=${PARTS:-build tests bench scaling oedometric triaxial chamber pile}
# BACKEND=emulated BUILD=build/cuda PARTS="bench oedometric" tries the script's steps on a
# machine without a GPU (with short runs it stops early, which the table says).
BACKEND=${BACKEND:-cuda}
BUILD=${BUILD:-build-gpu}
J=$(nproc)
B=$BUILD/crushdem-sand
mkdir -p "$OUT"
SUMMARY="$OUT/summary.txt"
: > "$SUMMARY"
row() { printf '%-58s %s\n' "$1" "$2" | tee -a "$SUMMARY"; }
want() { [[ " $PARTS " == *" $1 "* ]]; }
seconds_since() { echo $(( $(date +%s) - $1 )); }

nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader > "$OUT/gpu.txt" 2>&1
row "GPU" "$(head -1 "$OUT/gpu.txt")"
row "CPU cores" "$J"

if want build; then
  t0=$(date +%s)
  extra=()
  [ -d "$DEPS/include/toml++" ] && extra+=("-DCRUSHDEM_TOMLPP_INCLUDE=$PWD/$DEPS/include")
  [ -d "$DEPS/include/CLI" ] && extra+=("-DCRUSHDEM_CLI11_INCLUDE=$PWD/$DEPS/include")
  generator=()
  command -v ninja > /dev/null && generator=(-G Ninja)
  # sm_90 only (the H200): the default Volta-to-Hopper list would multiply the device code's
  # build time.
  if timeout 400 cmake -S . -B "$BUILD" "${generator[@]}" -DCRUSHDEM_CUDA=ON \
       -DCMAKE_CUDA_ARCHITECTURES=90 -DCRUSHDEM_TESTS=OFF "${extra[@]}" > "$OUT/build.log" 2>&1 &&
     timeout 400 cmake --build "$BUILD" -j"$J" --target crushdem_exe crushdem_device_test \
       crushdem_cuda_kernel_test >> "$OUT/build.log" 2>&1; then
    row "build [s]" "$(seconds_since "$t0")"
  else
    row "build" "FAILED (see $OUT/build.log)"
    tail -30 "$OUT/build.log"
    exit 1
  fi
fi

if want tests; then
  timeout 60 "$BUILD"/crushdem_cuda_kernel_test > "$OUT/kernel_test.log" 2>&1
  row "contact kernels on the device" "$(tail -1 "$OUT/kernel_test.log")"
  emulate=()
  [ "$BACKEND" = emulated ] && emulate=(--emulate)
  timeout 240 "$BUILD"/crushdem_device_test "${emulate[@]}" > "$OUT/device_test.log" 2>&1
  grep FAIL "$OUT/device_test.log" | head -5
  row "device step against the CPU and the emulation" "$(tail -1 "$OUT/device_test.log")"
fi

PACKING="$OUT/packing.txt"
if want bench; then
  gunzip -c "$DEPS/packing.txt.gz" > "$PACKING"
  python3 bench/tile_packing.py 5 "$OUT/packing_5.txt" "$PACKING"
  # The peer problem's constants (bench/peers/common/lib.sh), as bench/lib.sh
  # exports them.
  export RHO=2500 G_SHEAR=2.6e9 NU=0.3 MU=0.5 REST=0.5 DT=5e-8 SKIN=3.75e-5
  for law in hertz rough; do
    timeout 120 "$B" bench --packing "$PACKING" --backend "$BACKEND" --law $law --steps "${BENCH_STEPS:-20000}" \
      > "$OUT/bench_cuda_$law.log" 2>&1
    row "$BACKEND $law, 11,500 grains [particle-steps/s]" \
      "$(tail -1 "$OUT/bench_cuda_$law.log" | sed 's/.*=//')"
  done
  row "device bytes per grain (11,500, hertz)" \
    "$(grep -o 'device_bytes_per_particle=[0-9]*' "$OUT/bench_cuda_hertz.log" | sed 's/.*=//')"
  timeout 180 "$B" bench --packing "$OUT/packing_5.txt" --backend "$BACKEND" \
    --steps "${TILED_STEPS:-2000}" \
    > "$OUT/bench_cuda_tiled5.log" 2>&1
  row "$BACKEND hertz, 1.44 million grains [particle-steps/s]" \
    "$(tail -1 "$OUT/bench_cuda_tiled5.log" | sed 's/.*=//')"
  row "device bytes per grain (1.44 million)" \
    "$(grep -o 'device_bytes_per_particle=[0-9]*' "$OUT/bench_cuda_tiled5.log" | sed 's/.*=//')"
fi

if want scaling; then
  for t in 1 2 4 8 16; do
    [ "$t" -le "$J" ] || continue
    timeout 120 "$B" bench --packing "$DEPS/sample_rev.txt" --law rough --threads $t \
      --steps 400 > "$OUT/scaling_$t.log" 2>&1
    row "cpu rough, REV, $t threads [particle-steps/s]" \
      "$(tail -1 "$OUT/scaling_$t.log" | sed 's/.*=//')"
  done
fi

# A run on the GPU under a time limit: its wall-clock seconds and how far it got.
gpu_run() {
  local name=$1 config=$2 limit=$3
  rm -rf "$OUT/$name"
  local t0
  t0=$(date +%s)
  timeout "$limit" "$B" run "$config" --out "$OUT/$name" --backend "$BACKEND" > "$OUT/$name.log" 2>&1
  local rc=$?
  echo "$rc $(seconds_since "$t0")"
}

if want oedometric; then
  read -r rc secs <<< "$(gpu_run oedometric_rev "$DEPS/oedometric_relaxation_rev.toml" "${OEDOMETRIC_LIMIT:-300}")"
  if [ "$rc" = 0 ]; then
    row "REV oedometric relaxation on the GPU [s]" "$secs"
    python3 - "$OUT/oedometric_rev" << 'EOF' | tee -a "$SUMMARY"
import csv, math, sys
rows = [r for r in csv.DictReader(open(sys.argv[1] + "/events.csv"))]
t = [float(r["ageing_time_s"]) for r in rows]
s = [0.5 * (float(r["wall_zmin_stress_Pa"]) + float(r["wall_zmax_stress_Pa"])) for r in rows]
print(f"{'  phases, sigma_v at t = 0 and at the end [MPa]':58s} {len(rows)}, "
      f"{s[0] / 1e6:.4g}, {s[-1] / 1e6:.4g} (t = {t[-1]:.4g} s)")
EOF
  else
    row "REV oedometric relaxation on the GPU" "stopped after ${secs} s (rc $rc; see $OUT/oedometric_rev.log)"
  fi
fi

if want triaxial; then
  read -r rc secs <<< "$(gpu_run triaxial_rev "$DEPS/triaxial_relaxation_rev.toml" "${TRIAXIAL_LIMIT:-240}")"
  row "REV triaxial relaxation on the GPU: ran [s]" "$secs (rc $rc)"
  # Stopped by the time limit (SIGTERM: a checkpoint, then timing.json): its rate gives the
  # seconds of a 150,000-cycle dynamic phase at its grain count.
  python3 - "$OUT/triaxial_rev" << 'EOF' | tee -a "$SUMMARY"
import csv, json, os, sys
d = sys.argv[1]
ts = list(csv.DictReader(open(os.path.join(d, "timeseries.csv"))))
n, step = float(ts[-1]["n_particles"]), int(float(ts[-1]["step"]))
rate = json.load(open(os.path.join(d, "timing.json")))["particle_steps_per_second"]
print(f"{'  steps done, grains, particle-steps/s':58s} {step}, {n:.0f}, {rate:.3e}")
print(f"{'  seconds per 150,000-cycle dynamic phase at that size':58s} {150000 * n / rate:.1f}")
EOF
fi
# A study-scale example on the GPU under a time limit: how far it got and how fast.
progress_run() {
  local name=$1 config=$2 limit=$3 label=$4 rc secs
  read -r rc secs <<< "$(gpu_run "$name" "$config" "$limit")"
  row "$label on the GPU: ran [s]" "$secs (rc $rc)"
  python3 bench/run_progress.py "$OUT/$name" "${name%%_*}" | tee -a "$SUMMARY"
}
want chamber && progress_run chamber_cpt "${CHAMBER_CONFIG:-examples/chamber_cpt.toml}" \
  "${CHAMBER_LIMIT:-300}" "study-scale chamber CPT"
want pile && progress_run pile_chamber "${PILE_CONFIG:-examples/pile_chamber.toml}" \
  "${PILE_LIMIT:-90}" "study-scale pile"

# The logs and the small result files in one archive (the device tool brings back few files).
(cd "$OUT" && find . -type f \( -name '*.log' -o -name '*.csv' -o -name '*.json' -o -name '*.txt' \
   -o -name '*.toml' \) ! -name 'packing*.txt' ! -path './pile_chamber/sample.txt' -print0 | tar -czf results.tar.gz --null -T -) ||
  echo "gpu_check: results.tar.gz not written" >&2
echo "== figures"
cat "$SUMMARY"

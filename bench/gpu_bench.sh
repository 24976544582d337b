#!/bin/bash
# GPU build, device tests and --backend cuda figures in one go (for a machine with an NVIDIA
# GPU; writes logs to $OUT or ./gpu_bench_out). PACKING_GZ: the reference packing.
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-gpu_bench_out}
mkdir -p "$OUT"
PACKING_GZ=${PACKING_GZ:-../shared/bench-peers/common/packing.txt.gz}
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader
t0=$(date +%s)
cmake -S . -B build-gpu -G Ninja -DCRUSHDEM_CUDA=ON -DCRUSHDEM_TESTS=OFF > "$OUT/build.log" 2>&1 &&
  cmake --build build-gpu -j"$(nproc)" >> "$OUT/build.log" 2>&1 || { tail -40 "$OUT/build.log"; exit 1; }
echo "build_s=$(( $(date +%s) - t0 ))"
rc=0
build-gpu/crushdem_cuda_kernel_test > "$OUT/kernel_test.log" 2>&1 || rc=1
tail -1 "$OUT/kernel_test.log"
build-gpu/crushdem_gpu_stepper_test > "$OUT/stepper_test.log" 2>&1 || rc=1
grep -E "FAIL|passed" "$OUT/stepper_test.log"
gunzip -c "$PACKING_GZ" > /tmp/packing.txt
python3 bench/tile_packing.py 2 /tmp/packing_2.txt /tmp/packing.txt
python3 bench/tile_packing.py 4 /tmp/packing_4.txt /tmp/packing.txt
B=build-gpu/crushdem
{
  for law in hertz rough; do
    echo "== cuda $law 11,500"
    $B bench --packing /tmp/packing.txt --backend cuda --law $law --steps 20000 | tail -4
    echo "== cuda $law 11,500 settled"
    $B bench --packing /tmp/packing.txt --backend cuda --law $law --settle 30000 \
      --threads "$(nproc)" --steps 20000 | grep -E "settled|contacts|particle_steps"
  done
  for n in 2 4; do
    echo "== cuda hertz tiled $n"
    $B bench --packing /tmp/packing_$n.txt --backend cuda --steps 10000 | tail -4
  done
  echo "== cpu $(nproc) threads hertz tiled 2"
  $B bench --packing /tmp/packing_2.txt --threads "$(nproc)" --steps 2000 | tail -1
} 2>&1 | tee "$OUT/bench.log"
exit $rc

#!/usr/bin/env bash
# Checks that a wheel built by scripts/wheel.sh suits any x86-64 machine of the last decade:
#  1. pip installs it into a fresh environment with --only-binary=:all:, so nothing is compiled
#     (a step that needed a compiler would fail); a manylinux wheel loads OpenMP's libgomp from
#     the copy it carries, not from the system; a stable-ABI wheel (cp312-abi3) holds
#     _core.abi3.so, which every CPython from 3.12 on imports;
#  2. its compiled module holds no instruction beyond what a Westmere CPU has: no VEX or EVEX
#     form (AVX, AVX2, AVX-512: a v-prefixed mnemonic or a ymm/zmm register), no BMI1/BMI2,
#     LZCNT, TZCNT or MOVBE (LZCNT and TZCNT would not even fault there: they run as BSR/BSF and
#     give other results, which step 3 could not see);
#  3. under QEMU's user-mode emulation of a Westmere CPU (2010: SSE4.2, no AVX), `crushdem-sand check`
#     and the README's first Python example (27 grains) work.
# Installs qemu-user from Debian when it is missing. Usage: bash scripts/wheel_check.sh [WHEEL]
# (default: the newest dist/crushdem_sand-*.whl).
set -euo pipefail
wheel=${1:+$(realpath "$1")}  # given from any directory
cd "$(dirname "$0")/.."
wheel=${wheel:-$(ls -t dist/crushdem_sand-*.whl 2>/dev/null | head -1 || true)}
[ -f "$wheel" ] || { echo "no wheel: run bash scripts/wheel.sh first" >&2; exit 2; }
source scripts/deps.sh
apt_install_missing qemu-user binutils python3-venv

env_dir=$(mktemp -d)
trap 'rm -rf "$env_dir"' EXIT
"${PYTHON:-python3}" -m venv "$env_dir/venv"  # the interpreter scripts/wheel.sh built for
echo "== 1. pip install --only-binary=:all: $wheel"
"$env_dir/venv/bin/python" -m pip install --quiet --only-binary=:all: "$wheel"

core=$(ls "$env_dir"/venv/lib/python3*/site-packages/crushdem_sand/_core*.so)
if [[ $(basename "$wheel") == *-abi3-* && $(basename "$core") != *.abi3.so ]]; then
  echo "the stable-ABI wheel's module is $(basename "$core"), not _core.abi3.so: it would import" \
    "into no other CPython" >&2
  exit 1
fi
if [[ $(basename "$wheel") == *manylinux* ]]; then
  gomp=$(ldd "$core" | grep -o '=> [^ ]*libgomp[^ ]*' || true)
  echo "libgomp ${gomp:-not needed}"
  if [[ -n $gomp && $gomp != *crushdem_sand.libs/* ]]; then
    echo "the manylinux wheel's module loads the system's libgomp, not its own" >&2
    exit 1
  fi
fi

echo "== 2. the compiled module's instructions"
objdump -d --no-show-raw-insn "$core" >"$env_dir/core.asm"
total=$(grep -c $'^ *[0-9a-f]*:\t' "$env_dir/core.asm" || true)
beyond=$'^ *[0-9a-f]*:\t(v[a-z0-9]+|andn|bextr|blsi|blsmsk|blsr|bzhi|mulx|pdep|pext|rorx|sarx|shlx|shrx|lzcnt|tzcnt|movbe)( |$)|%[yz]mm[0-9]'
newer=$(grep -cE "$beyond" "$env_dir/core.asm" || true)
echo "$core: $total instructions, $newer of them beyond Westmere (AVX, AVX2, AVX-512, BMI, LZCNT, MOVBE)"
if [ "$newer" != 0 ]; then
  grep -m5 -E "$beyond" "$env_dir/core.asm" >&2 || true
  echo "the wheel's module needs a newer CPU: was it built with -march=native?" >&2
  exit 1
fi

if "$env_dir/venv/bin/python" -c 'import crushdem_sand, sys; sys.exit("cuda" not in crushdem_sand.backends())'; then
  # The architectures of the kernels: named in the fat binary's section (no cuobjdump needed).
  objcopy -O binary --only-section=.nv_fatbin "$core" "$env_dir/fatbin"
  archs=$(grep -ao 'sm_[0-9]\+a\?' "$env_dir/fatbin" | sort -u | tr '\n' ' ' || true)
  echo "the CUDA backend is in the wheel${archs:+, with kernels for $archs}"
else
  echo "the wheel has no CUDA backend (built without nvcc)"
fi

echo "== 3. run under qemu-x86_64 -cpu Westmere (no AVX)"
py="$env_dir/venv/bin/python"
qemu-x86_64 -cpu Westmere "$py" -m crushdem_sand check examples/compression_small.toml >/dev/null
# The README's first example: 27 grains pressed by a servo wall to 1 MPa.
qemu-x86_64 -cpu Westmere "$py" - <<'EOF'
import numpy as np

import crushdem_sand

sim = crushdem_sand.Simulation(
    contact={"law": "hertz"},
    box={"min": [0, 0, 0], "max": [1e-3, 1e-3, 1e-3]},
    walls={"zmax": {"mode": "servo", "target_stress": 1e6}},
)
g = (np.arange(3) + 0.5) / 3 * 1e-3
sim.add_particles(np.stack(np.meshgrid(g, g, g), axis=-1).reshape(-1, 3), 1.65e-4)
sim.step(10_000)
stress = sim.wall_stresses()[5]
print(f"crushdem {crushdem_sand.__version__} on a CPU without AVX: {sim.num_contacts} contacts, "
      f"top wall at {stress:.4g} Pa")
assert abs(stress - 1e6) < 1e3, stress
EOF
echo "wheel check passed: $wheel"

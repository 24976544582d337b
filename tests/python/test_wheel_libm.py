"""The portable wheel's libm pin (python/src/manylinux_libm.cpp, CMake option CRUSHDEM_MANYLINUX):
a program linked as the wheel's module is (-Wl,--wrap=log,--wrap=pow with that file) binds log and
pow to their GLIBC_2.2.5 version, needs no glibc symbol of 2.29, and computes the same bits as the
same program linked plainly, for the arguments crushdem passes (the Hertz and Weibull exponents,
Charles' law's large ones, logs of uniform deviates) and for the edges (zero, one, subnormals,
overflow). On glibc 2.29 or later both are one implementation, so an unequal bit means the pin
reaches something else."""

import os
import platform
import re
import shutil
import subprocess

import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))

PROGRAM = r"""
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <random>

static std::uint64_t bits(double v) {
  std::uint64_t b;
  std::memcpy(&b, &v, sizeof b);
  return b;
}

int main() {
  std::mt19937_64 rng(20261206);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::uint64_t h = 1469598103934665603ull;  // FNV-1a of every result's bits
  long n = 0;
  const auto mix = [&](double v) {
    h = (h ^ bits(v)) * 1099511628211ull;
    ++n;
  };
  // volatile: the calls stay calls, not folded at compile time.
  for (int k = 0; k < 200000; ++k) {
    volatile double u = unit(rng);
    volatile double x = 1e-3 + 10.0 * unit(rng);
    volatile double n_charles = 2.0 + 60.0 * unit(rng);
    mix(std::log(u > 0.0 ? u : 0.5));
    mix(std::log(x * 1e6));
    mix(std::pow(x, 1.5));
    mix(std::pow(u, n_charles));
    mix(std::pow(x, -3.0 / (1.0 + 20.0 * u)));
    mix(std::pow(x, 2.0 / 3.0));
  }
  const double edges[] = {0.0, 1.0, 2.0, std::numeric_limits<double>::denorm_min(),
                          std::numeric_limits<double>::min(), std::numeric_limits<double>::max(),
                          0.5, 1e300, 1e-300};
  for (double a : edges) {
    volatile double va = a;
    mix(std::log(va));
    for (double b : {0.5, 1.5, -1.0, 2.0, 40.0, -40.0}) {
      volatile double vb = b;
      mix(std::pow(va, vb));
    }
  }
  std::printf("%ld values, FNV-1a %016llx\n", n, static_cast<unsigned long long>(h));
  return 0;
}
"""


def _gxx():
    return shutil.which("g++")


pytestmark = pytest.mark.skipif(
    platform.system() != "Linux" or platform.machine() != "x86_64"
    or platform.libc_ver()[0] != "glibc" or _gxx() is None or shutil.which("objdump") is None,
    reason="the pin is for GCC on x86-64 Linux with glibc, with objdump to read the symbols")


def _build(tmp_path, name, extra):
    src = tmp_path / "libm_bits.cpp"
    src.write_text(PROGRAM)
    exe = tmp_path / name
    subprocess.run([_gxx(), "-std=c++20", "-O2", "-fno-builtin", str(src), *extra, "-o", str(exe)],
                   check=True)
    return exe


def _module_wrap_flag():
    """The --wrap flag of the module's link, as python/CMakeLists.txt gives it."""
    with open(os.path.join(ROOT, "python", "CMakeLists.txt")) as f:
        return "-Wl," + re.search(r'"LINKER:(--wrap=[^"]+)"', f.read()).group(1)


def test_the_pinned_log_and_pow_are_the_glibc_2_2_5_symbols_with_the_same_bits(tmp_path):
    plain = _build(tmp_path, "plain", [])
    pinned = _build(tmp_path, "pinned",
                    [os.path.join(ROOT, "python", "src", "manylinux_libm.cpp"),
                     _module_wrap_flag()])
    # A needed symbol's version: in parentheses from Debian 12's objdump, bare from Debian 11's.
    symbols = subprocess.run(["objdump", "-T", str(pinned)], capture_output=True, text=True,
                             check=True).stdout
    versions = {m.group(2): m.group(1) for m in
                re.finditer(r"\(?(GLIBC_[0-9.]+)\)?\s+(log|pow)\s*$", symbols, re.MULTILINE)}
    assert versions == {"log": "GLIBC_2.2.5", "pow": "GLIBC_2.2.5"}, symbols
    assert "GLIBC_2.29" not in symbols
    out_plain = subprocess.run([str(plain)], capture_output=True, text=True, check=True).stdout
    out_pinned = subprocess.run([str(pinned)], capture_output=True, text=True, check=True).stdout
    assert out_pinned == out_plain

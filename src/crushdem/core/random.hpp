// Reproducible random streams. std::mt19937_64's sequence is fixed by the C++ standard, but the
// standard distributions are not, so conversions to real numbers are written out here: the same
// seed gives the same numbers with every compiler and library.
#pragma once

#include <cstdint>
#include <random>

namespace crushdem {

class RandomStream {
 public:
  explicit RandomStream(std::uint64_t seed, std::uint64_t stream = 0)
      : engine_(seed ^ (0x9E3779B97F4A7C15ull * (stream + 1))) {}
  /// Uniform in [0, 1) with 53 random bits.
  double uniform() { return static_cast<double>(engine_() >> 11) * 0x1.0p-53; }
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  std::mt19937_64& engine() { return engine_; }
  const std::mt19937_64& engine_state() const { return engine_; }

 private:
  std::mt19937_64 engine_;
};

}  // namespace crushdem

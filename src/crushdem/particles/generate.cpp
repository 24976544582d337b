#include "crushdem/particles/generate.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <unordered_map>

#include "crushdem/core/error.hpp"
#include "crushdem/core/random.hpp"

namespace crushdem {

std::vector<PlacedSphere> random_sequential_addition(std::vector<double> radii,
                                                     const std::array<double, 6>& box,
                                                     std::uint64_t seed, std::uint64_t max_attempts,
                                                     const PlaceTest& inside) {
  std::sort(radii.begin(), radii.end(), std::greater<>());
  std::vector<PlacedSphere> out;
  if (radii.empty()) return out;
  out.reserve(radii.size());
  const double h = 2.0 * radii.front();  // cell side: no overlap can reach past the next cell
  auto cell = [&](double v, int a) {
    return static_cast<long>(std::floor((v - box[static_cast<std::size_t>(2 * a)]) / h));
  };
  auto key = [](long i, long j, long k) {
    return (static_cast<std::uint64_t>(i) & 0x1FFFFF) |
           ((static_cast<std::uint64_t>(j) & 0x1FFFFF) << 21) |
           ((static_cast<std::uint64_t>(k) & 0x1FFFFF) << 42);
  };
  std::unordered_map<std::uint64_t, std::vector<std::uint32_t>> grid;
  RandomStream rng(seed, 0x5EED);
  for (double r : radii) {
    bool placed = false;
    for (std::uint64_t attempt = 0; attempt < max_attempts && !placed; ++attempt) {
      Vec3 p{rng.uniform(box[0] + r, box[1] - r), rng.uniform(box[2] + r, box[3] - r),
             rng.uniform(box[4] + r, box[5] - r)};
      if (inside && !inside(p, r)) continue;
      const long ci = cell(p.x, 0), cj = cell(p.y, 1), ck = cell(p.z, 2);
      bool ok = true;
      for (long a = ci - 1; a <= ci + 1 && ok; ++a) {
        for (long b = cj - 1; b <= cj + 1 && ok; ++b) {
          for (long c = ck - 1; c <= ck + 1 && ok; ++c) {
            auto it = grid.find(key(a, b, c));
            if (it == grid.end()) continue;
            for (std::uint32_t q : it->second) {
              const Vec3 d = out[q].position - p;
              const double s = out[q].radius + r;
              if (dot(d, d) < s * s) {
                ok = false;
                break;
              }
            }
          }
        }
      }
      if (ok) {
        grid[key(ci, cj, ck)].push_back(static_cast<std::uint32_t>(out.size()));
        out.push_back({p, r});
        placed = true;
      }
    }
    if (!placed) {
      throw ConfigError("particles.generate: could not place grain " +
                        std::to_string(out.size() + 1) + " of " + std::to_string(radii.size()) +
                        " without overlap; enlarge the box or ask for fewer grains");
    }
  }
  return out;
}

}  // namespace crushdem

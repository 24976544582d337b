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

std::optional<DeepOverlap> find_deep_overlap(const std::vector<PlacedSphere>& grains,
                                             double max_share, std::size_t first_new) {
  if (grains.size() < 2 || first_new >= grains.size()) return std::nullopt;
  double r_max = 0.0;
  for (const PlacedSphere& g : grains) {
    if (std::isfinite(g.radius)) r_max = std::max(r_max, g.radius);
  }
  const double h = 2.0 * r_max;  // no overlapping pair spans more than one cell
  if (!(h > 0.0) || !std::isfinite(h)) return std::nullopt;
  // Cells far beyond any sample are clamped (no overflow; pairs there are still compared by
  // distance).
  const auto cell_of = [h](const Vec3& p) {
    const auto c = [h](double x) {
      return static_cast<long long>(std::clamp(std::floor(x / h), -1e12, 1e12));
    };
    return std::array<long long, 3>{c(p.x), c(p.y), c(p.z)};
  };
  const auto finite = [](const PlacedSphere& g) {
    return std::isfinite(g.position.x) && std::isfinite(g.position.y) &&
           std::isfinite(g.position.z) && std::isfinite(g.radius) && g.radius > 0.0;
  };
  const auto key = [](long long i, long long j, long long k) {
    const auto u = [](long long v) { return static_cast<std::uint64_t>(v) & 0x1FFFFFULL; };
    return (u(i) << 42) | (u(j) << 21) | u(k);
  };
  std::unordered_map<std::uint64_t, std::vector<std::size_t>> cells;
  cells.reserve(grains.size());
  for (std::size_t i = 0; i < grains.size(); ++i) {
    if (!finite(grains[i])) continue;  // refused by the caller's own checks
    const auto c = cell_of(grains[i].position);
    cells[key(c[0], c[1], c[2])].push_back(i);
  }
  std::optional<DeepOverlap> worst;
  for (std::size_t i = first_new; i < grains.size(); ++i) {
    if (!finite(grains[i])) continue;
    const auto c = cell_of(grains[i].position);
    for (long long di = -1; di <= 1; ++di) {
      for (long long dj = -1; dj <= 1; ++dj) {
        for (long long dk = -1; dk <= 1; ++dk) {
          const auto it = cells.find(key(c[0] + di, c[1] + dj, c[2] + dk));
          if (it == cells.end()) continue;
          for (const std::size_t j : it->second) {
            // Each new-new pair once (j < i), each old-new pair once (j old).
            if (j == i || (j >= first_new && j > i)) continue;
            const Vec3 d = grains[i].position - grains[j].position;
            const double dist = std::sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
            const double share = (grains[i].radius + grains[j].radius - dist) /
                                 std::min(grains[i].radius, grains[j].radius);
            if (share > max_share && (!worst || share > worst->share)) {
              worst = DeepOverlap{std::min(i, j), std::max(i, j), share};
            }
          }
        }
      }
    }
  }
  return worst;
}

}  // namespace crushdem

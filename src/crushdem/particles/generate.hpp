// Random sequential addition: spheres placed one by one at random positions inside a box,
// rejected while they overlap an earlier one. Gives a loose, overlap-free initial state that
// walls or radius growth then compact. Deterministic for a seed.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <optional>
#include <vector>

#include "crushdem/core/types.hpp"

namespace crushdem {

struct PlacedSphere {
  Vec3 position;
  double radius = 0.0;
};

/// Where a sphere of radius r centred at p may go besides the box (a cylinder's inside).
using PlaceTest = std::function<bool(Vec3 p, double r)>;

/// Places spheres with the given radii (largest first) in box [xmin,xmax,ymin,ymax,zmin,zmax],
/// and where `inside` holds when it is given (a place drawn in the box where it does not counts
/// as a failed try). Throws ConfigError when a sphere cannot be placed after `max_attempts`
/// tries.
std::vector<PlacedSphere> random_sequential_addition(std::vector<double> radii,
                                                     const std::array<double, 6>& box,
                                                     std::uint64_t seed,
                                                     std::uint64_t max_attempts = 100000,
                                                     const PlaceTest& inside = {});

/// Two grains that overlap by more than a contact can: their indices (a < b) and the overlap
/// r_a + r_b - |x_a - x_b| as a share of the smaller radius (>= 1 when one centre lies inside
/// the other grain; infinite-force territory for Hertz at any share near 1).
struct DeepOverlap {
  std::size_t a = 0, b = 0;
  double share = 0.0;
};

/// The grain sets crushdem takes from outside (sample files, the Python API) are checked with
/// this before any step: compressed samples overlap by well under 1 % of a radius, so an overlap
/// beyond `max_share` of the smaller radius (coincident centres included) is an input error.
/// Only pairs with at least one grain from index `first_new` on are examined (grains already in
/// a simulation were checked when they came in). A cell grid: O(N) for similar sizes.
inline constexpr double kMaxInputOverlapShare = 0.5;
std::optional<DeepOverlap> find_deep_overlap(const std::vector<PlacedSphere>& grains,
                                             double max_share = kMaxInputOverlapShare,
                                             std::size_t first_new = 0);

}  // namespace crushdem

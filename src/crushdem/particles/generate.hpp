// Random sequential addition: spheres placed one by one at random positions inside a box,
// rejected while they overlap an earlier one. Gives a loose, overlap-free initial state that
// walls or radius growth then compact. Deterministic for a seed.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
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

}  // namespace crushdem

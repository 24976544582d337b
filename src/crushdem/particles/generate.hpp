// Random sequential addition: spheres placed one by one at random positions inside a box,
// rejected while they overlap an earlier one. Gives a loose, overlap-free initial state that
// walls or radius growth then compact. Deterministic for a seed.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "crushdem/core/types.hpp"

namespace crushdem {

struct PlacedSphere {
  Vec3 position;
  double radius = 0.0;
};

/// Places spheres with the given radii (largest first) in box [xmin,xmax,ymin,ymax,zmin,zmax],
/// or with cylinder_radius > 0 in the cylinder of that radius about the box's vertical centre
/// line (a place drawn in the box outside it counts as a failed try). Throws ConfigError when a
/// sphere cannot be placed after `max_attempts` tries.
std::vector<PlacedSphere> random_sequential_addition(std::vector<double> radii,
                                                     const std::array<double, 6>& box,
                                                     std::uint64_t seed,
                                                     std::uint64_t max_attempts = 100000,
                                                     double cylinder_radius = 0.0);

}  // namespace crushdem

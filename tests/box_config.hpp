// The test configuration of a cubic box, with no GoogleTest in it, so that the device checks
// (tests/device_checks.hpp) build on a GPU machine without it.
#pragma once

#include <cstddef>

#include "crushdem/integrate/simulation.hpp"

namespace crushdem::testing {

/// A configuration with a cubic box [lo, hi]^3 of fixed walls and no damping.
inline SimulationConfig box_config(double lo, double hi, NormalLaw law = NormalLaw::Hertz) {
  SimulationConfig c;
  c.contact.law = law;
  c.damping.local_alpha = 0.0;
  for (int k = 0; k < kNumWalls; ++k) {
    c.walls[static_cast<std::size_t>(k)].position = wall_is_low(k) ? lo : hi;
  }
  return c;
}

}  // namespace crushdem::testing

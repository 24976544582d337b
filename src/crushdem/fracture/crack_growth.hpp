// Time-dependent failure by subcritical crack growth (docs/model.md 3; stress corrosion after
// Charles, as used by the reference study following Lei et al.).
//
//   v   = v0 (sigma / sigma_lim)^n      crack velocity at the grain's particle stress sigma
//   a  >= 0.5 d                          failure (cause "crack")
//   t_f = (0.5 d - a) / v                time to failure at a constant v
//
// sigma is the particle stress of the crushing criterion (fracture/strength.hpp), sigma_lim the
// grain's strength, a the crack half-length seeded at creation. Pure and usable on the device.
#pragma once

#include <cmath>

#include "crushdem/core/types.hpp"

namespace crushdem {

CD_HD inline double crack_velocity(double v0, double sigma, double sigma_lim, double n) {
  return v0 * std::pow(sigma / sigma_lim, n);
}

/// Time until a crack of half-length a in a grain of half-diameter half_d fails at velocity
/// v > 0; 0 for a crack already at or past failure.
CD_HD inline double crack_time_to_failure(double a, double half_d, double v) {
  const double t = (half_d - a) / v;
  return t > 0.0 ? t : 0.0;
}

}  // namespace crushdem

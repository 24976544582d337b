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

/// What one crushing check finds for a grain (docs/model.md 2 and 3).
enum class GrainFailure : unsigned char { None = 0, Instant = 1, Crack = 2 };

/// One crushing check of a grain of radius r at particle stress sigma, `elapsed` seconds after
/// the last check, the same for every backend: a grain smaller than d_c never breaks; one at
/// sigma >= sigma_lim fails at once; otherwise, with crack growth on and a crack (a not NaN), the
/// crack grows by v elapsed (v = 0 without load) and the grain fails when a >= 0.5 d.
CD_HD inline GrainFailure crushing_check(double r, double d_c, double sigma, double sigma_lim,
                                         bool crack_growth, double v0, double n, double elapsed,
                                         double& a) {
  if (2.0 * r < d_c) return GrainFailure::None;
  if (sigma >= sigma_lim) return GrainFailure::Instant;
  if (crack_growth && a == a) {
    const double v = sigma > 0.0 ? crack_velocity(v0, sigma, sigma_lim, n) : 0.0;
    a += v * elapsed;
    if (a >= r) return GrainFailure::Crack;  // a >= 0.5 d
  }
  return GrainFailure::None;
}

/// Time until a crack of half-length a in a grain of half-diameter half_d fails at velocity
/// v > 0; 0 for a crack already at or past failure.
CD_HD inline double crack_time_to_failure(double a, double half_d, double v) {
  const double t = (half_d - a) / v;
  return t > 0.0 ? t : 0.0;
}

}  // namespace crushdem

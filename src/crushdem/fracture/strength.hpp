// Grain crushing criterion and strength (docs/model.md 2.1; Ciantia et al. 2015, 2019).
//
// Contact stress of a contact:  sigma_c = F_n / (pi r' delta)
//   r' = R* (CHOICE, pi R* delta = pi a^2 the Hertz contact area) or 2 R* (PFC's effective
//   radius); for a wall contact R* = R. delta is the total overlap.
// Particle stress: sigma = max over the particle's contacts (walls included) of sigma_c.
// Strength, drawn once per particle when it is created:
//   sigma_lim = sigma_lim0 (d / d0)^(-3/m) f,   f ~ normal(1, var) truncated to [0.05, 1 + 3 var]
//   by redrawing (CHOICE), or uniform on [1 - var, 1 + var].
// A particle with d >= d_c breaks when sigma >= sigma_lim.
#pragma once

#include <cmath>

#include "crushdem/contact/contact_stress.hpp"
#include "crushdem/core/random.hpp"
#include "crushdem/core/types.hpp"

namespace crushdem {

CD_HD inline double size_scaled_strength(double sigma_lim0, double d, double d0, double m,
                                         double f) {
  return sigma_lim0 * std::pow(d / d0, -3.0 / m) * f;
}

enum class StrengthDistribution { Normal, Uniform };

/// A standard normal variate from two uniforms (Box-Muller, written out for reproducibility).
inline double standard_normal(RandomStream& rng) {
  double u1 = rng.uniform();
  while (u1 <= 0.0) u1 = rng.uniform();
  const double u2 = rng.uniform();
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * kPi * u2);
}

/// The variability factor f of docs/model.md 2.1.
inline double strength_factor(RandomStream& rng, StrengthDistribution dist, double var) {
  if (dist == StrengthDistribution::Uniform) return rng.uniform(1.0 - var, 1.0 + var);
  for (;;) {
    const double f = 1.0 + var * standard_normal(rng);
    if (f >= 0.05 && f <= 1.0 + 3.0 * var) return f;
  }
}

}  // namespace crushdem

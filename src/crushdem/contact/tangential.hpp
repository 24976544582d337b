// Incremental Mindlin tangential force with a Coulomb cap (model-notes 1.1; the PFC Hertz model).
//
//   F_t <- rot(F_t) - k_t du_t,  k_t = 2 (1 - nu) / (2 - nu) k_n,  |F_t| <= mu F_n
//
// rot() turns the stored force onto the current contact plane keeping its length, so that a
// rolling pair does not grow a normal component in its tangential history. k_n is the tangent
// normal stiffness of whichever normal law is in use (Mindlin & Deresiewicz 1953).
#pragma once

#include <cmath>

#include "crushdem/core/types.hpp"

namespace crushdem {

/// k_t / k_n for one material.
CD_HD inline double mindlin_stiffness_ratio(double nu) {
  return 2.0 * (1.0 - nu) / (2.0 - nu);
}

/// Returns the new tangential force; du_t is the tangential relative displacement of the first
/// body with respect to the second over the step, n the unit contact normal.
CD_HD inline Vec3 mindlin_tangential(Vec3 F_t, Vec3 n, Vec3 du_t, double k_t, double mu,
                                     double F_n) {
  // Rotate the stored force onto the current tangent plane, keeping its magnitude.
  const double len2 = dot(F_t, F_t);
  if (len2 > 0.0) {
    const double f_n = dot(F_t, n);
    F_t -= f_n * n;
    // Restoring the length multiplies by sqrt(len2 / (len2 - f_n^2)) = 1 + f_n^2 / (2 len2):
    // below 1e-17 relative that factor rounds to 1 in double precision, so the sqrt and the
    // division are skipped (the common case: the contact plane turns very little per step).
    if (f_n * f_n > 1e-17 * len2) {
      const double p2 = dot(F_t, F_t);
      F_t = p2 > 0.0 ? std::sqrt(len2 / p2) * F_t : Vec3{};
    }
  }
  F_t -= k_t * du_t;
  const double cap = mu * F_n;
  const double ft2 = dot(F_t, F_t);
  if (ft2 > cap * cap) F_t = (ft2 > 0.0 ? cap / std::sqrt(ft2) : 0.0) * F_t;
  return F_t;
}

}  // namespace crushdem

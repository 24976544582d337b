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

/// One step of an incremental elastic-perfectly-plastic spring that lives in the contact plane
/// (shared by the tangential force and the rolling moment): the stored value h is turned onto
/// the plane normal to n keeping its length, loaded by -k du, and capped at |h| <= h_max.
CD_HD inline Vec3 contact_plane_spring(Vec3 h, Vec3 n, Vec3 du, double k, double h_max) {
  // Rotate the stored value onto the current tangent plane, keeping its magnitude.
  const double len2 = dot(h, h);
  if (len2 > 0.0) {
    const double h_n = dot(h, n);
    h -= h_n * n;
    // Restoring the length multiplies by sqrt(len2 / (len2 - h_n^2)) = 1 + h_n^2 / (2 len2):
    // below 1e-17 relative that factor rounds to 1 in double precision, so the sqrt and the
    // division are skipped (the common case: the contact plane turns very little per step).
    if (h_n * h_n > 1e-17 * len2) {
      const double p2 = dot(h, h);
      h = p2 > 0.0 ? std::sqrt(len2 / p2) * h : Vec3{};
    }
  }
  h -= k * du;
  const double h2 = dot(h, h);
  if (h2 > h_max * h_max) h = (h2 > 0.0 ? h_max / std::sqrt(h2) : 0.0) * h;
  return h;
}

/// Returns the new tangential force; du_t is the tangential relative displacement of the first
/// body with respect to the second over the step, n the unit contact normal.
CD_HD inline Vec3 mindlin_tangential(Vec3 F_t, Vec3 n, Vec3 du_t, double k_t, double mu,
                                     double F_n) {
  return contact_plane_spring(F_t, n, du_t, k_t, mu * F_n);
}

}  // namespace crushdem

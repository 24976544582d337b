// Incremental Mindlin tangential force with a Coulomb cap (docs/model.md 1.1; the PFC Hertz model).
//
//   F_t <- rot(F_t) - k_t du_t,  k_t = 2 (1 - nu) / (2 - nu) k_n,  |F_t| <= mu F_n
//
// rot() turns the stored force onto the current contact plane keeping its length, so that a
// rolling pair does not grow a normal component in its tangential history. k_n is the tangent
// normal stiffness of whichever normal law is in use (Mindlin & Deresiewicz 1953).
#pragma once

#include <cmath>
#include <limits>

#include "crushdem/contact/history_field.hpp"
#include "crushdem/core/params.hpp"
#include "crushdem/core/types.hpp"

namespace crushdem {

/// The tangential sub-model's history: one spring per contact (grain pairs and walls).
inline constexpr HistoryField kTangentialHistory = {"ft",
                                                    "tangential spring force on the owner [N]"};

/// The keys of [contact] the tangential sub-model owns (the grain-grain friction is
/// material.friction).
struct TangentialConfig {
  double wall_friction = 0.0;  // mu against walls (CHOICE)
  static const ParamTable<TangentialConfig>& config_params() {
    using C = TangentialConfig;
    static const ParamTable<C> table = {
        {"wall_friction", &C::wall_friction, "-", "friction coefficient against walls (CHOICE)",
         [](double v) { return v >= 0.0; }, "a friction coefficient >= 0"},
    };
    return table;
  }
};

/// k_t / k_n for one material.
CD_HD inline double mindlin_stiffness_ratio(double nu) {
  return 2.0 * (1.0 - nu) / (2.0 - nu);
}

/// The two rare steps of contact_plane_spring(), each a square root and a division. Restoring
/// the length after a turn of the contact plane multiplies by sqrt(len2 / (len2 - h_n^2)) =
/// 1 + h_n^2 / (2 len2): below 1e-17 relative that factor rounds to 1 in double precision, so it
/// is skipped (the common case: the contact plane turns very little per step).
CD_HD inline bool plane_turn_restores_length(double h_n, double len2) {
  return h_n * h_n > 1e-17 * len2;
}
/// A spring of squared length h2 beyond its cap (a sliding contact).
CD_HD inline bool exceeds_cap(double h2, double h_max) {
  return h2 > h_max * h_max;
}

/// The value a fast-path evaluation gives every component of a spring whose rare step applies
/// (see contact_plane_spring()); no exact evaluation gives it to a finite state.
inline constexpr double kNeedsExactPath = std::numeric_limits<double>::infinity();

/// One step of an incremental elastic-perfectly-plastic spring that lives in the contact plane
/// (shared by the tangential force and the rolling moment): the stored value h is turned onto
/// the plane normal to n keeping its length, loaded by -k du, and capped at |h| <= h_max.
///
/// kFastPath leaves out both rare steps: in vector lanes both sides of a branch are computed,
/// so every contact would pay for them. Where one applies, every component of the result is
/// kNeedsExactPath, and the caller evaluates that contact again without kFastPath; elsewhere
/// both paths give the same bits.
template <bool kFastPath = false>
CD_HD_INLINE Vec3 contact_plane_spring(Vec3 h, Vec3 n, Vec3 du, double k, double h_max) {
  // Rotate the stored value onto the current tangent plane, keeping its magnitude.
  const double len2 = dot(h, h);
  double h_n = 0.0;  // a double, not a flag set in the branch: vector lanes need one mask width
  if (len2 > 0.0) {
    h_n = dot(h, n);
    h -= h_n * n;
    if (!kFastPath && plane_turn_restores_length(h_n, len2)) {
      const double p2 = dot(h, h);
      h = p2 > 0.0 ? std::sqrt(len2 / p2) * h : Vec3{};
    }
  }
  h -= k * du;
  const double h2 = dot(h, h);
  if constexpr (kFastPath) {
    if (plane_turn_restores_length(h_n, len2) | exceeds_cap(h2, h_max)) {
      h = {kNeedsExactPath, kNeedsExactPath, kNeedsExactPath};
    }
  } else {
    if (exceeds_cap(h2, h_max)) h = (h2 > 0.0 ? h_max / std::sqrt(h2) : 0.0) * h;
  }
  return h;
}

/// Returns the new tangential force; du_t is the tangential relative displacement of the first
/// body with respect to the second over the step, n the unit contact normal.
template <bool kFastPath = false>
CD_HD_INLINE Vec3 mindlin_tangential(Vec3 F_t, Vec3 n, Vec3 du_t, double k_t, double mu,
                                     double F_n) {
  return contact_plane_spring<kFastPath>(F_t, n, du_t, k_t, mu * F_n);
}

}  // namespace crushdem

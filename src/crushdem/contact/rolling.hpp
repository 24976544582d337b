// Rolling resistance: an elastic-perfectly-plastic moment spring (docs/model.md 1.5; the
// rolling-resistance linear model of PFC, `rrlinear`; Iwashita & Oda 1998, J. Eng. Mech. 124(3);
// model C of Ai et al. 2011, Powder Technol. 206, without its dashpot: local damping acts on
// the torques already).
//
//   M_r <- rot(M_r) - k_r dtheta_b,   k_r = k_t R*^2,   |M_r| <= mu_r R* F_n
//
// dtheta_b = (w_i - w_j) dt minus its twisting part along n: the relative bending rotation of
// body i with respect to body j over the step. M_r is the moment on i (j receives -M_r); k_t is
// the tangent tangential stiffness of the contact (Mindlin), R* the effective radius. Not in the
// study's Table 1: off (mu_r = 0) by default, and used for grain-grain contacts only (the walls
// are frictionless by default, and a moment from a flat wall would have no lever to resist).
#pragma once

#include <string>

#include "crushdem/contact/history_field.hpp"
#include "crushdem/contact/tangential.hpp"
#include "crushdem/core/error.hpp"
#include "crushdem/core/params.hpp"
#include "crushdem/core/types.hpp"

namespace crushdem {

/// Returns the new rolling moment on body 1. dw = w_1 - w_2 [rad/s]; n the unit contact normal;
/// k_t the tangential stiffness [N/m]; mu_r the rolling friction coefficient [-].
CD_HD inline Vec3 rolling_moment(Vec3 M_r, Vec3 n, Vec3 dw, double dt, double k_t, double R_star,
                                 double mu_r, double F_n) {
  const Vec3 dtheta = dt * dw;
  const Vec3 dtheta_b = dtheta - dot(dtheta, n) * n;
  return contact_plane_spring(M_r, n, dtheta_b, k_t * R_star * R_star, mu_r * R_star * F_n);
}

/// How grains turn. Free: spins integrated from the contact moments (Table 1 as stated).
/// Rolling: free spins plus the rolling-resistance moment above (mu_r = rolling_friction).
/// Blocked: spins held at zero and contact moments ignored, the "rotation prohibited" spheres
/// of Arroyo et al. (2011, Geotechnique 61(6)); sliding friction still acts on the translations.
/// Not in Table 1 (CHOICE).
enum class Rotation { Free, Rolling, Blocked };

inline constexpr std::array<Named<Rotation>, 3> kRotationNames = {
    {{Rotation::Free, "free"}, {Rotation::Rolling, "rolling"}, {Rotation::Blocked, "blocked"}}};

inline const char* to_string(Rotation r) {
  return name_of(kRotationNames, r);
}

/// The keys of [contact] on the grains' rotation and the rolling resistance.
struct RotationConfig {
  double rolling_friction = 0.0;  // mu_r of grain-grain rolling resistance (CHOICE; 0 = off)
  // "free" | "rolling" (needs mu_r > 0) | "blocked": crushdem's parameter set (the default,
  // io/parameter_sets.hpp); Table 1 as printed is "free".
  Rotation rotation = Rotation::Blocked;
  static const ParamTable<RotationConfig>& config_params() {
    using C = RotationConfig;
    static const ParamTable<C> table = {
        {"rolling_friction", &C::rolling_friction, "-",
         "mu_r of grain-grain rolling resistance (docs/model.md 1.5; PFC `rrlinear`): a moment "
         "spring k_r = k_t R*^2 on the relative bending rotation, capped at mu_r R* F_n "
         "(`contact/rolling.hpp`). Not in Table 1 (CHOICE); 0 = off; > 0 needs `rotation = "
         "\"rolling\"` (implied when `rotation` is not given). Grain-grain contacts only",
         [](double v) { return v >= 0.0; },
         "a rolling friction coefficient >= 0 (0 = no rolling resistance)"},
        {"rotation", enum_choice(&C::rotation, kRotationNames), "",
         "how grains turn (not in Table 1, CHOICE): `\"free\"` spins from the contact moments; "
         "`\"rolling\"` free spins plus the rolling resistance of `rolling_friction` (> 0); "
         "`\"blocked\"` spins held at zero and contact moments ignored (the rotation-prohibited "
         "spheres of Arroyo et al. 2011), sliding friction still acting. Grains and fragments "
         "alike. Without the key, `rolling_friction` > 0 means `\"rolling\"`. The default, "
         "`\"blocked\"`, is crushdem's parameter set (docs/model.md 1.5); `parameters = "
         "\"table1\"` gives `\"free\"`"},
    };
    return table;
  }
  static void check(const RotationConfig& c) {
    if (c.rotation == Rotation::Rolling && !(c.rolling_friction > 0.0)) {
      throw ConfigError(bad_value("contact.rolling_friction", show_number(c.rolling_friction),
                                  "mu_r > 0 with contact.rotation = \"rolling\""));
    }
    if (c.rotation != Rotation::Rolling && c.rolling_friction != 0.0) {
      throw ConfigError(bad_value("contact.rolling_friction", show_number(c.rolling_friction),
                                  std::string("0 with contact.rotation = \"") +
                                      to_string(c.rotation) +
                                      "\" (rolling resistance needs rotation = \"rolling\")"));
    }
  }
  /// Multiplies every spin update: 1, or 0 with rotation blocked (0 * w + 0 * T keeps w = 0;
  /// x * 1 is exact, so free rotation keeps its bits).
  double spin_scale() const { return rotation == Rotation::Blocked ? 0.0 : 1.0; }
};

// The couple sub-models (contact/contact_model.hpp): what acts on a pair's relative rotation
// besides the tangential force, with the history vectors each keeps per pair entry.

/// No couple: the pair's moments are those of its tangential force only.
struct NoRolling {
  static constexpr bool kActive = false;
  static constexpr int kHistory = 0;
  struct Params {};
  static bool selected(const RotationConfig& c) { return c.rotation != Rotation::Rolling; }
  static Params derive(const RotationConfig&) { return {}; }
};

/// Rolling resistance: the moment spring above on the owner, the partner receiving its negative.
struct RollingResistance {
  static constexpr bool kActive = true;
  static constexpr int kHistory = 1;
  static constexpr HistoryField kHistoryFields[kHistory] = {
      {"mr", "rolling-resistance moment on the owner [N m]"}};
  struct Params {  // plain values
    double mu_r = 0.0;
  };
  static bool selected(const RotationConfig& c) { return c.rotation == Rotation::Rolling; }
  static Params derive(const RotationConfig& c) { return {c.rolling_friction}; }
  /// The new moment on grain i of a pair contact with normal n, tangent normal stiffness k_n and
  /// elastic F_n, from the stored one; j receives the opposite moment. Plain values, not the
  /// pair's result struct: a struct passed by reference inside an `omp simd` loop becomes a
  /// per-lane array in memory, and the loop no longer vectorises.
  CD_HD static Vec3 moment(const Params& p, Vec3 n, double k_n, double F_n, Vec3 M_r_old, Vec3 w_i,
                           Vec3 w_j, double R_star, double tangential_ratio, double dt) {
    return rolling_moment(M_r_old, n, w_i - w_j, dt, tangential_ratio * k_n, R_star, p.mu_r, F_n);
  }
};

}  // namespace crushdem

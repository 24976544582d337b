// Smooth Hertz normal contact (docs/model.md 1.1).
//
//   F_n = (4/3) E* sqrt(R*) delta^(3/2),   k_n = dF_n/d delta = 2 E* sqrt(R* delta)
//
// with R* = R1 R2 / (R1 + R2) (R* = R against a plane) and E* = G / (1 - nu) for two grains of
// the same material. Hertz, H. (1882), J. reine angew. Math. 92; Johnson, Contact Mechanics (1985).
#pragma once

#include <cmath>

#include "crushdem/contact/material.hpp"
#include "crushdem/core/params.hpp"
#include "crushdem/core/types.hpp"

namespace crushdem {

/// Normal force and tangent stiffness of a contact.
struct NormalForce {
  double F_n = 0.0;       // [N], >= 0
  double k_n = 0.0;       // [N/m], dF_n/d delta
  double k_secant = 0.0;  // [N/m], F_n / delta (viscous damping); a law that knows it in closed
                          // form saves the division
};

/// Effective radius R* = R1 R2 / (R1 + R2) of a grain pair, and the effective mass
/// m* = 1 / (1/m1 + 1/m2) from the inverse masses. One expression for every caller (pair loops,
/// GPU upload, records), so that all of them get the same bits.
CD_HD inline double pair_R_star(double r_1, double r_2) {
  return r_1 * r_2 / (r_1 + r_2);
}
CD_HD inline double pair_m_eff(double inv_mass_1, double inv_mass_2) {
  return 1.0 / (inv_mass_1 + inv_mass_2);
}

CD_HD inline NormalForce hertz_normal(double delta, double R_star, double E_star) {
  if (delta <= 0.0) return {};
  const double k_n = 2.0 * E_star * std::sqrt(R_star * delta);
  return {k_n * delta * (2.0 / 3.0), k_n, k_n * (2.0 / 3.0)};
}

/// Normal-law evaluator for smooth Hertz (template argument of the contact kernels).
struct HertzLaw {
  double E_star = 0.0;
  CD_HD NormalForce operator()(double delta, double R_star, double /*sqrt_R_star*/) const {
    return hertz_normal(delta, R_star, E_star);
  }
};

/// The normal sub-model `contact.law = "hertz"` (the interface every normal sub-model has:
/// contact/contact_model.hpp): no keys beyond [material], no tables.
struct HertzNormal {
  static constexpr const char* kName = "hertz";
  static constexpr const char* kDoc = "smooth Hertz";
  struct Config {};
  static const ParamTable<Config>& config_params() {
    static const ParamTable<Config> none;
    return none;
  }
  static void check(const Config&) {}
  struct Params {  // plain values, the same on the host and the device
    double E_star = 0.0;
  };
  static Params derive(const MaterialConfig& m, const Config&) { return {m.E_star()}; }
  static constexpr int kTables = 0;
  using Law = HertzLaw;
  static Law pair_law(const Params& p, const double* const*) { return {p.E_star}; }
  static Law wall_law(const Params& p, const double* const*) { return {p.E_star}; }
};

}  // namespace crushdem

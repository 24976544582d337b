// Rough-surface Hertz normal contact (model-notes 1.2).
//
// Otsubo, M., O'Sullivan, C., Hanley, K.J., Sim, W.W. (2017), "The influence of particle surface
// roughness on elastic stiffness and dynamic response", Geotechnique 67(5), restated from the
// authors' public implementation (geoLAMMPS pair gran/CM/history). With the combined roughness s
// (sqrt(2) S_q between two grains, S_q against a smooth wall):
//
//   d_p1 = 0.82 s, d_p2 = 1.24 s, d_ps = d_p1 + d_p2
//   N_T1 = k1 X, N_T2 = k2 X,  X = s E* sqrt(2 R* s)
//   d_T2 = (3 N_T2 / (4 E* sqrt(R*)))^(2/3) + d_ps
//   b    = 2 E* sqrt(R* (d_T2 - d_ps)) (d_T2 - d_p1) / N_T2
//   d_T1 = (d_T2 - d_p1) (N_T1/N_T2)^(1/b) + d_p1
//   c    = b (N_T2/N_T1) d_T1 (d_T2 - d_p1)^(-b) (d_T1 - d_p1)^(b-1)
//   N(d) = N_T1 (d/d_T1)^c                          d <= d_T1
//        = N_T2 ((d - d_p1)/(d_T2 - d_p1))^b        d_T1 < d <= d_T2
//        = (4/3) E* sqrt(R*) (d - d_ps)^(3/2)       d > d_T2
//
// Lengths scale with s and b, c are pure numbers: none depends on R* or E*, so they are computed
// once per roughness (grain-grain and grain-wall) and the kernel only evaluates the branch.
#pragma once

#include <cmath>

#include "crushdem/contact/hertz.hpp"
#include "crushdem/contact/power_table.hpp"
#include "crushdem/core/types.hpp"

namespace crushdem {

/// Constants of the rough law for one combined roughness s (lengths in metres).
struct RoughHertzParams {
  double s = 0.0;  // combined rms roughness [m]; 0 means smooth Hertz
  double k1 = 0.05, k2 = 5.0;
  double d_p1 = 0.0, d_ps = 0.0, d_T1 = 0.0, d_T2 = 0.0;
  double b = 0.0, c = 0.0;
  double x_factor = 0.0;    // X / (E* sqrt(R*)) = s sqrt(2 s)
  double inv_span = 0.0;    // 1 / (d_T2 - d_p1)
  double inv_d_T1 = 0.0;    // 1 / d_T1
  PowerTable pow_b, pow_c;  // x^b and x^c on [0, 1]
};

/// Derives every constant of the law from s, k1 and k2 (exact transcription of the list above).
inline RoughHertzParams make_rough_hertz(double s, double k1, double k2) {
  RoughHertzParams p;
  p.s = s;
  p.k1 = k1;
  p.k2 = k2;
  if (s <= 0.0) return p;
  p.d_p1 = 0.82 * s;
  p.d_ps = (0.82 + 1.24) * s;
  // Evaluated with E* = 1, R* = 1: the constants do not depend on them.
  const double X = s * std::sqrt(2.0 * s);
  const double N_T1 = k1 * X;
  const double N_T2 = k2 * X;
  p.d_T2 = std::pow(3.0 * N_T2 / 4.0, 2.0 / 3.0) + p.d_ps;
  p.b = 2.0 * std::sqrt(p.d_T2 - p.d_ps) * (p.d_T2 - p.d_p1) / N_T2;
  p.d_T1 = (p.d_T2 - p.d_p1) * std::pow(N_T1 / N_T2, 1.0 / p.b) + p.d_p1;
  p.c = p.b * (N_T2 / N_T1) * p.d_T1 * std::pow(p.d_T2 - p.d_p1, -p.b) *
        std::pow(p.d_T1 - p.d_p1, p.b - 1.0);
  p.x_factor = X;
  p.inv_span = 1.0 / (p.d_T2 - p.d_p1);
  p.inv_d_T1 = 1.0 / p.d_T1;
  p.pow_b = power_table(p.b);
  p.pow_c = power_table(p.c);
  return p;
}

/// sqrt_R_star = sqrt(R*), passed in because callers keep it per contact (saves a square root).
CD_HD inline NormalForce rough_hertz_normal(double delta, double R_star, double sqrt_R_star,
                                            double E_star, const RoughHertzParams& p) {
  if (delta <= 0.0) return {};
  if (p.s <= 0.0 || delta > p.d_T2) {
    // Hertz branch, shifted by d_ps (d_ps = 0 when smooth).
    const double d = delta - p.d_ps;
    const double k_n = 2.0 * E_star * std::sqrt(R_star * d);
    const double F = k_n * d * (2.0 / 3.0);
    return {F, k_n, p.s <= 0.0 ? k_n * (2.0 / 3.0) : F / delta};
  }
  const double X = E_star * sqrt_R_star * p.x_factor;
  if (delta > p.d_T1) {
    const double u = delta - p.d_p1;
    const double F = p.k2 * X * p.pow_b(u * p.inv_span);
    return {F, p.b * F / u, F / delta};
  }
  const double F = p.k1 * X * p.pow_c(delta * p.inv_d_T1);
  // c F / delta, not c (F / delta): the same rounding as before k_secant existed, so runs
  // without viscous damping are bit-for-bit unchanged.
  return {F, p.c * F / delta, F / delta};
}

CD_HD inline NormalForce rough_hertz_normal(double delta, double R_star, double E_star,
                                            const RoughHertzParams& p) {
  return rough_hertz_normal(delta, R_star, std::sqrt(R_star), E_star, p);
}

/// Normal-law evaluator for the rough law; `rough` is chosen by the caller (grain-grain or wall).
struct RoughHertzLaw {
  double E_star = 0.0;
  RoughHertzParams rough;
  CD_HD NormalForce operator()(double delta, double R_star, double sqrt_R_star) const {
    return rough_hertz_normal(delta, R_star, sqrt_R_star, E_star, rough);
  }
};

}  // namespace crushdem

// Rough-surface Hertz normal contact (docs/model.md 1.2).
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
  PowerTable pow_b, pow_c;  // x^b and x^c on [0, 1], one block (power_table_pair())
};

/// Derives every constant of the law from s, k1 and k2 (exact transcription of the list above).
inline RoughHertzParams make_rough_hertz(double s, double k1, double k2) {
  RoughHertzParams p;
  p.s = s;
  p.k1 = k1;
  p.k2 = k2;
  if (s <= 0.0) {
    // Smooth: the law is Hertz, but the branch-free kernel still reads a table entry.
    const std::array<PowerTable, 2> tables = power_table_pair(1.0, 1.0);
    p.pow_b = tables[0];
    p.pow_c = tables[1];
    return p;
  }
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
  const std::array<PowerTable, 2> tables = power_table_pair(p.b, p.c);
  p.pow_b = tables[0];
  p.pow_c = tables[1];
  return p;
}

/// sqrt_R_star = sqrt(R*), passed in because callers keep it per contact (saves a square root).
/// kHertzRegime = false: for a caller that knows that no contact it evaluates is in the Hertz
/// regime (s > 0 and delta <= d_T2 in every lane; rough_may_reach_hertz() tells): that regime,
/// a square root per lane, is then not computed. Each result has the same bits as with it.
template <bool kHertzRegime = true>
CD_HD_INLINE NormalForce rough_hertz_normal(double delta, double R_star, double sqrt_R_star,
                                            double E_star, const RoughHertzParams& p) {
  // Every regime is evaluated and one selected, without branches, so that the CPU pair loop can
  // run the law in vector lanes (lanes in other regimes compute values that are thrown away,
  // NaN included). Each selected value is the same expression as in a branching form.
  const bool smooth = kHertzRegime && p.s <= 0.0;
  // | and not ||: both comparisons are made in every lane (a comparison that runs only on some
  // path "could trap" on NaN, which stops the compiler from flattening the branches).
  const bool hertz = kHertzRegime && (smooth | (delta > p.d_T2));
  // Hertz branch, shifted by d_ps (d_ps = 0 when smooth).
  double k_hertz = 0.0, F_hertz = 0.0;
  if constexpr (kHertzRegime) {
    const double d = delta - p.d_ps;
    k_hertz = 2.0 * E_star * std::sqrt(R_star * d);
    F_hertz = k_hertz * d * (2.0 / 3.0);
  }
  // Rough branches: N_T2 ((d - d_p1)/(d_T2 - d_p1))^b above d_T1, N_T1 (d/d_T1)^c below.
  const bool upper = delta > p.d_T1;
  const double X = E_star * sqrt_R_star * p.x_factor;
  const double u = delta - p.d_p1;
  // pow_c's nodes follow pow_b's on the same grid (power_table_pair()): one base address, and
  // an offset chosen per lane.
  const int c_first = 2 * (p.pow_b.n + 1);
  const double F_rough =
      (upper ? p.k2 : p.k1) * X *
      power_table_lookup(p.pow_b.nodes, upper ? 0 : c_first, p.pow_b.n, p.pow_b.inv_h,
                         upper ? u * p.inv_span : delta * p.inv_d_T1);
  // b F / u above d_T1; c F / delta below (c F / delta, not c (F / delta): the same rounding as
  // before k_secant existed, so runs without viscous damping are bit-for-bit unchanged).
  const double k_rough = (upper ? p.b : p.c) * F_rough / (upper ? u : delta);
  const double F = hertz ? F_hertz : F_rough;
  const double k_n = hertz ? k_hertz : k_rough;
  // One division in every lane: the numerator is selected first (the same bits as dividing
  // both and selecting). smooth implies hertz.
  const double k_secant = smooth ? k_hertz * (2.0 / 3.0) : (hertz ? F_hertz : F_rough) / delta;
  const bool touching = delta > 0.0;
  return {touching ? F : 0.0, touching ? k_n : 0.0, touching ? k_secant : 0.0};
}

CD_HD inline NormalForce rough_hertz_normal(double delta, double R_star, double E_star,
                                            const RoughHertzParams& p) {
  return rough_hertz_normal(delta, R_star, std::sqrt(R_star), E_star, p);
}

/// Whether a pair whose centres are sqrt(d2) apart, with radii summing to rsum (r_i + r_j, as
/// the kernels add them), can be in the Hertz regime, delta = rsum - sqrt(d2) > d_T2, without a
/// square root. Conservative: true for every such pair and for pairs within 1e-12 rsum of the
/// transition (a margin far above the roundings of delta, sqrt(d2) and this test); false
/// where the regime cannot be reached (reach <= 0: it would need a negative distance).
CD_HD inline bool rough_may_reach_hertz(double d2, double rsum, const RoughHertzParams& p) {
  const double reach = rsum - p.d_T2 + 1e-12 * rsum;
  return (p.s <= 0.0) | ((reach > 0.0) & (d2 < reach * reach));
}

/// Normal-law evaluator for the rough law; `rough` is chosen by the caller (grain-grain or wall).
/// kHertzRegime: see rough_hertz_normal(); without_hertz_regime() gives the evaluator for a set
/// of contacts of which rough_may_reach_hertz() is false for every one.
template <bool kHertzRegime = true>
struct RoughHertzLawT {
  double E_star = 0.0;
  RoughHertzParams rough;
  CD_HD NormalForce operator()(double delta, double R_star, double sqrt_R_star) const {
    return rough_hertz_normal<kHertzRegime>(delta, R_star, sqrt_R_star, E_star, rough);
  }
  CD_HD RoughHertzLawT<false> without_hertz_regime() const { return {E_star, rough}; }
};
using RoughHertzLaw = RoughHertzLawT<true>;

}  // namespace crushdem

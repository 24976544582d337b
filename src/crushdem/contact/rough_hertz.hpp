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
#include "crushdem/contact/material.hpp"
#include "crushdem/contact/power_table.hpp"
#include "crushdem/core/error.hpp"
#include "crushdem/core/params.hpp"
#include "crushdem/core/types.hpp"

namespace crushdem {

/// Constants of the rough law for one combined roughness s (lengths in metres). Plain values:
/// the tables of x^b and x^c the law reads are placed where the kernel runs (rough_table()) and
/// handed to the evaluator (RoughHertzLawT::nodes).
struct RoughHertzParams {
  double s = 0.0;  // combined rms roughness [m]; 0 means smooth Hertz
  double k1 = 0.05, k2 = 5.0;
  double d_p1 = 0.0, d_ps = 0.0, d_T1 = 0.0, d_T2 = 0.0;
  double b = 0.0, c = 0.0;
  double x_factor = 0.0;     // X / (E* sqrt(R*)) = s sqrt(2 s)
  double inv_span = 0.0;     // 1 / (d_T2 - d_p1)
  double inv_d_T1 = 0.0;     // 1 / d_T1
  int table_n = 0;           // intervals of each power table
  double table_inv_h = 0.0;  // 1 / their spacing
};

/// The host block of the law's tables: x^b on [0, 1], then x^c right after it
/// (power_table_pair(); for smooth Hertz, x^1 twice: the branch-free kernel still reads an
/// entry). 4 (table_n + 1) doubles, kept for the process lifetime.
inline std::array<PowerTable, 2> rough_tables(const RoughHertzParams& p) {
  return p.s <= 0.0 ? power_table_pair(1.0, 1.0) : power_table_pair(p.b, p.c);
}
inline TableBlock rough_table(const RoughHertzParams& p) {
  return {rough_tables(p)[0].nodes, 4 * (static_cast<std::size_t>(p.table_n) + 1)};
}

/// Derives every constant of the law from s, k1 and k2 (exact transcription of the list above).
inline RoughHertzParams make_rough_hertz(double s, double k1, double k2) {
  RoughHertzParams p;
  p.s = s;
  p.k1 = k1;
  p.k2 = k2;
  if (s > 0.0) {
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
  }
  const std::array<PowerTable, 2> tables = rough_tables(p);
  p.table_n = tables[0].n;
  p.table_inv_h = tables[0].inv_h;
  return p;
}

/// sqrt_R_star = sqrt(R*), passed in because callers keep it per contact (saves a square root).
/// kHertzRegime = false: for a caller that knows that no contact it evaluates is in the Hertz
/// regime (s > 0 and delta <= d_T2 in every lane; rough_may_reach_hertz() tells): that regime,
/// a square root per lane, is then not computed. Each result has the same bits as with it.
/// nodes: the law's table block (rough_table()) where the caller runs.
template <bool kHertzRegime = true>
CD_HD_INLINE NormalForce rough_hertz_normal(double delta, double R_star, double sqrt_R_star,
                                            double E_star, const RoughHertzParams& p,
                                            const double* nodes) {
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
  const int c_first = 2 * (p.table_n + 1);
  const double F_rough = (upper ? p.k2 : p.k1) * X *
                         power_table_lookup(nodes, upper ? 0 : c_first, p.table_n, p.table_inv_h,
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

/// On the host, with the host tables (tests, reporting).
inline NormalForce rough_hertz_normal(double delta, double R_star, double E_star,
                                      const RoughHertzParams& p) {
  return rough_hertz_normal(delta, R_star, std::sqrt(R_star), E_star, p, rough_table(p).host);
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

/// Normal-law evaluator for the rough law: one roughness (grain-grain or grain-wall) and its
/// tables where the kernel runs. kHertzRegime: see rough_hertz_normal(); without_hertz_regime()
/// gives the evaluator for a set of contacts of which rough_may_reach_hertz() is false for every
/// one (the CPU pair loop's batches, may_skip_regime()).
template <bool kHertzRegime = true>
struct RoughHertzLawT {
  double E_star = 0.0;
  RoughHertzParams rough;
  const double* nodes = nullptr;
  CD_HD NormalForce operator()(double delta, double R_star, double sqrt_R_star) const {
    return rough_hertz_normal<kHertzRegime>(delta, R_star, sqrt_R_star, E_star, rough, nodes);
  }
  CD_HD RoughHertzLawT<false> without_hertz_regime() const { return {E_star, rough, nodes}; }
  /// Whether a contact at squared distance d2 with radii summing to rsum may need the regime
  /// that without_hertz_regime() leaves out.
  CD_HD bool may_need_full(double d2, double rsum) const {
    return rough_may_reach_hertz(d2, rsum, rough);
  }
};
using RoughHertzLaw = RoughHertzLawT<true>;

/// The normal sub-model `contact.law = "rough"` (contact/contact_model.hpp has the interface):
/// s = sqrt(2) S_q between grains, S_q against a smooth wall (Otsubo et al. 2017).
struct RoughNormal {
  static constexpr const char* kName = "rough";
  static constexpr const char* kDoc = "rough-surface Hertz (Otsubo et al. 2017, docs/model.md 1.2)";
  struct Config {
    double roughness_Sq = 0.6e-6;  // S_q [m] (STUDY)
    double k1 = 0.05, k2 = 5.0;    // transition constants (CHOICE: Table 1 n1, n2)
  };
  static const ParamTable<Config>& config_params() {
    using C = Config;
    static const ParamTable<C> table = {
        {"roughness_Sq", &C::roughness_Sq, "m",
         "rms surface roughness S_q (Table 1); s = sqrt(2) S_q between grains, S_q against walls",
         [](double v) { return v >= 0.0; }, "a roughness >= 0 in m"},
        {"k1", &C::k1, "-", "transition-load constant (Table 1 n1; the original code used 1)",
         [](double v) { return v > 0.0; }, "a positive number"},
        {"k2", &C::k2, "-",
         "transition-load constant, > k1 (Table 1 n2; the original code used 100)"},
    };
    return table;
  }
  static void check(const Config& c) {
    if (!(c.k2 > c.k1) || !std::isfinite(c.k2)) {
      throw ConfigError(
          bad_value("contact.k2", show_number(c.k2), "a number larger than contact.k1"));
    }
  }
  struct Params {  // plain values, the same on the host and the device
    double E_star = 0.0;
    RoughHertzParams pp, pw;  // grain-grain and grain-wall
  };
  static Params derive(const MaterialConfig& m, const Config& c) {
    return {m.E_star(), make_rough_hertz(std::sqrt(2.0) * c.roughness_Sq, c.k1, c.k2),
            make_rough_hertz(c.roughness_Sq, c.k1, c.k2)};
  }
  static constexpr int kTables = 2;
  static std::array<TableBlock, kTables> tables(const Params& p) {
    return {rough_table(p.pp), rough_table(p.pw)};
  }
  using Law = RoughHertzLaw;
  static Law pair_law(const Params& p, const double* const* placed) {
    return {p.E_star, p.pp, placed[0]};
  }
  static Law wall_law(const Params& p, const double* const* placed) {
    return {p.E_star, p.pw, placed[1]};
  }
};

}  // namespace crushdem

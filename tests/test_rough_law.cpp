// Rough-surface Hertz law (docs/model.md 1.2) against the constants stated there.
#include <gtest/gtest.h>

#include <cmath>

#include "crushdem/contact/rough_hertz.hpp"

namespace crushdem {
namespace {

TEST(RoughLaw, ZeroRoughnessIsHertzExactly) {
  const RoughHertzParams p = make_rough_hertz(0.0, 0.05, 5.0);
  for (double delta : {1e-9, 3.7e-8, 1e-7, 2.5e-6}) {
    const NormalForce a = rough_hertz_normal(delta, 5e-5, 3.95e10, p);
    const NormalForce b = hertz_normal(delta, 5e-5, 3.95e10);
    EXPECT_EQ(a.F_n, b.F_n);
    EXPECT_EQ(a.k_n, b.k_n);
  }
}

struct Expected {
  double k1, k2, dT1_s, dT2_s, b, c, tol;
};

class RoughConstants : public ::testing::TestWithParam<Expected> {};

TEST_P(RoughConstants, MatchModelNotes) {
  const Expected e = GetParam();
  for (double s : {0.6e-6 * std::sqrt(2.0), 0.6e-6, 3e-7}) {
    const RoughHertzParams p = make_rough_hertz(s, e.k1, e.k2);
    EXPECT_NEAR(p.d_T1 / s, e.dT1_s, e.tol * e.dT1_s);
    EXPECT_NEAR(p.d_T2 / s, e.dT2_s, e.tol * e.dT2_s);
    EXPECT_NEAR(p.b, e.b, e.tol * e.b);
    EXPECT_NEAR(p.c, e.c, e.tol * e.c);
  }
}

// The notes give 3-4 significant digits; the tolerance is half a unit of the last one.
INSTANTIATE_TEST_SUITE_P(BothPairs, RoughConstants,
                         ::testing::Values(Expected{1, 100, 2.109, 24.47, 1.583, 2.590, 5e-4},
                                           Expected{0.05, 5, 1.30, 5.10, 2.112, 5.693, 4e-3}));

TEST(RoughLaw, ForceAndStiffnessContinuousAtTransitions) {
  for (auto [k1, k2] : {std::pair{0.05, 5.0}, std::pair{1.0, 100.0}}) {
    const double s = 0.6e-6 * std::sqrt(2.0);
    const RoughHertzParams p = make_rough_hertz(s, k1, k2);
    for (double R_star : {5e-6, 5e-5, 1e-4}) {
      for (double d : {p.d_T1, p.d_T2}) {
        const double eps = d * 1e-12;
        const NormalForce lo = rough_hertz_normal(d - eps, R_star, 3.95e10, p);
        const NormalForce hi = rough_hertz_normal(d + eps, R_star, 3.95e10, p);
        EXPECT_NEAR(lo.F_n / hi.F_n, 1.0, 1e-9) << "force jump at " << d / s << " s";
        EXPECT_NEAR(lo.k_n / hi.k_n, 1.0, 1e-9) << "stiffness jump at " << d / s << " s";
      }
      // Transition loads: N(d_T1) = k1 X, N(d_T2) = k2 X, X = s E* sqrt(2 R* s).
      const double X = s * 3.95e10 * std::sqrt(2.0 * R_star * s);
      EXPECT_NEAR(rough_hertz_normal(p.d_T1, R_star, 3.95e10, p).F_n / (k1 * X), 1.0, 1e-12);
      EXPECT_NEAR(rough_hertz_normal(p.d_T2, R_star, 3.95e10, p).F_n / (k2 * X), 1.0, 1e-12);
    }
  }
}

TEST(RoughLaw, StiffnessIsTheDerivativeOfForce) {
  const RoughHertzParams p = make_rough_hertz(0.85e-6, 0.05, 5.0);
  for (double d : {0.5e-6, 2e-6, 4e-6, 8e-6}) {
    const double h = d * 1e-6;
    const double dF = (rough_hertz_normal(d + h, 5e-5, 3.95e10, p).F_n -
                       rough_hertz_normal(d - h, 5e-5, 3.95e10, p).F_n) /
                      (2 * h);
    EXPECT_NEAR(rough_hertz_normal(d, 5e-5, 3.95e10, p).k_n / dF, 1.0, 1e-6);
  }
}

TEST(RoughLaw, SofterThanHertzAtSmallOverlap) {
  // Asperities make the contact softer at first: at the same overlap, less force than Hertz.
  const RoughHertzParams p = make_rough_hertz(0.85e-6, 0.05, 5.0);
  const double d = 2e-6;
  EXPECT_LT(rough_hertz_normal(d, 5e-5, 3.95e10, p).F_n, hertz_normal(d, 5e-5, 3.95e10).F_n);
}

namespace crushdem {
namespace {

// The tabulated powers against std::pow over the ranges the law uses.
TEST(RoughLaw, TabulatedPowersMatchPow) {
  for (auto [k1, k2] : {std::pair{0.05, 5.0}, std::pair{1.0, 100.0}}) {
    const RoughHertzParams p = make_rough_hertz(1e-6, k1, k2);
    const auto [pow_b, pow_c] = rough_tables(p);
    const double u1 = (p.d_T1 - p.d_p1) * p.inv_span;
    double worst_b = 0.0, worst_c = 0.0, worst_c_abs = 0.0;
    for (int k = 0; k <= 100000; ++k) {
      // middle regime: relative error over the whole range
      const double u = u1 + (1.0 - u1) * k / 100000.0;
      worst_b = std::max(worst_b, std::abs(pow_b(u) / std::pow(u, p.b) - 1.0));
      // lowest regime: relative where the force is above 1e-3 N_T1, absolute (in units of
      // N_T1) everywhere
      const double v = k / 100000.0;
      const double exact = std::pow(v, p.c);
      if (exact > 1e-3) worst_c = std::max(worst_c, std::abs(pow_c(v) / exact - 1.0));
      worst_c_abs = std::max(worst_c_abs, std::abs(pow_c(v) - exact));
    }
    EXPECT_LT(worst_b, 1e-11) << "b = " << p.b;
    EXPECT_LT(worst_c, 1e-11) << "c = " << p.c;
    EXPECT_LT(worst_c_abs, 3e-9) << "c = " << p.c;
    EXPECT_EQ(pow_b(1.0), 1.0);
    EXPECT_EQ(pow_c(0.0), 0.0);
    // Never negative (a negative force would flip the Coulomb cap), and monotone near zero.
    double prev = 0.0;
    for (int k = 0; k <= 20000; ++k) {
      const double v = k * 1e-6;
      ASSERT_GE(pow_c(v), prev) << "v = " << v;
      prev = pow_c(v);
    }
  }
}

}  // namespace
}  // namespace crushdem

// The secant stiffness the laws return for viscous damping is F_n / delta, in every regime.
TEST(RoughLaw, SecantStiffnessIsForceOverOverlap) {
  const RoughHertzParams p = make_rough_hertz(0.6e-6 * std::sqrt(2.0), 0.05, 5.0);
  const RoughHertzParams smooth = make_rough_hertz(0.0, 0.05, 5.0);
  for (double delta : {0.3 * p.d_T1, 0.5 * (p.d_T1 + p.d_T2), 3.0 * p.d_T2}) {
    for (const RoughHertzParams* q : {&p, &smooth}) {
      const NormalForce f = rough_hertz_normal(delta, 5e-5, 3.95e10, *q);
      EXPECT_NEAR(f.k_secant * delta / f.F_n, 1.0, 1e-14) << delta;
    }
    const NormalForce h = hertz_normal(delta, 5e-5, 3.95e10);
    EXPECT_NEAR(h.k_secant * delta / h.F_n, 1.0, 1e-14) << delta;
  }
  EXPECT_EQ(hertz_normal(-1e-9, 5e-5, 3.95e10).k_secant, 0.0);
}

}  // namespace
}  // namespace crushdem

// The grading measures against hand computations: mass passing with removed fines
// (passing_with_fines) and Einav's relative breakage B_r (particles/grading.hpp).
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "crushdem/core/types.hpp"
#include "crushdem/particles/grading.hpp"

namespace {

using crushdem::kPi;

double sphere_volume(double d) {
  return kPi / 6.0 * d * d * d;
}

// Two 1 mm grains at first; one of them breaks into 1,000 grains of 0.1 mm (the same solid
// volume), and fines of one more grain's volume are counted as removed.
TEST(Grading, PassingCountsRemovedFinesBelowEverySieve) {
  std::vector<double> current(1000, 0.1e-3);
  current.push_back(1e-3);
  const double fines = sphere_volume(1e-3);
  const std::vector<double> F =
      crushdem::passing_with_fines(current, fines, {0.05e-3, 0.1e-3, 0.5e-3, 1e-3});
  // Solids: 1 unit in the large grain, 1 in the small ones, 1 removed (finer than any sieve).
  ASSERT_EQ(F.size(), 4u);
  EXPECT_NEAR(F[0], 1.0 / 3.0, 1e-12);
  EXPECT_NEAR(F[1], 2.0 / 3.0, 1e-12);  // a grain passes a sieve of its own size
  EXPECT_NEAR(F[2], 2.0 / 3.0, 1e-12);
  EXPECT_NEAR(F[3], 1.0, 1e-12);
}

// B_r = B_t / B_p on x = ln d from d_min = 0.01 mm to d_max = 1 mm (L = ln 100):
//   initial: two 1 mm grains, F_0 = 0 below d_max;
//   ultimate F_u = (d / d_max)^(3 - D), D = 2.6: B_p = (1 - exp(-0.4 L)) / 0.4;
//   current: half the solids at 0.1 mm, F = 0.5 from 0.1 mm to d_max: B_t = 0.5 ln 10.
TEST(Grading, RelativeBreakageMatchesTheHandComputation) {
  const std::vector<double> initial = {1e-3, 1e-3};
  std::vector<double> current(1000, 0.1e-3);
  current.push_back(1e-3);
  const double L = std::log(100.0);
  const double Bp = (1.0 - std::exp(-0.4 * L)) / 0.4;
  const double Bt = 0.5 * std::log(10.0);
  const double Br = crushdem::relative_breakage(initial, current, 0.0, 0.01e-3, 1e-3);
  // The trapezoids over 400 log-spaced sieves blur each step of F by one interval
  // (ln(100) / 399 = 1.2 % of a decade).
  EXPECT_NEAR(Br, Bt / Bp, 0.005 * Bt / Bp) << "hand: " << Bt / Bp;
  EXPECT_NEAR(Bt / Bp, 0.5473, 1e-4);
  // Nothing broken: zero; everything removed as fines: B_t = L, above the ultimate grading.
  EXPECT_NEAR(crushdem::relative_breakage(initial, initial, 0.0, 0.01e-3, 1e-3), 0.0, 1e-12);
  EXPECT_NEAR(crushdem::relative_breakage(initial, {}, 2.0 * sphere_volume(1e-3), 0.01e-3, 1e-3),
              L / Bp, 0.005 * L / Bp);
}

}  // namespace

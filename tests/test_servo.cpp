// Servo-controlled walls compress a simple-cubic lattice: the wall stress reaches the target and
// the strain is the one Hertz theory gives for the lattice (docs/model.md 4.2).
#include <gtest/gtest.h>

#include <cmath>

#include "crushdem/contact/rough_hertz.hpp"
#include "crushdem/integrate/local_damping.hpp"
#include "helpers.hpp"

namespace crushdem {
namespace {

// PFC local damping, branch-free: equal bit for bit to the branching form it replaced, for
// both signs of force and velocity, a component at rest, signed zeros and a NaN velocity.
TEST(LocalDamping, EqualsTheBranchingFormBitForBit) {
  auto branching = [](double f, double v, double alpha) {
    return v > 0.0 ? f - alpha * std::abs(f) : (v < 0.0 ? f + alpha * std::abs(f) : f);
  };
  const double forces[] = {1.2345e-3, -7.5e-9, 0.0, -0.0, 3.0e4, -1.0 / 3.0};
  const double speeds[] = {2.5e-3, -1e-12, 0.0, -0.0, std::nan("")};
  const double alphas[] = {0.7, 0.1, 0.0, 1.0};
  for (double f : forces) {
    for (double v : speeds) {
      for (double a : alphas) {
        const double want = branching(f, v, a), got = local_damping(f, v, a);
        EXPECT_EQ(std::signbit(got), std::signbit(want)) << f << " " << v << " " << a;
        EXPECT_EQ(got, want) << f << " " << v << " " << a;
      }
    }
  }
  // It opposes the motion: the damped force points less along v than F does.
  EXPECT_DOUBLE_EQ(local_damping(1.0, 1.0, 0.7), 0.3);
  EXPECT_DOUBLE_EQ(local_damping(-1.0, 1.0, 0.7), -1.7);
  EXPECT_DOUBLE_EQ(local_damping(1.0, -1.0, 0.7), 1.7);
  EXPECT_DOUBLE_EQ(local_damping(1.0, 0.0, 0.7), 1.0);
}

// Overlap at which the normal law carries force F (bisection on the monotone law).
double overlap_for(double F, double R_star, const Simulation& sim, bool wall) {
  auto force = [&](double d) { return sim.normal_force(d, R_star, wall).F_n; };
  double lo = 0.0, hi = 1e-5;
  for (int k = 0; k < 200; ++k) {
    const double mid = 0.5 * (lo + hi);
    (force(mid) < F ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

class ServoLattice : public ::testing::TestWithParam<NormalLaw> {};

TEST_P(ServoLattice, SimpleCubicLatticeReachesTargetAndTheLawsStrain) {
  const int n = 4;
  const double R = 1e-4, L0 = 2 * n * R, sigma = 2e6;
  SimulationConfig cfg = testing::box_config(0.0, L0, GetParam());
  cfg.damping.local_alpha = 0.7;
  for (auto& w : cfg.walls) {
    w.mode = WallMode::Servo;
    w.target_stress = sigma;
    w.max_speed = 0.01;
  }
  Simulation sim(cfg);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      for (int k = 0; k < n; ++k) {
        sim.add_particle({R * (2 * i + 1), R * (2 * j + 1), R * (2 * k + 1)}, R);
      }
    }
  }
  sim.step(40000);
  // Each column of n grains carries F = sigma (2R)^2; grain-grain R* = R/2, wall R* = R.
  const double F = sigma * 4 * R * R;
  const double d_pp = overlap_for(F, R / 2, sim, false);
  const double d_pw = overlap_for(F, R, sim, true);
  if (GetParam() == NormalLaw::Hertz) {  // closed form as a check of the bisection
    const double E = cfg.material.E_star();
    EXPECT_NEAR(d_pp / std::pow(3 * F / (4 * E * std::sqrt(R / 2)), 2.0 / 3.0), 1.0, 1e-9);
  }
  const double strain = ((n - 1) * d_pp + 2 * d_pw) / L0;
  for (int k = 0; k < kNumWalls; ++k) {
    EXPECT_NEAR(sim.walls().stress(k) / sigma, 1.0, 0.005) << wall_name(k);
  }
  for (int a = 0; a < 3; ++a) {
    const double eps = 1.0 - sim.walls().length(a) / L0;
    EXPECT_NEAR(eps / strain, 1.0, 0.01) << "axis " << a;
  }
  // Love-Weber stress agrees with the wall stress.
  const auto s = sim.love_weber_stress();
  EXPECT_NEAR(s[8] / sim.walls().stress(5), 1.0, 0.005);
  EXPECT_NEAR(s[1] / sigma, 0.0, 1e-6);
}

INSTANTIATE_TEST_SUITE_P(Laws, ServoLattice, ::testing::Values(NormalLaw::Hertz, NormalLaw::Rough));

// A wall moving towards a grain that starts beyond the skin: the wall-travel part of the rebuild
// criterion must bring the grain into the wall's contact list before they overlap.
TEST(Servo, MovingWallFindsAGrainBeyondTheSkin) {
  SimulationConfig cfg = testing::box_config(0.0, 1e-3);
  cfg.timestep.dt = 1e-8;
  cfg.neighbor.skin = 1e-5;
  cfg.walls[5].mode = WallMode::Velocity;
  cfg.walls[5].velocity = -0.5;
  Simulation sim(cfg);
  const double R = 1e-4;
  sim.add_particle({5e-4, 5e-4, 1e-3 - R - 2.5e-5}, R);  // 2.5 skins below the wall
  sim.step(6000);  // the wall travels 30 um: it meets the grain after 25 um
  // Elastic rebound off a wall moving at -0.5 m/s: the grain leaves at twice the wall speed.
  EXPECT_NEAR(sim.particles().vz[0], -1.0, 0.01) << "the wall never pushed the grain";
}

}  // namespace
}  // namespace crushdem

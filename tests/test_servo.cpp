// Servo-controlled walls compress a simple-cubic lattice: the wall stress reaches the target and
// the strain is the one Hertz theory gives for the lattice (model-notes 4.2).
#include <gtest/gtest.h>

#include <cmath>

#include "helpers.hpp"

namespace crushdem {
namespace {

TEST(Servo, SimpleCubicLatticeReachesTargetAndHertzStrain) {
  const int n = 4;
  const double R = 1e-4, L0 = 2 * n * R, sigma = 2e6;
  SimulationConfig cfg = testing::box_config(0.0, L0);
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
  // Hertz: each column of n grains carries F = sigma (2R)^2; grain-grain R* = R/2, wall R* = R.
  const double E = cfg.material.E_star(), F = sigma * 4 * R * R;
  const double d_pp = std::pow(3 * F / (4 * E * std::sqrt(R / 2)), 2.0 / 3.0);
  const double d_pw = std::pow(3 * F / (4 * E * std::sqrt(R)), 2.0 / 3.0);
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

}  // namespace
}  // namespace crushdem

// Grain crushing (docs/model.md 2): the 14-fragment pattern, the breaking force of one
// grain against walls and of two grains, the size effect and spread of strength, conservation
// in a split, the comminution limit.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <numeric>
#include <utility>

#include "crushdem/core/error.hpp"
#include "crushdem/fracture/crushing.hpp"
#include "helpers.hpp"

using namespace crushdem;

namespace {

// Table 1 material, smooth Hertz (the closed-form figures of docs/model.md 2.1 are for Hertz).
SimulationConfig squeeze_config(double half_width, double gap_top) {
  SimulationConfig c = crushdem::testing::box_config(-half_width, half_width, NormalLaw::Hertz);
  c.damping.local_alpha = 0.7;
  c.walls[4].position = 0.0;
  c.walls[5].position = gap_top;
  return c;
}

CrushingConfig exact_strength(double d0) {
  CrushingConfig k;
  k.enabled = true;
  k.var = 0.0;  // f = 1
  k.d0 = d0;
  return k;
}

/// Moves the top wall down at `speed` until something breaks; returns the events.
std::vector<BreakageEvent> squeeze_until_break(Simulation& sim, Crusher& crusher, double speed,
                                               std::uint64_t max_steps = 400000) {
  sim.walls().config(5).mode = WallMode::Velocity;
  sim.walls().config(5).velocity = -speed;
  sim.walls().update_velocities(0.0);
  for (std::uint64_t s = 0; s < max_steps; ++s) {
    sim.step();
    auto ev = crusher.apply(sim);
    if (!ev.empty()) return ev;
  }
  return {};
}

double hertz_break_force(double sigma, double R_star, double E_star) {
  // sigma = F / (pi R* delta) with F = 4/3 E* sqrt(R*) delta^1.5  =>  F = 9 pi^3 s^3 R*^2 / (16
  // E*^2)
  return 9.0 * std::pow(kPi, 3) * std::pow(sigma, 3) * R_star * R_star / (16.0 * E_star * E_star);
}

}  // namespace

TEST(Pattern, Default14FragmentsInsideTouchingCentredHalfVolume) {
  const SplitPattern p = SplitPattern::default14();
  ASSERT_EQ(p.size(), 14u);
  EXPECT_NO_THROW(p.validate("default", 1e-12));
  Vec3 centroid{};
  double vol = 0.0;
  int touching = 0;
  for (std::size_t a = 0; a < p.size(); ++a) {
    EXPECT_LE(norm(p.position[a]) + p.radius[a], 1.0 + 1e-12);
    const double v = std::pow(p.radius[a], 3);
    centroid += v * p.position[a];
    vol += v;
    for (std::size_t b = 0; b < a; ++b) {
      const double gap = norm(p.position[a] - p.position[b]) - p.radius[a] - p.radius[b];
      EXPECT_GE(gap, -1e-12) << a << " " << b;
      if (std::abs(gap) < 1e-12) ++touching;
    }
  }
  EXPECT_NEAR(vol, 0.520, 5e-4);
  EXPECT_NEAR(norm(centroid), 0.0, 1e-15);
  EXPECT_GE(touching, 14);  // a connected cluster, not loose spheres
  SplitPattern bad = p;
  bad.position[2] = bad.position[3];
  EXPECT_THROW(bad.validate("bad"), ConfigError);
}

TEST(Crushing, GrainBetweenWallsBreaksAtTheHertzForce) {
  const double d = 0.21e-3, R = 0.5 * d;
  Simulation sim(squeeze_config(1e-3, d));
  sim.add_particle({0.0, 0.0, R}, R);
  Crusher crusher(exact_strength(d), SplitPattern::default14());
  crusher.begin(sim);
  const auto ev = squeeze_until_break(sim, crusher, 0.02);
  ASSERT_EQ(ev.size(), 1u);
  const double F_theory = hertz_break_force(3.75e9, R, sim.config().material.E_star());
  EXPECT_NEAR(F_theory, 6.5, 0.05);  // docs/model.md 2.1
  // The force on the top wall when the criterion was met (the step before the split).
  const double F = ev[0].sigma / 3.75e9;  // sigma >= sigma_lim at the first crossing
  EXPECT_GE(F, 1.0);
  EXPECT_LT(F, 1.0 + 1e-3);
  EXPECT_EQ(ev[0].fragments.size(), 14u);
  // Where it broke (breakage.csv's x_m, y_m, z_m): its centre, halfway between the walls.
  EXPECT_EQ(ev[0].position.x, 0.0);
  EXPECT_EQ(ev[0].position.y, 0.0);
  EXPECT_NEAR(ev[0].position.z, 0.5 * sim.walls().position(5), 1e-3 * R);
  EXPECT_EQ(sim.particles().size(), 14u);
  // Force from sigma: F = sigma pi R delta, delta from Hertz: compare with the closed form.
  const double delta =
      std::pow(3.0 * F_theory / (4.0 * sim.config().material.E_star() * std::sqrt(R)), 2.0 / 3.0);
  EXPECT_NEAR(ev[0].sigma * kPi * R * delta / F_theory, 1.0, 0.01);
}

TEST(Crushing, TwoGrainsBreakTogetherAtTheHertzForce) {
  const double d = 0.21e-3, R = 0.5 * d;
  Simulation sim(squeeze_config(1e-3, 2 * d));
  sim.add_particle({0.0, 0.0, R}, R);
  sim.add_particle({0.0, 0.0, 3 * R}, R);
  Crusher crusher(exact_strength(d), SplitPattern::default14());
  crusher.begin(sim);
  sim.step();  // contact forces exist before the top wall moves
  const auto ev = squeeze_until_break(sim, crusher, 0.02);
  ASSERT_EQ(ev.size(), 2u);  // the same contact stress on both: both break in that step
  const double F_theory = hertz_break_force(3.75e9, 0.5 * R, sim.config().material.E_star());
  EXPECT_NEAR(F_theory, 1.62, 0.01);
  const double Rs = 0.5 * R;
  const double delta =
      std::pow(3.0 * F_theory / (4.0 * sim.config().material.E_star() * std::sqrt(Rs)), 2.0 / 3.0);
  EXPECT_NEAR(ev[0].sigma * kPi * Rs * delta / F_theory, 1.0, 0.01);
  EXPECT_LT(ev[0].sigma / 3.75e9, 1.0 + 1e-3);
  EXPECT_EQ(sim.particles().size(), 28u);
}

namespace {

/// Layers of n x n equal grains of diameter d squeezed between two walls; each grain's strength
/// is its contact stress at failure. All fragments are removed (d_min above the largest
/// fragment), so a layer only loses grains. Appends (d, sigma at failure) per grain.
void squeeze_layer(double d, int n, double var, std::uint64_t seed,
                   std::vector<std::pair<double, double>>& out) {
  const double R = 0.5 * d, pitch = 1.6 * d;
  Simulation sim(squeeze_config(0.5 * n * pitch, d));
  for (int a = 0; a < n; ++a) {
    for (int b = 0; b < n; ++b) {
      sim.add_particle(
          {(a + 0.5) * pitch - 0.5 * n * pitch, (b + 0.5) * pitch - 0.5 * n * pitch, R}, R);
    }
  }
  CrushingConfig k;
  k.enabled = true;
  k.var = var;
  k.d0 = 0.21e-3;
  k.d_min = 0.6 * d;
  k.seed = seed;
  Crusher crusher(k, SplitPattern::default14());
  crusher.begin(sim);
  sim.set_dt(sim.dt());  // fixed: the wall speed below is set in steps
  sim.walls().config(5).mode = WallMode::Velocity;
  // The strongest grains (f <= 2.14, and the size effect) need delta up to ~0.24 d: 0.3 d of
  // travel in 60,000 steps.
  sim.walls().config(5).velocity = -0.3 * d / (60000.0 * sim.dt());
  sim.walls().update_velocities(0.0);
  int broken = 0;
  for (int s = 0; s < 100000 && broken < n * n; ++s) {
    sim.step();
    for (const auto& e : crusher.apply(sim)) {
      ++broken;
      out.emplace_back(d, e.sigma);
    }
  }
  ASSERT_EQ(broken, n * n) << "d = " << d;
}

}  // namespace

TEST(Crushing, SingleGrainTestsRecoverTheSizeEffect) {
  // f = 1: each grain's measured strength follows sigma_lim0 (d / d0)^(-3/m).
  std::vector<std::pair<double, double>> r;
  for (double d : {0.05e-3, 0.1e-3, 0.21e-3, 0.5e-3, 1.0e-3, 2.0e-3})
    squeeze_layer(d, 2, 0.0, 1, r);
  double mx = 0, my = 0;
  for (const auto& [d, s] : r) {
    mx += std::log(d) / static_cast<double>(r.size());
    my += std::log(s) / static_cast<double>(r.size());
  }
  double sxy = 0, sxx = 0;
  for (const auto& [d, s] : r) {
    sxy += (std::log(d) - mx) * (std::log(s) - my);
    sxx += (std::log(d) - mx) * (std::log(d) - mx);
    EXPECT_NEAR(s / (3.75e9 * std::pow(d / 0.21e-3, -0.25)), 1.0, 2e-3) << "d = " << d;
  }
  std::printf("size effect: slope %.5f (expected -3/m = %.5f)\n", sxy / sxx, -0.25);
  EXPECT_NEAR(sxy / sxx, -0.25, 0.1 * 0.25);
}

TEST(Crushing, SingleGrainTestsRecoverTheSpreadSetByVar) {
  // var = 0.38 at d = d0: f = sigma / sigma_lim0 is normal(1, 0.38) truncated to [0.05, 2.14]
  // (mean 1.00, standard deviation 0.37); 144 grains estimate the sd within about 6 %.
  const double var = 0.38;
  std::vector<std::pair<double, double>> r;
  squeeze_layer(0.21e-3, 12, var, 11, r);
  double fm = 0, fv = 0;
  for (const auto& e : r) fm += e.second / 3.75e9 / static_cast<double>(r.size());
  for (const auto& e : r) fv += std::pow(e.second / 3.75e9 - fm, 2);
  const double fsd = std::sqrt(fv / static_cast<double>(r.size() - 1));
  std::printf("spread: f mean %.4f, sd %.4f over %zu grains (var = %.2f)\n", fm, fsd, r.size(),
              var);
  EXPECT_NEAR(fm, 1.0, 0.08);
  EXPECT_NEAR(fsd, 0.37, 0.15 * 0.37);
}

TEST(Crushing, SplitConservesMomentumAndAccountsMass) {
  const double R = 0.1e-3;
  Simulation sim(crushdem::testing::box_config(-1e-3, 1e-3));
  sim.add_particle({1e-5, -2e-5, 3e-5}, R, {0.3, -0.1, 0.2}, {1000.0, -2000.0, 500.0});
  sim.add_particle({5e-4, 5e-4, 5e-4}, 0.3 * R);  // a bystander
  CrushingConfig k;
  k.enabled = true;
  k.d_min = 0.45 * R;  // removes the six R/5 fragments (d = 0.4 R), keeps the others
  Crusher crusher(k, SplitPattern::default14());
  crusher.begin(sim);
  const ParticleStore& p = sim.particles();
  const double M = p.mass[0], total0 = p.total_mass();
  const Vec3 v{p.vx[0], p.vy[0], p.vz[0]};
  const auto ev = crusher.split(sim, {0}, BreakCause::Instant);
  ASSERT_EQ(ev.size(), 1u);
  EXPECT_EQ(ev[0].fragments.size(), 8u);
  EXPECT_EQ(ev[0].removed_fragments, 6);
  Vec3 mom{};
  double m_frag = 0.0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (p.parent[i] != ev[0].id) continue;
    mom += p.mass[i] * Vec3{p.vx[i], p.vy[i], p.vz[i]};
    m_frag += p.mass[i];
    EXPECT_EQ(p.wx[i], 1000.0);  // the parent's angular velocity
  }
  // The retained fragments carry the parent's velocity times their mass: the pattern's
  // retained fragments are symmetric, so the omega x r terms cancel.
  EXPECT_NEAR(norm(mom - m_frag * v) / (m_frag * norm(v)), 0.0, 1e-12);
  EXPECT_NEAR((m_frag + crusher.removed_mass()) / M, 1.0, 1e-12);
  EXPECT_NEAR((p.total_mass() + crusher.removed_mass()) / total0, 1.0, 1e-12);
  const double V0 = 4.0 / 3.0 * kPi * R * R * R;
  EXPECT_NEAR(crusher.removed_volume() / V0, 1.0 - (0.25 + 6.0 / 27.0), 1e-12);
}

TEST(Crushing, GrainsBelowTheComminutionLimitNeverBreak) {
  const double d = 0.21e-3, R = 0.5 * d;
  Simulation sim(squeeze_config(1e-3, d));
  sim.add_particle({0.0, 0.0, R}, R);
  CrushingConfig k = exact_strength(d);
  k.sigma_lim0 = 1e7;  // far weaker than the load it will see
  k.dc_ratio = 1.01;   // d_c = 1.01 d50 > d
  Crusher crusher(k, SplitPattern::default14());
  crusher.begin(sim);
  EXPECT_TRUE(squeeze_until_break(sim, crusher, 0.05, 20000).empty());
  EXPECT_GT(sim.contact_load().sigma[0], 100 * 1e7);
  EXPECT_EQ(sim.particles().size(), 1u);
}

TEST(Pattern, ReadFromFileAndRejectOverlaps) {
  namespace fs = std::filesystem;
  const crushdem::testing::TempDir temp("pattern");
  const fs::path f = temp.path() / "two.txt";
  {
    std::FILE* out = std::fopen(f.string().c_str(), "w");
    std::fprintf(out, "# two halves along the axis\n0.5 0 0 0.5\n0.5 0 0 -0.5\n");
    std::fclose(out);
  }
  const SplitPattern p = SplitPattern::from_file(f.string());
  EXPECT_EQ(p.size(), 2u);
  EXPECT_NEAR(p.retained_volume_fraction(), 0.25, 1e-15);
  {
    std::FILE* out = std::fopen(f.string().c_str(), "w");
    std::fprintf(out, "0.5 0 0 0.4\n0.5 0 0 -0.5\n");  // 0.9 apart: they overlap
    std::fclose(out);
  }
  try {
    SplitPattern::from_file(f.string());
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("fragments 1 and 2 overlap"), std::string::npos)
        << e.what();
  }
}

// One grain pressed between the z walls, a smaller crushable one free beside it, after one step:
// the pressed grain's sigma / sigma_lim is known from the contact load.
struct PressedAndFreeGrain {
  static constexpr double d = 0.21e-3, R = 0.5 * d, delta = 1e-7;
  Simulation sim{squeeze_config(1e-3, d - 2.0 * delta)};
  Crusher crusher{exact_strength(d), SplitPattern::default14()};
  PressedAndFreeGrain() {
    sim.add_particle({0.0, 0.0, R - delta}, R);
    sim.add_particle({-8e-4, -8e-4, R - delta}, 0.7 * R);
    crusher.begin(sim);
    sim.step();
  }
};

TEST(Crushing, LoadedShareCountsCrushableGrainsNearTheirStrength) {
  // Half the crushable grains carry a load.
  PressedAndFreeGrain g;
  const std::vector<double>& sigma = g.sim.contact_load().sigma;  // grains in the store's order
  const double ratio = *std::max_element(sigma.begin(), sigma.end()) / 3.75e9;
  ASSERT_GT(ratio, 0.01);
  ASSERT_GE(0.7 * g.d, g.crusher.d_c());
  EXPECT_EQ(g.crusher.loaded_share(g.sim, 0.99 * ratio), 0.5);
  EXPECT_EQ(g.crusher.loaded_share(g.sim, 1.01 * ratio), 0.0);
  EXPECT_EQ(g.crusher.loaded_share(g.sim, 0.0), 1.0);
}

TEST(Crushing, OverStrengthCountsTheGrainsAlreadyFailing) {
  // Lowering the pressed grain's strength below its load puts it over; the free grain never
  // counts.
  PressedAndFreeGrain g;
  const std::vector<double>& sigma = g.sim.contact_load().sigma;
  const std::size_t pressed = sigma[0] > sigma[1] ? 0 : 1;
  std::vector<double>& strength = g.sim.particles().field(g.crusher.strength_field());
  Crusher::OverStrength o = g.crusher.over_strength(g.sim);
  EXPECT_EQ(o.grains, 0u);
  EXPECT_DOUBLE_EQ(o.max_ratio, sigma[pressed] / 3.75e9);
  strength[pressed] = 0.5 * sigma[pressed];
  o = g.crusher.over_strength(g.sim);
  EXPECT_EQ(o.grains, 1u);
  EXPECT_DOUBLE_EQ(o.max_ratio, 2.0);
  strength[pressed] = sigma[pressed];  // at it: fails
  EXPECT_EQ(g.crusher.over_strength(g.sim).grains, 1u);
}

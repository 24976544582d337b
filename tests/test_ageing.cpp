// Time-dependent failure and off-DEM ageing (docs/model.md 3): a grain under a constant
// contact stress fails at t = (0.5 d - a0) / v, in dynamic DEM and across an ageing jump; each
// jump brings exactly n_break grains to failure.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "crushdem/ageing/ageing_jump.hpp"
#include "crushdem/experiments/stages.hpp"
#include "crushdem/fracture/crack_growth.hpp"
#include "crushdem/fracture/crushing.hpp"
#include "helpers.hpp"

using namespace crushdem;

namespace {

/// One grain held between two fixed walls that overlap it by delta each (at rest, symmetric:
/// a constant contact stress).
struct Held {
  Simulation sim;
  Crusher crusher;
  Held(double d, double delta, const CrushingConfig& k)
      : sim([&] {
          SimulationConfig c = crushdem::testing::box_config(-1e-3, 1e-3, NormalLaw::Hertz);
          c.walls[4].position = delta;
          c.walls[5].position = d - delta;
          return c;
        }()),
        crusher(k, SplitPattern::default14()) {
    sim.add_particle({0.0, 0.0, 0.5 * d}, 0.5 * d);
    crusher.begin(sim);
    sim.compute_forces();
  }
  double a() const { return sim.particles().field(crusher.crack_field())[0]; }
  double sigma_ratio() const {
    return sim.contact_load().sigma[0] / sim.particles().field(crusher.strength_field())[0];
  }
};

CrushingConfig crack_config(double v0) {
  CrushingConfig k;
  k.enabled = true;
  k.crack_growth = true;
  k.var = 0.0;
  k.d0 = 0.21e-3;
  k.v0 = v0;
  k.seed = 4;
  return k;
}

}  // namespace

TEST(Ageing, ConstantStressGrainFailsAtTheCrackTimeInDynamicDem) {
  const double d = 0.21e-3;
  // delta = 4 um: sigma / sigma_lim ~ 0.87 (below instant failure).
  Held h(d, 4e-6, crack_config(3000.0));
  const double ratio = h.sigma_ratio();
  ASSERT_GT(ratio, 0.7);
  ASSERT_LT(ratio, 1.0);
  const double v = 3000.0 * std::pow(ratio, 60.0);
  const double t_expected = (0.5 * d - h.a()) / v;
  const double dt = h.sim.dt();
  ASSERT_GT(t_expected / dt, 1000.0);  // resolved by many steps
  ASSERT_LT(t_expected / dt, 200000.0);
  double t_fail = -1.0;
  for (int s = 0; s < 300000 && t_fail < 0; ++s) {
    h.sim.step();
    for (const auto& e : h.crusher.apply(h.sim)) {
      EXPECT_EQ(e.cause, BreakCause::Crack);
      t_fail = e.time;
    }
  }
  ASSERT_GT(t_fail, 0.0);
  EXPECT_NEAR(t_fail / t_expected, 1.0, 1e-3);
  EXPECT_EQ(h.crusher.breakages(BreakCause::Crack), 1u);
}

TEST(Ageing, ConstantStressGrainFailsAtTheCrackTimeAcrossAJump) {
  const double d = 0.21e-3;
  Held h(d, 4e-6, crack_config(0.1));  // Table 1: v0 = 0.1 m/s
  const double v = 0.1 * std::pow(h.sigma_ratio(), 60.0);
  const double t_expected = (0.5 * d - h.a()) / v;
  // A little dynamic DEM first (negligible growth), then one jump to the failure.
  for (int s = 0; s < 100; ++s) {
    h.sim.step();
    EXPECT_TRUE(h.crusher.apply(h.sim).empty());
  }
  const double t_dem = h.sim.time();
  const AgeingJump j = ageing_jump(h.sim, h.crusher, 1, 1e12);
  EXPECT_EQ(j.failing, 1u);
  EXPECT_NEAR((j.dt + t_dem) / t_expected, 1.0, 1e-3);
  EXPECT_EQ(h.a(), 0.5 * d);
  const auto ev = h.crusher.apply(h.sim);
  ASSERT_EQ(ev.size(), 1u);
  EXPECT_EQ(ev[0].cause, BreakCause::Crack);
  // A jump capped by the target time grows the crack by v dt and breaks nothing.
  Held g(d, 4e-6, crack_config(0.1));
  const double a0 = g.a();
  const double cap = 0.25 * (0.5 * d - a0) / (0.1 * std::pow(g.sigma_ratio(), 60.0));
  const AgeingJump jc = ageing_jump(g.sim, g.crusher, 1, cap);
  EXPECT_EQ(jc.failing, 0u);
  EXPECT_DOUBLE_EQ(jc.dt, cap);
  EXPECT_NEAR((g.a() - a0) / (0.25 * (0.5 * d - a0)), 1.0, 1e-12);
}

TEST(Ageing, EachJumpBringsExactlyNBreakGrainsToFailure) {
  // 64 grains of random strength and crack between two fixed walls that squeeze them all.
  const double d = 0.21e-3, R = 0.5 * d, pitch = 1.6 * d, delta = 3e-6;
  const int n = 8;
  SimulationConfig c =
      crushdem::testing::box_config(-0.5 * n * pitch, 0.5 * n * pitch, NormalLaw::Hertz);
  c.damping.local_alpha = 0.7;
  c.walls[4].position = delta;
  c.walls[5].position = d - delta;
  Simulation sim(c);
  for (int a = 0; a < n; ++a) {
    for (int b = 0; b < n; ++b) {
      sim.add_particle(
          {(a + 0.5) * pitch - 0.5 * n * pitch, (b + 0.5) * pitch - 0.5 * n * pitch, R}, R);
    }
  }
  CrushingConfig k = crack_config(0.1);
  k.var = 0.38;
  k.d_min = 0.6 * d;  // fragments vanish: the layer only loses grains
  Crusher crusher(k, SplitPattern::default14());
  crusher.begin(sim);
  for (int s = 0; s < 200; ++s) {
    sim.step();
    crusher.apply(sim);  // the weakest may break at once
  }
  double clock = 0.0;
  for (int jump = 0; jump < 5; ++jump) {
    const std::size_t before = sim.particles().size();
    const std::uint64_t cracks = crusher.breakages(BreakCause::Crack);
    const AgeingJump j = ageing_jump(sim, crusher, 3, 1e15);
    ASSERT_GT(j.dt, 0.0);
    clock += j.dt;
    EXPECT_EQ(j.failing, 3u) << "jump " << jump;
    crusher.apply(sim);
    EXPECT_EQ(crusher.breakages(BreakCause::Crack) - cracks, 3u) << "jump " << jump;
    EXPECT_EQ(sim.particles().size(), before - 3);
    for (int s = 0; s < 200; ++s) {  // a short dynamic phase (no further crack failures)
      sim.step();
      crusher.apply(sim);
    }
  }
  EXPECT_GT(clock, 0.0);
}

TEST(Ageing, InstantAndCrackFailuresInOneCheckBothKeepTheirLoad) {
  const double d = 0.21e-3, R = 0.5 * d, delta = 3e-6;
  SimulationConfig c = crushdem::testing::box_config(-1e-3, 1e-3, NormalLaw::Hertz);
  c.walls[4].position = delta;
  c.walls[5].position = d - delta;
  Simulation sim(c);
  sim.add_particle({-0.5e-3, 0.0, R}, R);
  sim.add_particle({0.5e-3, 0.0, R}, R);
  Crusher crusher(crack_config(0.1), SplitPattern::default14());
  crusher.begin(sim);
  sim.compute_forces();
  ParticleStore& p = sim.particles();
  const std::size_t weak = p.id[0] == 0 ? 0 : 1, cracked = 1 - weak;
  p.field(crusher.strength_field())[weak] = 1e6;      // far below its contact stress
  p.field(crusher.crack_field())[cracked] = 0.5 * d;  // the crack has reached failure
  const auto ev = crusher.apply(sim);
  ASSERT_EQ(ev.size(), 2u);
  for (const auto& e : ev) {
    EXPECT_GT(e.sigma, 1e8) << to_string(e.cause);  // the load of its own contacts
    EXPECT_EQ(e.fragments.size(), 14u);
  }
  EXPECT_EQ(crusher.breakages(BreakCause::Instant), 1u);
  EXPECT_EQ(crusher.breakages(BreakCause::Crack), 1u);
  // Split along the wall normal (z): the two R/2 fragments of each parent sit above each other.
  int vertical_pairs = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (std::abs(p.radius[i] - 0.5 * R) < 1e-15 && std::abs(p.z[i] - R) > 0.49 * R) {
      ++vertical_pairs;
    }
  }
  EXPECT_EQ(vertical_pairs, 4);
}

TEST(Ageing, CrackLawAndJumpDurationByHand) {
  // v = v0 (sigma / sigma_lim)^n: at half the strength with n = 2, v = v0 / 4.
  EXPECT_DOUBLE_EQ(crack_velocity(0.1, 1.0e9, 2.0e9, 2.0), 0.025);
  EXPECT_DOUBLE_EQ(crack_time_to_failure(0.02e-3, 0.1e-3, 0.025), 0.08e-3 / 0.025);
  EXPECT_EQ(crack_time_to_failure(0.2e-3, 0.1e-3, 0.025), 0.0);  // already past failure
  const double inf = std::numeric_limits<double>::infinity();
  const std::vector<double> t = {5.0, inf, 1.0, 3.0, 2.0, inf, 4.0};
  EXPECT_EQ(ageing_jump_duration(t, 1, 100.0), 1.0);
  EXPECT_EQ(ageing_jump_duration(t, 3, 100.0), 3.0);
  EXPECT_EQ(ageing_jump_duration(t, 3, 2.5), 2.5);      // capped at the time left
  EXPECT_EQ(ageing_jump_duration(t, 6, 100.0), 100.0);  // only five grains can fail
  EXPECT_EQ(ageing_jump_duration(t, 8, 100.0), 100.0);  // more than there are grains
  EXPECT_EQ(ageing_jump_duration({}, 1, 7.0), 7.0);
}

// The share an age stage reports as done (its progress lines' ETA), on the ageing clocks of two
// measured runs: the main job's relaxation (jumps from 0.013 s, eleven phases to a day) and the
// 300-grain creep test (a first jump of 3,264 s, then 44 s). Never below the log1p share, which
// leads late in a day-long relaxation; in its first half, near the share of the phases done
// (where the log1p share alone said 0.004 after the second phase).
TEST(Ageing, AnAgeStagesShareDoneFollowsItsPhases) {
  const double day = 86400.0;
  const std::vector<double> relaxation = {0.0132, 0.0458,  2.84,    10.77,  30.80,
                                          219.8,  11741.3, 74805.1, 85661.4};
  for (std::size_t k = 2; k <= relaxation.size(); ++k) {
    const double t = relaxation[k - 1];
    const double share = ageing_progress(t, day, relaxation[0], k);
    EXPECT_GE(share, std::log1p(t) / std::log1p(day));
    if (k <= 6) {
      EXPECT_NEAR(share, static_cast<double>(k) / 11.0, 0.12) << "after phase " << k;
    }
  }
  const std::vector<double> creep = {3263.8, 3307.9, 51956.3, 52034.6};
  for (std::size_t k = 2; k <= creep.size(); ++k) {
    const double t = creep[k - 1];
    EXPECT_DOUBLE_EQ(ageing_progress(t, day, creep[0], k), std::log1p(t) / std::log1p(day));
  }
  EXPECT_EQ(ageing_progress(0.0, day, 0.0, 0), 0.0);
  EXPECT_EQ(ageing_progress(day, day, 0.0132, 10), 1.0);
  EXPECT_EQ(ageing_progress(5.0, 0.0, 0.0, 0), 1.0);
}

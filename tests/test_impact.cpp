// Two-body collisions against Hertz theory (Johnson, Contact Mechanics, 1985, section 11.4).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "helpers.hpp"

namespace crushdem {
namespace {

struct ImpactResult {
  double max_delta = 0.0, max_force = 0.0, duration = 0.0;
  double ke_before = 0.0, ke_after = 0.0;
};

// Hertz impact: delta_max = (15 m* v^2 / (16 E* sqrt(R*)))^(2/5), F_max = 4/3 E* sqrt(R*) d^1.5,
// contact duration t_c = 2.9432 delta_max / v (v: approach speed).
struct HertzImpact {
  double delta_max, F_max, t_c;
  HertzImpact(double m_eff, double R_star, double E_star, double v) {
    delta_max = std::pow(15.0 * m_eff * v * v / (16.0 * E_star * std::sqrt(R_star)), 0.4);
    F_max = 4.0 / 3.0 * E_star * std::sqrt(R_star) * std::pow(delta_max, 1.5);
    t_c = 2.9432 * delta_max / v;
  }
};

ImpactResult run_impact(Simulation& sim, bool wall) {
  ImpactResult r;
  r.ke_before = sim.kinetic_energy();
  bool in_contact = false, done = false;
  double t_start = 0.0;
  for (int s = 0; s < 200000 && !done; ++s) {
    sim.step();
    const auto cs = sim.contacts();
    double delta = 0.0, F = 0.0;
    for (const auto& c : cs) {
      if (c.is_wall == wall) {
        delta = c.delta;
        F = c.F_n;
      }
    }
    if (delta > 0.0 && !in_contact) {
      in_contact = true;
      t_start = sim.time();
    }
    if (in_contact && delta <= 0.0) {
      r.duration = sim.time() - t_start;
      done = true;
    }
    r.max_delta = std::max(r.max_delta, delta);
    r.max_force = std::max(r.max_force, F);
  }
  EXPECT_TRUE(done);
  r.ke_after = sim.kinetic_energy();
  return r;
}

TEST(Impact, TwoEqualSpheresHeadOn) {
  SimulationConfig cfg = testing::box_config(-1e-3, 1e-3);
  cfg.timestep.dt = 5e-10;
  Simulation sim(cfg);
  const double R = 1e-4, v = 0.1;
  sim.add_particle({-R - 1e-7, 0, 0}, R, {v, 0, 0});
  sim.add_particle({R + 1e-7, 0, 0}, R, {-v, 0, 0});
  const double m = sim.particles().mass[0];
  const ImpactResult r = run_impact(sim, false);
  const HertzImpact th(m / 2, R / 2, cfg.material.E_star(), 2 * v);
  EXPECT_NEAR(r.max_delta / th.delta_max, 1.0, 0.01);
  EXPECT_NEAR(r.max_force / th.F_max, 1.0, 0.01);
  EXPECT_NEAR(r.duration / th.t_c, 1.0, 0.01);
  EXPECT_NEAR(r.ke_after / r.ke_before, 1.0, 0.001);
}

TEST(Impact, SphereOnWall) {
  SimulationConfig cfg = testing::box_config(-1e-3, 1e-3);
  cfg.timestep.dt = 5e-10;
  Simulation sim(cfg);
  const double R = 1e-4, v = 0.2;
  sim.add_particle({0, 0, -1e-3 + R + 1e-7}, R, {0, 0, -v});
  const double m = sim.particles().mass[0];
  const ImpactResult r = run_impact(sim, true);
  const HertzImpact th(m, R, cfg.material.E_star(), v);
  EXPECT_NEAR(r.max_delta / th.delta_max, 1.0, 0.01);
  EXPECT_NEAR(r.max_force / th.F_max, 1.0, 0.01);
  EXPECT_NEAR(r.duration / th.t_c, 1.0, 0.01);
  EXPECT_NEAR(r.ke_after / r.ke_before, 1.0, 0.001);
  EXPECT_GT(sim.particles().vz[0], 0.0);
}

// Oblique impact in gross sliding: the tangential impulse is mu times the normal one, so with
// e = 1: v_t' = v_t - 2 mu v_n and w' = 5 mu v_n / R (sliding all along needs v_t > 7 mu v_n).
TEST(Impact, ObliqueSphereWallGrossSliding) {
  SimulationConfig cfg = testing::box_config(-1e-3, 1e-3);
  cfg.timestep.dt = 2e-10;
  cfg.contact.wall_friction = 0.1;
  cfg.contact.rotation = Rotation::Free;  // the spin w' is what is checked
  Simulation sim(cfg);
  const double R = 1e-4, v_n = 0.1, v_t = 0.2, mu = 0.1;
  sim.add_particle({0, 0, -1e-3 + R + 1e-8}, R, {v_t, 0, -v_n});
  run_impact(sim, true);
  const auto& p = sim.particles();
  EXPECT_NEAR(p.vx[0] / (v_t - 2 * mu * v_n), 1.0, 0.02);
  EXPECT_NEAR(p.wy[0] / (5 * mu * v_n / R), 1.0, 0.02);
  EXPECT_NEAR(p.vz[0] / v_n, 1.0, 0.01);
}

}  // namespace
}  // namespace crushdem

namespace crushdem {
namespace {

// Tsuji viscous damping: the rebound speed over the impact speed is near the configured
// coefficient of restitution, for a pair and for a wall. The polynomial fit alpha(e) (with
// LAMMPS' sqrt(2) convention) is approximate: measured 0.550 for e = 0.5.
TEST(Impact, ViscousDampingGivesTheRestitution) {
  for (double e : {0.5, 0.8}) {
    SimulationConfig cfg = testing::box_config(-1e-3, 1e-3);
    cfg.timestep.dt = 5e-10;
    cfg.contact.restitution = e;
    Simulation sim(cfg);
    const double R = 1e-4, v = 0.1;
    const ParticleId a = sim.add_particle({-R - 1e-7, 0, 0}, R, {v, 0, 0});
    const ParticleId b = sim.add_particle({R + 1e-7, 0, 0}, R, {-v, 0, 0});
    const ParticleId w = sim.add_particle({0, 0, -1e-3 + R + 1e-7}, R, {0, 0, -v});
    sim.step(6000);
    const auto& p = sim.particles();
    auto at = [&](ParticleId id) {  // indices change when particles are re-sorted
      return static_cast<std::size_t>(std::find(p.id.begin(), p.id.end(), id) - p.id.begin());
    };
    EXPECT_NEAR((p.vx[at(b)] - p.vx[at(a)]) / (2 * v), e, 0.12 * e) << "pair, e = " << e;
    EXPECT_NEAR(p.vz[at(w)] / v, e, 0.12 * e) << "wall, e = " << e;
    for (const auto& c : sim.contacts()) EXPECT_GE(c.F_n, 0.0);
  }
}

}  // namespace
}  // namespace crushdem

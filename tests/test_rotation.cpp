// The rotation models (contact.rotation): free spins, rolling resistance (its moment law is
// tested in test_rolling.cpp) and rotation blocked. A blocked grain keeps exactly zero spin
// under an eccentric contact while friction still acts on its translation; fragments of a
// broken grain are held the same way; the configuration key is read, written and checked.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "crushdem/core/error.hpp"
#include "crushdem/fracture/crushing.hpp"
#include "crushdem/io/config.hpp"
#include "helpers.hpp"

namespace crushdem {
namespace {

struct ObliqueImpact {
  double max_spin = 0.0;        // largest |w| of either grain over the run [rad/s]
  double max_tangential = 0.0;  // largest |F_t| at the pair contact [N]
  Vec3 momentum_before, momentum_after;
  double vy_after = 0.0;  // the striker's velocity across the line of impact afterwards
};

// A grain moving along x strikes a resting one whose centre is offset by R/2 in y: the contact
// normal is oblique, so friction at the contact point gives each grain a moment about its centre.
ObliqueImpact oblique_impact(Rotation rotation, Vec3 initial_spin = {}) {
  SimulationConfig cfg = testing::box_config(-2e-3, 2e-3);
  cfg.material.friction = 0.5;
  cfg.contact.rotation = rotation;
  Simulation sim(cfg);
  const double R = 1e-4;
  sim.add_particle({-2.2 * R, 0.0, 0.0}, R, {1.0, 0.0, 0.0}, initial_spin);
  sim.add_particle({0.0, 0.5 * R, 0.0}, R);
  ObliqueImpact r;
  const ParticleStore& p = sim.particles();
  auto momentum = [&p] {
    Vec3 m{};
    for (std::size_t i = 0; i < p.size(); ++i) m += p.mass[i] * Vec3{p.vx[i], p.vy[i], p.vz[i]};
    return m;
  };
  r.momentum_before = momentum();
  for (int s = 0; s < 6000; ++s) {
    sim.step();
    for (std::size_t i = 0; i < p.size(); ++i) {
      r.max_spin = std::max(r.max_spin, norm(Vec3{p.wx[i], p.wy[i], p.wz[i]}));
    }
    for (const ContactRecord& c : sim.contacts()) {
      if (!c.is_wall) r.max_tangential = std::max(r.max_tangential, norm(c.F_t));
    }
  }
  r.momentum_after = momentum();
  r.vy_after = p.id[0] == 0 ? p.vy[0] : p.vy[1];
  return r;
}

TEST(Rotation, FreeGrainsSpinUpInAnObliqueImpact) {
  const ObliqueImpact free = oblique_impact(Rotation::Free);
  EXPECT_GT(free.max_tangential, 0.0);
  EXPECT_GT(free.max_spin, 10.0);  // friction's moment turns both grains
  EXPECT_LT(norm(free.momentum_after - free.momentum_before), 1e-12 * norm(free.momentum_before));
}

TEST(Rotation, BlockedGrainsKeepZeroSpinWhileFrictionActs) {
  const ObliqueImpact blocked = oblique_impact(Rotation::Blocked, {3000.0, -2000.0, 1000.0});
  EXPECT_EQ(blocked.max_spin, 0.0);  // even the striker's initial spin is held at zero
  EXPECT_GT(blocked.max_tangential, 0.0);
  EXPECT_LT(norm(blocked.momentum_after - blocked.momentum_before),
            1e-12 * norm(blocked.momentum_before));
  // Without rolling, the contact point slides more (no spin takes up the slip), so friction
  // deflects the striker differently from the free case.
  const ObliqueImpact free = oblique_impact(Rotation::Free);
  EXPECT_GT(std::abs(blocked.vy_after - free.vy_after), 1e-3 * std::abs(free.vy_after));
}

TEST(Rotation, FragmentsOfABlockedGrainKeepZeroSpin) {
  // A grain squeezed between frictional walls until it breaks; its 14 fragments then push on
  // each other and on the walls with friction.
  const double d = 0.21e-3, R = 0.5 * d;
  SimulationConfig cfg = testing::box_config(-1e-3, 1e-3);
  cfg.damping.local_alpha = 0.7;
  cfg.contact.wall_friction = 0.3;
  cfg.contact.rotation = Rotation::Blocked;
  cfg.walls[4].position = 0.0;
  cfg.walls[5].position = d;
  Simulation sim(cfg);
  sim.add_particle({1e-6, 0.0, R}, R, {0.01, 0.0, 0.0});
  CrushingConfig k;
  k.enabled = true;
  k.var = 0.0;
  k.d0 = d;
  Crusher crusher(k, SplitPattern::default14());
  crusher.begin(sim);
  sim.walls().config(5).mode = WallMode::Velocity;
  sim.walls().config(5).velocity = -0.02;
  sim.walls().update_velocities(0.0);
  std::size_t broken = 0;
  for (int s = 0; s < 400000 && broken == 0; ++s) {
    sim.step();
    broken = crusher.apply(sim).size();
  }
  ASSERT_EQ(broken, 1u);
  double max_spin = 0.0, max_tangential = 0.0;
  const ParticleStore& p = sim.particles();
  for (int s = 0; s < 3000; ++s) {
    sim.step();
    for (std::size_t i = 0; i < p.size(); ++i) {
      max_spin = std::max(max_spin, norm(Vec3{p.wx[i], p.wy[i], p.wz[i]}));
    }
    for (const ContactRecord& c : sim.contacts())
      max_tangential = std::max(max_tangential, norm(c.F_t));
  }
  EXPECT_EQ(p.size(), 14u);
  EXPECT_GT(max_tangential, 0.0);
  EXPECT_EQ(max_spin, 0.0);
}

// --- the configuration key --------------------------------------------------------------------

const std::string kBase = testing::tiny_run_toml() + "[contact]\n";

RunConfig parse(const std::string& contact_keys) {
  return run_config_from_toml(toml::parse(kBase + contact_keys, "cfg.toml"), "cfg.toml", ".");
}

std::string error_of(const std::string& contact_keys) {
  try {
    parse(contact_keys).validate();
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(RotationConfig, ReadWrittenAndInferredFromRollingFriction) {
  // The default parameter set blocks rotation; Table 1 as printed turns grains freely.
  EXPECT_EQ(parse("").simulation.contact.rotation, Rotation::Blocked);
  const std::string table1 = "parameters = \"table1\"\n" + kBase;
  EXPECT_EQ(run_config_from_toml(toml::parse(table1, "cfg.toml"), "cfg.toml", ".")
                .simulation.contact.rotation,
            Rotation::Free);
  EXPECT_EQ(parse("rotation = \"blocked\"\n").simulation.contact.rotation, Rotation::Blocked);
  const RunConfig rolling = parse("rotation = \"rolling\"\nrolling_friction = 0.3\n");
  EXPECT_EQ(rolling.simulation.contact.rotation, Rotation::Rolling);
  // A configuration written before the key existed: mu_r > 0 meant rolling resistance.
  EXPECT_EQ(parse("rolling_friction = 0.3\n").simulation.contact.rotation, Rotation::Rolling);
  // Written out and read back.
  const toml::Table t = to_toml(parse("rotation = \"blocked\"\n").simulation);
  EXPECT_EQ(t.at("contact").table->at("rotation").str, "blocked");
  const ContactLaw rolling_law(rolling.simulation.material, rolling.simulation.contact);
  ASSERT_TRUE(rolling_law.has_couple());
  EXPECT_EQ(std::get<ContactLaw::Chosen<RollingResistance>>(rolling_law.couple()).params.mu_r, 0.3);
  EXPECT_EQ(rolling_law.pair_history().size(), 2u);  // the tangential spring and the moment
  EXPECT_STREQ(rolling_law.pair_history()[1].name, "mr");
  const RunConfig blocked = parse("rotation = \"blocked\"\n");
  EXPECT_EQ(make_contact_params(blocked.simulation.material, blocked.simulation.contact).spin_scale,
            0.0);
}

TEST(RotationConfig, ContradictionsNameTheKey) {
  EXPECT_NE(error_of("rotation = \"spinning\"\n").find("contact.rotation"), std::string::npos);
  EXPECT_NE(error_of("rotation = \"spinning\"\n").find("\"blocked\""), std::string::npos);
  const std::string no_mu = error_of("rotation = \"rolling\"\n");
  EXPECT_NE(no_mu.find("contact.rolling_friction"), std::string::npos) << no_mu;
  EXPECT_NE(no_mu.find("mu_r > 0"), std::string::npos) << no_mu;
  const std::string blocked_mu = error_of("rotation = \"blocked\"\nrolling_friction = 0.3\n");
  EXPECT_NE(blocked_mu.find("contact.rolling_friction"), std::string::npos) << blocked_mu;
  EXPECT_NE(blocked_mu.find("\"blocked\""), std::string::npos) << blocked_mu;
  EXPECT_EQ(error_of("rotation = \"free\"\n"), "");
}

}  // namespace
}  // namespace crushdem

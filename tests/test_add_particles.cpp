// Grains given from outside (Simulation::add_particles, what Python's add_particles calls): each
// is checked before any is added, and the error names the first that would blow the run up.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "crushdem/core/error.hpp"
#include "crushdem/integrate/simulation.hpp"
#include "helpers.hpp"

namespace crushdem {
namespace {

NewParticle grain(Vec3 x, double r) {
  NewParticle g;
  g.position = x;
  g.radius = r;
  return g;
}

std::string refusal(Simulation& sim, const std::vector<NewParticle>& grains) {
  try {
    sim.add_particles(grains);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "accepted";
}

TEST(AddParticles, RefusesWhatWouldBlowUpAndAddsNothing) {
  Simulation sim(testing::box_config(0.0, 1e-3));
  const Vec3 mid{5e-4, 5e-4, 5e-4};
  EXPECT_NE(refusal(sim, {grain(mid, 5e-3)}).find("grain 0 (centre [0.0005, 0.0005, 0.0005] m"),
            std::string::npos);
  const std::string outside = refusal(sim, {grain(mid, 1e-4), grain({5e-4, 5e-4, 2e-3}, 1e-4)});
  EXPECT_NE(outside.find("grain 1"), std::string::npos) << outside;
  EXPECT_NE(outside.find("not inside the box"), std::string::npos) << outside;
  EXPECT_NE(refusal(sim, {grain({std::nan(""), 5e-4, 5e-4}, 1e-4)}).find("finite"),
            std::string::npos);
  EXPECT_NE(refusal(sim, {grain(mid, -1.0)}).find("positive radius"), std::string::npos);
  EXPECT_EQ(sim.particles().size(), 0u);  // a refused call adds none, not the ones before
  // A grain may overlap a wall by up to a tenth of its radius (samples prepared under stress
  // do), not more.
  EXPECT_EQ(refusal(sim, {grain({0.95e-4, 5e-4, 5e-4}, 1e-4)}), "accepted");
  EXPECT_NE(refusal(sim, {grain({0.85e-4, 5e-4, 5e-4}, 1e-4)}), "accepted");
  ASSERT_EQ(sim.particles().size(), 1u);
  EXPECT_EQ(sim.particles().radius[0], 1e-4);
}

}  // namespace
}  // namespace crushdem

// Within one step(n) call the gather pass of a step also runs the next step's kick and drift
// (one pass over the grains instead of two), and the scatter pass adds four contacts at a time
// with vector shuffles. Both are speed-ups only: n steps in one call must give the same bits as
// n calls of one step (where nothing is fused), with damping, wall contacts, the contact load
// of crushing, an automatic time step re-evaluated inside the call, and on 2 threads.
#include <gtest/gtest.h>

#include <vector>

#include "crushdem/core/deterministic.hpp"
#include "helpers.hpp"

namespace crushdem {
namespace {

// The tight lattice (tests/helpers.hpp) with the time step automatic and re-evaluated every 7
// steps and the contact load tracked.
Simulation make_sample(NormalLaw law) {
  SimulationConfig cfg = testing::tight_lattice_config(law);
  cfg.timestep.update_interval = 7;
  Simulation sim(cfg);
  testing::add_tight_lattice(sim, 23);
  sim.track_contact_load(0.5);
  return sim;
}

void expect_same_load(const Simulation& a, const Simulation& b) {
  EXPECT_EQ(a.contact_load().sigma, b.contact_load().sigma);
  EXPECT_EQ(a.contact_load().F_n_max, b.contact_load().F_n_max);
  EXPECT_EQ(a.contact_load().nx, b.contact_load().nx);
  EXPECT_EQ(a.contact_load().nz, b.contact_load().nz);
}

class StepFusion : public testing::ThreadedLawTest {};

TEST_P(StepFusion, ManyStepsInOneCallEqualOneStepPerCall) {
  constexpr int kSteps = 150;
  testing::set_threads(1);
  Simulation one_per_call = make_sample(GetParam());
  for (int s = 0; s < kSteps; ++s) one_per_call.step(1);
  Simulation one_call = make_sample(GetParam());
  one_call.step(kSteps);
  // The sample is not at rest and touches the walls: the test exercises something.
  ASSERT_GT(one_call.num_contacts(), 100u);
  ASSERT_GT(one_call.kinetic_energy(), 0.0);
  double wall_force = 0.0;
  for (int k = 0; k < kNumWalls; ++k) wall_force += one_call.walls().state(k).normal_force;
  ASSERT_GT(wall_force, 0.0);
  testing::expect_same_state(one_per_call, one_call);
  expect_same_load(one_per_call, one_call);
  EXPECT_EQ(one_per_call.dt(), one_call.dt());

  // The same call on 2 threads (the sample is below the threading threshold: lowered).
  threading_threshold() = 0;
  testing::set_threads(2);
  Simulation two_threads = make_sample(GetParam());
  two_threads.step(kSteps);
  testing::expect_same_state(one_per_call, two_threads);
  expect_same_load(one_per_call, two_threads);
}

INSTANTIATE_TEST_SUITE_P(Laws, StepFusion, ::testing::Values(NormalLaw::Hertz, NormalLaw::Rough),
                         [](const ::testing::TestParamInfo<NormalLaw>& law) {
                           return law.param == NormalLaw::Hertz ? "Hertz" : "Rough";
                         });

}  // namespace
}  // namespace crushdem

// The pruned neighbour list (neighbor.prune) is a speed-up only: with it on, every step must give
// the same bits as with it off, on any thread count, after a position set by hand between steps,
// and across a checkpoint.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "crushdem/core/deterministic.hpp"
#include "crushdem/core/state_io.hpp"
#include "helpers.hpp"

namespace crushdem {
namespace {

constexpr double kR0 = testing::kTightR0;

// The tight lattice (tests/helpers.hpp) with rolling resistance on (its history follows the
// list). Skin r0 / 2.
Simulation make_sample(bool prune, NormalLaw law) {
  SimulationConfig cfg = testing::tight_lattice_config(law);
  cfg.contact.rotation = Rotation::Rolling;
  cfg.contact.rolling_friction = 0.1;
  cfg.neighbor.prune = prune;
  cfg.neighbor.skin = 0.5 * kR0;
  Simulation sim(cfg);
  testing::add_tight_lattice(sim, 11);
  return sim;
}

class Pruning : public testing::ThreadedLawTest {};

TEST_P(Pruning, StepsAreBitIdenticalToTheFullListOnOneAndTwoThreads) {
  Simulation full = make_sample(false, GetParam());
  Simulation pruned_1 = make_sample(true, GetParam());
  Simulation pruned_2 = make_sample(true, GetParam());
  testing::set_threads(1);
  full.step(600);
  pruned_1.step(600);
  testing::set_threads(2);
  threading_threshold() = 0;  // thread even this small system (729 grains)
  pruned_2.step(600);
  testing::expect_same_state(full, pruned_1);
  testing::expect_same_state(full, pruned_2);
  // The pruned list was made more than once and used in between, and it is shorter.
  const PrunedList& list = pruned_2.pruned_neighbors();
  EXPECT_GE(list.builds(), 2u);
  EXPECT_LT(list.builds(), 300u);
  EXPECT_GT(list.size(), 0u);
  EXPECT_LT(list.size(), pruned_2.neighbors().num_pairs());
  EXPECT_EQ(full.pruned_neighbors().builds(), 0u);
}

// A grain moved by hand between steps, into a partner the pruned list had left out (its gap was
// above the inner skin, and below half the Verlet skin, so the Verlet list stands): the pair is
// found, as with the full list.
TEST_P(Pruning, APositionSetByHandIsSeen) {
  Simulation full = make_sample(false, GetParam());
  Simulation pruned = make_sample(true, GetParam());
  full.step(200);
  pruned.step(200);
  const NeighborList& nl = pruned.neighbors();
  const PrunedList& list = pruned.pruned_neighbors();
  const ParticleStore& p = pruned.particles();
  ASSERT_GT(list.inner_skin(), 0.0);
  // The first entry left out whose gap is between twice the inner skin and a quarter skin.
  std::size_t owner = 0, entry = nl.num_pairs();
  double gap = 0.0;
  for (std::size_t i = 0; i < nl.num_particles() && entry == nl.num_pairs(); ++i) {
    for (auto e = nl.offsets[i]; e < nl.offsets[i + 1]; ++e) {
      const std::size_t j = nl.neighbors[e];
      const double d = std::hypot(p.x[j] - p.x[i], p.y[j] - p.y[i], p.z[j] - p.z[i]);
      const double g = d - p.radius[i] - p.radius[j];
      bool kept = false;
      for (auto k = nl.offsets[i]; k < nl.offsets[i] + list.count[i]; ++k) {
        kept = kept || list.entries[k].e == e;
      }
      if (!kept && g > 2.0 * list.inner_skin() && g < 0.25 * nl.skin()) {
        owner = i;
        entry = e;
        gap = g;
        break;
      }
    }
  }
  ASSERT_LT(entry, nl.num_pairs()) << "no entry left out at a suitable gap";
  const std::size_t i = owner, j = nl.neighbors[entry];
  // Move i towards j by its gap and 1 % of r0: an overlap of 5 um.
  const double d = std::hypot(p.x[j] - p.x[i], p.y[j] - p.y[i], p.z[j] - p.z[i]);
  const double shift = (gap + 0.01 * kR0) / d;
  for (Simulation* sim : {&full, &pruned}) {
    ParticleStore& q = sim->particles();
    const double dx = q.x[j] - q.x[i], dy = q.y[j] - q.y[i], dz = q.z[j] - q.z[i];
    q.x[i] += shift * dx;
    q.y[i] += shift * dy;
    q.z[i] += shift * dz;
  }
  const std::size_t builds = nl.builds();
  full.step(1);
  pruned.step(1);
  EXPECT_EQ(pruned.neighbors().builds(), builds) << "the Verlet list was rebuilt: no test";
  // The moved pair touches, and the two runs agree.
  bool touching = false;
  for (const ContactRecord& c : pruned.contacts()) {
    touching = touching || (!c.is_wall && ((c.id_i == p.id[i] && c.id_j == p.id[j]) ||
                                           (c.id_i == p.id[j] && c.id_j == p.id[i])));
  }
  EXPECT_TRUE(touching);
  testing::expect_same_state(full, pruned);
  full.step(100);
  pruned.step(100);
  testing::expect_same_state(full, pruned);
}

// A run stopped and continued from a checkpoint: the loaded state may carry the build count the
// pruned list was made for, with other entries behind it.
TEST_P(Pruning, ACheckpointedRunContinuesBitIdentically) {
  Simulation full = make_sample(false, GetParam());
  Simulation first = make_sample(true, GetParam());
  full.step(300);
  first.step(150);
  StateWriter out;
  save_state(first, out);
  Simulation second = make_sample(true, GetParam());
  second.step(40);  // a pruned list of its own, for another state
  StateReader in(out.bytes(), "memory");
  load_state(second, in);
  second.step(150);
  testing::expect_same_state(full, second);
}

INSTANTIATE_TEST_SUITE_P(Laws, Pruning, ::testing::Values(NormalLaw::Hertz, NormalLaw::Rough),
                         [](const ::testing::TestParamInfo<NormalLaw>& law) {
                           return law.param == NormalLaw::Hertz ? "Hertz" : "Rough";
                         });

}  // namespace
}  // namespace crushdem

// Neighbour list against an O(N^2) search, and contact history across rebuilds and compaction.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>

#include "crushdem/core/random.hpp"
#include "crushdem/neighbor/neighbor_list.hpp"
#include "helpers.hpp"

namespace crushdem {
namespace {

ParticleStore random_store(std::size_t n, double r_min, double r_max, double L,
                           std::uint64_t seed) {
  ParticleStore p;
  RandomStream rng(seed);
  TopologyChange ch;
  for (std::size_t i = 0; i < n; ++i) {
    NewParticle np;
    // log-uniform radii: every size level is populated
    np.radius = r_min * std::pow(r_max / r_min, rng.uniform());
    np.position = {rng.uniform(0, L), rng.uniform(0, L), rng.uniform(0, L)};
    np.density = 2650;
    ch.add.push_back(np);
  }
  p.apply(ch);
  return p;
}

std::set<std::pair<ParticleId, ParticleId>> list_pairs(const NeighborList& nl,
                                                       const ParticleStore& p) {
  std::set<std::pair<ParticleId, ParticleId>> s;
  for (std::size_t i = 0; i + 1 < nl.offsets.size(); ++i) {
    for (auto e = nl.offsets[i]; e < nl.offsets[i + 1]; ++e) {
      const ParticleId a = p.id[i], b = p.id[nl.neighbors[e]];
      EXPECT_TRUE(s.insert({std::min(a, b), std::max(a, b)}).second) << "pair listed twice";
    }
  }
  return s;
}

std::set<std::pair<ParticleId, ParticleId>> brute_pairs(const ParticleStore& p, double skin) {
  std::set<std::pair<ParticleId, ParticleId>> s;
  for (std::size_t i = 0; i < p.size(); ++i) {
    for (std::size_t j = i + 1; j < p.size(); ++j) {
      const double dx = p.x[i] - p.x[j], dy = p.y[i] - p.y[j], dz = p.z[i] - p.z[j];
      const double c = p.radius[i] + p.radius[j] + skin;
      if (dx * dx + dy * dy + dz * dz < c * c) {
        s.insert({std::min(p.id[i], p.id[j]), std::max(p.id[i], p.id[j])});
      }
    }
  }
  return s;
}

class NeighborBruteForce : public ::testing::TestWithParam<double> {};

TEST_P(NeighborBruteForce, EqualsQuadraticSearch) {
  const double ratio = GetParam();  // r_max / r_min
  for (std::uint64_t seed : {1u, 2u, 3u}) {
    ParticleStore p = random_store(1500, 1e-4 / ratio, 1e-4, 2e-3, seed);
    NeighborList nl;
    const double skin = 2e-5;
    nl.build(p, skin);
    EXPECT_EQ(list_pairs(nl, p), brute_pairs(p, skin));
    // Columns: every particle in exactly one column; no pair spans more than one column in y or
    // z (the condition for the race-free coloured scatter).
    std::vector<int> seen(p.size(), 0), column(p.size(), -1), color(p.size(), -1);
    for (int k = 0; k < NeighborList::kColors; ++k) {
      for (auto c = nl.color_offsets[k]; c < nl.color_offsets[k + 1]; ++c) {
        for (auto m = nl.column_offsets[c]; m < nl.column_offsets[c + 1]; ++m) {
          ++seen[nl.column_members[m]];
          column[nl.column_members[m]] = static_cast<int>(c);
          color[nl.column_members[m]] = k;
        }
      }
    }
    // Two columns of one colour never hold the two ends of pairs that reach a common particle:
    // checked directly, each owner writes to itself and its partners; no particle may be written
    // from two different columns of the same colour.
    std::vector<std::vector<int>> writers(p.size());
    for (std::size_t i = 0; i < p.size(); ++i) {
      writers[i].push_back(column[i]);
      for (auto e = nl.offsets[i]; e < nl.offsets[i + 1]; ++e)
        writers[nl.neighbors[e]].push_back(column[i]);
    }
    std::vector<int> col_color(nl.column_offsets.size(), -1);
    for (std::size_t i = 0; i < p.size(); ++i)
      col_color[static_cast<std::size_t>(column[i])] = color[i];
    for (const auto& w : writers) {
      for (std::size_t a = 0; a < w.size(); ++a) {
        for (std::size_t b = 0; b < w.size(); ++b) {
          if (w[a] != w[b]) {
            ASSERT_NE(col_color[static_cast<std::size_t>(w[a])],
                      col_color[static_cast<std::size_t>(w[b])]);
          }
        }
      }
    }
    EXPECT_TRUE(std::all_of(seen.begin(), seen.end(), [](int c) { return c == 1; }));
  }
}

INSTANTIATE_TEST_SUITE_P(RadiusRatios, NeighborBruteForce,
                         ::testing::Values(1.0, 1.8, 30.0, 100.0));

TEST(Neighbor, RebuildCriterion) {
  ParticleStore p = random_store(200, 5e-5, 1e-4, 1e-3, 7);
  NeighborList nl;
  nl.build(p, 2e-5);
  EXPECT_FALSE(nl.needs_rebuild(p));
  p.x[3] += 0.9e-5;
  EXPECT_FALSE(nl.needs_rebuild(p));
  p.x[3] += 0.2e-5;  // moved more than half the skin
  EXPECT_TRUE(nl.needs_rebuild(p));
}

// A sheared pair keeps its tangential force when the list is rebuilt, particles are re-sorted,
// and unrelated particles are removed before them (indices shift, ids do not): the pair evolves
// exactly as in a run where nothing was removed.
TEST(Neighbor, TangentialHistorySurvivesRebuildAndCompaction) {
  SimulationConfig cfg = testing::box_config(-1e-3, 1e-3);
  cfg.timestep.dt = 1e-9;
  const double R = 1e-4;
  auto make = [&](Simulation& sim, std::vector<ParticleId>& others) {
    for (int k = 0; k < 5; ++k) {
      others.push_back(sim.add_particle({-8e-4, -8e-4 + 3e-4 * k, 0}, 1e-4));
    }
    // b is smaller (another size level), so b owns the pair although its id is larger: the
    // history is saved as the force on a and must come back with its sign flipped.
    const ParticleId a = sim.add_particle({-R, 0, 0}, R, {0, 0.01, 0});
    const ParticleId b = sim.add_particle({0.4 * R - 1e-6, 0, 0}, 0.4 * R, {0, -0.01, 0});
    return std::pair{a, b};
  };
  Simulation with(cfg), without(cfg);
  std::vector<ParticleId> others, unused;
  const auto [a, b] = make(with, others);
  make(without, unused);
  auto ft_of_pair = [&](const Simulation& sim) {
    for (const auto& c : sim.contacts()) {
      if (!c.is_wall && ((c.id_i == a && c.id_j == b) || (c.id_i == b && c.id_j == a))) {
        return c.id_i == a ? c.F_t : -c.F_t;
      }
    }
    return Vec3{};
  };
  with.step(60);
  without.step(60);
  ASSERT_GT(norm(ft_of_pair(with)), 0.0);
  TopologyChange ch;
  for (std::size_t i = 0; i < with.particles().size(); ++i) {
    if (std::find(others.begin(), others.end(), with.particles().id[i]) != others.end()) {
      ch.remove.push_back(i);
    }
  }
  ASSERT_EQ(ch.remove.size(), 5u);
  const auto builds = with.neighbors().builds();
  with.apply_topology(ch);
  with.step(20);
  without.step(20);
  EXPECT_GT(with.neighbors().builds(), builds);
  const Vec3 f1 = ft_of_pair(with), f2 = ft_of_pair(without);
  ASSERT_GT(norm(f2), 0.0);
  EXPECT_EQ(f1.x, f2.x);
  EXPECT_EQ(f1.y, f2.y);
  EXPECT_EQ(f1.z, f2.z);
}

// A rebuild of the same grains carries the history by index through the rebuild's re-sorting
// (ContactHistory::carry); after a topology change it goes by ids (capture, rebuild). On the
// same state the two give the same list and the same bits of every history vector, touching
// flag and wall spring, with friction, rolling resistance and grains on the walls.
TEST(Neighbor, HistoryCarriedByIndexEqualsByIds) {
  SimulationConfig cfg = testing::tight_lattice_config(NormalLaw::Hertz);
  cfg.contact.rotation = Rotation::Rolling;
  cfg.contact.rolling_friction = 0.2;
  cfg.contact.wall_friction = 0.3;
  Simulation by_index(cfg), by_ids(cfg);
  testing::add_tight_lattice(by_index, 7);
  testing::add_tight_lattice(by_ids, 7);
  by_index.step(300);
  by_ids.step(300);
  const std::vector<ParticleId> ids_before = by_index.particles().id;
  by_index.rebuild_neighbors();
  by_ids.invalidate();  // keeps the history by ids, as before a topology change
  by_ids.rebuild_neighbors();
  // The re-sorting moved grains, so indices changed under the history.
  ASSERT_NE(by_index.particles().id, ids_before);
  ASSERT_EQ(by_index.particles().id, by_ids.particles().id);
  const NeighborList &a = by_index.neighbors(), &b = by_ids.neighbors();
  EXPECT_EQ(a.offsets, b.offsets);
  EXPECT_EQ(a.neighbors, b.neighbors);
  const ContactHistory &ha = by_index.history(), &hb = by_ids.history();
  ASSERT_EQ(ha.pair.size(), 2u);  // the tangential spring and the rolling moment
  std::size_t carried = 0;
  for (std::size_t k = 0; k < ha.pair.size(); ++k) {
    for (const auto& [u, v] :
         {std::pair{&ha.pair[k].x, &hb.pair[k].x}, std::pair{&ha.pair[k].y, &hb.pair[k].y},
          std::pair{&ha.pair[k].z, &hb.pair[k].z}}) {
      ASSERT_EQ(u->size(), v->size());
      for (std::size_t e = 0; e < u->size(); ++e) {
        // Bit for bit: a zero carried as -0 would differ here.
        EXPECT_EQ(std::signbit((*u)[e]), std::signbit((*v)[e])) << "field " << k << " entry " << e;
        EXPECT_EQ((*u)[e], (*v)[e]) << "field " << k << " entry " << e;
        carried += (*u)[e] != 0.0 ? 1 : 0;
      }
    }
  }
  EXPECT_GT(carried, 100u);
  EXPECT_EQ(ha.touching, hb.touching);
  const WallContacts &wa = by_index.wall_contacts(), &wb = by_ids.wall_contacts();
  EXPECT_EQ(wa.particle, wb.particle);
  EXPECT_EQ(wa.wall, wb.wall);
  EXPECT_EQ(wa.ft_x, wb.ft_x);
  EXPECT_EQ(wa.ft_y, wb.ft_y);
  EXPECT_EQ(wa.ft_z, wb.ft_z);
  EXPECT_TRUE(std::any_of(wa.ft_x.begin(), wa.ft_x.end(), [](double f) { return f != 0.0; }));
}

}  // namespace
}  // namespace crushdem

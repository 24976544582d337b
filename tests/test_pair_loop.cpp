// The CPU pair loop (compaction of the touching pairs, one vectorised evaluation per batch, the
// scatter in colour order) against the plainest possible reference: every pair of grains
// tested by brute force and evaluated one at a time with the same kernel, pair_contact().
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "crushdem/contact/contact_kernel.hpp"
#include "crushdem/contact/hertz.hpp"
#include "crushdem/contact/rough_hertz.hpp"
#include "helpers.hpp"

namespace crushdem {
namespace {

struct Totals {
  std::vector<Vec3> force, torque;
  int rough_regimes[3] = {0, 0, 0};  // contacts below d_T1, between d_T1 and d_T2, above d_T2
};

// Brute-force O(N^2) forces and torques of the first force evaluation (zero tangential history,
// no increment), from the simulation's own particle arrays.
// rough: the grain-grain constants whose regimes are counted (all zero for Hertz: one regime).
template <class Law>
Totals reference(const Simulation& sim, const Law& law, const ContactParams& cp,
                 const RoughHertzParams& rough) {
  const ParticleStore& p = sim.particles();
  const std::size_t N = p.size();
  Totals t;
  t.force.assign(N, Vec3{});
  t.torque.assign(N, Vec3{});
  for (std::size_t i = 0; i < N; ++i) {
    for (std::size_t j = i + 1; j < N; ++j) {
      const Vec3 dx{p.x[j] - p.x[i], p.y[j] - p.y[i], p.z[j] - p.z[i]};
      const double d2 = dot(dx, dx);
      const double rsum = p.radius[i] + p.radius[j];
      if (d2 >= rsum * rsum) continue;
      const double R_star = p.radius[i] * p.radius[j] / rsum;
      const PairContact pc =
          pair_contact(law, dx, d2, p.radius[i], p.radius[j],
                       Vec3{p.vx[i] - p.vx[j], p.vy[i] - p.vy[j], p.vz[i] - p.vz[j]},
                       Vec3{p.wx[i], p.wy[i], p.wz[i]}, Vec3{p.wx[j], p.wy[j], p.wz[j]}, R_star,
                       std::sqrt(R_star), 1.0 / (p.inv_mass[i] + p.inv_mass[j]), Vec3{}, cp, 0.0);
      t.force[i] += pc.c.force;
      t.force[j] -= pc.c.force;
      t.torque[i] += pc.a_i * pc.tn;
      t.torque[j] += pc.a_j * pc.tn;
      const int regime = pc.delta <= rough.d_T1 ? 0 : (pc.delta <= rough.d_T2 ? 1 : 2);
      ++t.rough_regimes[regime];
    }
  }
  return t;
}

// A jittered cubic lattice of grains of radius 0.8 to 1.2 r0 far from the walls: overlaps from
// none (a third of the list's pairs do not touch) to 0.2 r0, random velocities and spins.
// wide_skin: a Verlet skin of 4 lattice spacings, so that the grains inside the lattice own about
// 250 list entries each, more than one batch of the pair loop holds.
Simulation make_sample(NormalLaw law, bool wide_skin = false) {
  const double r0 = 0.5e-3;
  const int n = 12;
  const double a = 2.0 * r0;
  SimulationConfig cfg = testing::box_config(-10.0 * a, (n + 10) * a, law);
  cfg.material.friction = 0.05;   // small, so the Coulomb cap binds the viscous tangential force
  cfg.contact.restitution = 0.5;  // viscous damping on
  cfg.contact.rotation = Rotation::Rolling;
  cfg.contact.rolling_friction = 0.1;
  if (wide_skin) cfg.neighbor.skin = 4.0 * a;
  Simulation sim(cfg);
  testing::add_jittered_lattice(sim, n, a, 7, 0.02, r0, 1.0, 0.2, 0.1, 100.0);
  return sim;
}

void check(NormalLaw law_kind, bool wide_skin = false) {
  Simulation sim = make_sample(law_kind, wide_skin);
  sim.compute_forces();
  if (wide_skin) {
    // Grains with more list entries than a batch holds (PairBatch::kTarget = 136).
    const auto& off = sim.neighbors().offsets;
    std::size_t most = 0;
    for (std::size_t i = 0; i + 1 < off.size(); ++i)
      most = std::max<std::size_t>(most, off[i + 1] - off[i]);
    ASSERT_GT(most, 136u);
  }
  const ContactLaw& law = sim.contact_law();
  const ContactParams& cp = law.params();
  const Totals ref =
      law_kind == NormalLaw::Hertz
          ? reference(sim, law.pair_law<HertzNormal>(), cp, RoughHertzParams{})
          : reference(sim, law.pair_law<RoughNormal>(), cp, law.normal_params<RoughNormal>().pp);
  const ParticleStore& p = sim.particles();
  double f_max = 0.0, t_max = 0.0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    f_max = std::max(
        {f_max, std::abs(ref.force[i].x), std::abs(ref.force[i].y), std::abs(ref.force[i].z)});
    t_max = std::max(
        {t_max, std::abs(ref.torque[i].x), std::abs(ref.torque[i].y), std::abs(ref.torque[i].z)});
  }
  ASSERT_GT(f_max, 0.0);
  ASSERT_GT(t_max, 0.0);
  const auto& fx = sim.resultant_force(0);
  const auto& fy = sim.resultant_force(1);
  const auto& fz = sim.resultant_force(2);
  double f_err = 0.0, t_err = 0.0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    f_err = std::max({f_err, std::abs(fx[i] - ref.force[i].x), std::abs(fy[i] - ref.force[i].y),
                      std::abs(fz[i] - ref.force[i].z)});
    t_err = std::max({t_err, std::abs(p.tx[i] - ref.torque[i].x),
                      std::abs(p.ty[i] - ref.torque[i].y), std::abs(p.tz[i] - ref.torque[i].z)});
  }
  // Only the order of the sums differs from the reference.
  EXPECT_LT(f_err, 1e-12 * f_max) << "largest force " << f_max;
  EXPECT_LT(t_err, 1e-12 * t_max) << "largest torque " << t_max;
  const std::size_t contacts =
      static_cast<std::size_t>(ref.rough_regimes[0] + ref.rough_regimes[1] + ref.rough_regimes[2]);
  EXPECT_EQ(sim.num_contacts(), contacts);
  EXPECT_GT(sim.neighbors().num_pairs(), contacts + contacts / 4);  // untouched pairs in the list
  if (law_kind == NormalLaw::Rough) {
    // Every regime of the rough law is exercised.
    for (int k = 0; k < 3; ++k) EXPECT_GT(ref.rough_regimes[k], 10) << "regime " << k;
  }
}

TEST(PairLoop, HertzForcesAndTorquesEqualABruteForcePairByPairEvaluation) {
  check(NormalLaw::Hertz);
}

TEST(PairLoop, RoughLawForcesAndTorquesEqualABruteForcePairByPairEvaluation) {
  check(NormalLaw::Rough);
}

// A grain with more list entries than a batch holds is collected into a batch of its own.
TEST(PairLoop, GrainsWithMoreEntriesThanABatchHoldsGetTheSameForces) {
  check(NormalLaw::Hertz, true);
  check(NormalLaw::Rough, true);
}

}  // namespace
}  // namespace crushdem

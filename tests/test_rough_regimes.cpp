// The rough law without its Hertz regime (RoughHertzLawT<false>), which the CPU pair loop uses
// for a batch none of whose contacts can reach that regime: the test that rules the regime out
// must never miss a contact in it, and the law without it must give the same bits.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "crushdem/contact/contact_kernel.hpp"
#include "crushdem/contact/rough_hertz.hpp"
#include "helpers.hpp"

namespace crushdem {
namespace {

std::uint64_t bits(double x) {
  return std::bit_cast<std::uint64_t>(x);
}

// Grain-grain roughness of the study (S_q = 0.6 um) with both (k1, k2) pairs of docs/model.md 1.2.
std::vector<RoughHertzParams> params() {
  return {make_rough_hertz(0.6e-6 * std::sqrt(2.0), 0.05, 5.0),
          make_rough_hertz(0.6e-6 * std::sqrt(2.0), 0.2, 10.0)};
}

TEST(RoughRegimes, MayReachHertzNeverMissesAContactInThatRegime) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> log_r(std::log(2e-6), std::log(1e-3));
  for (const RoughHertzParams& p : params()) {
    int above = 0, below = 0;
    for (int trial = 0; trial < 2000; ++trial) {
      const double r_i = std::exp(log_r(rng)), r_j = std::exp(log_r(rng));
      const double rsum = r_i + r_j;
      const double dist0 = rsum - p.d_T2;
      if (dist0 <= 0.0) {
        // Too small to reach the regime at any distance.
        EXPECT_FALSE(rough_may_reach_hertz(0.0, rsum, p)) << rsum;
        continue;
      }
      // Squared distances within a few hundred roundings of the transition, on both sides,
      // and a few far from it.
      double d2 = dist0 * dist0;
      for (int k = 0; k < 300; ++k) d2 = std::nextafter(d2, 0.0);
      std::vector<double> d2s;
      for (int k = 0; k < 600; ++k, d2 = std::nextafter(d2, 1.0)) d2s.push_back(d2);
      for (double f : {0.5, 0.999, 1.001, 1.5}) d2s.push_back(dist0 * dist0 * f);
      for (double x : d2s) {
        // delta exactly as pair_contact() computes it.
        const double delta = r_i + r_j - std::sqrt(x);
        const bool may = rough_may_reach_hertz(x, r_i + r_j, p);
        if (delta > p.d_T2) {
          ++above;
          EXPECT_TRUE(may) << "r_i " << r_i << " r_j " << r_j << " d2 " << x;
        } else {
          ++below;
          // Not needlessly cautious: only pairs next to the transition are kept.
          if (delta < p.d_T2 * (1.0 - 1e-6)) {
            EXPECT_FALSE(may) << delta;
          }
        }
      }
    }
    EXPECT_GT(above, 100000);
    EXPECT_GT(below, 100000);
  }
  // Smooth (s = 0): every contact is in the Hertz regime.
  EXPECT_TRUE(rough_may_reach_hertz(1.0, 1e-4, make_rough_hertz(0.0, 0.05, 5.0)));
}

TEST(RoughRegimes, LawWithoutHertzRegimeGivesTheSameBitsBelowIt) {
  for (const RoughHertzParams& p : params()) {
    const RoughHertzLaw full{3.95e10, p, rough_table(p).host};
    const RoughHertzLawT<false> below = full.without_hertz_regime();
    std::vector<double> deltas{-1e-7,
                               0.0,
                               std::nextafter(p.d_T1, 0.0),
                               p.d_T1,
                               std::nextafter(p.d_T1, 1.0),
                               std::nextafter(p.d_T2, 0.0),
                               p.d_T2};
    for (int k = 1; k < 200; ++k) deltas.push_back(p.d_T2 * k / 200.0);
    for (double R_star : {3e-6, 5e-5, 4e-4}) {
      for (double delta : deltas) {
        ASSERT_LE(delta, p.d_T2);
        const NormalForce a = full(delta, R_star, std::sqrt(R_star));
        const NormalForce b = below(delta, R_star, std::sqrt(R_star));
        EXPECT_EQ(bits(a.F_n), bits(b.F_n)) << delta;
        EXPECT_EQ(bits(a.k_n), bits(b.k_n)) << delta;
        EXPECT_EQ(bits(a.k_secant), bits(b.k_secant)) << delta;
      }
      // Above d_T2 the two differ: the comparison above can fail.
      const double delta = 1.5 * p.d_T2;
      EXPECT_NE(full(delta, R_star, std::sqrt(R_star)).F_n,
                below(delta, R_star, std::sqrt(R_star)).F_n);
    }
  }
}

// Isolated pairs of grains, so that each grain's resultant force is its one contact's force,
// bit for bit: in the pair loop (which picks a law per batch) and one at a time with the full
// law. Overlaps across the rough regimes below d_T2; with hertz_pair, one pair above it.
void check_pairs(bool hertz_pair) {
  const double r0 = 1e-4, spacing = 8.0 * r0;
  const int side = 7, pairs = side * side * side;
  SimulationConfig cfg = testing::box_config(-spacing, (side + 1) * spacing, NormalLaw::Rough);
  cfg.contact.restitution = 0.5;  // viscous damping: the secant stiffness is used too
  Simulation sim(cfg);
  const RoughHertzParams& p = sim.contact_law().normal_params<RoughNormal>().pp;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int k = 0; k < pairs; ++k) {
    const double r_i = r0 * (1.0 + 0.3 * u(rng)), r_j = r0 * (1.0 + 0.3 * u(rng));
    double delta = p.d_T2 * (0.5 + 0.499 * u(rng));  // 0.001 d_T2 to 0.999 d_T2
    if (hertz_pair && k == pairs / 2) delta = 3.0 * p.d_T2;
    const Vec3 xi{spacing * (k % side), spacing * (k / side % side), spacing * (k / side / side)};
    // A slanted normal, so that every component carries the law's numbers.
    const Vec3 n{0.6, 0.48, 0.64};
    sim.add_particle(xi, r_i, Vec3{0.01 * u(rng), 0.01 * u(rng), 0.01 * u(rng)},
                     Vec3{u(rng), u(rng), u(rng)});
    sim.add_particle(xi + (r_i + r_j - delta) * n, r_j, Vec3{0.01 * u(rng), 0.0, 0.0},
                     Vec3{u(rng), u(rng), u(rng)});
  }
  sim.compute_forces();
  ASSERT_EQ(sim.num_contacts(), static_cast<std::size_t>(pairs));
  const RoughHertzLaw law = sim.contact_law().pair_law<RoughNormal>();
  const ContactParams& cp = sim.contact_params();
  const ParticleStore& s = sim.particles();
  const NeighborList& nl = sim.neighbors();
  std::vector<std::size_t> index(s.size());
  for (std::size_t q = 0; q < s.size(); ++q) index[s.id[q]] = q;
  int in_hertz_regime = 0;
  for (int k = 0; k < pairs; ++k) {
    std::size_t i = index[2 * static_cast<std::size_t>(k)];
    std::size_t j = index[2 * static_cast<std::size_t>(k) + 1];
    // The pair loop evaluates the contact from the grain whose list holds the other.
    bool listed = false;
    for (auto e = nl.offsets[i]; e < nl.offsets[i + 1]; ++e) listed |= nl.neighbors[e] == j;
    if (!listed) std::swap(i, j);
    const Vec3 dx{s.x[j] - s.x[i], s.y[j] - s.y[i], s.z[j] - s.z[i]};
    const double R_star = pair_R_star(s.radius[i], s.radius[j]);
    const PairContact pc =
        pair_contact(law, dx, dot(dx, dx), s.radius[i], s.radius[j],
                     Vec3{s.vx[i] - s.vx[j], s.vy[i] - s.vy[j], s.vz[i] - s.vz[j]},
                     Vec3{s.wx[i], s.wy[i], s.wz[i]}, Vec3{s.wx[j], s.wy[j], s.wz[j]}, R_star,
                     std::sqrt(R_star), pair_m_eff(s.inv_mass[i], s.inv_mass[j]), Vec3{}, cp, 0.0);
    in_hertz_regime += pc.delta > p.d_T2 ? 1 : 0;
    const double want[3] = {pc.c.force.x, pc.c.force.y, pc.c.force.z};
    for (int axis = 0; axis < 3; ++axis) {
      // One contact per grain: its sum is the contact's force, on i, and minus it on j.
      EXPECT_EQ(bits(sim.resultant_force(axis)[i]), bits(want[axis])) << "pair " << k;
      EXPECT_EQ(bits(sim.resultant_force(axis)[j]), bits(-want[axis])) << "pair " << k;
    }
  }
  EXPECT_EQ(in_hertz_regime, hertz_pair ? 1 : 0);
}

TEST(RoughRegimes, PairLoopBelowTheHertzRegimeMatchesTheFullLaw) {
  check_pairs(false);
}

TEST(RoughRegimes, PairLoopWithOneContactInTheHertzRegimeMatchesTheFullLaw) {
  check_pairs(true);
}

}  // namespace
}  // namespace crushdem

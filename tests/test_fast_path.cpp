// The fast path of the contact kernel (pair_contact<Law, true>: without the length restore of a
// turned contact plane, the Coulomb cap and the cap on the viscous total) against the exact
// kernel, contact by contact: wherever the fast path does not flag its result
// (fast_path_inexact()), every output must be bit for bit the exact one. The CPU pair loop relies
// on it: it evaluates every contact on the fast path and only the flagged ones again.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>

#include "crushdem/contact/contact_kernel.hpp"
#include "crushdem/contact/hertz.hpp"
#include "crushdem/contact/rough_hertz.hpp"
#include "helpers.hpp"

namespace crushdem {
namespace {

bool same_bits(double a, double b) {
  return std::memcmp(&a, &b, sizeof a) == 0;
}
bool same_bits(Vec3 a, Vec3 b) {
  return same_bits(a.x, b.x) && same_bits(a.y, b.y) && same_bits(a.z, b.z);
}

// What a case is built to exercise.
enum Kind { kCommon, kTurnedPlane, kSliding, kViscousCap, kKinds };

template <class Law>
void check(const Law& law, NormalLaw law_kind) {
  SimulationConfig cfg = testing::box_config(-1.0, 1.0, law_kind);
  cfg.material.friction = 0.3;
  const ContactParams elastic = make_contact_params(cfg.material, cfg.contact);
  cfg.contact.restitution = 0.5;  // Tsuji damping: the viscous total has its own cap
  const ContactParams viscous = make_contact_params(cfg.material, cfg.contact);

  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0), u01(0.0, 1.0);
  int flagged[kKinds] = {}, cases[kKinds] = {};
  const double r0 = 1e-4, dt = 1e-8;
  for (int c = 0; c < 40000; ++c) {
    const auto kind = static_cast<Kind>(c % kKinds);
    const ContactParams& cp = (kind == kViscousCap || c % 3 == 0) ? viscous : elastic;
    const double r_i = r0 * (0.5 + u01(rng)), r_j = r0 * (0.5 + u01(rng));
    Vec3 dir{u(rng), u(rng), u(rng)};
    dir = (1.0 / norm(dir)) * dir;
    // Overlaps from 1e-5 to 1e-2 of r_i + r_j: every regime of the rough law.
    const double delta = (r_i + r_j) * std::pow(10.0, -5.0 + 3.0 * u01(rng));
    const Vec3 dx = (r_i + r_j - delta) * dir;
    const double R_star = pair_R_star(r_i, r_j);
    const double m_eff = 1e-8 * (0.5 + u01(rng));
    // The elastic normal force, for scaling the stored tangential force against its cap.
    const double F_n = law(delta, R_star, std::sqrt(R_star)).F_n;
    const double cap = cp.mu * F_n;
    // A stored force in the contact plane (up to 0.95 of the cap), turned out of it for
    // kTurnedPlane; a tangential velocity that pushes it past the cap for kSliding.
    Vec3 t{u(rng), u(rng), u(rng)};
    t -= dot(t, dir) * dir;
    t = (1.0 / norm(t)) * t;
    Vec3 F_t_old = (0.95 * cap * u01(rng)) * t;
    if (kind == kTurnedPlane) F_t_old += (1e-6 * cap * u(rng)) * dir;
    if (kind == kViscousCap) F_t_old = (0.99 * cap) * t;
    const double v_scale = kind == kSliding ? 10.0 : (kind == kViscousCap ? 0.5 : 1e-4);
    const Vec3 dv{v_scale * u(rng), v_scale * u(rng), v_scale * u(rng)};
    const double w_scale = kind == kCommon ? 1e-2 : 100.0;  // spins add to the sliding velocity
    const Vec3 w_i{w_scale * u(rng), w_scale * u(rng), w_scale * u(rng)};
    const Vec3 w_j{w_scale * u(rng), w_scale * u(rng), w_scale * u(rng)};
    const double d2 = dot(dx, dx);

    const PairContact exact = pair_contact<Law, false>(law, dx, d2, r_i, r_j, dv, w_i, w_j, R_star,
                                                       std::sqrt(R_star), m_eff, F_t_old, cp, dt);
    const PairContact fast = pair_contact<Law, true>(law, dx, d2, r_i, r_j, dv, w_i, w_j, R_star,
                                                     std::sqrt(R_star), m_eff, F_t_old, cp, dt);
    ++cases[kind];
    if (fast_path_inexact(fast.c.F_t.x)) {
      ++flagged[kind];
      continue;
    }
    ASSERT_TRUE(same_bits(fast.c.force, exact.c.force)) << "case " << c << " kind " << kind;
    ASSERT_TRUE(same_bits(fast.c.F_t, exact.c.F_t)) << "case " << c << " kind " << kind;
    ASSERT_TRUE(same_bits(fast.c.tangential, exact.c.tangential)) << "case " << c;
    ASSERT_TRUE(same_bits(fast.c.F_n, exact.c.F_n) && same_bits(fast.c.k_n, exact.c.k_n));
    ASSERT_TRUE(same_bits(fast.tn, exact.tn) && same_bits(fast.n, exact.n));
    ASSERT_TRUE(same_bits(fast.a_i, exact.a_i) && same_bits(fast.a_j, exact.a_j));
    ASSERT_TRUE(same_bits(fast.delta, exact.delta));
  }
  // Each rare step was met (and flagged) and the common case mostly was not.
  EXPECT_GT(flagged[kTurnedPlane], cases[kTurnedPlane] / 2);
  EXPECT_GT(flagged[kSliding], cases[kSliding] / 2);
  EXPECT_GT(flagged[kViscousCap], cases[kViscousCap] / 10);
  EXPECT_LT(flagged[kCommon], cases[kCommon] / 4);
}

TEST(FastPath, HertzEqualsTheExactKernelWhereverItIsNotFlagged) {
  const SimulationConfig cfg = testing::box_config(-1.0, 1.0);
  check(ContactLaw(cfg.material, cfg.contact).pair_law<HertzNormal>(), NormalLaw::Hertz);
}

TEST(FastPath, RoughLawEqualsTheExactKernelWhereverItIsNotFlagged) {
  const SimulationConfig cfg = testing::box_config(-1.0, 1.0, NormalLaw::Rough);
  check(ContactLaw(cfg.material, cfg.contact).pair_law<RoughNormal>(), NormalLaw::Rough);
}

}  // namespace
}  // namespace crushdem

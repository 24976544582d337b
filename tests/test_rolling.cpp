// Rolling resistance (contact/rolling.hpp): the pure moment spring, then two counter-rotating
// spheres, where the contact point does not slip and only the rolling moment acts on the spins
// (an analytic two-body test in the elastic and in the fully mobilised regime).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "crushdem/contact/hertz.hpp"
#include "crushdem/contact/rolling.hpp"
#include "helpers.hpp"

namespace crushdem {
namespace {

TEST(RollingMoment, ElasticIncrementIgnoresTwistAndCapsAtMuRRStarFn) {
  const Vec3 n{0.0, 0.0, 1.0};
  const double k_t = 2e5, R_star = 1e-4, dt = 1e-8, F_n = 0.5;
  const double k_r = k_t * R_star * R_star;
  // Bending about x plus a twist about n: only the bending part loads the spring.
  const Vec3 M = rolling_moment({}, n, {100.0, 0.0, 300.0}, dt, k_t, R_star, 1.0, F_n);
  EXPECT_DOUBLE_EQ(M.x, -k_r * 100.0 * dt);
  EXPECT_EQ(M.y, 0.0);
  EXPECT_EQ(M.z, 0.0);
  // A large rotation saturates the moment at mu_r R* F_n, in the direction opposing it.
  const double mu_r = 0.1;
  const Vec3 Ms = rolling_moment({}, n, {0.0, -1e6, 0.0}, dt, k_t, R_star, mu_r, F_n);
  EXPECT_DOUBLE_EQ(norm(Ms), mu_r * R_star * F_n);
  EXPECT_GT(Ms.y, 0.0);
  // mu_r = 0: no moment at all.
  const Vec3 M0 = rolling_moment({1e-6, 0.0, 0.0}, n, {5.0, 0.0, 0.0}, dt, k_t, R_star, 0.0, F_n);
  EXPECT_EQ(norm(M0), 0.0);
  // A stored moment is turned onto a tilted contact plane with its length kept.
  const Vec3 n2 = (1.0 / std::sqrt(1.0 + 1e-4)) * Vec3{0.01, 0.0, 1.0};
  const Vec3 Mr = rolling_moment({2e-7, 0.0, 0.0}, n2, {}, dt, k_t, R_star, 1.0, F_n);
  EXPECT_NEAR(dot(Mr, n2), 0.0, 1e-22);
  EXPECT_NEAR(norm(Mr), 2e-7, 1e-20);
}

// Two equal spheres (radius R) along x, held between the x walls at force balance: the wall
// overlap delta_w = 2^(-1/3) delta gives the wall (R* = R) the pair's (R* = R/2) Hertz force.
// Spinning them with w_1 = -w_2 = w0 about z moves the contact point of neither, so the
// tangential spring stays unloaded and each spin obeys I phi'' = -M with M = k_r (2 phi) while
// elastic: Omega = sqrt(2 k_r / I), M_peak = w0 sqrt(2 k_r I). Fully mobilised, M = mu_r R* F_n
// and the spin decays linearly.
struct CounterRotatingPair {
  double R = 1e-4, delta = 1e-6, mu_r = 0.1, dt = 1e-9;
  SimulationConfig cfg;
  double k_r = 0.0, M_max = 0.0;

  CounterRotatingPair() {
    cfg = testing::box_config(-1e-3, 1e-3);
    cfg.contact.rotation = Rotation::Rolling;
    cfg.contact.rolling_friction = mu_r;
    cfg.timestep.dt = dt;
    const double delta_w = delta * std::cbrt(0.5);
    cfg.walls[0].position = -(2.0 * R - 0.5 * delta - delta_w);
    cfg.walls[1].position = 2.0 * R - 0.5 * delta - delta_w;
    const double R_star = 0.5 * R;
    const NormalForce nf = HertzLaw{cfg.material.E_star()}(delta, R_star, std::sqrt(R_star));
    k_r = mindlin_stiffness_ratio(cfg.material.poisson_ratio) * nf.k_n * R_star * R_star;
    M_max = mu_r * R_star * nf.F_n;
  }

  struct Trace {
    std::vector<double> M_z, w_z;  // moment on and spin of the first sphere, after each step
    double I = 0.0;                // moment of inertia of one sphere
    double max_tangential = 0.0;   // largest |F_t| seen at the pair contact
  };

  Trace run(double w0, int steps) const {
    Simulation sim(cfg);
    const ParticleId first = sim.add_particle({-(R - 0.5 * delta), 0, 0}, R, {}, {0, 0, w0});
    sim.add_particle({R - 0.5 * delta, 0, 0}, R, {}, {0, 0, -w0});
    Trace t;
    t.I = 1.0 / sim.particles().inv_inertia[0];
    for (int s = 0; s < steps; ++s) {
      sim.step();
      for (const ContactRecord& c : sim.contacts()) {
        if (c.is_wall) continue;
        t.M_z.push_back(c.id_i == first ? c.M_r.z : -c.M_r.z);
        t.max_tangential = std::max(t.max_tangential, norm(c.F_t));
      }
      const ParticleStore& p = sim.particles();
      t.w_z.push_back(p.id[0] == first ? p.wz[0] : p.wz[1]);
    }
    EXPECT_EQ(t.M_z.size(), t.w_z.size()) << "the pair lost contact";
    return t;
  }
};

TEST(RollingResistance, CounterRotatingSpheresOscillateAtTheRollingStiffness) {
  const CounterRotatingPair pair;
  const double I = 0.4 * 2650.0 * (4.0 / 3.0) * kPi * std::pow(pair.R, 5);
  const double Omega = std::sqrt(2.0 * pair.k_r / I);
  const double M_peak = pair.M_max * 0.5;  // elastic: half the limit
  const double w0 = M_peak / std::sqrt(2.0 * pair.k_r * I);
  const double period = 2.0 * kPi / Omega;
  ASSERT_GT(period / pair.dt, 300.0);  // resolved in time
  const auto t = pair.run(w0, static_cast<int>(3.3 * period / pair.dt));
  EXPECT_NEAR(t.I / I, 1.0, 1e-12);
  // Peak moment and period (from the downward zero crossings of the spin, t = 0 being one).
  double peak = 0.0;
  for (double m : t.M_z) peak = std::max(peak, std::abs(m));
  EXPECT_NEAR(peak / M_peak, 1.0, 0.01);
  std::vector<double> crossings;
  for (std::size_t s = 1; s < t.w_z.size(); ++s) {
    if (t.w_z[s - 1] > 0.0 && t.w_z[s] <= 0.0) {
      // Linear interpolation between the steps: sub-step accuracy for the period.
      crossings.push_back(pair.dt *
                          (static_cast<double>(s) + t.w_z[s - 1] / (t.w_z[s - 1] - t.w_z[s])));
    }
  }
  ASSERT_GE(crossings.size(), 3u);
  EXPECT_NEAR((crossings[2] - crossings[0]) / 2.0 / period, 1.0, 0.01);
  // No slip at the contact point: the tangential spring never loads (beyond round-off).
  EXPECT_LT(t.max_tangential, 1e-9 * pair.M_max / (0.5 * pair.R));
  // No energy lost in the elastic regime (no damping): the spin comes back to w0.
  double w_max = 0.0;
  for (std::size_t s = t.w_z.size() / 2; s < t.w_z.size(); ++s) w_max = std::max(w_max, t.w_z[s]);
  EXPECT_NEAR(w_max / w0, 1.0, 1e-3);
}

TEST(RollingResistance, FullyMobilisedMomentStopsTheSpinAtTheLimitRate) {
  const CounterRotatingPair pair;
  const double I = 0.4 * 2650.0 * (4.0 / 3.0) * kPi * std::pow(pair.R, 5);
  // Ten times the largest elastic spin: the spring reaches the limit at sin(Omega t_e) = 0.1,
  // with w(t_e) = w0 sqrt(0.99); then I dw/dt = -mu_r R* F_n until the spin stops.
  const double w0 = 10.0 * pair.M_max / std::sqrt(2.0 * pair.k_r * I);
  const double Omega = std::sqrt(2.0 * pair.k_r / I);
  const double t_e = std::asin(0.1) / Omega;
  const double t_stop = t_e + I * w0 * std::sqrt(0.99) / pair.M_max;
  const auto t = pair.run(w0, static_cast<int>(1.3 * t_stop / pair.dt));
  double stop = 0.0;
  for (std::size_t s = 1; s < t.w_z.size() && stop == 0.0; ++s) {
    if (t.w_z[s] <= 0.0) stop = pair.dt * static_cast<double>(s + 1);
  }
  ASSERT_GT(stop, 0.0) << "the spin never stopped";
  EXPECT_NEAR(stop / t_stop, 1.0, 0.005);
  // While sliding, the moment sits on the limit and never exceeds it.
  const auto mid = static_cast<std::size_t>(0.5 * t_stop / pair.dt);
  EXPECT_NEAR(t.M_z[mid] / -pair.M_max, 1.0, 1e-9);
  for (double m : t.M_z) EXPECT_LE(std::abs(m), pair.M_max * (1.0 + 1e-12));
}

TEST(RollingResistance, OffByDefaultAndRejectedWhenNegative) {
  const SimulationConfig plain = testing::box_config(-1e-3, 1e-3);
  EXPECT_EQ(plain.contact.rolling_friction, 0.0);
  SimulationConfig bad = plain;
  bad.contact.rolling_friction = -0.1;
  try {
    bad.validate();
    ADD_FAILURE() << "a negative rolling friction was accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("contact.rolling_friction"), std::string::npos);
  }
}

}  // namespace
}  // namespace crushdem

#include "crushdem/integrate/time_step.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "crushdem/core/params.hpp"

namespace crushdem {

const ParamTable<TimestepConfig>& timestep_params() {
  using T = TimestepConfig;
  static const ParamTable<T> table = {
      {"dt", &T::dt, "s", "fixed time step; 0 = automatic", [](double v) { return v >= 0.0; },
       "a step >= 0 in s (0 = automatic)"},
      {"rayleigh_fraction", &T::rayleigh_fraction, "-",
       "automatic: dt <= fraction x Rayleigh time of the smallest grain",
       [](double v) { return v > 0.0 && v <= 1.0; }, "a value in (0, 1]"},
      {"safety", &T::safety, "-",
       "automatic: dt <= safety x min_i sqrt(m_i / sum of k_n + k_t of its contacts)",
       [](double v) { return v > 0.0 && v <= 1.0; }, "a value in (0, 1]"},
      {"update_interval", &T::update_interval, "", "automatic: steps between re-evaluations",
       [](double v) { return v > 0.0; }, "a number of steps >= 1"},
  };
  return table;
}

TimeStep::TimeStep(const TimestepConfig& cfg) : update_interval_(cfg.update_interval) {
  if (cfg.dt > 0.0) fix(cfg.dt);
}

void TimeStep::state(StateArchive& a) {
  a(dt_, fixed_, computed_at_, valid_);
}

double rayleigh_time(const ParticleStore& p, const MaterialConfig& material) {
  // T_R = pi r sqrt(rho / G) / (0.1631 nu + 0.8766), smallest over the grains.
  if (p.size() == 0) return std::numeric_limits<double>::infinity();
  double r_sqrt_rho = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < p.size(); ++i) {
    const double r = p.radius[i];
    const double rho = p.mass[i] / (4.0 / 3.0 * kPi * r * r * r);
    r_sqrt_rho = std::min(r_sqrt_rho, r * std::sqrt(rho));
  }
  const double G = material.shear_modulus, nu = material.poisson_ratio;
  return kPi * r_sqrt_rho / std::sqrt(G) / (0.1631 * nu + 0.8766);
}

double stiffness_time(const ParticleStore& p, const NeighborList& nl, const WallContacts& wc,
                      const Walls& walls, double tangential_ratio, const NormalLawAt& normal) {
  const std::size_t N = p.size();
  if (N == 0) return std::numeric_limits<double>::infinity();
  std::vector<double> ksum(N, 0.0);
  const double kt_ratio = 1.0 + tangential_ratio;
  for (std::size_t i = 0; i < N; ++i) {
    for (auto e = nl.offsets[i]; e < nl.offsets[i + 1]; ++e) {
      const auto j = nl.neighbors[e];
      const double dx = p.x[j] - p.x[i], dy = p.y[j] - p.y[i], dz = p.z[j] - p.z[i];
      const double delta = p.radius[i] + p.radius[j] - std::sqrt(dx * dx + dy * dy + dz * dz);
      if (delta <= 0.0) continue;
      const double k = kt_ratio * normal(delta, pair_R_star(p.radius[i], p.radius[j]), false).k_n;
      ksum[i] += k;
      ksum[j] += k;
    }
  }
  for (std::size_t e = 0; e < wc.size(); ++e) {
    const std::size_t i = wc.particle[e];
    const SurfacePoint s = walls.surface(wc.wall[e], {p.x[i], p.y[i], p.z[i]});
    const double delta = p.radius[i] - s.dist;
    if (delta > 0.0) {
      ksum[i] +=
          kt_ratio * normal(delta, surface_R_star(p.radius[i], s.kappa_1, s.kappa_2), true).k_n;
    }
  }
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < N; ++i) {
    if (ksum[i] > 0.0) best = std::min(best, std::sqrt(p.mass[i] / ksum[i]));
  }
  return best;
}

}  // namespace crushdem

#include "crushdem/ageing/ageing_jump.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "crushdem/core/part_clock.hpp"
#include "crushdem/fracture/crack_growth.hpp"
#include "crushdem/fracture/crushing.hpp"

namespace crushdem {

double ageing_jump_duration(std::vector<double> t_fail, std::size_t n_break, double max_dt) {
  double dt = std::numeric_limits<double>::infinity();
  if (n_break > 0 && n_break <= t_fail.size()) {
    const auto nth = t_fail.begin() + static_cast<std::ptrdiff_t>(n_break - 1);
    std::nth_element(t_fail.begin(), nth, t_fail.end());
    dt = *nth;
  }
  dt = std::min(dt, max_dt);
  return std::isfinite(dt) ? dt : max_dt;
}

AgeingJump ageing_jump(Simulation& sim, Crusher& crusher, std::size_t n_break, double max_dt) {
  const PartScope timed(sim.part_clock(), Part::Ageing);
  sim.compute_forces();
  ParticleStore& p = sim.particles();
  std::vector<double>& a = p.field(crusher.crack_field());
  const std::vector<double>& strength = p.field(crusher.strength_field());
  const ContactLoad& load = sim.contact_load();
  const bool loaded = load.sigma.size() == p.size();
  std::vector<double> v(p.size(), 0.0), t_fail(p.size(), std::numeric_limits<double>::infinity());
  for (std::size_t i = 0; i < p.size(); ++i) {
    // A grain already at its strength fails instantly at the next check, not by its crack.
    if (loaded && load.sigma[i] >= strength[i]) continue;
    v[i] = crusher.crack_velocity(sim, i);
    if (v[i] > 0.0) t_fail[i] = crack_time_to_failure(a[i], p.radius[i], v[i]);
  }
  AgeingJump j;
  j.dt = ageing_jump_duration(t_fail, n_break, max_dt);
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (!(v[i] > 0.0)) continue;
    if (t_fail[i] <= j.dt) {
      a[i] = p.radius[i];  // exactly at failure (a = 0.5 d): broken at the next check
      ++j.failing;
    } else {
      a[i] += v[i] * j.dt;
    }
  }
  return j;
}

}  // namespace crushdem

#include "crushdem/experiments/measurements.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "crushdem/core/deterministic.hpp"
#include "crushdem/fracture/crushing.hpp"
#include "crushdem/particles/grading.hpp"

namespace crushdem {

StrainReference StrainReference::from(const Walls& w) {
  StrainReference r;
  for (int a = 0; a < 3; ++a) r.length[a] = w.length(a);
  r.volume = w.volume();
  return r;
}

Measurement measure(const Simulation& sim, const StrainReference& ref) {
  Measurement m;
  const Walls& w = sim.walls();
  const ParticleStore& p = sim.particles();
  m.emplace_back("time_s", sim.time());
  m.emplace_back("step", static_cast<double>(sim.step_count()));
  m.emplace_back("n_particles", static_cast<double>(p.size()));
  for (int k = 0; k < kNumWalls; ++k) {
    m.emplace_back(std::string("wall_") + wall_name(k) + "_position_m", w.position(k));
  }
  double s_axis[3];
  for (int k = 0; k < kNumWalls; ++k) {
    m.emplace_back(std::string("wall_") + wall_name(k) + "_stress_Pa", w.stress(k));
  }
  for (int a = 0; a < 3; ++a) s_axis[a] = 0.5 * (w.stress(2 * a) + w.stress(2 * a + 1));
  const double p_wall = (s_axis[0] + s_axis[1] + s_axis[2]) / 3.0;
  const double q_wall = s_axis[2] - 0.5 * (s_axis[0] + s_axis[1]);
  m.emplace_back("mean_stress_Pa", p_wall);
  m.emplace_back("deviator_stress_Pa", q_wall);
  const auto lw = sim.love_weber_stress();
  const char* comp[6] = {"xx", "yy", "zz", "xy", "yz", "xz"};
  const int idx[6] = {0, 4, 8, 1, 5, 2};
  for (int c = 0; c < 6; ++c) {
    m.emplace_back(std::string("love_") + comp[c] + "_Pa", lw[static_cast<std::size_t>(idx[c])]);
  }
  m.emplace_back("love_mean_stress_Pa", (lw[0] + lw[4] + lw[8]) / 3.0);
  const double eps_axial = ref.length[2] > 0 ? 1.0 - w.length(2) / ref.length[2] : 0.0;
  const double eps_vol = ref.volume > 0 ? 1.0 - w.volume() / ref.volume : 0.0;
  m.emplace_back("axial_strain", eps_axial);
  m.emplace_back("lateral_strain_x", ref.length[0] > 0 ? 1.0 - w.length(0) / ref.length[0] : 0.0);
  m.emplace_back("lateral_strain_y", ref.length[1] > 0 ? 1.0 - w.length(1) / ref.length[1] : 0.0);
  m.emplace_back("volumetric_strain", eps_vol);
  const double Vs = deterministic_sum(p.size(), [&](std::size_t i) {
    return 4.0 / 3.0 * kPi * p.radius[i] * p.radius[i] * p.radius[i];
  });
  m.emplace_back("void_ratio", Vs > 0 ? (w.volume() - Vs) / Vs : 0.0);
  const auto contacts = sim.contacts();
  std::size_t n_pp = 0;
  double sum_fn = 0, sum_fn2 = 0, sum_ft = 0, sum_ft2 = 0;
  for (const auto& c : contacts) {
    if (c.is_wall) continue;
    ++n_pp;
    const double ft = norm(c.F_t);
    sum_fn += c.F_n;
    sum_fn2 += c.F_n * c.F_n;
    sum_ft += ft;
    sum_ft2 += ft * ft;
  }
  const double nc = static_cast<double>(n_pp);
  m.emplace_back("n_contacts", nc);
  m.emplace_back("coordination_number", p.size() ? 2.0 * nc / static_cast<double>(p.size()) : 0.0);
  auto mean = [&](double s) { return n_pp ? s / nc : 0.0; };
  auto sd = [&](double s, double s2) {
    return n_pp ? std::sqrt(std::max(0.0, s2 / nc - (s / nc) * (s / nc))) : 0.0;
  };
  m.emplace_back("mean_Fn_N", mean(sum_fn));
  m.emplace_back("std_Fn_N", sd(sum_fn, sum_fn2));
  m.emplace_back("mean_Ft_N", mean(sum_ft));
  m.emplace_back("std_Ft_N", sd(sum_ft, sum_ft2));
  // Unbalanced-force ratio: mean resultant force on a grain (before local damping) over the
  // mean contact force.
  const auto &ux = sim.resultant_force(0), &uy = sim.resultant_force(1),
             &uz = sim.resultant_force(2);
  const double mean_unbalanced =
      p.size() && ux.size() == p.size()
          ? deterministic_sum(p.size(),
                              [&](std::size_t i) {
                                return std::sqrt(ux[i] * ux[i] + uy[i] * uy[i] + uz[i] * uz[i]);
                              }) /
                static_cast<double>(p.size())
          : std::numeric_limits<double>::quiet_NaN();  // not available: say so, not 0
  m.emplace_back("unbalanced_force_ratio",
                 n_pp && sum_fn > 0 ? mean_unbalanced / mean(sum_fn) : 0.0);
  m.emplace_back("kinetic_energy_J", sim.kinetic_energy());
  m.emplace_back("dt_s", sim.current_dt());
  return m;
}

namespace {

std::vector<double> current_diameters(const ParticleStore& p) {
  std::vector<double> d(p.size());
  for (std::size_t i = 0; i < p.size(); ++i) d[i] = 2.0 * p.radius[i];
  return d;
}

double largest(const std::vector<double>& d) {
  double m = 0.0;
  for (double x : d) m = std::max(m, x);
  return m;
}

}  // namespace

Measurement crushing_measurements(const Simulation& sim, const Crusher& crusher) {
  const ParticleStore& p = sim.particles();
  const double Vs = deterministic_sum(p.size(), [&](std::size_t i) {
    return 4.0 / 3.0 * kPi * p.radius[i] * p.radius[i] * p.radius[i];
  });
  const double Vr = crusher.removed_volume();
  const double V = sim.walls().volume();
  const std::vector<double> d = current_diameters(p);
  const double d_max = largest(crusher.initial_diameters());
  const double d_min = crusher.config().d_min > 0 ? crusher.config().d_min : 1e-3 * d_max;
  Measurement m;
  m.emplace_back("breakages_instant", static_cast<double>(crusher.breakages(BreakCause::Instant)));
  m.emplace_back("breakages_crack", static_cast<double>(crusher.breakages(BreakCause::Crack)));
  m.emplace_back("removed_volume_m3", Vr);
  m.emplace_back("removed_mass_kg", crusher.removed_mass());
  m.emplace_back("void_ratio_with_fines", Vs + Vr > 0 ? (V - Vs - Vr) / (Vs + Vr) : 0.0);
  m.emplace_back("relative_breakage_Br",
                 relative_breakage(crusher.initial_diameters(), d, Vr, d_min, d_max));
  return m;
}

std::vector<double> grading_sieves(const Crusher& crusher) {
  const double d_max = largest(crusher.initial_diameters());
  const double d_min = crusher.config().d_min > 0 ? crusher.config().d_min : 1e-3 * d_max;
  return log_sieves(d_min, d_max, 16);
}

Measurement grading_measurements(const Simulation& sim, const Crusher& crusher,
                                 const std::vector<double>& sieves) {
  const std::vector<double> F =
      passing_with_fines(current_diameters(sim.particles()), crusher.removed_volume(), sieves);
  Measurement m;
  m.emplace_back("time_s", sim.time());
  m.emplace_back("step", static_cast<double>(sim.step_count()));
  for (std::size_t k = 0; k < sieves.size(); ++k) {
    char name[64];
    std::snprintf(name, sizeof name, "passing_%.4e_m", sieves[k]);
    m.emplace_back(name, F[k]);
  }
  return m;
}

}  // namespace crushdem

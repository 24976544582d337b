#include "crushdem/experiments/measurements.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "crushdem/core/deterministic.hpp"
#include "crushdem/fracture/crushing.hpp"
#include "crushdem/particles/grading.hpp"
#include "crushdem/walls/body_probe.hpp"

namespace crushdem {

StrainReference StrainReference::from(const Walls& w) {
  StrainReference r;
  for (int a = 0; a < 3; ++a) r.length[a] = w.length(a);
  r.volume = w.volume();
  return r;
}

double mean_resultant_force(const Simulation& sim) {
  const ParticleStore& p = sim.particles();
  const auto &ux = sim.resultant_force(0), &uy = sim.resultant_force(1),
             &uz = sim.resultant_force(2);
  if (p.size() == 0 || ux.size() != p.size()) {
    return std::numeric_limits<double>::quiet_NaN();  // not available: say so, not 0
  }
  return deterministic_sum(p.size(),
                           [&](std::size_t i) {
                             return std::sqrt(ux[i] * ux[i] + uy[i] * uy[i] + uz[i] * uz[i]);
                           }) /
         static_cast<double>(p.size());
}

double unbalanced_force_ratio(const Simulation& sim) {
  if (const Simulation::Inspection* i = sim.current_inspection()) {  // reduced on a device
    if (sim.particles().size() == 0 || !(i->pairs > 0.0) || !(i->pair_F_n_sum > 0.0)) {
      return std::numeric_limits<double>::quiet_NaN();
    }
    return (i->resultant_sum / static_cast<double>(sim.particles().size())) /
           (i->pair_F_n_sum / i->pairs);
  }
  double sum_fn = 0.0;
  std::size_t n = 0;
  for (const ContactRecord& c : sim.contacts()) {
    if (c.is_wall) continue;
    sum_fn += c.F_n;
    ++n;
  }
  if (n == 0 || !(sum_fn > 0.0)) return std::numeric_limits<double>::quiet_NaN();
  return mean_resultant_force(sim) / (sum_fn / static_cast<double>(n));
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

  for (int k = 0; k < kNumWalls; ++k) {
    m.emplace_back(std::string("wall_") + wall_name(k) + "_stress_Pa", w.stress(k));
  }
  // The bodies beyond the box: degree of freedom, the grains' force on it and their moment
  // about its reference point, its stress.
  // Zero while the forces are not current, as the contact columns of such a row (the wall
  // entries may then not match the grains); none to sum in a box.
  const std::vector<Vec3> moments = w.size() > kNumWalls && sim.forces_current()
                                        ? body_moments(w, sim.wall_contacts(), p)
                                        : std::vector<Vec3>(static_cast<std::size_t>(w.size()));
  for (int k = kNumWalls; k < w.size(); ++k) {
    const std::string b = "body_" + w.name(k) + "_";
    const WallState& s = w.state(k);
    const Vec3& M = moments[static_cast<std::size_t>(k)];
    m.emplace_back(b + "position_m", s.position);
    m.emplace_back(b + "force_x_N", s.force.x);
    m.emplace_back(b + "force_y_N", s.force.y);
    m.emplace_back(b + "force_z_N", s.force.z);
    m.emplace_back(b + "moment_x_Nm", M.x);
    m.emplace_back(b + "moment_y_Nm", M.y);
    m.emplace_back(b + "moment_z_Nm", M.z);
    m.emplace_back(b + "stress_Pa", w.stress(k));
  }
  m.emplace_back("mean_stress_Pa", w.mean_stress());
  m.emplace_back("deviator_stress_Pa", w.axial_stress() - w.lateral_stress());
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
  const double Vs = p.solid_volume();
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
  const double mean_unbalanced = mean_resultant_force(sim);
  m.emplace_back("unbalanced_force_ratio",
                 n_pp && sum_fn > 0 ? mean_unbalanced / mean(sum_fn) : 0.0);
  m.emplace_back("kinetic_energy_J", sim.kinetic_energy());
  m.emplace_back("dt_s", sim.current_dt());
  return m;
}

namespace {

/// The size range of the grading outputs and B_r: d_min (or d_max / 1000) to the largest
/// initial grain.
struct SizeRange {
  double d_min, d_max;
};
SizeRange size_range(const Crusher& crusher) {
  double d_max = 0.0;
  for (double x : crusher.initial_diameters()) d_max = std::max(d_max, x);
  return {crusher.config().d_min > 0 ? crusher.config().d_min : 1e-3 * d_max, d_max};
}

}  // namespace

Measurement crushing_measurements(const Simulation& sim, const Crusher& crusher) {
  const ParticleStore& p = sim.particles();
  const double Vs = p.solid_volume();
  const double Vr = crusher.removed_volume();
  const double V = sim.walls().volume();
  const SizeRange r = size_range(crusher);
  Measurement m;
  m.emplace_back("breakages_instant", static_cast<double>(crusher.breakages(BreakCause::Instant)));
  m.emplace_back("breakages_crack", static_cast<double>(crusher.breakages(BreakCause::Crack)));
  m.emplace_back("removed_volume_m3", Vr);
  m.emplace_back("removed_mass_kg", crusher.removed_mass());
  m.emplace_back("void_ratio_with_fines", Vs + Vr > 0 ? (V - Vs - Vr) / (Vs + Vr) : 0.0);
  m.emplace_back("relative_breakage_Br", relative_breakage(crusher.initial_diameters(),
                                                           p.diameters(), Vr, r.d_min, r.d_max));
  return m;
}

std::vector<double> grading_sieves(const Crusher& crusher) {
  const SizeRange r = size_range(crusher);
  return log_sieves(r.d_min, r.d_max, 16);
}

Measurement grading_measurements(const Simulation& sim, const Crusher& crusher,
                                 const std::vector<double>& sieves) {
  const std::vector<double> F =
      passing_with_fines(sim.particles().diameters(), crusher.removed_volume(), sieves);
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

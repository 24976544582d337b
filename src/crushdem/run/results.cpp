#include "crushdem/run/results.hpp"

#include <cmath>
#include <utility>

#include "crushdem/core/build_info.hpp"
#include "crushdem/experiments/measurements.hpp"
#include "crushdem/particles/grading.hpp"

#ifdef CRUSHDEM_HAVE_OPENMP
#include <omp.h>
#endif

namespace crushdem {

JsonObject stage_json(const StageResult& r) {
  JsonObject o;
  o.string("name", r.name);
  o.string("type", r.kind);
  o.string("end", r.end_reason);
  o.integer("steps", static_cast<long long>(r.steps));
  // The numbers, in the order summary.json has always written them.
  static constexpr std::pair<const char*, double StageResult::*> kPeak[] = {
      {"q_max_Pa", &StageResult::q_max},
      {"axial_strain_at_q_max", &StageResult::axial_strain_at_q_max},
      {"sigma_3_at_q_max_Pa", &StageResult::sigma_3_at_q_max},
      {"friction_angle_peak_deg", &StageResult::friction_angle_deg},
      {"K0_end", &StageResult::K0},
      {"max_inertial_number", &StageResult::max_inertial_number},
      {"max_lateral_stress_error", &StageResult::max_lateral_stress_error},
      {"max_lateral_strain", &StageResult::max_lateral_strain}};
  for (const auto& [key, member] : kPeak) o.number(key, r.*member);
  o.integer("dynamic_phases", static_cast<long long>(r.dynamic_phases));
  o.number("ageing_time_s", r.ageing_time);
  if (r.kind == "load_test") {
    o.number("capacity_N", r.capacity);
    o.number("shaft_at_capacity_N", r.shaft_at_capacity);
    o.number("base_at_capacity_N", r.base_at_capacity);
    o.number("displacement_at_capacity_m", r.displacement_at_capacity);
  }
  o.string("warning", r.warning);
  return o;
}

JsonObject loaded_share_json(const Simulation& sim, const Crusher& crusher) {
  JsonObject o;
  for (const char* ratio : {"0.5", "0.6", "0.7", "0.72", "0.75", "0.8", "0.9"}) {
    o.number(ratio, crusher.loaded_share(sim, std::stod(ratio)));
  }
  return o;
}

JsonObject sample_json(const Simulation& sim, const SampleConfig& cfg,
                       const PreparationController& prep) {
  const std::vector<double> d = sim.particles().diameters();
  JsonObject so;
  so.integer("grains", static_cast<long long>(sim.particles().size()));
  so.number("void_ratio", prep.void_ratio());
  so.number("void_ratio_target", cfg.void_ratio);
  so.number("preparation_friction", prep.preparation_friction());
  so.number("side_m", std::cbrt(sim.walls().volume()));
  so.number("d50_m", diameter_at_fraction(d, 0.5));
  so.numbers("sieve_m", cfg.grading.diameter);
  so.numbers("passing_target", cfg.grading.passing);
  so.numbers("passing", mass_passing(d, cfg.grading.diameter));
  so.string("warning", prep.warning());
  return so;
}

namespace {

JsonObject crushing_json(const Simulation& sim, const Crusher& crusher) {
  JsonObject co;
  co.number("d50_initial_m", crusher.d50_initial());
  co.number("d0_m", crusher.d0());
  co.number("d_c_m", crusher.d_c());
  co.number("pattern_retained_volume_fraction", crusher.pattern().retained_volume_fraction());
  co.integer("pattern_fragments", static_cast<long long>(crusher.pattern().size()));
  for (auto& [k, v] : crushing_measurements(sim, crusher)) co.number(k, v);
  // The solid mass balance from volumes and the material density (with density scaling the
  // stored masses of small fragments are not their solid masses): initial = retained +
  // removed, up to rounding.
  const double rho = sim.config().material.density;
  double initial_volume = 0.0;
  for (double d : crusher.initial_diameters()) initial_volume += kPi / 6.0 * d * d * d;
  const double retained_volume = sim.particles().solid_volume();
  const double removed_volume = crusher.removed_volume();
  co.number("solid_density_kg_m3", rho);
  co.number("initial_solid_mass_kg", rho * initial_volume);
  co.number("retained_solid_mass_kg", rho * retained_volume);
  co.number("removed_solid_mass_kg", rho * removed_volume);
  co.number("mass_balance_relative_error",
            initial_volume > 0.0
                ? (initial_volume - retained_volume - removed_volume) / initial_volume
                : 0.0);
  return co;
}

}  // namespace

JsonObject summary_json(const RunPosition& position, const Simulation& sim, std::size_t snapshots,
                        const Crusher* crusher, const std::string& branch_json) {
  JsonObject summary;
  summary.string("crushdem_version", CRUSHDEM_VERSION);
  summary.string("crushdem_commit", build_commit());
  // Every build that ran it: more than one when it was resumed or branched by another.
  if (!position.builds.empty()) summary.strings("crushdem_builds", position.builds);
  if (position.has_sample_json) summary.object("sample", position.sample_json);
  if (!branch_json.empty()) {
    std::string b = branch_json;
    while (!b.empty() && (b.back() == '\n' || b.back() == ' ')) b.pop_back();
    summary.fields.emplace_back("branched_from", b);
  }
  summary.integer("steps", static_cast<long long>(sim.step_count()));
  summary.number("time_s", sim.time());
  summary.integer("particles", static_cast<long long>(sim.particles().size()));
  summary.integer("snapshots", static_cast<long long>(snapshots));
  if (!position.stage_results.empty()) summary.array("stages", position.stage_results);
  summary.integer("warnings", static_cast<long long>(position.warnings.size()));
  if (crusher) summary.object("crushing", crushing_json(sim, *crusher));
  JsonObject final_state;
  for (const auto& [k, v] : measure(sim, position.ref)) final_state.number(k, v);
  summary.object("final", final_state);
  return summary;
}

std::pair<std::size_t, double> write_timing(const std::string& path, const std::string& backend,
                                            bool finished, bool resumed, double seconds,
                                            double particle_steps, Simulation& sim) {
  JsonObject timing;
  timing.string("backend", backend);
  timing.boolean("finished", finished);
  timing.number("wall_seconds", seconds);
  timing.boolean("resumed", resumed);
#ifdef CRUSHDEM_HAVE_OPENMP
  timing.integer("threads", omp_get_max_threads());
#else
  timing.integer("threads", 1);
#endif
  timing.integer("steps", static_cast<long long>(sim.step_count()));
  // Particles times steps summed over the steps (the count changes as grains break).
  timing.number("particle_steps_per_second", seconds > 0 ? particle_steps / seconds : 0.0);
  timing.integer("neighbor_builds", static_cast<long long>(sim.neighbors().builds()));
  const std::array<double, PartClock::kParts> parts = sim.part_clock().seconds();
  JsonObject by_part;
  std::size_t dominant = 0;
  for (std::size_t k = 0; k < PartClock::kParts; ++k) {
    by_part.number(std::string(kPartNames[k]), parts[k]);
    if (parts[k] > parts[dominant]) dominant = k;
  }
  timing.object("seconds_by_part", by_part);
  timing.string("dominant_part", std::string(kPartNames[dominant]));
  write_text_file(path, timing.dump() + "\n");
  return {dominant, seconds > 0.0 ? parts[dominant] / seconds : 0.0};
}

}  // namespace crushdem

#include "crushdem/io/runner.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "crushdem/core/error.hpp"
#include "crushdem/core/random.hpp"
#include "crushdem/experiments/measurements.hpp"
#include "crushdem/io/output.hpp"
#include "crushdem/io/packing.hpp"
#include "crushdem/particles/generate.hpp"

#ifdef CRUSHDEM_HAVE_OPENMP
#include <omp.h>
#endif

namespace crushdem {

void add_packing_particles(Simulation& sim, const Packing& pk) {
  for (const PackingRow& r : pk.rows) {
    NewParticle np;
    np.position = r.position;
    np.radius = 0.5 * r.diameter;
    np.density = sim.config().material.density;
    sim.particles().insert_with_id(r.id, np);
  }
  sim.invalidate();
}

void add_configured_particles(Simulation& sim, const RunConfig& cfg) {
  const auto box = cfg.box();
  if (!cfg.particles.file.empty()) {
    const Packing pk = read_packing(cfg.particles.file);
    for (const PackingRow& r : pk.rows) {
      const double rad = 0.5 * r.diameter;
      const double c[3] = {r.position.x, r.position.y, r.position.z};
      for (int a = 0; a < 3; ++a) {
        // The centre must lie inside the box (grains may overlap a wall: samples prepared
        // under stress do); the grain must fit between the walls.
        const double lo = box[static_cast<std::size_t>(2 * a)];
        const double hi = box[static_cast<std::size_t>(2 * a + 1)];
        const char axis = static_cast<char>('x' + a);
        if (!(c[a] > lo && c[a] < hi)) {
          throw ConfigError(cfg.particles.file + ": particle id " + std::to_string(r.id) + " has " +
                            axis + " = " + show_number(c[a]) +
                            " m: expected a centre inside the box [" + show_number(lo) + ", " +
                            show_number(hi) + "] given by [box]");
        }
        if (2.0 * rad > hi - lo) {
          throw ConfigError(cfg.particles.file + ": particle id " + std::to_string(r.id) +
                            " (diameter " + show_number(r.diameter) +
                            " m) is wider than the box along " + axis);
        }
      }
    }
    add_packing_particles(sim, pk);
    return;
  }
  const GenerateConfig& g = cfg.particles.generate;
  RandomStream rng(g.seed, 0xD1A);
  std::vector<double> radii(g.count);
  for (double& r : radii) r = 0.5 * rng.uniform(g.diameter_min, g.diameter_max);
  for (const PlacedSphere& s : random_sequential_addition(radii, box, g.seed)) {
    sim.add_particle(s.position, s.radius);
  }
}

namespace {

std::string stamp(std::size_t k) {
  char b[16];
  std::snprintf(b, sizeof b, "%06zu", k);
  return b;
}

}  // namespace

RunSummary run_to_directory(const RunConfig& cfg, const RunOptions& opt) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(fs::path(opt.out_dir) / "vtk", ec);
  if (ec)
    throw ConfigError("--out '" + opt.out_dir + "': cannot create directory: " + ec.message());
  write_text_file((fs::path(opt.out_dir) / "config.toml").string(), toml::serialize(to_toml(cfg)));

  Simulation sim(cfg.simulation);
  add_configured_particles(sim, cfg);
  sim.compute_forces();
  const StrainReference ref = StrainReference::from(sim.walls());
  CsvWriter series((fs::path(opt.out_dir) / "timeseries.csv").string());
  std::size_t snapshots = 0;
  auto snapshot = [&]() {
    const std::string k = stamp(snapshots++);
    write_vtk_particles((fs::path(opt.out_dir) / "vtk" / ("particles_" + k + ".vtk")).string(),
                        sim.particles(), sim.resultant_force(0), sim.resultant_force(1),
                        sim.resultant_force(2));
    double b[6];
    for (int w = 0; w < kNumWalls; ++w) b[w] = sim.walls().position(w);
    write_vtk_box((fs::path(opt.out_dir) / "vtk" / ("box_" + k + ".vtk")).string(), b);
  };
  series.write(measure(sim, ref));
  snapshot();

  using clock = std::chrono::steady_clock;
  const auto t0 = clock::now();
  auto last_progress = t0;
  auto done = [&]() {
    return cfg.steps > 0 ? sim.step_count() >= cfg.steps : sim.time() >= cfg.duration;
  };
  bool last_row_written = true;
  // Steps are taken in chunks that end exactly on the output points (the same steps as one at a
  // time, so the results do not depend on the chunking); a backend may take a chunk at once.
  while (!done()) {
    const std::uint64_t s0 = sim.step_count();
    std::uint64_t n = cfg.output.interval - s0 % cfg.output.interval;
    if (cfg.output.vtk_interval > 0) {
      n = std::min(n, cfg.output.vtk_interval - s0 % cfg.output.vtk_interval);
    }
    if (cfg.steps > 0) {
      n = std::min(n, cfg.steps - s0);
    } else {
      const double h = sim.dt();
      const double left = std::ceil((cfg.duration - sim.time()) / h);
      n = std::min(n, static_cast<std::uint64_t>(std::max(1.0, left)));
    }
    if (opt.advance) {
      opt.advance(sim, n);
    } else {
      sim.step(n);
    }
    if (opt.sync) opt.sync(sim);
    last_row_written = false;
    const std::uint64_t s = sim.step_count();
    if (s % cfg.output.interval == 0 || done()) {
      series.write(measure(sim, ref));
      last_row_written = true;
    }
    if (cfg.output.vtk_interval > 0 && s % cfg.output.vtk_interval == 0 && !done()) snapshot();
    if (opt.progress && cfg.output.progress_seconds > 0) {
      const auto now = clock::now();
      if (std::chrono::duration<double>(now - last_progress).count() >=
          cfg.output.progress_seconds) {
        last_progress = now;
        const double frac = cfg.steps > 0 ? static_cast<double>(s) / static_cast<double>(cfg.steps)
                                          : sim.time() / cfg.duration;
        const double el = std::chrono::duration<double>(now - t0).count();
        std::fprintf(
            stderr,
            "[crushdem] step %llu  t = %.4e s  (%.1f %%)  sigma_zz(wall) = %.4g MPa  ETA %.0f s\n",
            static_cast<unsigned long long>(s), sim.time(), 100.0 * frac,
            0.5e-6 * (sim.walls().stress(4) + sim.walls().stress(5)),
            frac > 0 ? el * (1.0 - frac) / frac : 0.0);
      }
    }
  }
  if (!last_row_written) series.write(measure(sim, ref));
  snapshot();
  const double secs = std::chrono::duration<double>(clock::now() - t0).count();

  JsonObject summary;
  summary.string("crushdem_version", "0.1.0");
  summary.integer("steps", static_cast<long long>(sim.step_count()));
  summary.number("time_s", sim.time());
  summary.integer("particles", static_cast<long long>(sim.particles().size()));
  summary.integer("snapshots", static_cast<long long>(snapshots));
  JsonObject final_state;
  for (const auto& [k, v] : measure(sim, ref)) final_state.number(k, v);
  summary.object("final", final_state);
  write_text_file((fs::path(opt.out_dir) / "summary.json").string(), summary.dump() + "\n");

  JsonObject timing;
  timing.string("backend", opt.backend);
  timing.number("wall_seconds", secs);
#ifdef CRUSHDEM_HAVE_OPENMP
  timing.integer("threads", omp_get_max_threads());
#else
  timing.integer("threads", 1);
#endif
  timing.number("particle_steps_per_second", secs > 0
                                                 ? static_cast<double>(sim.particles().size()) *
                                                       static_cast<double>(sim.step_count()) / secs
                                                 : 0.0);
  timing.integer("neighbor_builds", static_cast<long long>(sim.neighbors().builds()));
  write_text_file((fs::path(opt.out_dir) / "timing.json").string(), timing.dump() + "\n");

  RunSummary r;
  r.steps = sim.step_count();
  r.time = sim.time();
  r.wall_seconds = secs;
  r.particles = sim.particles().size();
  return r;
}

}  // namespace crushdem

#include "crushdem/io/runner.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>

#include "crushdem/core/error.hpp"
#include "crushdem/core/random.hpp"
#include "crushdem/experiments/measurements.hpp"
#include "crushdem/experiments/protocol.hpp"
#include "crushdem/fracture/crushing.hpp"
#include "crushdem/io/output.hpp"
#include "crushdem/io/packing.hpp"
#include "crushdem/particles/generate.hpp"
#include "crushdem/particles/grading.hpp"

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

/// The plain [run]: the walls as configured, for a number of steps or a duration.
class FixedLengthController final : public Controller {
 public:
  FixedLengthController(std::uint64_t steps, double duration)
      : steps_(steps), duration_(duration) {}
  void begin(Simulation& sim) override {
    start_step_ = sim.step_count();
    start_time_ = sim.time();
  }
  bool update(Simulation& sim) override {
    return steps_ > 0 ? sim.step_count() - start_step_ >= steps_
                      : sim.time() - start_time_ >= duration_;
  }
  std::uint64_t steps_to_check(Simulation& sim) override {
    if (steps_ > 0) return std::max<std::uint64_t>(1, steps_ - (sim.step_count() - start_step_));
    const double left = std::ceil((start_time_ + duration_ - sim.time()) / sim.dt());
    return static_cast<std::uint64_t>(std::max(1.0, left));
  }
  Measurement columns(const Simulation&) const override { return {}; }
  double fraction(const Simulation& sim) const {
    return steps_ > 0
               ? static_cast<double>(sim.step_count() - start_step_) / static_cast<double>(steps_)
               : (sim.time() - start_time_) / duration_;
  }

 private:
  std::uint64_t steps_;
  double duration_;
  std::uint64_t start_step_ = 0;
  double start_time_ = 0.0;
};

/// Steps a simulation under one controller after another, in chunks that end exactly on the
/// output points and the controller's checks (the same steps as one at a time, so results do not
/// depend on the chunking or on the backend taking a chunk at once).
class Driver {
 public:
  Driver(Simulation& sim, const RunConfig& cfg, const RunOptions& opt)
      : sim_(sim), cfg_(cfg), opt_(opt), dir_(opt.out_dir), t0_(clock::now()), last_(t0_) {}

  void snapshot() {
    const std::string k = stamp(snapshots_++);
    write_vtk_particles((dir_ / "vtk" / ("particles_" + k + ".vtk")).string(), sim_.particles(),
                        sim_.resultant_force(0), sim_.resultant_force(1), sim_.resultant_force(2));
    double b[6];
    for (int w = 0; w < kNumWalls; ++w) b[w] = sim_.walls().position(w);
    write_vtk_box((dir_ / "vtk" / ("box_" + k + ".vtk")).string(), b);
  }

  /// Grains break from now on: the criterion is checked every crushing.interval steps (counted
  /// from step 0) and every breakage is appended to breakage.csv.
  void attach_crusher(Crusher* crusher) {
    crusher_ = crusher;
    const std::string path = (dir_ / "breakage.csv").string();
    log_ = std::fopen(path.c_str(), "w");
    if (!log_) throw ConfigError("cannot write '" + path + "'");
    std::fprintf(log_,
                 "time_s,step,id,diameter_m,cause,sigma_Pa,sigma_lim_Pa,fragments,"
                 "removed_fragments,fragment_ids\n");
    std::fflush(log_);
  }
  ~Driver() {
    if (log_) std::fclose(log_);
  }
  Driver(const Driver&) = delete;
  Driver& operator=(const Driver&) = delete;

  /// Runs `c` to its end; `row` gives the time-series row (written at the start, every output
  /// interval and at the end).
  void drive(Controller& c, CsvWriter& csv, const std::function<Measurement()>& row,
             const std::string& label, const std::function<double()>& fraction = {}) {
    c.begin(sim_);
    csv.write(row());
    bool finished = false;
    std::uint64_t to_check = c.steps_to_check(sim_);
    const std::uint64_t interval = cfg_.output.interval, vtk = cfg_.output.vtk_interval;
    while (!finished) {
      const std::uint64_t s0 = sim_.step_count();
      std::uint64_t n = std::min(interval - s0 % interval, to_check);
      if (vtk > 0) n = std::min(n, vtk - s0 % vtk);
      if (crusher_) {
        const std::uint64_t k = crusher_->config().interval;
        n = std::min(n, k - s0 % k);
      }
      if (opt_.advance) {
        opt_.advance(sim_, n);
      } else {
        sim_.step(n);
      }
      if (opt_.sync) opt_.sync(sim_);
      to_check -= n;
      const std::uint64_t s = sim_.step_count();
      if (crusher_ && s % crusher_->config().interval == 0) {
        const std::vector<BreakageEvent> events = crusher_->apply(sim_);
        log(events);
        // Outputs and checks at this step read forces: evaluate them for the new grains (what
        // the next step would do first anyway, with no tangential increment).
        if (!events.empty()) sim_.compute_forces();
      }
      if (to_check == 0) {
        finished = c.update(sim_);
        if (!finished) to_check = c.steps_to_check(sim_);
      }
      if (s % interval == 0 || finished) csv.write(row());
      if (vtk > 0 && s % vtk == 0 && !finished) snapshot();  // the final one follows the run
      progress(label, fraction);
    }
  }

  double seconds() const { return std::chrono::duration<double>(clock::now() - t0_).count(); }
  std::size_t snapshots() const { return snapshots_; }

 private:
  using clock = std::chrono::steady_clock;
  void progress(const std::string& label, const std::function<double()>& fraction) {
    if (!opt_.progress || !(cfg_.output.progress_seconds > 0)) return;
    const auto now = clock::now();
    if (std::chrono::duration<double>(now - last_).count() < cfg_.output.progress_seconds) return;
    last_ = now;
    const Walls& w = sim_.walls();
    const double sz = w.axial_stress(), sr = w.lateral_stress();
    std::fprintf(stderr,
                 "[crushdem] %s  step %llu  t = %.4e s  sigma_z = %.4g MPa  sigma_r = %.4g MPa  "
                 "q = %.4g MPa",
                 label.c_str(), static_cast<unsigned long long>(sim_.step_count()), sim_.time(),
                 1e-6 * sz, 1e-6 * sr, 1e-6 * (sz - sr));
    if (fraction) {
      const double f = fraction();
      const double el = std::chrono::duration<double>(now - t0_).count();
      std::fprintf(stderr, "  (%.1f %%, ETA %.0f s)", 100.0 * f, f > 0 ? el * (1 - f) / f : 0.0);
    }
    std::fprintf(stderr, "\n");
  }

  void log(const std::vector<BreakageEvent>& events) {
    for (const BreakageEvent& e : events) {
      std::fprintf(log_, "%s,%llu,%llu,%s,%s,%s,%s,%zu,%d,", format_double(e.time).c_str(),
                   static_cast<unsigned long long>(e.step), static_cast<unsigned long long>(e.id),
                   format_double(e.diameter).c_str(), to_string(e.cause),
                   format_double(e.sigma).c_str(), format_double(e.sigma_lim).c_str(),
                   e.fragments.size(), e.removed_fragments);
      for (std::size_t k = 0; k < e.fragments.size(); ++k) {
        std::fprintf(log_, "%s%llu", k ? " " : "", static_cast<unsigned long long>(e.fragments[k]));
      }
      std::fprintf(log_, "\n");
    }
    if (!events.empty()) std::fflush(log_);  // finished work is on disk
  }

  Simulation& sim_;
  const RunConfig& cfg_;
  const RunOptions& opt_;
  Crusher* crusher_ = nullptr;
  std::FILE* log_ = nullptr;
  std::filesystem::path dir_;
  std::size_t snapshots_ = 0;
  clock::time_point t0_, last_;
};

JsonObject stage_json(const StageResult& r) {
  JsonObject o;
  o.string("name", r.name);
  o.string("type", r.kind);
  o.string("end", r.end_reason);
  o.integer("steps", static_cast<long long>(r.steps));
  o.number("q_max_Pa", r.q_max);
  o.number("axial_strain_at_q_max", r.axial_strain_at_q_max);
  o.number("sigma_3_at_q_max_Pa", r.sigma_3_at_q_max);
  o.number("friction_angle_peak_deg", r.friction_angle_deg);
  o.number("K0_end", r.K0);
  o.number("max_inertial_number", r.max_inertial_number);
  o.number("max_lateral_stress_error", r.max_lateral_stress_error);
  o.number("max_lateral_strain", r.max_lateral_strain);
  o.integer("dynamic_phases", static_cast<long long>(r.dynamic_phases));
  o.number("ageing_time_s", r.ageing_time);
  o.string("warning", r.warning);
  return o;
}

}  // namespace

RunSummary run_to_directory(const RunConfig& cfg, const RunOptions& opt) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path dir(opt.out_dir);
  fs::create_directories(dir / "vtk", ec);
  if (ec)
    throw ConfigError("--out '" + opt.out_dir + "': cannot create directory: " + ec.message());
  write_text_file((dir / "config.toml").string(), toml::serialize(to_toml(cfg)));

  JsonObject summary;
  summary.string("crushdem_version", "0.1.0");
  std::vector<std::string> warnings;

  // The sample: prepared here from a grading curve, or read / generated as configured.
  SimulationConfig sim_cfg = cfg.simulation;
  LooseCloud cloud;
  if (cfg.has_sample) {
    cloud = make_loose_cloud(cfg.sample);
    for (int a = 0; a < 3; ++a) {
      sim_cfg.walls[static_cast<std::size_t>(2 * a)].position = 0.0;
      sim_cfg.walls[static_cast<std::size_t>(2 * a + 1)].position = cloud.side;
    }
  }
  Simulation sim(sim_cfg);
  Driver driver(sim, cfg, opt);
  if (cfg.has_sample) {
    for (std::size_t i = 0; i < cloud.radius.size(); ++i) {
      sim.add_particle(cloud.position[i], cloud.radius[i]);
    }
    sim.compute_forces();
    driver.snapshot();
    PreparationController prep(cfg.sample, cfg.simulation.material.friction);
    const StrainReference ref0 = StrainReference::from(sim.walls());
    CsvWriter csv((dir / (cfg.stages.empty() ? "timeseries.csv" : "preparation.csv")).string());
    driver.drive(
        prep, csv,
        [&]() {
          Measurement m = measure(sim, ref0);
          for (auto& kv : prep.columns(sim)) m.push_back(kv);
          return m;
        },
        "prepare");
    // The sample file: grains and the box, reusable as particles.file by any test.
    Packing pk;
    for (int k = 0; k < kNumWalls; ++k) {
      pk.header[std::string("box_") + wall_name(k)] = format_double(sim.walls().position(k));
    }
    pk.header["void_ratio"] = format_double(prep.void_ratio());
    pk.header["preparation_friction"] = format_double(prep.preparation_friction());
    pk.header["stress_Pa"] = format_double(cfg.sample.stress);
    pk.header["seed"] = std::to_string(cfg.sample.seed);
    const ParticleStore& p = sim.particles();
    for (std::size_t i = 0; i < p.size(); ++i) {
      pk.rows.push_back({p.id[i], {p.x[i], p.y[i], p.z[i]}, 2.0 * p.radius[i]});
    }
    write_packing((dir / "sample.txt").string(), pk);

    const std::vector<double> d = p.diameters();
    JsonObject so;
    so.integer("grains", static_cast<long long>(p.size()));
    so.number("void_ratio", prep.void_ratio());
    so.number("void_ratio_target", cfg.sample.void_ratio);
    so.number("preparation_friction", prep.preparation_friction());
    so.number("side_m", std::cbrt(sim.walls().volume()));
    so.number("d50_m", diameter_at_fraction(d, 0.5));
    so.numbers("sieve_m", cfg.sample.grading.diameter);
    so.numbers("passing_target", cfg.sample.grading.passing);
    so.numbers("passing", mass_passing(d, cfg.sample.grading.diameter));
    so.string("warning", prep.warning());
    summary.object("sample", so);
    if (!prep.warning().empty()) {
      warnings.push_back(prep.warning());
      std::fprintf(stderr, "[crushdem] warning: %s\n", prep.warning().c_str());
    }
    if (opt.progress) {
      std::fprintf(stderr,
                   "[crushdem] sample: %zu grains, e = %.4f (target %.4f), preparation friction "
                   "%.4g\n",
                   p.size(), prep.void_ratio(), cfg.sample.void_ratio, prep.preparation_friction());
    }
  } else {
    add_configured_particles(sim, cfg);
    sim.compute_forces();
    driver.snapshot();
  }

  // Crushing acts during the test (not during preparation).
  std::unique_ptr<Crusher> crusher;
  std::unique_ptr<CsvWriter> grading;
  std::vector<double> sieves;
  if (cfg.crushing.enabled) {
    crusher = std::make_unique<Crusher>(
        cfg.crushing, cfg.crushing.pattern.empty() ? SplitPattern::default14()
                                                   : SplitPattern::from_file(cfg.crushing.pattern));
    crusher->begin(sim);
    driver.attach_crusher(crusher.get());
    sieves = grading_sieves(*crusher);
    grading = std::make_unique<CsvWriter>((dir / "grading.csv").string());
  }
  // Every time-series row: the crushing columns and a grading row when grains can break.
  auto crushing_row = [&](Measurement& m) {
    if (!crusher) return;
    for (auto& kv : crushing_measurements(sim, *crusher)) m.push_back(kv);
    grading->write(grading_measurements(sim, *crusher, sieves));
  };

  // The test: a plain run, or stage after stage.
  const StrainReference ref = StrainReference::from(sim.walls());
  const double d50 = diameter_at_fraction(sim.particles().diameters(), 0.5);
  std::vector<JsonObject> stage_results;
  if (!cfg.stages.empty()) {
    CsvWriter series((dir / "timeseries.csv").string());
    std::unique_ptr<CsvWriter> events;  // one row per dynamic phase of "age" stages
    for (std::size_t k = 0; k < cfg.stages.size(); ++k) {
      StageController stage(cfg.stages[k], d50, crusher.get());
      if (cfg.stages[k].kind == StageKind::Age) {
        if (!events) events = std::make_unique<CsvWriter>((dir / "events.csv").string());
        stage.on_dynamic_phase_end = [&, k](const Simulation& s, double t_age,
                                            std::uint64_t phase) {
          Measurement m;
          m.emplace_back("ageing_time_s", t_age);
          m.emplace_back("stage", static_cast<double>(k));
          m.emplace_back("dynamic_phase", static_cast<double>(phase));
          for (auto& kv : measure(s, ref)) m.push_back(kv);
          for (auto& kv : crushing_measurements(s, *crusher)) m.push_back(kv);
          events->write(m);
        };
      }
      driver.drive(
          stage, series,
          [&]() {
            stage.observe(sim);
            Measurement m = measure(sim, ref);
            m.emplace_back("stage", static_cast<double>(k));
            for (auto& kv : stage.columns(sim)) m.push_back(kv);
            crushing_row(m);
            return m;
          },
          cfg.stages[k].label());
      stage_results.push_back(stage_json(stage.result()));
      if (!stage.result().warning.empty()) warnings.push_back(stage.result().warning);
      if (opt.progress) {
        std::fprintf(stderr, "[crushdem] stage '%s' ended (%s) after %llu steps\n",
                     stage.result().name.c_str(), stage.result().end_reason.c_str(),
                     static_cast<unsigned long long>(stage.result().steps));
      }
    }
  } else if (!cfg.has_sample) {
    CsvWriter series((dir / "timeseries.csv").string());
    FixedLengthController run(cfg.steps, cfg.duration);
    driver.drive(
        run, series,
        [&]() {
          Measurement m = measure(sim, ref);
          crushing_row(m);
          return m;
        },
        "run", [&]() { return run.fraction(sim); });
  }
  driver.snapshot();
  const double secs = driver.seconds();

  summary.integer("steps", static_cast<long long>(sim.step_count()));
  summary.number("time_s", sim.time());
  summary.integer("particles", static_cast<long long>(sim.particles().size()));
  summary.integer("snapshots", static_cast<long long>(driver.snapshots()));
  if (!stage_results.empty()) summary.array("stages", stage_results);
  summary.integer("warnings", static_cast<long long>(warnings.size()));
  if (crusher) {
    JsonObject co;
    co.number("d50_initial_m", crusher->d50_initial());
    co.number("d0_m", crusher->d0());
    co.number("d_c_m", crusher->d_c());
    co.number("pattern_retained_volume_fraction", crusher->pattern().retained_volume_fraction());
    co.integer("pattern_fragments", static_cast<long long>(crusher->pattern().size()));
    for (auto& [k, v] : crushing_measurements(sim, *crusher)) co.number(k, v);
    summary.object("crushing", co);
  }
  JsonObject final_state;
  for (const auto& [k, v] : measure(sim, ref)) final_state.number(k, v);
  summary.object("final", final_state);
  write_text_file((dir / "summary.json").string(), summary.dump() + "\n");

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
  write_text_file((dir / "timing.json").string(), timing.dump() + "\n");

  RunSummary r;
  r.steps = sim.step_count();
  r.time = sim.time();
  r.wall_seconds = secs;
  r.particles = sim.particles().size();
  return r;
}

}  // namespace crushdem

#include "crushdem/run/runner.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <memory>

#include "crushdem/core/deterministic.hpp"
#include "crushdem/core/error.hpp"
#include "crushdem/core/random.hpp"
#include "crushdem/experiments/measurements.hpp"
#include "crushdem/experiments/protocol.hpp"
#include "crushdem/experiments/stages.hpp"
#include "crushdem/fracture/crushing.hpp"
#include "crushdem/io/output.hpp"
#include "crushdem/particles/generate.hpp"
#include "crushdem/particles/grading.hpp"
#include "crushdem/run/checkpoint.hpp"
#include "crushdem/run/driver.hpp"
#include "crushdem/run/results.hpp"
#include "crushdem/run/run_directory.hpp"
#include "crushdem/walls/body_probe.hpp"

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

namespace fs = std::filesystem;

// A sample prepared here starts as a loose cloud (`cloud`; null when resumed) in a cube of its
// own size; a cylindrical one in its chamber about the z axis, between the box's z walls (the
// box's side walls stand half a diameter clear of it).
SimulationConfig starting_simulation(const RunConfig& cfg, const LooseCloud* cloud) {
  SimulationConfig sim_cfg = cfg.simulation;
  const bool cylinder = cfg.has_sample && cfg.sample.shape == SampleShape::Cylinder;
  if (cfg.has_sample && cloud != nullptr) {
    for (int a = 0; a < 3; ++a) {
      const bool side = cylinder && a < 2;
      sim_cfg.walls[static_cast<std::size_t>(2 * a)].position = side ? -cloud->side : 0.0;
      sim_cfg.walls[static_cast<std::size_t>(2 * a + 1)].position = side    ? cloud->side
                                                                    : a < 2 ? cloud->side
                                                                            : cloud->height;
    }
  }
  // The chamber's bodies (its place, when resumed, is in the state); a file's stands about the
  // file's box, at the radius it was prepared to.
  std::vector<BodyConfig> chamber;
  if (cylinder) {
    chamber =
        chamber_sample_bodies(cloud != nullptr ? *cloud : make_loose_cloud(cfg.sample, false), 0.0);
  } else if (cfg.file_chamber_radius > 0.0) {
    chamber = file_chamber_bodies(cfg.file_chamber_radius, cfg.file_sector,
                                  sim_cfg.walls[4].position, sim_cfg.walls[5].position);
  }
  for (const BodyConfig& b : chamber) sim_cfg.bodies.push_back(b);
  return sim_cfg;
}

// The grains a new run starts from, the sample's loose cloud or the configured ones, checked
// clear of the bodies (the chamber of a sample file holds its grains, so only the configured
// bodies are checked there).
void add_starting_grains(Simulation& sim, const RunConfig& cfg, const LooseCloud& cloud) {
  std::vector<std::string> driven;  // the bodies the stages move
  for (const StageConfig& s : cfg.stages) {
    if (!s.body.empty()) driven.push_back(s.body);
  }
  if (cfg.has_sample) {
    for (std::size_t i = 0; i < cloud.radius.size(); ++i) {
      sim.add_particle(cloud.position[i], cloud.radius[i]);
    }
    check_bodies_clear(sim.walls(), sim.particles(), -1, driven);
  } else {
    add_configured_particles(sim, cfg);
    check_bodies_clear(sim.walls(), sim.particles(), static_cast<int>(cfg.simulation.bodies.size()),
                       driven);
  }
}

void create_directory(const fs::path& dir, const std::string& out) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw ConfigError("--out '" + out + "': cannot create directory: " + ec.message());
}

/// The run's result files as its stages see them (Stage::attach).
class RunFiles final : public StageOutputs {
 public:
  RunFiles(Driver& driver, const StrainReference& ref, const Crusher* crusher)
      : driver_(driver), ref_(ref), crusher_(crusher) {}
  void write(const std::string& file, const Measurement& row) override {
    driver_.file(file).write(row);
  }
  Measurement measure(const Simulation& sim) const override {
    Measurement m = crushdem::measure(sim, ref_);
    if (crusher_) {
      for (auto& kv : crushing_measurements(sim, *crusher_)) m.push_back(kv);
    }
    return m;
  }
  void request_checkpoint() override { driver_.request_checkpoint(); }
  void set_ageing_clock(double ageing_time) override { driver_.set_ageing_clock(ageing_time); }
  void snapshot() override { driver_.snapshot(); }

 private:
  Driver& driver_;
  const StrainReference& ref_;
  const Crusher* crusher_;
};

/// One run, from its directory to its summary: open (directory, lock, a saved state to continue
/// from), prepare (the sample or the configured grains), test (stage after stage, or a plain
/// [run]), finish (summary.json, timing.json). Each part starts from the checkpoint when the run
/// resumes inside it.
class Run {
 public:
  Run(const RunConfig& cfg, const RunOptions& opt)
      : cfg_(upscaled(cfg)),
        opt_(opt),
        dir_(opt.out_dir),
        stepper_(make_stepper(opt.backend)),
        branch_(checked_branch(cfg_, opt)),
        lock_(open_directory(opt)),
        manifest_(dir_),
        config_text_(toml::serialize(to_toml(cfg))),
        branching_(!opt.branch_dir.empty()),
        resumed_(opt.resume || branching_),
        from_(branching_ ? fs::absolute(opt.branch_dir) : fs::path()) {}

  RunSummary execute() {
    // A resume writes nothing before its checkpoint is found good (a finished or foreign folder
    // gets no manifest); one in a folder of a release before manifests adopts the files a run
    // writes there.
    if (opt_.resume) {
      try {
        read_saved_position();
      } catch (const std::exception& e) {
        log_refused_resume(e.what());
        throw;
      }
      if (!RunManifest::present(dir_)) manifest_.adopt_earlier_run();
    }
    manifest_.add(".lock");
    manifest_.add("vtk");
    create_directory(dir_ / "vtk", opt_.out_dir);
    if (!opt_.resume) {
      // branch.json first: a branch stopped before its first checkpoint starts again as the
      // branch (resume_directory), never as a run from its own sample.
      if (branching_) write_branch_json();
      manifest_.add("config.toml");
      write_text_file((dir_ / "config.toml").string(), config_text_);
    }
    if (branching_) read_saved_position();
    make_simulation();
    const std::string build = opt_.build.empty() ? this_build() : opt_.build;
    driver_->say(std::string(opt_.resume  ? "resume"
                             : branching_ ? "branch"
                                          : "run") +
                     " with crushdem " + build + ", backend " + opt_.backend + ", " +
                     std::to_string(max_team_size()) +
                     (max_team_size() == 1 ? " thread" : " threads") +
                     (branching_ ? ", from " + from_.string() + " stage " + opt_.branch_stage
                                 : std::string()),
                 false);
    for (const std::string& line : parameter_set_report(cfg_.parameters, cfg_.simulation.contact,
                                                        cfg_.crushing, cfg_.crushing.enabled)) {
      driver_->say(line, false);
    }
    if (resumed_) {
      // Said now; recorded once this process has taken a step (take_build()), so that a state
      // it saves before stepping (a branch's first stage boundary) names only its own builds.
      std::vector<std::string> builds = pos_.builds;
      build_warning_ = note_build(builds, build, branching_ ? "branched" : "resumed");
      if (!build_warning_.empty()) driver_->say("warning: " + build_warning_);
      build_ = build;
    } else {
      pos_.builds = {build};
    }
    if (!opt_.resume) {  // a branch may change keys that warn (v0, n): its own
      for (const std::string& w : cfg_.warnings()) {
        if (std::find(pos_.warnings.begin(), pos_.warnings.end(), w) != pos_.warnings.end()) {
          continue;
        }
        pos_.warnings.push_back(w);
        driver_->say("warning: " + w);
      }
    }
    try {
      if (resumed_) restore();
      driver_->checkpoint = [this](const Controller& c, std::uint64_t to_check) {
        save_checkpoint(&c, to_check);
      };
      prepare();
      start_test();
      if (!cfg_.stages.empty()) {
        driver_->file("timeseries.csv");  // listed in every checkpoint of the test, as it began
        const std::size_t first = in_test_ ? pos_.part - kPartFirstStage : 0;
        for (std::size_t k = first; k < cfg_.stages.size(); ++k) run_stage(k);
      } else if (!cfg_.has_sample) {
        run_plain();
      }
      return finish();
    } catch (const Interrupted&) {
      throw;  // the log says so already
    } catch (const std::exception& e) {
      // The log of a run that stops on an error ends with it, for whoever reads it later.
      try {
        driver_->report_left_out_columns();
      } catch (const std::exception&) {  // (the error below is the one to report)
      }
      driver_->say(std::string("error: ") + e.what(), false);
      throw;
    }
  }

  /// Records this process's build among the run's once it has stepped (see execute()).
  void take_build() {
    if (build_.empty() || sim_->step_count() == steps_at_start_) return;
    note_build(pos_.builds, build_, "");
    if (!build_warning_.empty()) pos_.warnings.push_back(build_warning_);
    build_.clear();
  }

 private:
  static std::unique_ptr<DirectoryLock> open_directory(const RunOptions& opt) {
    clear_stop_request();
    const fs::path dir(opt.out_dir);
    create_directory(dir, opt.out_dir);
    auto lock = std::make_unique<DirectoryLock>(dir);
    if (!opt.resume) prepare_new_run_directory(dir, opt.overwrite, opt.restart);
    return lock;
  }

  // Resuming: the checkpoint says where the run stood; the state is read part by part after
  // it. A branch reads the original run's state at the start of its branch stage the same way.
  // A refused resume (a changed config.toml, a damaged checkpoint) leaves its reason in the log
  // of an unfinished run crushdem wrote there, and touches nothing else.
  void log_refused_resume(const std::string& why) const {
    const fs::path log = dir_ / "run.log";
    if (!RunManifest::present(dir_) || !fs::exists(log) || fs::exists(dir_ / "summary.json")) {
      return;
    }
    const std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(log.c_str(), "a"),
                                                            &std::fclose);
    if (f) write_log_line(f.get(), "error: resume refused: " + why);
  }

  // The saved state a branch at stage k of run `from` starts from.
  static fs::path branch_state(const fs::path& from, std::size_t k) {
    return from / "stages" / ("stage_" + std::to_string(k) + ".bin");
  }

  // A branch's stage and the saved state it starts from, checked before its folder is made or
  // cleared (the configurations key by key, the saved state's format and checksum): a refused
  // branch writes nothing and an --overwrite'd folder keeps its files. Stage 0 and no state when
  // not branching.
  struct Branch {
    std::size_t k = 0;
    OpenCheckpoint state;
  };
  static Branch checked_branch(const RunConfig& cfg, const RunOptions& opt) {
    if (opt.branch_dir.empty()) return {};
    check_branch_directories(opt.out_dir, opt.branch_dir);
    const fs::path from = fs::absolute(opt.branch_dir);
    const std::size_t k = branch_stage(read_binary_file((from / "config.toml").string()), cfg,
                                       opt.branch_stage, from);
    const fs::path state = branch_state(from, k);
    if (!fs::exists(state)) {
      throw ConfigError("--from '" + opt.branch_dir + "': no saved state at the start of stage " +
                        std::to_string(k) + " (" + state.string() +
                        "; runs keep one per stage they reached)");
    }
    return {k, open_checkpoint(state.string())};
  }

  void write_branch_json() {
    JsonObject b;
    b.string("run", from_.string());
    b.integer("stage", static_cast<long long>(branch_.k));
    manifest_.add("branch.json");
    write_text_file((dir_ / "branch.json").string(), b.dump() + "\n");
  }

  void read_saved_position() {
    const std::string path = (dir_ / "checkpoint.bin").string();
    if (!branching_ && !fs::exists(path)) {
      throw ConfigError("crushdem-sand resume: no checkpoint in '" + opt_.out_dir + "'" +
                        (fs::exists(dir_ / "summary.json") ? " (the run has finished)" : ""));
    }
    // A branch's state was read and checked before its folder was touched.
    OpenCheckpoint saved = branching_ ? std::move(branch_.state) : open_checkpoint(path);
    in_ = std::move(saved.reader);
    if (!branching_) {
      const std::string d = saved_config_difference(saved.config_text, config_text_, dir_);
      if (!d.empty()) {
        throw ConfigError("crushdem-sand resume: " + (dir_ / "config.toml").string() +
                          " differs from the configuration the checkpoint was taken with: " + d);
      }
    }
    load_state(pos_, *in_);
    if (branching_) {  // timing.json describes the branch's own work
      pos_.wall_seconds = 0.0;
      pos_.part_seconds = {};
      pos_.particle_steps = 0.0;
    }
  }

  void make_simulation() {
    if (cfg_.has_sample && !resumed_) cloud_ = make_loose_cloud(cfg_.sample);
    const SimulationConfig sim_cfg = starting_simulation(cfg_, resumed_ ? nullptr : &cloud_);
    sim_ = std::make_unique<Simulation>(sim_cfg);
    driver_ = std::make_unique<Driver>(*sim_, *stepper_, cfg_, opt_);
    driver_->manifest = &manifest_;
  }

  void make_crusher() {
    crusher_ = std::make_unique<Crusher>(cfg_.crushing,
                                         cfg_.crushing.pattern.empty()
                                             ? SplitPattern::default14()
                                             : SplitPattern::from_file(cfg_.crushing.pattern));
  }

  // The files, the simulation and the crusher from the saved state. A branch starts with the
  // original's result files as they stood at its state: each file the state lists (cut to its
  // length there by load_state), the snapshots before it, and the states of the stages before
  // it.
  void restore() {
    std::vector<std::string> copied;
    if (branching_) copied = copy_run_files(from_, dir_, manifest_);
    load_state(*driver_, *in_);
    if (branching_) {
      manifest_.add("stages");
      for (const KeptFile& k : driver_->kept_files()) {
        manifest_.add(fs::path(k.path).begin()->string());
      }
      keep_branch_files(from_, dir_, *driver_, branch_.k, copied);
    } else {
      driver_->check_kept_files();
    }
    load_state(*sim_, *in_);
    if (pos_.has_crusher) {
      make_crusher();
      load_state(*crusher_, *in_);
      driver_->attach_crusher(crusher_.get(), true);
    }
    // Timing totals go on from the checkpoint's.
    sim_->part_clock().add(pos_.part_seconds);
    driver_->add_particle_steps(pos_.particle_steps);
    char b[96];
    std::snprintf(b, sizeof b, "resuming at step %llu, t = %.6e s",
                  static_cast<unsigned long long>(sim_->step_count()), sim_->time());
    driver_->say(b);
    steps_at_start_ = sim_->step_count();
  }

  std::string timing_path() {
    manifest_.add("timing.json");
    return (dir_ / "timing.json").string();
  }

  // The whole state at this point of the run (checkpoint.bin). stage_state: the copy kept for
  // branches (stages/stage_K.bin) instead, without the wall-clock times (a branch starts its
  // own), so that it is a result like the others: the same bytes for any thread count and after
  // any resume.
  void save_checkpoint(const Controller* running, std::uint64_t to_check,
                       const std::string& stage_state = "") {
    const PartScope timed(sim_->part_clock(), Part::Output);
    driver_->report_left_out_columns();
    take_build();
    RunPosition saved = pos_;
    saved.begun = running != nullptr;
    saved.to_check = to_check;
    saved.has_crusher = crusher_ != nullptr;
    if (stage_state.empty()) {
      saved.part_seconds = sim_->part_clock().seconds();
      saved.particle_steps = driver_->particle_steps();
      saved.wall_seconds += driver_->seconds();
    } else {
      saved.part_seconds = {};
      saved.particle_steps = 0.0;
      saved.wall_seconds = 0.0;
    }
    pos_.begun = saved.begun;
    pos_.to_check = saved.to_check;
    pos_.has_crusher = saved.has_crusher;
    const std::string bytes =
        checkpoint_bytes(config_text_, saved, *driver_, *sim_, crusher_.get(), running);
    if (!stage_state.empty()) {
      write_file_atomically(stage_state, bytes);
      driver_->keep(fs::relative(stage_state, dir_).generic_string(), &bytes);
      return;
    }
    manifest_.add("checkpoint.bin");
    manifest_.add("checkpoint.bin.tmp");
    write_file_atomically((dir_ / "checkpoint.bin").string(), bytes);
    write_timing(timing_path(), opt_.backend, false, resumed_,
                 pos_.wall_seconds + driver_->seconds(), driver_->particle_steps(), *sim_);
    driver_->checkpoint_written();
  }

  // Between two parts: a checkpoint (and the state kept for branches at a stage), then stop here
  // if asked to.
  void boundary(std::uint32_t part) {
    pos_.part = part;
    save_checkpoint(nullptr, 0);
    if (part >= kPartFirstStage) {
      manifest_.add("stages");
      create_directory(dir_ / "stages", opt_.out_dir);
      save_checkpoint(
          nullptr, 0,
          (dir_ / "stages" / ("stage_" + std::to_string(part - kPartFirstStage) + ".bin"))
              .string());
    }
    if (stop_signal() != 0) {
      driver_->say("stopped by signal " + std::to_string(stop_signal()) + " between two parts; " +
                       "continue with `" + driver_->resume_command() + "`",
                   false);
      throw Interrupted(stop_signal(), opt_.out_dir, driver_->resume_command());
    }
  }

  // The controller of the part the checkpoint was taken in continues where it was.
  bool resume_here(std::uint32_t part) const { return resumed_ && pos_.begun && pos_.part == part; }

  void prepare() {
    if (cfg_.has_sample && (!resumed_ || pos_.part == kPartPreparation)) {
      prepare_sample();
    } else if (!cfg_.has_sample && !resumed_) {
      add_starting_grains(*sim_, cfg_, cloud_);
      sim_->compute_forces();
      driver_->snapshot();
    }
  }

  // The sample from a grading curve (PreparationController), then the sample file: grains and
  // the box, reusable as particles.file by any test.
  void prepare_sample() {
    Simulation& sim = *sim_;
    if (!resumed_) {
      add_starting_grains(sim, cfg_, cloud_);
      sim.compute_forces();
      // No frame of the loose cloud: the first is the prepared sample (below).
      pos_.ref0 = StrainReference::from(sim.walls());
      pos_.part = kPartPreparation;
    }
    PreparationController prep(cfg_.sample, cfg_.simulation.material.friction);
    const bool cont = resume_here(kPartPreparation);
    if (cont) load_state(prep, *in_);
    CsvWriter& csv = driver_->file(cfg_.stages.empty() ? "timeseries.csv" : "preparation.csv");
    driver_->drive(
        prep, csv,
        [&]() {
          Measurement m = measure(sim, pos_.ref0);
          for (auto& kv : prep.columns(sim)) m.push_back(kv);
          return m;
        },
        "prepare", {}, cont, pos_.to_check);
    Packing pk;
    for (int k = 0; k < kNumWalls; ++k) {
      pk.header[Packing::box_header_key(k)] = format_double(sim.walls().position(k));
    }
    if (sim.walls().chamber() >= 0) {  // its axis is the z axis
      pk.header["chamber_radius"] = format_double(sim.walls().chamber_radius());
      if (cfg_.sample.sector != 360.0) pk.header["sector"] = format_double(cfg_.sample.sector);
    }
    pk.header["void_ratio"] = format_double(prep.void_ratio());
    pk.header["preparation_friction"] = format_double(prep.preparation_friction());
    pk.header["stress_Pa"] = format_double(cfg_.sample.stress);
    pk.header["seed"] = std::to_string(cfg_.sample.seed);
    if (cfg_.upscaling.factor != 1.0) {
      pk.header[kUpscalingHeader] = format_double(cfg_.upscaling.factor);
    }
    const ParticleStore& p = sim.particles();
    for (std::size_t i = 0; i < p.size(); ++i) {
      pk.rows.push_back({p.id[i], {p.x[i], p.y[i], p.z[i]}, 2.0 * p.radius[i]});
    }
    manifest_.add("sample.txt");
    write_packing((dir_ / "sample.txt").string(), pk);
    driver_->keep("sample.txt");
    driver_->snapshot();
    pos_.sample_json = sample_json(sim, cfg_.sample, prep);
    pos_.has_sample_json = true;
    if (!prep.warning().empty()) {
      pos_.warnings.push_back(prep.warning());
      driver_->say("warning: " + prep.warning());
    }
    char b[160];
    std::snprintf(b, sizeof b,
                  "sample: %zu grains, e = %.4f (target %.4f), preparation friction %.4g", p.size(),
                  prep.void_ratio(), cfg_.sample.void_ratio, prep.preparation_friction());
    driver_->say(b);
  }

  // The test starts here: its strain reference and d50, and crushing (which acts during the
  // test, not during preparation).
  void start_test() {
    in_test_ = resumed_ && pos_.part != kPartPreparation;
    if (!in_test_) {
      warn_about_timestep();
      pos_.ref = StrainReference::from(sim_->walls());
      pos_.d50 = diameter_at_fraction(sim_->particles().diameters(), 0.5);
      if (cfg_.crushing.enabled) {
        make_crusher();
        crusher_->begin(*sim_);
        driver_->attach_crusher(crusher_.get(), false);
        // Tracking the contact loads invalidates the forces: evaluate them now (as the first
        // step would) so that the test's first row measures the contacts, not an empty list.
        sim_->compute_forces();
        warn_about_over_strength();
      }
    }
    if (crusher_) sieves_ = grading_sieves(*crusher_);
  }

  // A sample is prepared without crushing, so at a high stress some grains may start the test
  // over their strength: the first crushing check breaks them before the test has loaded them.
  void warn_about_over_strength() {
    const Crusher::OverStrength o = crusher_->over_strength(*sim_);
    if (o.grains == 0) return;
    char b[400];
    std::snprintf(
        b, sizeof b,
        "%zu grain%s of the sample %s at or over %s strength when the test starts (up "
        "to %.3g times it): the first crushing check breaks %s, before the test loads "
        "the sample (samples are prepared without crushing: docs/configuration.md [crushing])",
        o.grains, o.grains == 1 ? "" : "s", o.grains == 1 ? "is" : "are",
        o.grains == 1 ? "its" : "their", o.max_ratio, o.grains == 1 ? "it" : "them");
    pos_.warnings.emplace_back(b);
    driver_->say(std::string("warning: ") + b);
  }

  void warn_about_timestep() {
    const double dt = cfg_.simulation.timestep.dt;
    if (!(dt > 0.0)) return;
    const double automatic = sim_->automatic_dt();
    if (dt <= automatic) return;
    const std::string w = "timestep.dt = " + show_number(dt) + " s is " +
                          show_number(dt / automatic) + " times the automatic step " +
                          show_number(automatic) +
                          " s (rayleigh_fraction x the Rayleigh time, safety x sqrt(m / k)): "
                          "the run may be unstable (0 = automatic)";
    pos_.warnings.push_back(w);
    driver_->say("warning: " + w);
  }

  // Every time-series row of the test: the crushing columns and a grading row when grains can
  // break.
  void add_crushing_columns(Measurement& m) {
    if (!crusher_) return;
    for (auto& kv : crushing_measurements(*sim_, *crusher_)) m.push_back(kv);
    driver_->file("grading.csv").write(grading_measurements(*sim_, *crusher_, sieves_));
  }

  void run_stage(std::size_t k) {
    Simulation& sim = *sim_;
    const auto part = static_cast<std::uint32_t>(kPartFirstStage + k);
    const bool cont = resume_here(part);
    if (!cont) boundary(part);
    const std::unique_ptr<Stage> made = make_stage(cfg_.stages[k], pos_.d50, crusher_.get());
    Stage& stage = *made;
    RunFiles files(*driver_, pos_.ref, crusher_.get());
    stage.attach(files, k);
    // The ageing clock runs on through the age stages: theirs before this one, summed.
    double clock = 0.0;
    for (const JsonObject& r : pos_.stage_results) {
      const double t = r.number_value("ageing_time_s");
      if (std::isfinite(t)) clock += t;
    }
    stage.set_ageing_clock(clock);
    if (cont) {
      load_state(stage, *in_);
      driver_->set_ageing_clock(stage.ageing_clock_now());  // a format-6 checkpoint lacks it
    } else {
      driver_->set_ageing_clock(clock);
      driver_->snapshot();  // the stage's start (none twice: the last stage's end is the same)
    }
    driver_->drive(
        stage, driver_->file("timeseries.csv"),
        [&]() {
          stage.observe(sim);
          Measurement m = measure(sim, pos_.ref);
          m.emplace_back("stage", static_cast<double>(k));
          for (auto& kv : stage.columns(sim)) m.push_back(kv);
          add_crushing_columns(m);
          return m;
        },
        cfg_.stages[k].label(), [&]() { return stage.fraction(sim); }, cont, pos_.to_check,
        [&]() { return stage.progress_note(); });
    JsonObject result = stage_json(stage.result());
    if (crusher_) result.object("loaded_share", loaded_share_json(sim, *crusher_));
    pos_.stage_results.push_back(result);
    if (!stage.result().warning.empty()) {
      pos_.warnings.push_back(stage.result().warning);
      driver_->say("warning: stage '" + stage.result().name + "': " + stage.result().warning,
                   false);  // the stage said it on the terminal when it happened
    }
    driver_->say("stage '" + stage.result().name + "' ended (" + stage.result().end_reason +
                 ") after " + std::to_string(stage.result().steps) + " steps");
  }

  void run_plain() {
    const bool cont = resume_here(kPartRun);
    if (!cont) boundary(kPartRun);
    FixedLengthController run(cfg_.steps, cfg_.duration);
    if (cont) load_state(run, *in_);
    driver_->drive(
        run, driver_->file("timeseries.csv"),
        [&]() {
          Measurement m = measure(*sim_, pos_.ref);
          add_crushing_columns(m);
          return m;
        },
        "run", [&]() { return run.fraction(*sim_); }, cont, pos_.to_check);
  }

  RunSummary finish() {
    driver_->snapshot();
    driver_->report_left_out_columns();
    take_build();
    const double secs = pos_.wall_seconds + driver_->seconds();
    const std::string branch =
        fs::exists(dir_ / "branch.json") ? read_binary_file((dir_ / "branch.json").string()) : "";
    const JsonObject summary =
        summary_json(pos_, *sim_, driver_->snapshots(), crusher_.get(), branch);
    manifest_.add("summary.json");
    write_text_file((dir_ / "summary.json").string(), summary.dump() + "\n");
    const auto [dominant, dominant_fraction] = write_timing(
        timing_path(), opt_.backend, true, resumed_, secs, driver_->particle_steps(), *sim_);
    char b[160];
    std::snprintf(b, sizeof b, "finished: %llu steps, t = %.6e s, %.1f s of wall-clock time",
                  static_cast<unsigned long long>(sim_->step_count()), sim_->time(), secs);
    driver_->say(b, false);
    // The run is complete: its checkpoint is no longer needed.
    std::error_code ec;
    fs::remove(dir_ / "checkpoint.bin", ec);

    RunSummary r;
    r.steps = sim_->step_count();
    r.time = sim_->time();
    r.wall_seconds = secs;
    r.particles = sim_->particles().size();
    r.dominant_part = std::string(kPartNames[dominant]);
    r.dominant_fraction = dominant_fraction;
    return r;
  }

  const RunConfig cfg_;  // upscaled(): the sizes the run simulates
  const RunOptions& opt_;
  const fs::path dir_;
  std::unique_ptr<Stepper> stepper_;  // what advances the simulation (opt.backend)
  Branch branch_;  // the stage a branch starts at, its state until read (checked_branch)
  std::unique_ptr<DirectoryLock> lock_;
  RunManifest manifest_;  // read after the lock is held and an old run is cleared
  const std::string config_text_;
  const bool branching_, resumed_;
  const fs::path from_;  // the run a branch starts from
  RunPosition pos_;
  std::string build_, build_warning_;  // a resuming build not yet recorded (take_build())
  std::uint64_t steps_at_start_ = 0;   // the step this process started at
  std::unique_ptr<StateReader> in_;    // the saved state, read part by part
  LooseCloud cloud_;
  std::unique_ptr<Simulation> sim_;
  std::unique_ptr<Driver> driver_;
  std::unique_ptr<Crusher> crusher_;
  std::vector<double> sieves_;
  bool in_test_ = false;  // resumed inside the test (preparation done)
};

}  // namespace

void check_start(const RunConfig& given) {
  const RunConfig cfg = upscaled(given);
  const LooseCloud cloud = cfg.has_sample ? make_loose_cloud(cfg.sample) : LooseCloud{};
  Simulation sim(starting_simulation(cfg, &cloud));
  add_starting_grains(sim, cfg, cloud);
}

RunSummary run_to_directory(const RunConfig& cfg, const RunOptions& opt) {
  // Only a run that continues result files (a resume's, a branch's copies) has columns to keep.
  if (opt.keep_columns && !opt.resume && !opt.restart && opt.branch_dir.empty()) {
    throw ConfigError(
        "--keep-columns (keep_columns): given for a new run; it keeps the columns of the result "
        "files a run continues (a branch's, copied from its original run with --from, or a "
        "resume's)");
  }
  Run run(cfg, opt);
  return run.execute();
}

RunSummary resume_directory(const std::string& dir, const RunOptions& opt) {
  const std::string path = (fs::path(dir) / "config.toml").string();
  if (!fs::exists(path)) {
    throw ConfigError("crushdem-sand resume: '" + dir +
                      "' has no config.toml (not a crushdem run)");
  }
  const RunConfig cfg = load_saved_run_config(path);
  RunOptions o = opt;
  o.out_dir = dir;
  o.resume = true;
  const fs::path d(dir);
  if (!fs::exists(d / "checkpoint.bin") && !fs::exists(d / "summary.json")) {
    // Stopped before its first checkpoint (during sample preparation, say): nothing to continue
    // from, and nothing finished to lose, so the run starts again from its config.toml, in
    // place of the files its manifest lists (only a folder crushdem started as a run has one).
    if (!RunManifest::present(d)) {
      throw ConfigError("crushdem-sand resume: '" + dir +
                        "' has a config.toml but no checkpoint and no manifest.json, so it is not "
                        "a run crushdem started there; start one with `crushdem-sand run " +
                        path + " --out NEW_DIR`");
    }
    if (opt.progress) {
      std::fprintf(stderr, "[crushdem] %s has no checkpoint yet: starting the run again\n",
                   dir.c_str());
    }
    o.resume = false;
    o.overwrite = true;
    o.restart = true;
    if (fs::exists(d / "branch.json")) {  // a branch starts again from its state
      const std::string b = read_binary_file((d / "branch.json").string());
      const auto field = [&b](const std::string& key) {
        const std::size_t k = b.find("\"" + key + "\"");
        const std::size_t q0 = b.find_first_not_of(" :", k + key.size() + 2);
        if (k == std::string::npos || q0 == std::string::npos) return std::string();
        if (b[q0] == '"') return b.substr(q0 + 1, b.find('"', q0 + 1) - q0 - 1);
        return b.substr(q0, b.find_first_of(",}\n", q0) - q0);
      };
      o.branch_dir = field("run");
      o.branch_stage = field("stage");
    }
  }
  return run_to_directory(cfg, o);
}

}  // namespace crushdem

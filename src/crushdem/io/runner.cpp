#include "crushdem/io/runner.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <set>

#include "crushdem/core/build_info.hpp"
#include "crushdem/core/error.hpp"
#include "crushdem/core/random.hpp"
#include "crushdem/core/state_io.hpp"
#include "crushdem/experiments/measurements.hpp"
#include "crushdem/experiments/protocol.hpp"
#include "crushdem/fracture/crushing.hpp"
#include "crushdem/io/output.hpp"
#include "crushdem/io/packing.hpp"
#include "crushdem/io/vtk.hpp"
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

volatile std::sig_atomic_t g_stop_signal = 0;

std::string stamp(std::size_t k) {
  char b[24];  // any size_t
  std::snprintf(b, sizeof b, "%06zu", k);
  return b;
}

/// Snapshot file names carry the step, zero-padded so that they sort in order.
std::string step_stamp(std::uint64_t step) {
  char b[24];  // any uint64
  std::snprintf(b, sizeof b, "%010llu", static_cast<unsigned long long>(step));
  return b;
}

/// A ParaView snapshot: the step (its files' names) and the simulated time (the .pvd's).
struct Snapshot {
  std::uint64_t step = 0;
  double time = 0.0;
};
constexpr const char* kSnapshotKinds[] = {"particles", "contacts", "box"};

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
  void save_state(StateWriter& out) const override {
    out.tag("run");
    out.put(start_step_);
    out.put(start_time_);
  }
  void load_state(StateReader& in) override {
    in.tag("run");
    in.get(start_step_);
    in.get(start_time_);
  }
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

void put_json(StateWriter& out, const JsonObject& o) {
  std::vector<std::string> keys, values;
  for (const auto& [k, v] : o.fields) {
    keys.push_back(k);
    values.push_back(v);
  }
  out.put(keys);
  out.put(values);
}

JsonObject get_json(StateReader& in) {
  std::vector<std::string> keys, values;
  in.get(keys);
  in.get(values);
  JsonObject o;
  for (std::size_t k = 0; k < keys.size() && k < values.size(); ++k) {
    o.fields.emplace_back(keys[k], values[k]);
  }
  return o;
}

/// Steps a simulation under one controller after another, in chunks that end exactly on the
/// output points and the controller's checks (the same steps as one at a time, so results do not
/// depend on the chunking or on the backend taking a chunk at once). Owns the result files, so
/// that a checkpoint records how far each has been written.
class Driver {
 public:
  Driver(Simulation& sim, const RunConfig& cfg, const RunOptions& opt)
      : sim_(sim),
        cfg_(cfg),
        opt_(opt),
        dir_(opt.out_dir),
        t0_(clock::now()),
        last_(t0_),
        last_checkpoint_(t0_) {}

  /// The CSV file `name` in the output directory (opened when its first row is written).
  CsvWriter& file(const std::string& name) {
    auto& f = files_[name];
    if (!f) f = std::make_unique<CsvWriter>((dir_ / name).string());
    return *f;
  }

  /// The state as ParaView files named by step (vtk/particles_, contacts_ and box_STEP.vtp),
  /// listed with their times in vtk/particles.pvd, contacts.pvd and box.pvd.
  void snapshot() {
    const PartScope timed(sim_.part_clock(), Part::Output);
    const Snapshot now{sim_.step_count(), sim_.time()};
    if (!snapshots_.empty() && snapshots_.back().step == now.step) return;  // written already
    const std::filesystem::path vtk = dir_ / "vtk";
    const std::string k = step_stamp(now.step);
    write_vtp_particles((vtk / ("particles_" + k + ".vtp")).string(), sim_.particles(),
                        sim_.resultant_force(0), sim_.resultant_force(1), sim_.resultant_force(2));
    write_vtp_contacts((vtk / ("contacts_" + k + ".vtp")).string(), sim_.particles(),
                       sim_.contacts());
    double b[6];
    for (int w = 0; w < kNumWalls; ++w) b[w] = sim_.walls().position(w);
    write_vtp_box((vtk / ("box_" + k + ".vtp")).string(), b);
    snapshots_.push_back(now);
    write_collections();
  }

  /// vtk/KIND.pvd for each kind of snapshot file, from the snapshots written so far.
  void write_collections() const {
    for (const char* kind : kSnapshotKinds) {
      std::vector<PvdEntry> entries;
      for (const Snapshot& s : snapshots_) {
        entries.push_back({s.time, std::string(kind) + "_" + step_stamp(s.step) + ".vtp"});
      }
      write_pvd((dir_ / "vtk" / (std::string(kind) + ".pvd")).string(), entries);
    }
  }

  /// Grains break from now on: the criterion is checked every crushing.interval steps (counted
  /// from step 0) and every breakage is appended to breakage.csv (started unless resumed).
  void attach_crusher(Crusher* crusher, bool resumed) {
    crusher_ = crusher;
    if (!resumed) {
      file("breakage.csv")
          .start({"time_s", "step", "id", "diameter_m", "cause", "sigma_Pa", "sigma_lim_Pa",
                  "fragments", "removed_fragments", "fragment_ids"});
    }
  }

  /// Called with the running controller and the steps left to its next check whenever a
  /// checkpoint is due inside drive(): at a requested event, every output.checkpoint_seconds of
  /// wall-clock time, and on a stop request (after which drive() throws Interrupted).
  std::function<void(const Controller&, std::uint64_t)> checkpoint;
  void request_checkpoint() { checkpoint_requested_ = true; }
  void checkpoint_written() { last_checkpoint_ = clock::now(); }

  /// Runs `c` to its end; `row` gives the time-series row (written at the start, every output
  /// interval and at the end). resumed: `c` was restored from a checkpoint taken inside this
  /// loop, `to_check` steps before its next check (begin() and the first row are not repeated).
  void drive(Controller& c, CsvWriter& csv, const std::function<Measurement()>& row,
             const std::string& label, const std::function<double()>& fraction = {},
             bool resumed = false, std::uint64_t to_check = 0,
             std::function<std::string()> note = {}) {
    progress_note_ = std::move(note);
    if (!resumed) {
      c.begin(sim_);
      csv.write(row());
      to_check = c.steps_to_check(sim_);
    }
    bool finished = false;
    const std::uint64_t interval = cfg_.output.interval, vtk = cfg_.output.vtk_interval;
    while (!finished) {
      const std::uint64_t s0 = sim_.step_count();
      std::uint64_t n = std::min(interval - s0 % interval, to_check);
      if (vtk > 0) n = std::min(n, vtk - s0 % vtk);
      if (crusher_) {
        const std::uint64_t k = crusher_->config().interval;
        n = std::min(n, k - s0 % k);
      }
      // Short chunks on the CPU so that a stop request is answered within seconds (the chunking
      // does not change the result); another backend keeps its long chunks.
      if (!opt_.advance) n = std::min<std::uint64_t>(n, kMaxChunk);
      if (opt_.advance) {
        opt_.advance(sim_, n);
      } else {
        sim_.step(n);
      }
      if (opt_.sync) opt_.sync(sim_);
      particle_steps_ += static_cast<double>(n) * static_cast<double>(sim_.particles().size());
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
      if (s % interval == 0 || finished) {
        const Measurement m = row();
        const PartScope timed(sim_.part_clock(), Part::Output);
        csv.write(m);
      }
      if (vtk > 0 && s % vtk == 0 && !finished) snapshot();  // the final one follows the run
      progress(label, fraction);
      if (!finished && checkpoint) {
        const int stop = g_stop_signal;
        const double since = std::chrono::duration<double>(clock::now() - last_checkpoint_).count();
        const double every = cfg_.output.checkpoint_seconds;
        if (checkpoint_requested_ || stop != 0 || (every > 0.0 && since >= every)) {
          checkpoint(c, to_check);
          checkpoint_requested_ = false;
        }
        if (stop != 0) throw Interrupted(stop, opt_.out_dir);
      }
    }
  }

  /// Before the boundary checkpoint between two parts of a run.
  bool stop_requested() const { return g_stop_signal != 0; }

  double seconds() const { return std::chrono::duration<double>(clock::now() - t0_).count(); }
  /// Particles times steps over the run (the count is fixed within a chunk); a resumed run
  /// starts from the total its checkpoint holds.
  double particle_steps() const { return particle_steps_; }
  void add_particle_steps(double earlier) { particle_steps_ += earlier; }
  /// Snapshots written, by older releases' checkpoints (legacy .vtk, counted only) included.
  std::size_t snapshots() const { return legacy_snapshots_ + snapshots_.size(); }
  const std::vector<Snapshot>& snapshot_list() const { return snapshots_; }
  std::size_t legacy_snapshots() const { return legacy_snapshots_; }
  std::vector<std::string> file_names() const {
    std::vector<std::string> names;
    for (const auto& [name, f] : files_) names.push_back(name);
    return names;
  }

  void save_state(StateWriter& out) const {
    out.tag("files");
    out.put(static_cast<std::uint64_t>(legacy_snapshots_));
    out.put(static_cast<std::uint64_t>(snapshots_.size()));
    for (const Snapshot& snap : snapshots_) {
      out.put(snap.step);
      out.put(snap.time);
    }
    out.put(static_cast<std::uint64_t>(files_.size()));
    for (const auto& [name, f] : files_) {
      out.put(name);
      out.put(f->size());
      out.put(f->columns());
    }
  }
  void load_state(StateReader& in) {
    in.tag("files");
    // Format 4 and older: a count of legacy .vtk snapshots only.
    legacy_snapshots_ = static_cast<std::size_t>(in.value<std::uint64_t>());
    snapshots_.clear();
    if (in.version() >= 5) {
      const auto count = in.value<std::uint64_t>();
      for (std::uint64_t k = 0; k < count; ++k) {
        Snapshot snap;
        in.get(snap.step);
        in.get(snap.time);
        snapshots_.push_back(snap);
      }
    }
    const auto n = in.value<std::uint64_t>();
    for (std::uint64_t k = 0; k < n; ++k) {
      std::string name;
      in.get(name);
      const auto size = in.value<long long>();
      std::vector<std::string> columns;
      in.get(columns);
      file(name).resume(size, columns);
    }
  }

 private:
  using clock = std::chrono::steady_clock;
  static constexpr std::uint64_t kMaxChunk = 2000;
  std::function<std::string()> progress_note_;  // set by drive() from its caller's note
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
    if (progress_note_) {
      const std::string note = progress_note_();
      if (!note.empty()) std::fprintf(stderr, "  %s", note.c_str());
    }
    if (fraction) {
      const double f = fraction();
      const double el = std::chrono::duration<double>(now - t0_).count();
      std::fprintf(stderr, "  (%.1f %%, ETA %.0f s)", 100.0 * f, f > 0 ? el * (1 - f) / f : 0.0);
    }
    std::fprintf(stderr, "\n");
  }

  void log(const std::vector<BreakageEvent>& events) {
    CsvWriter& out = file("breakage.csv");
    for (const BreakageEvent& e : events) {
      std::string line = format_double(e.time) + "," + std::to_string(e.step) + "," +
                         std::to_string(e.id) + "," + format_double(e.diameter) + "," +
                         to_string(e.cause) + "," + format_double(e.sigma) + "," +
                         format_double(e.sigma_lim) + "," + std::to_string(e.fragments.size()) +
                         "," + std::to_string(e.removed_fragments) + ",";
      for (std::size_t k = 0; k < e.fragments.size(); ++k) {
        if (k) line += ' ';
        line += std::to_string(e.fragments[k]);
      }
      out.write_line(line);  // flushed: finished work is on disk
    }
  }

  Simulation& sim_;
  const RunConfig& cfg_;
  const RunOptions& opt_;
  Crusher* crusher_ = nullptr;
  std::map<std::string, std::unique_ptr<CsvWriter>> files_;  // by name: a fixed save order
  std::filesystem::path dir_;
  std::vector<Snapshot> snapshots_;
  std::size_t legacy_snapshots_ = 0;
  bool checkpoint_requested_ = false;
  double particle_steps_ = 0.0;
  clock::time_point t0_, last_, last_checkpoint_;
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

// Shares of the crushable grains loaded to at least a fraction of their strength at the end of a
// stage (Crusher::loaded_share), keyed by the fraction.
JsonObject loaded_share_json(const Simulation& sim, const Crusher& crusher) {
  JsonObject o;
  for (const char* ratio : {"0.5", "0.6", "0.7", "0.72", "0.75", "0.8", "0.9"}) {
    o.number(ratio, crusher.loaded_share(sim, std::stod(ratio)));
  }
  return o;
}

// The format tag carries kStateVersion (core/state_io.hpp); older checkpoints still resume.
std::string checkpoint_tag(int version) {
  return "crushdem-checkpoint-" + std::to_string(version);
}

/// The version of a checkpoint's format tag, 0 if it is not one crushdem can read.
int checkpoint_version(const std::string& format) {
  for (int v = 1; v <= kStateVersion; ++v) {
    if (format == checkpoint_tag(v)) return v;
  }
  return 0;
}
constexpr std::uint32_t kPartPreparation = 0, kPartRun = 1, kPartFirstStage = 2;

/// Where a run stands between steps, beyond the simulation and the controllers: which part
/// (preparation, plain run, stage k) it is in, and what earlier parts produced for summary.json.
struct Progress {
  std::uint32_t part = 0;
  bool begun = false;          // the part's controller has begun (its state is saved too)
  std::uint64_t to_check = 0;  // steps to the controller's next check
  double wall_seconds = 0.0;   // wall-clock time of the run before this process
  std::array<double, PartClock::kParts> part_seconds{};  // the run's seconds by part so far
  double particle_steps = 0.0;                           // the run's particles times steps so far
  bool has_sample_json = false;                          // preparation finished
  JsonObject sample_json;
  std::vector<JsonObject> stage_results;
  std::vector<std::string> warnings;
  StrainReference ref0, ref;  // strains of the preparation, and of the test
  double d50 = 0.0;           // of the sample at the start of the test
  bool has_crusher = false;

  void save(StateWriter& out) const {
    out.tag("progress");
    out.put(part);
    out.put(begun);
    out.put(to_check);
    out.put(wall_seconds);
    out.put(part_seconds);
    out.put(particle_steps);
    out.put(has_sample_json);
    put_json(out, sample_json);
    out.put(static_cast<std::uint64_t>(stage_results.size()));
    for (const JsonObject& o : stage_results) put_json(out, o);
    out.put(warnings);
    out.put(ref0);
    out.put(ref);
    out.put(d50);
    out.put(has_crusher);
  }
  void load(StateReader& in) {
    in.tag("progress");
    in.get(part);
    in.get(begun);
    in.get(to_check);
    in.get(wall_seconds);
    if (in.version() >= 2) {
      in.get(part_seconds);
      in.get(particle_steps);
    }
    in.get(has_sample_json);
    sample_json = get_json(in);
    const auto n = in.value<std::uint64_t>();
    stage_results.clear();
    for (std::uint64_t k = 0; k < n; ++k) stage_results.push_back(get_json(in));
    in.get(warnings);
    in.get(ref0);
    in.get(ref);
    in.get(d50);
    in.get(has_crusher);
  }
};

/// A checkpoint stores the resolved configuration text it was taken with; a later crushdem
/// writes keys added since (at their defaults) as well. The two texts describe the same run when
/// the saved one, resolved again, gives the current one.
bool same_resolved_config(const std::string& saved, const std::string& current,
                          const std::filesystem::path& dir) {
  try {
    const std::string source = (dir / "checkpoint.bin").string();
    const RunConfig again = run_config_from_toml(toml::parse(saved, source), source, dir.string());
    return toml::serialize(to_toml(again)) == current;
  } catch (const std::exception&) {
    return false;  // not readable as a configuration any more: certainly not the same run
  }
}

}  // namespace

void request_stop(int signal) {
  g_stop_signal = signal;
}

namespace {
extern "C" void stop_on_signal(int sig) {
  // The run saves a checkpoint and stops within seconds; a second signal ends it at once.
  request_stop(sig);
  std::signal(sig, SIG_DFL);
}
}  // namespace

StopOnSignals::StopOnSignals()
    : int_(std::signal(SIGINT, stop_on_signal)), term_(std::signal(SIGTERM, stop_on_signal)) {}

StopOnSignals::~StopOnSignals() {
  std::signal(SIGINT, int_);
  std::signal(SIGTERM, term_);
}

namespace {

constexpr const char* kLockName = ".lock";

// A new run starts in a new or empty directory: finished or stopped work is never overwritten
// or mixed with a new run's files unless asked (overwrite), and then only a crushdem run
// directory (one with config.toml) is emptied.
void prepare_new_run_directory(const std::filesystem::path& dir, bool overwrite) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::exists(dir, ec)) return;
  if (!fs::is_directory(dir, ec)) {
    throw ConfigError("--out '" + dir.string() + "': exists and is not a directory");
  }
  std::vector<fs::path> entries;
  for (const fs::directory_entry& e : fs::directory_iterator(dir, ec)) {
    if (e.path().filename() != kLockName) entries.push_back(e.path());
  }
  if (ec) throw ConfigError("--out '" + dir.string() + "': cannot read it: " + ec.message());
  if (entries.empty()) return;
  const bool is_run = fs::exists(dir / "config.toml");
  if (!overwrite) {
    std::string what;
    if (fs::exists(dir / "checkpoint.bin")) {
      what =
          "holds a run that stopped before its end (checkpoint.bin): continue it with "
          "`crushdem resume " +
          dir.string() + "`, or start it again with --overwrite";
    } else if (fs::exists(dir / "summary.json")) {
      what =
          "holds a finished run (summary.json): choose another --out, or replace it with "
          "--overwrite";
    } else if (is_run) {
      what =
          "holds a run that stopped before its first checkpoint: start it again with "
          "`crushdem resume " +
          dir.string() + "` or --overwrite";
    } else {
      what =
          "is not empty and is not a crushdem run directory: choose a new or empty "
          "directory";
    }
    throw ConfigError("--out '" + dir.string() + "' " + what);
  }
  if (!is_run) {
    throw ConfigError("--out '" + dir.string() +
                      "' is not a crushdem run directory (no config.toml), and --overwrite "
                      "replaces only crushdem runs: choose a new or empty directory");
  }
  for (const fs::path& p : entries) {
    fs::remove_all(p, ec);
    if (ec) throw ConfigError("--overwrite: cannot remove '" + p.string() + "': " + ec.message());
  }
}

// An exclusive lock on DIR/.lock for the life of the run: a second run or resume into the
// same directory stops at once instead of splicing its rows into the first one's files.
class DirectoryLock {
 public:
  explicit DirectoryLock(const std::filesystem::path& dir) {
    const std::string path = (dir / kLockName).string();
    fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd_ < 0) throw ConfigError("cannot open the lock file '" + path + "'");
    if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
      ::close(fd_);
      throw ConfigError("'" + dir.string() +
                        "' is being written by another crushdem run (its .lock is held); wait "
                        "for it to end or stop it first");
    }
  }
  ~DirectoryLock() { ::close(fd_); }
  DirectoryLock(const DirectoryLock&) = delete;
  DirectoryLock& operator=(const DirectoryLock&) = delete;

 private:
  int fd_ = -1;
};

// A checkpoint or stage state: its bytes without the checksum (checked) and its format version.
std::pair<std::string, int> read_state_file(const std::string& path) {
  std::string bytes = read_binary_file(path);
  int version = 0;
  {
    StateReader head(bytes, path);
    std::string format;
    head.get(format);
    version = checkpoint_version(format);
    if (version == 0) {
      throw ConfigError("'" + path + "' is not a crushdem checkpoint (format '" +
                        format.substr(0, 40) + "', expected '" + checkpoint_tag(kStateVersion) +
                        "')");
    }
  }
  if (version >= 4) {  // the last 8 bytes: the checksum of the others
    std::uint64_t saved = 0;
    const bool sized = bytes.size() >= sizeof saved;
    if (sized) std::memcpy(&saved, bytes.data() + bytes.size() - sizeof saved, sizeof saved);
    if (!sized || saved != fnv1a64(bytes.data(), bytes.size() - sizeof saved)) {
      throw ConfigError("'" + path +
                        "' is damaged (its checksum does not match its contents), so it cannot "
                        "be resumed; start the run again with `crushdem run ... --overwrite`");
    }
    bytes.resize(bytes.size() - sizeof saved);
  }
  return {std::move(bytes), version};
}

// One value as TOML text (for comparing two configurations key by key).
std::string toml_text(const toml::Value& v) {
  toml::Table t;
  t["v"] = v;
  return toml::serialize(t);
}

// The first key under `prefix` where two values differ ("" when they are equal).
std::string first_difference(const toml::Value* a, const toml::Value* b, const std::string& prefix,
                             const std::set<std::string>& ignored = {}) {
  if (!a || !b) return prefix;
  if (a->type == toml::Type::Table && b->type == toml::Type::Table) {
    std::set<std::string> keys;
    for (const auto& [k, v] : *a->table) keys.insert(k);
    for (const auto& [k, v] : *b->table) keys.insert(k);
    for (const std::string& k : keys) {
      if (ignored.count(k)) continue;
      const auto ia = a->table->find(k), ib = b->table->find(k);
      std::string d =
          first_difference(ia == a->table->end() ? nullptr : &ia->second,
                           ib == b->table->end() ? nullptr : &ib->second, prefix + "." + k);
      if (!d.empty()) return d;
    }
    return "";
  }
  return toml_text(*a) == toml_text(*b) ? "" : prefix;
}

// Where a branch starts (the stage index) and whether its configuration may start there: the
// stages before it, the grains and the material must be the original's.
std::size_t branch_stage(const std::string& original_text, const RunConfig& cfg,
                         const std::string& spec, const std::filesystem::path& from) {
  const std::string src = (from / "config.toml").string();
  const RunConfig old = run_config_from_toml(toml::parse(original_text, src), src, from.string());
  const toml::Table a = to_toml(old), b = to_toml(cfg);
  const auto stages_of = [](const toml::Table& t) {
    const auto it = t.find("stage");
    return it == t.end() ? std::vector<toml::Value>{} : it->second.array;
  };
  const std::vector<toml::Value> sa = stages_of(a), sb = stages_of(b);
  if (sa.empty()) throw ConfigError("--from '" + from.string() + "': the run has no [[stage]]");
  std::size_t k = 0;
  if (spec.empty()) {
    while (k < sa.size() && k < sb.size() && toml_text(sa[k]) == toml_text(sb[k])) ++k;
    if (k == sa.size()) {
      throw ConfigError("--from '" + from.string() +
                        "': the stages are the original's; name the stage to branch from "
                        "(--from DIR:STAGE, its index or name)");
    }
  } else if (std::all_of(spec.begin(), spec.end(), [](char c) { return c >= '0' && c <= '9'; })) {
    k = std::stoul(spec);
  } else {
    k = sa.size();
    for (std::size_t i = 0; i < old.stages.size(); ++i) {
      if (old.stages[i].name == spec) k = std::min(k, i);
    }
    if (k == sa.size()) {
      std::string names;
      for (const auto& st : old.stages) names += (names.empty() ? "" : ", ") + st.name;
      throw ConfigError(bad_value("--from", spec, "a stage of the original run (" + names + ")"));
    }
  }
  if (k >= sa.size()) {
    throw ConfigError(
        bad_value("--from", spec, "a stage index below " + std::to_string(sa.size())));
  }
  for (std::size_t i = 0; i < k; ++i) {
    const std::string d = i < sb.size()
                              ? first_difference(&sa[i], &sb[i], "stage[" + std::to_string(i) + "]")
                              : "stage[" + std::to_string(i) + "]";
    if (!d.empty()) {
      throw ConfigError(d + ": differs from the original run, but a branch at stage " +
                        std::to_string(k) + " keeps the stages before it as they ran");
    }
  }
  // Crushing keys that act at run time only (the strengths and cracks already drawn stay).
  const std::set<std::string> runtime = {"crack_growth", "v0",       "n",
                                         "r_prime",      "interval", "density_scaling"};
  std::set<std::string> sections;
  for (const auto& [key, v] : a) sections.insert(key);
  for (const auto& [key, v] : b) sections.insert(key);
  for (const std::string& key : sections) {
    if (key == "stage" || key == "output") continue;
    const auto ia = a.find(key), ib = b.find(key);
    const std::string d = first_difference(ia == a.end() ? nullptr : &ia->second,
                                           ib == b.end() ? nullptr : &ib->second, key,
                                           key == "crushing" ? runtime : std::set<std::string>{});
    if (!d.empty()) {
      throw ConfigError(d +
                        ": cannot change in a branch (it sets the grains, the material or a "
                        "state drawn before the branch; a branch may change the stages from its "
                        "own on, [output] and crushing's " +
                        "crack_growth, v0, n, r_prime, interval, density_scaling)");
    }
  }
  return k;
}

// Copies the original run's result files (CSV) into a branch's directory.
void copy_run_files(const std::filesystem::path& from, const std::filesystem::path& dir) {
  namespace fs = std::filesystem;
  for (const fs::directory_entry& e : fs::directory_iterator(from)) {
    if (e.is_regular_file() && e.path().extension() == ".csv") {
      fs::copy_file(e.path(), dir / e.path().filename(), fs::copy_options::overwrite_existing);
    }
  }
}

// After the state is loaded: the CSVs it does not list are removed (the original wrote them
// later), its snapshots and the states of the stages before the branch are copied.
void keep_branch_files(const std::filesystem::path& from, const std::filesystem::path& dir,
                       const std::vector<std::string>& listed, const Driver& driver,
                       std::size_t stage) {
  namespace fs = std::filesystem;
  for (const fs::directory_entry& e : fs::directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    if (e.path().extension() == ".csv" &&
        std::find(listed.begin(), listed.end(), name) == listed.end()) {
      fs::remove(e.path());
    }
  }
  fs::create_directories(dir / "vtk");
  const auto keep = [&](const std::string& file) {
    const fs::path f = from / "vtk" / file;
    if (fs::exists(f)) fs::copy_file(f, dir / "vtk" / file, fs::copy_options::overwrite_existing);
  };
  for (std::size_t k = 0; k < driver.legacy_snapshots(); ++k) {
    for (const char* kind : {"particles_", "box_"}) keep(kind + stamp(k) + ".vtk");
  }
  for (const Snapshot& snap : driver.snapshot_list()) {
    for (const char* kind : kSnapshotKinds) {
      keep(std::string(kind) + "_" + step_stamp(snap.step) + ".vtp");
    }
  }
  driver.write_collections();
  fs::create_directories(dir / "stages");
  for (std::size_t k = 0; k < stage; ++k) {
    const fs::path f = from / "stages" / ("stage_" + std::to_string(k) + ".bin");
    if (fs::exists(f))
      fs::copy_file(f, dir / "stages" / f.filename(), fs::copy_options::overwrite_existing);
  }
}

}  // namespace

RunSummary run_to_directory(const RunConfig& cfg, const RunOptions& opt) {
  namespace fs = std::filesystem;
  g_stop_signal = 0;
  std::error_code ec;
  const fs::path dir(opt.out_dir);
  fs::create_directories(dir, ec);
  if (ec)
    throw ConfigError("--out '" + opt.out_dir + "': cannot create directory: " + ec.message());
  const DirectoryLock lock(dir);
  if (!opt.resume) prepare_new_run_directory(dir, opt.overwrite);
  fs::create_directories(dir / "vtk", ec);
  if (ec)
    throw ConfigError("--out '" + opt.out_dir + "': cannot create directory: " + ec.message());
  const std::string config_text = toml::serialize(to_toml(cfg));
  if (!opt.resume) write_text_file((dir / "config.toml").string(), config_text);

  // Resuming: the checkpoint says where the run stood; the state is read part by part below. A
  // branch reads the original run's state at the start of its branch stage the same way.
  Progress st;
  std::unique_ptr<StateReader> in;
  const bool branching = !opt.branch_dir.empty();
  std::size_t branch_k = 0;
  const fs::path from = branching ? fs::absolute(opt.branch_dir) : fs::path();
  if (opt.resume || branching) {
    std::string path = (dir / "checkpoint.bin").string();
    if (branching) {
      const std::string original = read_binary_file((from / "config.toml").string());
      branch_k = branch_stage(original, cfg, opt.branch_stage, from);
      path = (from / "stages" / ("stage_" + std::to_string(branch_k) + ".bin")).string();
      if (!fs::exists(path)) {
        throw ConfigError("--from '" + opt.branch_dir + "': no saved state at the start of stage " +
                          std::to_string(branch_k) + " (" + path +
                          "; runs keep one per stage they reached)");
      }
    } else if (!fs::exists(path)) {
      throw ConfigError("crushdem resume: no checkpoint in '" + opt.out_dir + "'" +
                        (fs::exists(dir / "summary.json") ? " (the run has finished)" : ""));
    }
    auto [bytes, version] = read_state_file(path);
    in = std::make_unique<StateReader>(std::move(bytes), path);
    std::string format;
    in->get(format);
    in->set_version(version);
    std::string saved_config;
    in->get(saved_config);
    if (!branching && saved_config != config_text &&
        !same_resolved_config(saved_config, config_text, dir)) {
      throw ConfigError("crushdem resume: " + (dir / "config.toml").string() +
                        " differs from the configuration the checkpoint was taken with");
    }
    st.load(*in);
    if (branching) {  // timing.json describes the branch's own work
      st.wall_seconds = 0.0;
      st.part_seconds = {};
      st.particle_steps = 0.0;
      JsonObject b;
      b.string("run", from.string());
      b.integer("stage", static_cast<long long>(branch_k));
      write_text_file((dir / "branch.json").string(), b.dump() + "\n");
    }
  }
  const bool resumed = opt.resume || branching;

  // The sample: prepared here from a grading curve, or read / generated as configured.
  SimulationConfig sim_cfg = cfg.simulation;
  LooseCloud cloud;
  if (cfg.has_sample && !resumed) {
    cloud = make_loose_cloud(cfg.sample);
    for (int a = 0; a < 3; ++a) {
      sim_cfg.walls[static_cast<std::size_t>(2 * a)].position = 0.0;
      sim_cfg.walls[static_cast<std::size_t>(2 * a + 1)].position = cloud.side;
    }
  }
  Simulation sim(sim_cfg);
  Driver driver(sim, cfg, opt);
  std::unique_ptr<Crusher> crusher;
  auto make_crusher = [&]() {
    crusher = std::make_unique<Crusher>(
        cfg.crushing, cfg.crushing.pattern.empty() ? SplitPattern::default14()
                                                   : SplitPattern::from_file(cfg.crushing.pattern));
  };
  if (resumed) {
    // A branch starts with the original's result files as they stood at its state: each file
    // the state lists (cut to its length there by load_state), the snapshots before it, and the
    // states of the stages before it.
    if (branching) copy_run_files(from, dir);
    driver.load_state(*in);
    if (branching) keep_branch_files(from, dir, driver.file_names(), driver, branch_k);
    sim.load_state(*in);
    if (st.has_crusher) {
      make_crusher();
      crusher->load_state(*in);
      driver.attach_crusher(crusher.get(), true);
    }
    // Timing totals go on from the checkpoint's.
    sim.part_clock().add(st.part_seconds);
    driver.add_particle_steps(st.particle_steps);
    if (opt.progress) {
      std::fprintf(stderr, "[crushdem] resuming at step %llu, t = %.6e s\n",
                   static_cast<unsigned long long>(sim.step_count()), sim.time());
    }
  }
  // timing.json: this process plus, when resumed, the processes before it; rewritten at every
  // checkpoint (finished = false) so that a long or interrupted run shows where its time goes.
  // Returns the part that took the most time and its share of the wall-clock time.
  auto write_timing = [&](double secs, bool finished) {
    JsonObject timing;
    timing.string("backend", opt.backend);
    timing.integer("finished", finished ? 1 : 0);
    timing.number("wall_seconds", secs);
    timing.integer("resumed", resumed ? 1 : 0);
#ifdef CRUSHDEM_HAVE_OPENMP
    timing.integer("threads", omp_get_max_threads());
#else
    timing.integer("threads", 1);
#endif
    timing.integer("steps", static_cast<long long>(sim.step_count()));
    // Particles times steps summed over the steps (the count changes as grains break).
    timing.number("particle_steps_per_second", secs > 0 ? driver.particle_steps() / secs : 0.0);
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
    write_text_file((dir / "timing.json").string(), timing.dump() + "\n");
    return std::pair<std::size_t, double>{dominant, secs > 0.0 ? parts[dominant] / secs : 0.0};
  };
  // The whole state at this point of the run: the part, the files, the simulation, the crusher
  // and the running controller (none between two parts).
  // stage_state: the copy kept for branches (stages/stage_K.bin), without the wall-clock times
  // (a branch starts its own), so that it is a result like the others: the same bytes for any
  // thread count and after any resume.
  auto save_checkpoint = [&](const Controller* running, std::uint64_t to_check,
                             const std::string& stage_state = "") {
    const PartScope timed(sim.part_clock(), Part::Output);
    st.begun = running != nullptr;
    st.to_check = to_check;
    st.has_crusher = crusher != nullptr;
    const Progress saved_st = st;
    if (stage_state.empty()) {
      st.part_seconds = sim.part_clock().seconds();
      st.particle_steps = driver.particle_steps();
      st.wall_seconds += driver.seconds();
    } else {
      st.part_seconds = {};
      st.particle_steps = 0.0;
      st.wall_seconds = 0.0;
    }
    StateWriter out;
    out.tag(checkpoint_tag(kStateVersion).c_str());
    out.put(config_text);
    st.save(out);
    st = saved_st;
    driver.save_state(out);
    sim.save_state(out);
    if (crusher) crusher->save_state(out);
    if (running) running->save_state(out);
    out.put(fnv1a64(out.bytes().data(), out.bytes().size()));
    if (!stage_state.empty()) {
      write_file_atomically(stage_state, out.bytes());
      return;
    }
    write_file_atomically((dir / "checkpoint.bin").string(), out.bytes());
    write_timing(st.wall_seconds + driver.seconds(), false);
    driver.checkpoint_written();
  };
  // Another backend (the GPU stepper) keeps its state on the device: no checkpoints there.
  const bool checkpoints = !opt.advance;
  if (checkpoints) {
    driver.checkpoint = [&](const Controller& c, std::uint64_t to_check) {
      save_checkpoint(&c, to_check);
    };
  }
  // Between two parts: a checkpoint, then stop here if asked to.
  auto boundary = [&](std::uint32_t part) {
    st.part = part;
    if (checkpoints) save_checkpoint(nullptr, 0);
    if (checkpoints && part >= kPartFirstStage) {  // kept for branches
      fs::create_directories(dir / "stages");
      save_checkpoint(
          nullptr, 0,
          (dir / "stages" / ("stage_" + std::to_string(part - kPartFirstStage) + ".bin")).string());
    }
    if (checkpoints && driver.stop_requested()) {
      throw Interrupted(static_cast<int>(g_stop_signal), opt.out_dir);
    }
  };
  // The controller of the part the checkpoint was taken in continues where it was.
  auto resume_here = [&](std::uint32_t part) { return resumed && st.begun && st.part == part; };

  if (cfg.has_sample && (!resumed || st.part == kPartPreparation)) {
    if (!resumed) {
      for (std::size_t i = 0; i < cloud.radius.size(); ++i) {
        sim.add_particle(cloud.position[i], cloud.radius[i]);
      }
      sim.compute_forces();
      driver.snapshot();
      st.ref0 = StrainReference::from(sim.walls());
      st.part = kPartPreparation;
    }
    PreparationController prep(cfg.sample, cfg.simulation.material.friction);
    const bool cont = resume_here(kPartPreparation);
    if (cont) prep.load_state(*in);
    CsvWriter& csv = driver.file(cfg.stages.empty() ? "timeseries.csv" : "preparation.csv");
    driver.drive(
        prep, csv,
        [&]() {
          Measurement m = measure(sim, st.ref0);
          for (auto& kv : prep.columns(sim)) m.push_back(kv);
          return m;
        },
        "prepare", {}, cont, st.to_check);
    // The sample file: grains and the box, reusable as particles.file by any test.
    Packing pk;
    for (int k = 0; k < kNumWalls; ++k) {
      pk.header[Packing::box_header_key(k)] = format_double(sim.walls().position(k));
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
    st.sample_json = so;
    st.has_sample_json = true;
    if (!prep.warning().empty()) {
      st.warnings.push_back(prep.warning());
      std::fprintf(stderr, "[crushdem] warning: %s\n", prep.warning().c_str());
    }
    if (opt.progress) {
      std::fprintf(stderr,
                   "[crushdem] sample: %zu grains, e = %.4f (target %.4f), preparation friction "
                   "%.4g\n",
                   p.size(), prep.void_ratio(), cfg.sample.void_ratio, prep.preparation_friction());
    }
  } else if (!cfg.has_sample && !resumed) {
    add_configured_particles(sim, cfg);
    sim.compute_forces();
    driver.snapshot();
  }

  // The test starts here. Crushing acts during the test (not during preparation).
  const bool in_test = resumed && st.part != kPartPreparation;
  if (!in_test && cfg.simulation.timestep.dt > 0.0) {
    const double automatic = sim.automatic_dt();
    if (cfg.simulation.timestep.dt > automatic) {
      const std::string w = "timestep.dt = " + show_number(cfg.simulation.timestep.dt) + " s is " +
                            show_number(cfg.simulation.timestep.dt / automatic) +
                            " times the automatic step " + show_number(automatic) +
                            " s (rayleigh_fraction x the Rayleigh time, safety x sqrt(m / k)): "
                            "the run may be unstable (0 = automatic)";
      st.warnings.push_back(w);
      if (opt.progress) std::fprintf(stderr, "[crushdem] warning: %s\n", w.c_str());
    }
  }
  if (!in_test) {
    st.ref = StrainReference::from(sim.walls());
    st.d50 = diameter_at_fraction(sim.particles().diameters(), 0.5);
    if (cfg.crushing.enabled) {
      make_crusher();
      crusher->begin(sim);
      driver.attach_crusher(crusher.get(), false);
    }
  }
  std::vector<double> sieves;
  if (crusher) sieves = grading_sieves(*crusher);
  // Every time-series row: the crushing columns and a grading row when grains can break.
  auto crushing_row = [&](Measurement& m) {
    if (!crusher) return;
    for (auto& kv : crushing_measurements(sim, *crusher)) m.push_back(kv);
    driver.file("grading.csv").write(grading_measurements(sim, *crusher, sieves));
  };

  // The test: a plain run, or stage after stage.
  const StrainReference& ref = st.ref;
  if (!cfg.stages.empty()) {
    CsvWriter& series = driver.file("timeseries.csv");
    const std::size_t first = in_test ? st.part - kPartFirstStage : 0;
    for (std::size_t k = first; k < cfg.stages.size(); ++k) {
      const auto part = static_cast<std::uint32_t>(kPartFirstStage + k);
      const bool cont = resume_here(part);
      if (!cont) boundary(part);
      StageController stage(cfg.stages[k], st.d50, crusher.get());
      if (cfg.stages[k].kind == StageKind::Age) {
        stage.on_dynamic_phase_end = [&, k](const Simulation& s, double t_age,
                                            std::uint64_t phase) {
          Measurement m;
          m.emplace_back("ageing_time_s", t_age);
          m.emplace_back("stage", static_cast<double>(k));
          m.emplace_back("dynamic_phase", static_cast<double>(phase));
          for (auto& kv : measure(s, ref)) m.push_back(kv);
          for (auto& kv : crushing_measurements(s, *crusher)) m.push_back(kv);
          driver.file("events.csv").write(m);
          driver.request_checkpoint();  // every event is a checkpoint
        };
        stage.on_phase_record = [&, k](const Measurement& r) {
          Measurement m;
          m.emplace_back("stage", static_cast<double>(k));
          for (const auto& kv : r) m.push_back(kv);
          driver.file("phases.csv").write(m);
        };
      }
      if (cont) stage.load_state(*in);
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
          cfg.stages[k].label(), {}, cont, st.to_check, [&]() { return stage.progress_note(); });
      JsonObject result = stage_json(stage.result());
      if (crusher) result.object("loaded_share", loaded_share_json(sim, *crusher));
      st.stage_results.push_back(result);
      if (!stage.result().warning.empty()) st.warnings.push_back(stage.result().warning);
      if (opt.progress) {
        std::fprintf(stderr, "[crushdem] stage '%s' ended (%s) after %llu steps\n",
                     stage.result().name.c_str(), stage.result().end_reason.c_str(),
                     static_cast<unsigned long long>(stage.result().steps));
      }
    }
  } else if (!cfg.has_sample) {
    const bool cont = resume_here(kPartRun);
    if (!cont) boundary(kPartRun);
    FixedLengthController run(cfg.steps, cfg.duration);
    if (cont) run.load_state(*in);
    driver.drive(
        run, driver.file("timeseries.csv"),
        [&]() {
          Measurement m = measure(sim, ref);
          crushing_row(m);
          return m;
        },
        "run", [&]() { return run.fraction(sim); }, cont, st.to_check);
  }
  driver.snapshot();
  const double secs = st.wall_seconds + driver.seconds();

  JsonObject summary;
  summary.string("crushdem_version", CRUSHDEM_VERSION);
  summary.string("crushdem_commit", build_commit());
  if (st.has_sample_json) summary.object("sample", st.sample_json);
  if (fs::exists(dir / "branch.json")) {
    std::string b = read_binary_file((dir / "branch.json").string());
    while (!b.empty() && (b.back() == '\n' || b.back() == ' ')) b.pop_back();
    summary.fields.emplace_back("branched_from", b);
  }
  summary.integer("steps", static_cast<long long>(sim.step_count()));
  summary.number("time_s", sim.time());
  summary.integer("particles", static_cast<long long>(sim.particles().size()));
  summary.integer("snapshots", static_cast<long long>(driver.snapshots()));
  if (!st.stage_results.empty()) summary.array("stages", st.stage_results);
  summary.integer("warnings", static_cast<long long>(st.warnings.size()));
  if (crusher) {
    JsonObject co;
    co.number("d50_initial_m", crusher->d50_initial());
    co.number("d0_m", crusher->d0());
    co.number("d_c_m", crusher->d_c());
    co.number("pattern_retained_volume_fraction", crusher->pattern().retained_volume_fraction());
    co.integer("pattern_fragments", static_cast<long long>(crusher->pattern().size()));
    for (auto& [k, v] : crushing_measurements(sim, *crusher)) co.number(k, v);
    // The solid mass balance from volumes and the material density (with density scaling the
    // stored masses of small fragments are not their solid masses): initial = retained +
    // removed, up to rounding.
    const double rho = sim.config().material.density;
    double initial_volume = 0.0;
    for (double d : crusher->initial_diameters()) initial_volume += kPi / 6.0 * d * d * d;
    const double retained_volume = sim.particles().solid_volume();
    const double removed_volume = crusher->removed_volume();
    co.number("solid_density_kg_m3", rho);
    co.number("initial_solid_mass_kg", rho * initial_volume);
    co.number("retained_solid_mass_kg", rho * retained_volume);
    co.number("removed_solid_mass_kg", rho * removed_volume);
    co.number("mass_balance_relative_error",
              initial_volume > 0.0
                  ? (initial_volume - retained_volume - removed_volume) / initial_volume
                  : 0.0);
    summary.object("crushing", co);
  }
  JsonObject final_state;
  for (const auto& [k, v] : measure(sim, ref)) final_state.number(k, v);
  summary.object("final", final_state);
  write_text_file((dir / "summary.json").string(), summary.dump() + "\n");

  const auto [dominant, dominant_fraction] = write_timing(secs, true);
  // The run is complete: its checkpoint is no longer needed.
  fs::remove(dir / "checkpoint.bin", ec);

  RunSummary r;
  r.steps = sim.step_count();
  r.time = sim.time();
  r.wall_seconds = secs;
  r.particles = sim.particles().size();
  r.dominant_part = std::string(kPartNames[dominant]);
  r.dominant_fraction = dominant_fraction;
  return r;
}

RunSummary resume_directory(const std::string& dir, const RunOptions& opt) {
  const std::string path = (std::filesystem::path(dir) / "config.toml").string();
  if (!std::filesystem::exists(path)) {
    throw ConfigError("crushdem resume: '" + dir + "' has no config.toml (not a crushdem run)");
  }
  const RunConfig cfg = load_run_config(path);
  RunOptions o = opt;
  o.out_dir = dir;
  o.resume = true;
  const std::filesystem::path d(dir);
  if (!std::filesystem::exists(d / "checkpoint.bin") &&
      !std::filesystem::exists(d / "summary.json")) {
    // Stopped before its first checkpoint (during sample preparation, say): nothing to continue
    // from, and nothing finished to lose, so the run starts again from its config.toml.
    if (opt.progress) {
      std::fprintf(stderr, "[crushdem] %s has no checkpoint yet: starting the run again\n",
                   dir.c_str());
    }
    o.resume = false;
    o.overwrite = true;
    if (std::filesystem::exists(d / "branch.json")) {  // a branch starts again from its state
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

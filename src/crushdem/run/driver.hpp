// The run driver: steps a Simulation under one controller after another, in chunks that end
// exactly on the output points and the controller's checks (the same steps as one at a time, so
// results depend neither on the chunking nor on a backend taking a chunk at once). It owns the
// result files (CSV and ParaView snapshots), so that a checkpoint records how far each has been
// written, and it writes progress lines and periodic checkpoints.
#pragma once

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "crushdem/backend/stepper.hpp"
#include "crushdem/experiments/protocol.hpp"
#include "crushdem/fracture/crushing.hpp"
#include "crushdem/io/config.hpp"
#include "crushdem/io/output.hpp"
#include "crushdem/run/options.hpp"

namespace crushdem {

class RunManifest;

/// "000012": legacy snapshot ordinals (format 4 and older checkpoints).
std::string ordinal_stamp(std::size_t k);
/// Snapshot file names carry the step, zero-padded so that they sort in order.
std::string step_stamp(std::uint64_t step);
/// Appends "UTC-STAMP  text" to an open run.log and flushes it.
void write_log_line(std::FILE* log, const std::string& text);

/// A ParaView snapshot: the step (its files' names), the simulated (DEM) time and the run's
/// ageing clock then. The .pvd's time is their sum, the physical time: the DEM time plus every
/// ageing jump before it, so that the frames of an age stage stand at their ageing times.
struct Snapshot {
  std::uint64_t step = 0;
  double time = 0.0;
  double ageing = 0.0;  // [s]
};
inline constexpr const char* kSnapshotKinds[] = {"particles", "contacts", "box"};

/// A file the run wrote whole (the sample, a snapshot, a stage's state), by its path in the run
/// directory, with its size and fnv1a64 when written: resume and branches check it is unchanged.
struct KeptFile {
  std::string path;
  long long size = 0;
  std::uint64_t digest = 0;
};

/// The plain [run]: the walls as configured, for a number of steps or a duration.
class FixedLengthController final : public Controller {
 public:
  FixedLengthController(std::uint64_t steps, double duration)
      : steps_(steps), duration_(duration) {}
  void begin(Simulation& sim) override;
  bool update(Simulation& sim) override;
  std::uint64_t steps_to_check(Simulation& sim) override;
  bool reads_grains(const Simulation&) const override { return false; }  // the clock only
  Measurement columns(const Simulation&) const override { return {}; }
  void state(StateArchive& a) override;
  double fraction(const Simulation& sim) const;

 private:
  std::uint64_t steps_;
  double duration_;
  std::uint64_t start_step_ = 0;
  double start_time_ = 0.0;
};

class Driver {
 public:
  Driver(Simulation& sim, Stepper& stepper, const RunConfig& cfg, const RunOptions& opt);

  /// The CSV file `name` in the output directory (opened when its first row is written).
  CsvWriter& file(const std::string& name);
  /// Says in run.log which columns of this crushdem's rows the result files have left out since
  /// it last did (a resume with RunOptions::keep_columns).
  void report_left_out_columns();
  /// The command that continues this run after a stop.
  std::string resume_command() const;
  /// Where the run directory's entries are recorded (each CSV as it is first named).
  RunManifest* manifest = nullptr;

  /// The state as ParaView files named by step (vtk/particles_, contacts_ and box_STEP.vtp),
  /// listed with their times (DEM time plus the ageing clock) in vtk/particles.pvd,
  /// contacts.pvd and box.pvd. The runner takes one when the sample is prepared, at each stage's
  /// start and at the end; an age stage at the end of each dynamic phase.
  void snapshot();
  /// The run's ageing clock now (the ageing jumps so far) [s]: the time the frames add.
  void set_ageing_clock(double t) { ageing_clock_ = t; }
  /// vtk/KIND.pvd for each kind of snapshot file, from the snapshots written so far.
  void write_collections() const;

  /// Grains break from now on: the stepper checks the criterion every crushing.interval steps
  /// (counted from step 0) and every breakage is appended to breakage.csv (started unless
  /// resumed).
  void attach_crusher(Crusher* crusher, bool resumed);

  /// Called with the running controller and the steps left to its next check whenever a
  /// checkpoint is due inside drive(): at a requested event, every output.checkpoint_seconds of
  /// wall-clock time, and on a stop request (after which drive() throws Interrupted).
  std::function<void(const Controller&, std::uint64_t)> checkpoint;
  void request_checkpoint() { checkpoint_requested_ = true; }
  void checkpoint_written() { last_checkpoint_ = clock::now(); }

  /// Runs `c` to its end; `row` gives the time-series row (written at the start, every output
  /// interval and at the end). resumed: `c` was restored from a checkpoint taken inside this
  /// loop, `to_check` steps before its next check (begin() and the first row are not repeated).
  /// `fraction` (done share, NaN when unknown) adds a percentage and ETA to progress lines,
  /// `note` a text; every line gives the steps per second since the drive began.
  void drive(Controller& c, CsvWriter& csv, const std::function<Measurement()>& row,
             const std::string& label, const std::function<double()>& fraction = {},
             bool resumed = false, std::uint64_t to_check = 0,
             std::function<std::string()> note = {});

  /// A line for the person running: "[crushdem] text" on the terminal (with progress on, and
  /// `terminal`), and always DIR/run.log with a UTC time stamp. run.log also gets a progress
  /// line every kLogSeconds, so a quiet run still says how it went.
  void say(const std::string& text, bool terminal = true);
  static constexpr double kLogSeconds = 60.0;

  double seconds() const { return std::chrono::duration<double>(clock::now() - t0_).count(); }
  /// Particles times steps over the run (the count is fixed within a chunk); a resumed run
  /// starts from the total its checkpoint holds.
  double particle_steps() const { return particle_steps_; }
  void add_particle_steps(double earlier) { particle_steps_ += earlier; }
  /// Snapshots written, by older releases' checkpoints (legacy .vtk, counted only) included.
  std::size_t snapshots() const { return legacy_snapshots_ + snapshots_.size(); }
  const std::vector<Snapshot>& snapshot_list() const { return snapshots_; }
  /// The kinds of snapshot file this run writes: kSnapshotKinds, and "bodies" with bodies beyond
  /// the box.
  std::vector<std::string> snapshot_kinds() const;
  std::size_t legacy_snapshots() const { return legacy_snapshots_; }
  std::vector<std::string> file_names() const;

  /// Records DIR/`path`, just written whole, with its size and checksum (`bytes`: its contents
  /// when at hand, else the file is read back).
  void keep(const std::string& path, const std::string* bytes = nullptr);
  const std::vector<KeptFile>& kept_files() const { return kept_; }
  /// Every kept file is in DIR as it was written: otherwise a ConfigError names the first that
  /// is missing or changed (what a resume or branch would build on).
  void check_kept_files() const;

  /// The snapshots, each result file's length, columns and checksum, and the kept files
  /// (checkpoints).
  void state(StateArchive& a);

 private:
  using clock = std::chrono::steady_clock;
  void progress(const std::string& label, const std::function<double()>& fraction);
  void log(const std::vector<BreakageEvent>& events);
  void log_line(const std::string& text);
  struct FileCloser {
    void operator()(std::FILE* f) const { std::fclose(f); }
  };
  std::unique_ptr<std::FILE, FileCloser> run_log_;  // DIR/run.log, opened at its first line

  Simulation& sim_;
  Stepper& stepper_;
  const RunConfig& cfg_;
  const RunOptions& opt_;
  Crusher* crusher_ = nullptr;
  std::map<std::string, std::unique_ptr<CsvWriter>> files_;  // by name: a fixed save order
  std::map<std::string, std::size_t> left_out_told_;         // report_left_out_columns()
  std::filesystem::path dir_;
  std::vector<Snapshot> snapshots_;
  double ageing_clock_ = 0.0;
  std::vector<KeptFile> kept_;
  std::size_t legacy_snapshots_ = 0;
  bool checkpoint_requested_ = false;
  double particle_steps_ = 0.0;
  std::function<std::string()> progress_note_;  // set by drive() from its caller's note
  clock::time_point t0_, last_, last_checkpoint_, last_logged_;
  // The current drive's start, for the progress lines' rate and ETA: its time, step and share
  // done (NaN when the controller gives none).
  clock::time_point drive_t0_;
  std::uint64_t drive_step0_ = 0;
  double drive_f0_ = 0.0;
};

}  // namespace crushdem

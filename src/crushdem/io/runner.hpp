// Runs a RunConfig and writes its result directory:
//   config.toml      the resolved configuration (every key, defaults filled in)
//   timeseries.csv   one row per output interval (SI units in the column names)
//   summary.json     final state and run description (identical for any thread count)
//   timing.json      wall-clock time, threads, throughput (the only file that varies)
//   vtk/particles_NNNNNN.vtk, vtk/box_NNNNNN.vtk   snapshots for ParaView
//   checkpoint.bin   the whole state while the run is going (at every ageing event, between
//                    stages, every output.checkpoint_seconds and on a stop request); removed
//                    when the run ends. `crushdem resume DIR` continues from it, and the files
//                    come out identical to those of an uninterrupted run.
//   stages/stage_K.bin  the state at the start of stage K, kept for branches (RunOptions)
//   branch.json      where a branch started (run directory and stage)
//   .lock            held (flock) while a run or resume writes the directory
// A new run needs a new or empty directory (RunOptions::overwrite replaces an old run).
#pragma once

#include <functional>
#include <stdexcept>
#include <string>

#include "crushdem/io/config.hpp"
#include "crushdem/io/packing.hpp"

namespace crushdem {

struct RunOptions {
  std::string out_dir;
  bool progress = true;  // progress lines on stderr
  /// Advances the simulation by n steps; empty = Simulation::step. Another backend (the GPU
  /// stepper) plugs in here, and `sync` then brings the Simulation up to date before each output.
  std::function<void(Simulation&, std::uint64_t)> advance;
  std::function<void(Simulation&)> sync;
  std::string backend = "cpu";  // recorded in timing.json
  bool resume = false;          // continue from out_dir/checkpoint.bin
  /// A new run refuses a directory that holds files; with overwrite, a crushdem run directory
  /// (one with config.toml) is emptied first.
  bool overwrite = false;
  /// A branch: start from the state of the finished (or stopped) run in branch_dir at the start
  /// of stage branch_stage (its index or name; empty: the first stage the configuration
  /// changes), with this run's configuration. What may differ from the original run: the stages
  /// from that one on, the crushing keys that act at run time (crack_growth, v0, n, r_prime,
  /// interval, density_scaling) and [output]; anything else is refused, naming the key.
  std::string branch_dir, branch_stage;
};

/// Asks the running run_to_directory to write a checkpoint and stop at its next chunk boundary
/// (within seconds). Async-signal-safe: the CLI calls it from its SIGINT / SIGTERM handler.
void request_stop(int signal);

/// SIGINT and SIGTERM call request_stop() for as long as this object lives, so that a run
/// saves its checkpoint and stops; a second signal ends the process at once. The previous
/// handlers (Python's, say) come back afterwards. Used by the CLI and by the Python run/resume.
class StopOnSignals {
 public:
  StopOnSignals();
  ~StopOnSignals();
  StopOnSignals(const StopOnSignals&) = delete;
  StopOnSignals& operator=(const StopOnSignals&) = delete;

 private:
  using Handler = void (*)(int);
  Handler int_, term_;
};

/// Thrown by run_to_directory when it stopped on request, after saving its checkpoint in
/// out_dir; what() tells the user where the state is and how to go on.
class Interrupted : public std::runtime_error {
 public:
  Interrupted(int signal, const std::string& out_dir)
      : std::runtime_error("stopped by signal " + std::to_string(signal) +
                           "; the state is saved in " + out_dir +
                           "/checkpoint.bin. Continue with: crushdem resume " + out_dir),
        signal_(signal),
        out_dir_(out_dir) {}
  int signal() const { return signal_; }
  const std::string& out_dir() const { return out_dir_; }

 private:
  int signal_;
  std::string out_dir_;
};

struct RunSummary {
  std::uint64_t steps = 0;
  double time = 0.0;
  double wall_seconds = 0.0;
  std::size_t particles = 0;
  std::string dominant_part;       // the part of the step that took most wall-clock time
  double dominant_fraction = 0.0;  // its share of the wall-clock time
};

/// Adds the rows of a particle file to a simulation (ids kept, the configured density).
void add_packing_particles(Simulation& sim, const Packing& pk);

/// Adds the configured particles (from a file or generated) to a simulation.
void add_configured_particles(Simulation& sim, const RunConfig& cfg);

RunSummary run_to_directory(const RunConfig& cfg, const RunOptions& opt);

/// Continues the run in `dir` from its checkpoint (configuration from dir/config.toml).
RunSummary resume_directory(const std::string& dir, const RunOptions& opt);

}  // namespace crushdem

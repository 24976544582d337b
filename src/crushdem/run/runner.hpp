// Runs a RunConfig and writes its result directory:
//   config.toml      the resolved configuration (every key, defaults filled in)
//   timeseries.csv   one row per output interval (SI units in the column names)
//   summary.json     final state and run description (identical for any thread count)
//   timing.json      wall-clock time, threads, throughput (the only file that varies)
//   vtk/*_STEP.vtp, vtk/*.pvd   ParaView snapshots (particles, contacts, box) and their series
//   checkpoint.bin   the whole state while the run is going (at every ageing event, between
//                    stages, every output.checkpoint_seconds and on a stop request); removed
//                    when the run ends. `crushdem-sand resume DIR` continues from it, and the files
//                    come out identical to those of an uninterrupted run.
//   stages/stage_K.bin  the state at the start of stage K, kept for branches (RunOptions)
//   branch.json      where a branch started (run directory and stage)
//   .lock            held (flock) while a run or resume writes the directory
// A run is prepare (sample preparation or the configured grains) -> test (stage after stage, or
// a plain [run]) -> finish (summary.json, timing.json). A new run needs a new or empty directory
// (RunOptions::overwrite replaces an old run).
#pragma once

#include "crushdem/io/config.hpp"
#include "crushdem/io/packing.hpp"
#include "crushdem/run/options.hpp"
#include "crushdem/run/signals.hpp"

namespace crushdem {

/// Adds the rows of a particle file to a simulation (ids kept, the configured density).
void add_packing_particles(Simulation& sim, const Packing& pk);

/// Adds the configured particles (from a file or generated) to a simulation.
void add_configured_particles(Simulation& sim, const RunConfig& cfg);

/// What a new run checks of its starting state before its first step (the bodies clear of the
/// grains: the sample's loose cloud, or the configured grains), without running it; ConfigError
/// naming the key otherwise.
void check_start(const RunConfig& cfg);
RunSummary run_to_directory(const RunConfig& cfg, const RunOptions& opt);

/// Continues the run in `dir` from its checkpoint (configuration from dir/config.toml); a run
/// stopped before its first checkpoint starts again.
RunSummary resume_directory(const std::string& dir, const RunOptions& opt);

}  // namespace crushdem

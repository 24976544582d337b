// What the caller of a run chooses beyond its configuration (where it writes, progress, the
// backend that steps it, resume or branch), and what a finished run reports back.
#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include "crushdem/integrate/simulation.hpp"

namespace crushdem {

struct RunOptions {
  std::string out_dir;
  bool progress = true;  // progress lines on stderr
  /// What advances the simulation (backend/stepper.hpp): "cpu", "emulated" (the GPU's step run
  /// on the host) or "cuda"; recorded in timing.json. Sample preparation, every stage,
  /// crushing, ageing, checkpoints and resuming work on each.
  std::string backend = "cpu";
  bool resume = false;  // continue from out_dir/checkpoint.bin
  /// A resume by a crushdem that writes other columns than the one that started the run (a
  /// newer build): each result file keeps the columns it has, the new ones are left out (run.log
  /// names them) and a column the file has that this build does not write is still refused.
  /// Without it such a resume is refused at its first row.
  bool keep_columns = false;
  /// A new run refuses a directory that holds files; with overwrite, the entries the manifest of
  /// a crushdem run directory lists are removed first (nothing else; never the current
  /// directory or one that holds it).
  bool overwrite = false;
  /// A resume that starts a run again (no checkpoint yet): overwrite, in the current directory
  /// too (only the listed entries go).
  bool restart = false;
  /// A branch: start from the state of the finished (or stopped) run in branch_dir at the start
  /// of stage branch_stage (its index or name; empty: the first stage the configuration
  /// changes), with this run's configuration. What may differ from the original run: the stages
  /// from that one on, the crushing keys that act at run time (crack_growth, v0, n, r_prime,
  /// interval, density_scaling) and [output]; anything else is refused, naming the key.
  std::string branch_dir, branch_stage;
  /// The crushdem that runs it, as run.log and summary.json's crushdem_builds name it: empty for
  /// this build's "VERSION (COMMIT)" (tests stand in another build here; crushdem_commit stays
  /// the binary's).
  std::string build;
};

struct RunSummary {
  std::uint64_t steps = 0;
  double time = 0.0;
  double wall_seconds = 0.0;
  std::size_t particles = 0;
  std::string dominant_part;       // the part of the step that took most wall-clock time
  double dominant_fraction = 0.0;  // its share of the wall-clock time
};

}  // namespace crushdem

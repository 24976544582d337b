// The checkpoint format (checkpoint.bin, and stages/stage_K.bin kept for branches), version
// kStateVersion (core/state_io.hpp); older versions still resume. In order:
//   format tag "crushdem-checkpoint-V", the resolved configuration text it was taken with,
//   the run position (RunPosition), the result files (Driver), the simulation, the crusher (when
//   grains break), the running controller (when one has begun), then from version 4 on an
//   FNV-1a checksum of all the bytes before it.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "crushdem/core/part_clock.hpp"
#include "crushdem/core/state_io.hpp"
#include "crushdem/experiments/measurements.hpp"
#include "crushdem/io/output.hpp"

namespace crushdem {

class Controller;
class Crusher;
class Driver;
class Simulation;

/// The run's parts in the order they run: preparation, a plain [run], then stage k at
/// kPartFirstStage + k.
constexpr std::uint32_t kPartPreparation = 0, kPartRun = 1, kPartFirstStage = 2;

/// Where a run stands between steps, beyond the simulation and the controllers: which part it
/// is in, and what earlier parts produced for summary.json.
struct RunPosition {
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
  /// Each crushdem that ran the run so far, as "VERSION (COMMIT)", in order, once per change of
  /// build (empty from a checkpoint before format 8): a resume or branch by another build says
  /// so, and summary.json lists them.
  std::vector<std::string> builds;

  void state(StateArchive& a);
};

/// "VERSION (COMMIT)" of this build of crushdem.
std::string this_build();

/// Adds `current` to a run's `builds` and returns the warning the run gives when it differs from
/// the build that ran the run last (empty otherwise; nothing is known of the builds of a
/// checkpoint before format 8). `what`: "resumed", "branched".
std::string note_build(std::vector<std::string>& builds, const std::string& current,
                       const std::string& what);

/// The format tag of version `version`.
std::string checkpoint_tag(int version);

/// The bytes of a checkpoint at this point of a run (checksum included). `running`: the
/// controller of the current part, null between two parts.
std::string checkpoint_bytes(const std::string& config_text, const RunPosition& position,
                             const Driver& driver, const Simulation& sim, const Crusher* crusher,
                             const Controller* running);

/// A checkpoint opened for reading: its version checked and its checksum verified (ConfigError
/// naming the file otherwise); `reader` stands after the configuration text, at the position.
struct OpenCheckpoint {
  std::unique_ptr<StateReader> reader;
  std::string config_text;
};
OpenCheckpoint open_checkpoint(const std::string& path);

/// What stands between a checkpoint's configuration and the run directory's: "" when they
/// describe the same run, else the first key that differs ("stage[1].depth = 0.2 (the
/// checkpoint's: 0.1)"). A later crushdem writes keys added since (at their defaults) into the
/// resolved configuration as well, so the saved text is resolved again before it is compared.
std::string saved_config_difference(const std::string& saved, const std::string& current,
                                    const std::filesystem::path& dir);

}  // namespace crushdem

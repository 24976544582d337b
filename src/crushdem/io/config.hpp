// The one configuration model: plain structs filled from a TOML table (the CLI reads a file,
// Python turns keyword arguments into the same table), validated before anything runs. Every
// key is documented in docs/configuration.md; units are SI.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "crushdem/experiments/protocol.hpp"
#include "crushdem/experiments/stages.hpp"
#include "crushdem/fracture/crushing.hpp"
#include "crushdem/integrate/simulation.hpp"
#include "crushdem/io/param_io.hpp"
#include "crushdem/io/parameter_sets.hpp"
#include "crushdem/io/toml.hpp"

namespace crushdem {

/// A sample file's header key for the upscaling factor it was prepared with (none: 1).
inline constexpr const char* kUpscalingHeader = "upscaling_factor";

/// Grains placed at random without overlap (random sequential addition) inside the box.
struct GenerateConfig {
  std::uint64_t count = 0;
  double diameter_min = 0.0;  // [m]
  double diameter_max = 0.0;  // [m]; diameters uniform by number in [min, max]
  std::uint64_t seed = 1;
  void validate(const std::array<double, 6>& box) const;
};

/// The keys of [particles.generate] (core/params.hpp).
const ParamTable<GenerateConfig>& generate_params();

struct ParticlesConfig {
  std::string file;         // "id x y z diameter" rows (relative to the config file); a
                            // "# box_xmin=..." header (written by sample preparation) gives the
                            // box when there is no [box] section
  GenerateConfig generate;  // used when file is empty
  void validate(const std::array<double, 6>& box) const;
};

struct OutputConfig {
  std::uint64_t interval = 1000;      // steps between rows of timeseries.csv
  std::uint64_t vtk_interval = 0;     // steps between VTK snapshots (0 = first and last only)
  double progress_seconds = 2.0;      // wall-clock seconds between progress lines
  double checkpoint_seconds = 600.0;  // wall-clock seconds between periodic checkpoints (0: at
                                      // events and stage ends only)
};

/// The keys of [output] (core/params.hpp).
const ParamTable<OutputConfig>& output_params();

/// The rows of every configuration section that has a parameter table, as (section, rows)
/// pairs; a stage kind's section is "stage.KIND".
std::vector<std::pair<std::string, std::vector<param_io::ParamRow>>> parameter_tables();

/// The reference of those sections as (section, Markdown) pairs: a table each, and for the
/// stages ("stage") each kind's heading and table. docs/configuration.md holds them verbatim (a
/// test checks it).
std::vector<std::pair<std::string, std::string>> parameter_reference();

/// Particle upscaling (docs/chamber.md): each simulated grain stands for a real grain `factor`
/// times smaller, and every length that belongs to a grain is multiplied by the factor for the
/// run (upscaled()): the grading (or the generated diameters), the rough law's S_q, crushing's
/// d0 (when given) and d_min, and the crack velocity v0 (a crack crosses a grain N times larger
/// in the same time). `strength` is the rule for the strength's size effect.
enum class UpscaledStrength {
  Similar,  // sigma_lim0 (d / (N d0))^(-3/m): the real grain's strength (Ciantia et al.)
  Weibull   // sigma_lim0 (d / d0)^(-3/m) at the upscaled size: N^(-3/m) weaker
};
inline constexpr std::array<Named<UpscaledStrength>, 2> kUpscaledStrengthNames = {
    {{UpscaledStrength::Similar, "similar"}, {UpscaledStrength::Weibull, "weibull"}}};

struct UpscalingConfig {
  double factor = 1.0;  // N >= 1 [-]
  UpscaledStrength strength = UpscaledStrength::Similar;
};

/// The keys of [upscaling] (core/params.hpp).
const ParamTable<UpscalingConfig>& upscaling_params();

struct RunConfig {
  ParameterSetUse parameters;  // the top-level key `parameters` (io/parameter_sets.hpp)
  SimulationConfig simulation;
  ParticlesConfig particles;  // unless has_sample
  bool has_sample = false;    // [sample]: prepare a sample from a grading curve first
  SampleConfig sample;
  std::vector<StageConfig> stages;  // [[stage]]: a laboratory test, stage after stage
  CrushingConfig crushing;          // [crushing]: grains break (during the test, not preparation)
  UpscalingConfig upscaling;        // [upscaling]: grains larger than the real ones
  // A chamber sample read from particles.file (its header's chamber_radius and sector): the run
  // rebuilds its chamber as [sample] made it. Not keys.
  double file_upscaling_factor = 1.0;  // the factor the sample file was prepared with
  double file_chamber_radius = 0.0;    // [m]; 0: not a chamber sample
  double file_sector = 360.0;          // [deg]
  OutputConfig output;
  std::uint64_t steps = 0;  // [run] without stages: run length in steps, or
  double duration = 0.0;    // in simulated seconds (exactly one of the two)
  void validate() const;
  /// Valid values outside what a grain material takes (plausibility_warnings of [material] and,
  /// with crushing on, [crushing]): printed by `crushdem-sand check` and by a run, and kept in its
  /// summary.json.
  std::vector<std::string> warnings() const;
  /// The checks across stages: the ageing clock's `until`s in order, a load test after its
  /// body's installation, no body pushed into the bottom platen; errors name stage[i].key.
  void validate_stage_sequence() const;
  /// Box as [xmin, xmax, ymin, ymax, zmin, zmax] from the wall positions.
  std::array<double, 6> box() const;
};

/// Reads [material] [contact] [damping] [timestep] [neighbor] [box] [walls.*]; any other key,
/// at the top level or inside these sections, is an error naming it.
SimulationConfig simulation_config_from_toml(const toml::Table& root, const std::string& source);
/// Reads a whole run file: the simulation sections plus [particles] or [sample], [run] or
/// [[stage]], and [output].
/// Relative particle file paths are resolved against `base_dir`.
RunConfig run_config_from_toml(const toml::Table& root, const std::string& source,
                               const std::string& base_dir);
RunConfig load_run_config(const std::string& path);
/// A run directory's own configuration (its config.toml, or the text a checkpoint keeps): one
/// written before the key `parameters` existed was resolved under the earlier defaults, which
/// are the set "table1", and is read with that set.
RunConfig saved_run_config_from_toml(toml::Table root, const std::string& source,
                                     const std::string& base_dir);
RunConfig load_saved_run_config(const std::string& path);

/// The configuration a run uses: `c` with the grain lengths multiplied by the upscaling factor
/// and the strength rule set (UpscalingConfig); `c` itself when the factor is 1. The run's
/// config.toml keeps `c` (the real sizes and the factor).
RunConfig upscaled(const RunConfig& c);

/// The resolved configuration (every key, defaults filled in) as TOML.
toml::Table to_toml(const SimulationConfig& c);
toml::Table to_toml(const RunConfig& c);

}  // namespace crushdem

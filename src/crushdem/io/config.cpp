#include "crushdem/io/config.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <map>
#include <set>
#include <sstream>

#include "crushdem/core/error.hpp"
#include "crushdem/io/packing.hpp"
#include "crushdem/io/param_io.hpp"
#include "crushdem/io/parameter_sets.hpp"

namespace crushdem {
namespace {

using param_io::markdown;
using param_io::read_params;
using param_io::Section;
using param_io::write_params;
using toml::Table;
using toml::Value;

/// A section read whole through its table (unknown keys refused).
template <class S>
void read_section(Section& root, const std::string& name, S& c, const ParamTable<S>& table) {
  Section s = root.sub(name);
  read_params(s, c, table);
  s.finish();
}

void read_simulation(Section& root, SimulationConfig& c, bool box_required = true) {
  read_section(root, "material", c.material, material_params());
  {
    Section s = root.sub("contact");
    read_params(s, c.contact, contact_params());
    // Without the key, mu_r > 0 means rolling resistance, as it did before the key existed.
    if (!s.has("rotation") && c.contact.rolling_friction > 0.0) {
      c.contact.rotation = Rotation::Rolling;
    }
    s.finish();
  }
  read_section(root, "damping", c.damping, damping_params());
  read_section(root, "timestep", c.timestep, timestep_params());
  read_section(root, "neighbor", c.neighbor, neighbor_params());
  read_section(root, "gravity", c.gravity, gravity_params());
  {
    Section walls = root.sub("walls");
    for (int k = 0; k < kNumWalls; ++k) {
      Section s = walls.sub(wall_name(k));
      WallConfig& w = c.walls[static_cast<std::size_t>(k)];
      read_params(s, w, wall_params());
      // A key that the chosen mode does not use is almost always a forgotten `mode` line.
      param_io::refuse_unused_keys(s, w, wall_params(), true, [&](const Param<WallConfig>& p) {
        return "no '" + std::string(p.key) + "' for a wall in mode \"" + to_string(w.mode) +
               "\" (set mode or remove the key)";
      });
      s.finish();
    }
    walls.finish();
  }
  for (Section& s : root.table_array("body")) {
    BodyConfig b;
    read_params(s, b, body_params());
    // The motion keys apply as a wall's do: a key the mode does not use is a forgotten `mode`.
    param_io::refuse_unused_keys(s, b, body_params(), true, [&b](const Param<BodyConfig>& p) {
      const std::string key(p.key);
      if (key == "target_stress" && b.mode == WallMode::Servo) {  // so target_force is given
        return std::string(
            "no 'target_stress' beside target_force (the servo holds one of "
            "them: give either)");
      }
      if (key == "tip") {
        return "no 'tip' for a " + std::string(to_string(b.kind)) + " (only a pile has one)";
      }
      return "no '" + key + "' for a body in mode \"" + to_string(b.mode) +
             "\" (set mode or remove the key)";
    });
    s.finish();
    c.bodies.push_back(b);
  }
  {
    Section s = root.sub("box");
    if (!root.has("box") && !box_required) return;
    if (!root.has("box")) {
      throw ConfigError(
          "missing section [box]: expected min = [x, y, z] and max = [x, y, z] (wall positions, "
          "m)");
    }
    double lo[3], hi[3];
    bool has_lo = false, has_hi = false;
    s.vec3("min", lo, has_lo);
    s.vec3("max", hi, has_hi);
    if (!has_lo || !has_hi) {
      throw ConfigError(std::string("missing key 'box.") + (has_lo ? "max" : "min") +
                        "': expected an array of 3 numbers [x, y, z] in m");
    }
    for (int a = 0; a < 3; ++a) {
      for (const auto& [name, v] : {std::pair{"min", lo[a]}, std::pair{"max", hi[a]}}) {
        if (!std::isfinite(v)) {
          throw ConfigError(bad_value("box." + std::string(name) + "[" + std::to_string(a) + "]",
                                      show_number(v), "a finite coordinate in m"));
        }
      }
    }
    s.finish();
    for (int a = 0; a < 3; ++a) {
      c.walls[static_cast<std::size_t>(2 * a)].position = lo[a];
      c.walls[static_cast<std::size_t>(2 * a + 1)].position = hi[a];
    }
  }
}

Value num(double v) {
  return Value::make_float(v);
}
Value cnt(std::uint64_t v) {
  return Value::make_integer(static_cast<std::int64_t>(v));
}

}  // namespace

SimulationConfig simulation_config_from_toml(const toml::Table& root, const std::string& source) {
  SimulationConfig c;
  CrushingConfig crushing;  // the set's [crushing] values: no crushing here
  read_parameter_set(root, source, c.contact, crushing);
  Section r(&root, "", source);
  read_simulation(r, c);
  // Only the simulation sections are read here; the caller owns the others.
  for (const auto& [k, v] : root) {
    static const std::set<std::string> mine = {"parameters", "material", "contact", "damping",
                                               "timestep",   "neighbor", "box",     "walls",
                                               "body",       "gravity"};
    if (!mine.count(k)) {
      throw ConfigError(r.where(v) + "unknown key '" + k +
                        "' (valid: parameters and the sections material, contact, damping, "
                        "timestep, neighbor, box, walls, body, gravity)");
    }
  }
  c.validate();
  return c;
}

namespace {

void read_sample(Section& s, SampleConfig& c) {
  Section g = s.sub("grading");
  g.numbers("diameter", c.grading.diameter, "an array of sieve sizes in m, increasing");
  g.numbers("passing", c.grading.passing,
            "an array of mass fractions passing (0 ... 1), one per size");
  g.finish();
  read_params(s, c, sample_params());
  if (s.has("count") && c.count == 0) {
    throw ConfigError(bad_value(s.key("count"), "0", "a positive number of grains"));
  }
  s.finish();
}

void read_stage(Section& s, StageConfig& c) {
  if (!s.has("type")) {
    throw ConfigError("missing key '" + s.key("type") + "': expected " + stage_kind_names());
  }
  std::string type;
  s.string("type", type);
  c.kind = &stage_kind(type, s.key("type"));
  s.string("name", c.name);
  // A key of another kind is a mistake, not a no-op: say so before the unknown-key check.
  const ParamTable<StageConfig>& own = c.kind->params;
  for (const StageKind* other : stage_kinds()) {
    for (const Param<StageConfig>& p : other->params) {
      const std::string k(p.key);
      const bool mine = std::any_of(own.begin(), own.end(),
                                    [&](const Param<StageConfig>& q) { return q.key == p.key; });
      if (s.has(k) && !mine) {
        throw ConfigError(
            bad_value(s.key(k), "given", "no '" + k + "' in a \"" + type + "\" stage"));
      }
    }
  }
  read_params(s, c, own);
  s.finish();
  // A key without its switch (a field's rings without field_interval, a pile's head without
  // its body) would be dropped without a word: the run would lack what it asked for.
  param_io::refuse_unused_keys(s, c, own, false, [](const Param<StageConfig>& p) {
    const std::string k(p.key), needs(p.needs);
    return "no '" + k + "' without '" + needs + "' (" + k + ": " + std::string(p.doc) + "); give " +
           needs + " or remove " + k;
  });
}

// A sample's box: a cube of its side, or a cylinder's about the z axis with the box's side
// walls a diameter clear of it.
void place_sample_box(RunConfig& c) {
  const bool cylinder = c.sample.shape == SampleShape::Cylinder;
  const double D = c.sample.cube_side();
  for (int a = 0; a < 3; ++a) {
    c.simulation.walls[static_cast<std::size_t>(2 * a)].position = cylinder && a < 2 ? -D : 0.0;
    c.simulation.walls[static_cast<std::size_t>(2 * a + 1)].position =
        a < 2 ? D : c.sample.height();
  }
}

}  // namespace

RunConfig run_config_from_toml(const toml::Table& root, const std::string& source,
                               const std::string& base_dir) {
  RunConfig c;
  c.parameters = read_parameter_set(root, source, c.simulation.contact, c.crushing);
  Section r(&root, "", source);
  r.find("parameters");  // read above
  read_simulation(r, c.simulation, /*box_required=*/false);
  c.has_sample = root.count("sample") > 0;
  const bool has_particles = root.count("particles") > 0;
  if (c.has_sample && has_particles) {
    throw ConfigError(
        "give either [sample] (prepare a sample from a grading curve) or [particles] (a "
        "particle file or a random cloud), not both");
  }
  if (!c.has_sample && !has_particles) {
    throw ConfigError(
        "missing section [particles] or [sample]: expected particles.file = \"...\", "
        "[particles.generate] or a [sample] to prepare");
  }
  if (c.has_sample) {
    Section s = r.sub("sample");
    read_sample(s, c.sample);
  } else {
    Section s = r.sub("particles");
    s.string("file", c.particles.file);
    if (!c.particles.file.empty() && std::filesystem::path(c.particles.file).is_relative()) {
      // Absolute, so that the resolved config.toml (read again by `crushdem-sand resume`) still
      // points at the file from inside the output directory.
      c.particles.file =
          std::filesystem::absolute(std::filesystem::path(base_dir) / c.particles.file)
              .lexically_normal()
              .string();
    }
    Section g = s.sub("generate");
    read_params(g, c.particles.generate, generate_params());
    g.finish();
    if (!c.particles.file.empty() && s.has("generate")) {
      throw ConfigError(
          "particles: give either 'particles.file' or [particles.generate], not both");
    }
    s.finish();
  }
  if (root.count("crushing")) {
    Section s = r.sub("crushing");
    CrushingConfig& k = c.crushing;
    k.enabled = true;
    read_params(s, k, crushing_params());
    s.string("pattern", k.pattern);
    if (!k.pattern.empty() && std::filesystem::path(k.pattern).is_relative()) {
      k.pattern = std::filesystem::absolute(std::filesystem::path(base_dir) / k.pattern)
                      .lexically_normal()
                      .string();
    }
    s.finish();
  }
  read_section(r, "upscaling", c.upscaling, upscaling_params());
  {
    auto stages = r.table_array("stage");
    for (Section& s : stages) {
      StageConfig st;
      read_stage(s, st);
      c.stages.push_back(st);
    }
  }
  if ((c.has_sample || !c.stages.empty()) && root.count("walls")) {
    throw ConfigError(
        "walls: a [sample] or [[stage]] run sets the walls itself; remove the [walls] sections "
        "(stage keys such as max_strain_rate set the servo)");
  }
  if (c.has_sample && root.count("box")) {
    throw ConfigError(
        "box: a [sample] makes its own cube (sample.side or sample.count); remove "
        "the [box] section");
  }
  if (c.has_sample) {
    place_sample_box(c);
  } else if (!root.count("box")) {
    // The box of a prepared sample is in its file's header.
    if (c.particles.file.empty()) {
      throw ConfigError(
          "missing section [box]: expected min = [x, y, z] and max = [x, y, z] (wall positions, "
          "m)");
    }
    if (!std::filesystem::exists(c.particles.file)) {
      throw ConfigError(
          bad_value("particles.file", "\"" + c.particles.file + "\"",
                    "an existing particle file (a prepared sample: `crushdem-sand run "
                    "SAMPLE.toml --out DIR` writes DIR/sample.txt)"));
    }
    const Packing pk = read_packing(c.particles.file);
    if (!pk.has_box()) {
      throw ConfigError("missing section [box]: " + c.particles.file +
                        " has no '# box_xmin=' header (only prepared samples carry their box); "
                        "expected [box] min = [x, y, z] and max = [x, y, z]");
    }
    const std::array<double, kNumWalls> box = pk.box(c.particles.file);
    for (int k = 0; k < kNumWalls; ++k) {
      c.simulation.walls[static_cast<std::size_t>(k)].position = box[static_cast<std::size_t>(k)];
    }
  }
  if (!c.has_sample && !c.particles.file.empty() && std::filesystem::exists(c.particles.file)) {
    const Packing pk = read_packing(c.particles.file);
    if (pk.header.count(kUpscalingHeader)) {
      c.file_upscaling_factor = pk.header_number(kUpscalingHeader, c.particles.file);
    }
    const Packing::Chamber chamber = pk.chamber(c.particles.file, "particles.file");
    c.file_chamber_radius = chamber.radius;
    c.file_sector = chamber.sector;
  }
  {
    Section s = r.sub("run");
    if (root.count("run") && (c.has_sample || !c.stages.empty())) {
      throw ConfigError(
          "run: a [sample] or [[stage]] run ends with its last stage; remove [run] (a 'hold' "
          "stage runs for a set time)");
    }
    s.count("steps", c.steps);
    s.number("duration", c.duration);
    s.finish();
  }
  read_section(r, "output", c.output, output_params());
  r.finish();
  c.validate();
  return c;
}

const ParamTable<GenerateConfig>& generate_params() {
  using Row = Param<GenerateConfig>;
  static const ParamTable<GenerateConfig> table = {
      Row{"count", &GenerateConfig::count, "", "number of grains placed at random without overlap"},
      Row{"diameter_min", &GenerateConfig::diameter_min, "m",
          "smallest diameter (uniform by number in [min, max])"},
      Row{"diameter_max", &GenerateConfig::diameter_max, "m", "largest diameter"},
      Row{"seed", &GenerateConfig::seed, "", "random seed; same seed, same sample"},
  };
  return table;
}

namespace {

// The sections with a table, the stages aside.
std::vector<std::pair<std::string, std::vector<param_io::ParamRow>>> section_tables() {
  using param_io::param_rows;
  return {
      {"material", param_rows(material_params())},
      {"contact", param_rows(contact_params())},
      {"damping", param_rows(damping_params())},
      {"timestep", param_rows(timestep_params())},
      {"neighbor", param_rows(neighbor_params())},
      {"gravity", param_rows(gravity_params())},
      {"crushing", param_rows(crushing_params())},
      {"upscaling", param_rows(upscaling_params())},
      {"output", param_rows(output_params())},
      {"walls.NAME", param_rows(wall_params())},
      {"body", param_rows(body_params())},
      {"particles.generate", param_rows(generate_params())},
      {"sample", param_rows(sample_params())},
  };
}

}  // namespace

std::vector<std::pair<std::string, std::vector<param_io::ParamRow>>> parameter_tables() {
  auto tables = section_tables();
  for (const StageKind* k : stage_kinds()) {
    tables.emplace_back("stage." + std::string(k->name), param_io::param_rows(k->params));
  }
  return tables;
}

std::vector<std::pair<std::string, std::string>> parameter_reference() {
  // Keys read outside the tables.
  const std::map<std::string, std::vector<std::string>> extra_rows = {
      {"crushing",
       {"| `pattern` | (the 14 fragments) | | file of `radius_fraction x y z` rows (units of the "
        "parent radius, local axis z = the normal of the parent's largest contact force); "
        "relative to the config file |"}},
      {"sample",
       {"| `grading.diameter` | NE34-like: 0.12 ... 0.27 mm | m | sieve sizes, increasing |",
        "| `grading.passing` | 0, 0.1, 0.3, 0.5, 0.7, 0.9, 1 | - | mass fraction passing each "
        "size (0 ... 1, first 0, last 1) |"}},
  };
  std::vector<std::pair<std::string, std::string>> ref;
  for (const auto& [section, rows] : section_tables()) {
    const auto extra = extra_rows.find(section);
    ref.emplace_back(section, markdown(rows, extra == extra_rows.end() ? std::vector<std::string>{}
                                                                       : extra->second));
  }
  std::string stages;
  for (const StageKind* k : stage_kinds()) {
    if (!stages.empty()) stages += "\n";
    stages += "### type = \"" + std::string(k->name) + "\": " + std::string(k->description) +
              "\n\n" + markdown(k->params);
  }
  ref.emplace_back("stage", stages);
  return ref;
}

RunConfig load_run_config(const std::string& path) {
  const toml::Table t = toml::parse_file(path);
  const auto base = std::filesystem::path(path).parent_path().string();
  return run_config_from_toml(t, path, base.empty() ? "." : base);
}

RunConfig saved_run_config_from_toml(toml::Table root, const std::string& source,
                                     const std::string& base_dir) {
  if (!root.count("parameters")) root["parameters"] = Value::make_string("table1");
  return run_config_from_toml(root, source, base_dir);
}

RunConfig load_saved_run_config(const std::string& path) {
  const auto base = std::filesystem::path(path).parent_path().string();
  return saved_run_config_from_toml(toml::parse_file(path), path, base.empty() ? "." : base);
}

std::array<double, 6> RunConfig::box() const {
  std::array<double, 6> b{};
  for (int k = 0; k < kNumWalls; ++k) {
    b[static_cast<std::size_t>(k)] = simulation.walls[static_cast<std::size_t>(k)].position;
  }
  return b;
}

void GenerateConfig::validate(const std::array<double, 6>& box) const {
  if (count == 0) throw ConfigError(bad_value("particles.generate.count", "0", "a positive count"));
  if (!(diameter_min > 0.0) || !std::isfinite(diameter_min)) {
    throw ConfigError(bad_value("particles.generate.diameter_min", show_number(diameter_min),
                                "a positive diameter in m"));
  }
  if (!(diameter_max >= diameter_min) || !std::isfinite(diameter_max)) {
    throw ConfigError(bad_value("particles.generate.diameter_max", show_number(diameter_max),
                                "a diameter >= particles.generate.diameter_min in m"));
  }
  const double side = std::min({box[1] - box[0], box[3] - box[2], box[5] - box[4]});
  if (diameter_max >= side) {
    throw ConfigError(
        bad_value("particles.generate.diameter_max", show_number(diameter_max),
                  "a diameter smaller than the box side " + show_number(side) + " m"));
  }
  // Random sequential addition jams near a solid fraction of 0.38 for spheres; ask for less.
  const double V = (box[1] - box[0]) * (box[3] - box[2]) * (box[5] - box[4]);
  const double dm = 0.5 * (diameter_min + diameter_max);
  const double solid = static_cast<double>(count) * kPi / 6.0 * dm * dm * dm;
  if (solid > 0.3 * V) {
    throw ConfigError(bad_value(
        "particles.generate.count", std::to_string(count),
        "at most about " + std::to_string(static_cast<long>(0.3 * V / (kPi / 6.0 * dm * dm * dm))) +
            " grains: random placement without overlap cannot exceed a "
            "solid fraction of 0.3 in this box"));
  }
}

void ParticlesConfig::validate(const std::array<double, 6>& box) const {
  if (file.empty()) {
    if (generate.count == 0) {
      throw ConfigError(
          "particles: expected 'particles.file' or [particles.generate] with count > 0");
    }
    generate.validate(box);
  } else if (!std::filesystem::exists(file)) {
    throw ConfigError(bad_value("particles.file", "\"" + file + "\"",
                                "an existing particle file (a prepared sample: `crushdem-sand run "
                                "SAMPLE.toml --out DIR` writes DIR/sample.txt)"));
  } else {
    // Read here too, so that `crushdem-sand check` finds a bad file (its rows, ids, positions) and
    // grains that stick out of the box, not the run. A loaded sample presses its outer grains
    // slightly into the walls: an overlap up to a tenth of the radius is accepted.
    const Packing pk = read_packing(file);
    for (const PackingRow& r : pk.rows) {
      const double x[3] = {r.position.x, r.position.y, r.position.z};
      const double reach = 0.9 * 0.5 * r.diameter;
      for (int a = 0; a < 3; ++a) {
        if (x[a] - reach < box[static_cast<std::size_t>(2 * a)] ||
            x[a] + reach > box[static_cast<std::size_t>(2 * a + 1)]) {
          throw ConfigError(file + ": particle " + std::to_string(r.id) + " (centre " +
                            show_number(x[0]) + ", " + show_number(x[1]) + ", " +
                            show_number(x[2]) + " m, diameter " + show_number(r.diameter) +
                            " m) is not inside the box: expected every grain between the walls");
        }
      }
    }
  }
}

const ParamTable<OutputConfig>& output_params() {
  using O = OutputConfig;
  static const ParamTable<O> table = {
      {"interval", &O::interval, "", "steps between rows of `timeseries.csv`",
       [](double v) { return v > 0.0; }, "a number of steps >= 1"},
      {"vtk_interval", &O::vtk_interval, "",
       "steps between ParaView snapshots (counted from step 0); 0 = none between the frames "
       "always written: the first state (a prepared sample once prepared), each stage's start, "
       "each dynamic phase's end and the last state"},
      {"progress_seconds", &O::progress_seconds, "s",
       "wall-clock seconds between progress lines on the terminal; 0 = none",
       [](double v) { return v >= 0.0; }, "a time >= 0 in s"},
      {"checkpoint_seconds", &O::checkpoint_seconds, "s",
       "wall-clock seconds between periodic checkpoints; 0 = only at ageing events and stage "
       "ends (see Checkpoints)",
       [](double v) { return v >= 0.0; },
       "a wall-clock time >= 0 in s (0: checkpoints at events and stage ends only)"},
  };
  return table;
}

const ParamTable<UpscalingConfig>& upscaling_params() {
  using U = UpscalingConfig;
  static const ParamTable<U> table = {
      {"factor", &U::factor, "-",
       "N: each grain stands for a real grain N times smaller; the grading (or the generated "
       "diameters), `contact.roughness_Sq`, `crushing.d0` (when given), `crushing.d_min` and "
       "`crushing.v0` are multiplied by N for the run (docs/chamber.md, Particle upscaling)",
       [](double v) { return v >= 1.0 && v <= 1e4; }, "a factor from 1 to 1e4"},
      {"strength", enum_choice(&U::strength, kUpscaledStrengthNames), "",
       "the strength's size effect: `\"similar\"` gives a grain the strength of the real grain "
       "it stands for, sigma_lim0 (d / (N d0))^(-3/m) (CHOICE, Ciantia et al. 2015); "
       "`\"weibull\"` applies the size effect at the upscaled size (N^(-3/m) weaker)"},
  };
  return table;
}

RunConfig upscaled(const RunConfig& c) {
  const double N = c.upscaling.factor;
  if (N == 1.0) return c;
  RunConfig u = c;
  for (double& d : u.sample.grading.diameter) d *= N;
  u.particles.generate.diameter_min *= N;
  u.particles.generate.diameter_max *= N;
  u.simulation.contact.roughness_Sq *= N;
  CrushingConfig& k = u.crushing;
  k.d_min *= N;
  k.v0 *= N;
  // d0 in use: the real reference diameter N d0 at the simulated scale ("similar"), or the real
  // d0 itself ("weibull"); with d0 = 0 the initial d50, which is already the simulated grains'.
  const bool similar = c.upscaling.strength == UpscaledStrength::Similar;
  if (k.d0 > 0.0) {
    k.d0_factor = similar ? N : 1.0;
  } else {
    k.d0_factor = similar ? 1.0 : 1.0 / N;
  }
  if (u.has_sample) place_sample_box(u);
  return u;
}

namespace {

// A body driven in a sector of a chamber: on the sector's axis, the z axis, and moving along it.
void check_on_axis(const BodyConfig& body, std::size_t j) {
  const std::string key = "body[" + std::to_string(j) + "].";
  const char* why =
      "the sample is a sector of a chamber about the z axis, and a body driven "
      "in it must be on that axis";
  if (body.origin.x != 0.0 || body.origin.y != 0.0) {
    throw ConfigError(bad_value(key + "origin", show_vec(body.origin),
                                std::string("a point on the z axis, [0, 0, z]: ") + why));
  }
  if (body.axis.x != 0.0 || body.axis.y != 0.0) {
    throw ConfigError(
        bad_value(key + "axis", show_vec(body.axis), std::string("the z axis, [0, 0, 1]: ") + why));
  }
  if (body.direction.x != 0.0 || body.direction.y != 0.0) {
    throw ConfigError(bad_value(key + "direction", show_vec(body.direction),
                                std::string("[0, 0, -1] (or [0, 0, 0]: -axis): ") + why));
  }
}

}  // namespace

void RunConfig::validate_stage_sequence() const {
  // The ageing clock runs on through the age stages: each `until` beyond the clock before it.
  double clock = 0.0;
  for (std::size_t i = 0; i < stages.size(); ++i) {
    const StageConfig& s = stages[i];
    if (s.kind != &age_stage_kind()) continue;
    if (s.until > 0.0 && !(s.until > clock)) {
      throw ConfigError(bad_value("stage[" + std::to_string(i) + "].until", show_number(s.until),
                                  "an ageing time after the one the age stages before it reach (" +
                                      show_number(clock) + " s)"));
    }
    clock = s.until > 0.0 ? s.until : clock + s.duration;
  }
  // A body's travel into the sample: penetrate stages, then compression load tests; a load test
  // comes after its body's installation, and no body ends inside the bottom platen.
  const std::array<double, 6> b = upscaled(*this).box();
  const double height = b[5] - b[4];
  // A sector of a chamber about the z axis: a body driven there must be on that axis.
  const bool sector = has_sample ? sample.sector_fraction() < 1.0
                                 : file_chamber_radius > 0.0 && file_sector < 360.0;
  for (std::size_t j = 0; j < simulation.bodies.size(); ++j) {
    const BodyConfig& body = simulation.bodies[j];
    double travel = 0.0;  // below the sample's top, when the first push starts there
    bool installed = false, from_top = false;
    std::size_t installed_by = 0;
    for (std::size_t i = 0; i < stages.size(); ++i) {
      const StageConfig& s = stages[i];
      if (s.body != body.name) continue;
      const std::string prefix = "stage[" + std::to_string(i) + "]";
      if (s.kind == &penetrate_stage_kind()) {
        if (installed && s.from_top) {
          throw ConfigError(bad_value(
              prefix + ".from_top", "true",
              "false: body \"" + body.name + "\" is already in the sample (stage[" +
                  std::to_string(installed_by) +
                  "] pushed it); from_top lowers a body from above the top wall at its first "
                  "push"));
        }
        if (!installed) {
          if (sector) check_on_axis(body, j);
          from_top = s.from_top;
          installed_by = i;
        }
        installed = true;
        travel += s.depth;
      } else if (s.kind == &load_test_stage_kind()) {
        if (!installed) {
          throw ConfigError(bad_value(prefix + ".body", "\"" + s.body + "\"",
                                      "a body a penetrate stage before it has installed (a load "
                                      "test comes after the installation)"));
        }
        travel += s.direction == LoadDirection::Compression ? s.displacement : -s.displacement;
      } else {
        continue;
      }
      if (from_top && height > 0.0 && travel >= height) {
        throw ConfigError(
            bad_value(prefix + (s.kind == &penetrate_stage_kind() ? ".depth" : ".displacement"),
                      show_number(s.kind == &penetrate_stage_kind() ? s.depth : s.displacement),
                      "a travel that keeps body \"" + body.name +
                          "\"'s tip above the bottom platen: it "
                          "would reach " +
                          show_number(travel) + " m below the sample's top, and the sample is " +
                          show_number(height) + " m high"));
      }
    }
  }
}

std::vector<std::string> RunConfig::warnings() const {
  std::vector<std::string> out =
      plausibility_warnings(simulation.material, material_params(), "material");
  if (crushing.enabled) {
    for (std::string& w : plausibility_warnings(crushing, crushing_params(), "crushing")) {
      out.push_back(std::move(w));
    }
  }
  if (has_sample && sample.compaction == Compaction::Walls) {
    // The walls' sweep jams around a loose core in wide samples: measured at 63 d50 across (a
    // hole about a chamber's axis), slight at 31, none in a cube 23 across (docs/chamber.md,
    // "Compaction"). 40 is where this warns (CHOICE).
    const RunConfig run = upscaled(*this);
    const double across = run.sample.cube_side() / run.sample.grading.diameter_at(0.5);
    if (across > 40.0) {
      out.push_back(
          "sample.compaction = \"walls\" on a sample " + std::to_string(std::lround(across)) +
          " d50 across: the walls' sweep can leave a sample this wide with a loose "
          "core (docs/chamber.md, Compaction); sample.compaction = \"affine\" contracts it "
          "evenly");
    }
  }
  return out;
}

void RunConfig::validate() const {
  // The sample before the walls: a sample's walls come from its keys (void_ratio, grading), so
  // a bad one is named by its own key, not by the wall position it made.
  validate_params(simulation.material, material_params(), "material");
  validate_params(upscaling, upscaling_params(), "upscaling");
  // The sample as the run makes it: with upscaled grains.
  if (has_sample) upscaled(*this).sample.validate(simulation);
  simulation.validate();
  if (has_sample || file_chamber_radius > 0.0) {
    for (std::size_t i = 0; i < simulation.bodies.size(); ++i) {
      const std::string& n = simulation.bodies[i].name;
      if (has_sample && sample.shape != SampleShape::Cylinder) continue;
      for (const char* made : kSampleBodyNames) {
        if (n != made) continue;
        throw ConfigError(bad_value("body[" + std::to_string(i) + "].name", "\"" + n + "\"",
                                    "another name: a cylindrical sample makes the bodies "
                                    "\"chamber\", \"symmetry_x\" and \"symmetry_y\""));
      }
    }
  }
  if (!has_sample) particles.validate(box());
  // Upscaled grains carry lengths (S_q, d_min, v0) that a run at another factor would give the
  // wrong sizes.
  if (!has_sample && !particles.file.empty() && file_upscaling_factor != upscaling.factor) {
    throw ConfigError(bad_value("upscaling.factor", show_number(upscaling.factor),
                                show_number(file_upscaling_factor) + ", the factor " +
                                    particles.file + " was prepared with (its '# " +
                                    kUpscalingHeader + "=' header; none: 1)"));
  }
  for (std::size_t i = 0; i < stages.size(); ++i) {
    // A kind that cannot run here is said first, whatever its keys.
    if (stages[i].kind->needs_crack_growth && !(crushing.enabled && crushing.crack_growth)) {
      throw ConfigError("stage[" + std::to_string(i) + "]: an \"" +
                        std::string(stages[i].kind->name) +
                        "\" stage needs crack growth: add [crushing] with crack_growth = true");
    }
    const std::string prefix = "stage[" + std::to_string(i) + "]";
    stages[i].validate(prefix);
    if (stages[i].kind->check_bodies) {
      stages[i].kind->check_bodies(stages[i], simulation.bodies, prefix);
    }
  }
  validate_stage_sequence();
  validate_params(output, output_params(), "output");
  if (crushing.enabled) {
    crushing.validate();
    if (!crushing.pattern.empty()) SplitPattern::from_file(crushing.pattern);  // fails early
  }
  if (has_sample || !stages.empty()) {
    if (steps != 0 || duration != 0.0) {
      throw ConfigError("run: a [sample] or [[stage]] run ends with its last stage; remove [run]");
    }
    return;
  }
  if ((steps == 0) == (duration <= 0.0)) {
    throw ConfigError(
        "run: expected exactly one of 'run.steps' (a positive count) or "
        "'run.duration' (a positive time in s)");
  }
  if (!std::isfinite(duration) || duration < 0.0) {
    throw ConfigError(bad_value("run.duration", std::to_string(duration), "a positive time in s"));
  }
}

toml::Table to_toml(const SimulationConfig& c) {
  Table t;
  t["material"] = Value::make_table(write_params(c.material, material_params()));
  t["contact"] = Value::make_table(write_params(c.contact, contact_params()));
  t["damping"] = Value::make_table(write_params(c.damping, damping_params()));
  t["timestep"] = Value::make_table(write_params(c.timestep, timestep_params()));
  t["neighbor"] = Value::make_table(write_params(c.neighbor, neighbor_params()));
  // Written only when on: a run without gravity keeps the configuration text it had.
  if (c.gravity.on()) t["gravity"] = Value::make_table(write_params(c.gravity, gravity_params()));
  Table box;
  std::vector<Value> lo, hi;
  for (int a = 0; a < 3; ++a) {
    lo.push_back(num(c.walls[static_cast<std::size_t>(2 * a)].position));
    hi.push_back(num(c.walls[static_cast<std::size_t>(2 * a + 1)].position));
  }
  box["min"] = Value::make_array(lo);
  box["max"] = Value::make_array(hi);
  t["box"] = Value::make_table(box);
  Table walls;
  for (int k = 0; k < kNumWalls; ++k) {
    const WallConfig& w = c.walls[static_cast<std::size_t>(k)];
    const Table wt = write_params(w, wall_params());
    walls[wall_name(k)] = Value::make_table(wt);
  }
  t["walls"] = Value::make_table(walls);
  if (!c.bodies.empty()) {  // written only when there are any: a box run's file is unchanged
    std::vector<Value> bodies;
    for (const BodyConfig& b : c.bodies) {
      bodies.push_back(Value::make_table(write_params(b, body_params())));
    }
    t["body"] = Value::make_array(bodies);
  }
  return t;
}

namespace {
toml::Table output_table(const OutputConfig& o) {
  using toml::Value;
  return write_params(o, output_params());
}
}  // namespace

toml::Table to_toml(const RunConfig& c) {
  Table t = to_toml(c.simulation);
  // Every key of the set is written as well; the name says where they came from.
  t["parameters"] = Value::make_string(c.parameters.name);
  if (c.has_sample || !c.stages.empty()) t.erase("walls");  // the stages set the walls
  if (c.has_sample) {
    t.erase("box");
    const SampleConfig& s = c.sample;
    Table st, g;
    std::vector<Value> d, pa;
    for (double x : s.grading.diameter) d.push_back(num(x));
    for (double x : s.grading.passing) pa.push_back(num(x));
    g["diameter"] = Value::make_array(d);
    g["passing"] = Value::make_array(pa);
    st["grading"] = Value::make_table(g);
    for (auto& [key, value] : write_params(s, sample_params())) st[key] = value;
    if (s.count == 0) st["side"] = num(s.cube_side());  // the side in use (4 mm when not given)
    t["sample"] = Value::make_table(st);
  }
  if (!c.stages.empty()) {
    std::vector<Value> arr;
    for (const StageConfig& s : c.stages) {
      Table st = write_params(s, s.kind->params);
      st["type"] = Value::make_string(std::string(s.kind->name));
      st["name"] = Value::make_string(s.label());
      arr.push_back(Value::make_table(st));
    }
    t["stage"] = Value::make_array(arr);
  }
  if (c.crushing.enabled) {
    const CrushingConfig& k = c.crushing;
    Table ct = write_params(k, crushing_params());
    if (!k.pattern.empty()) ct["pattern"] = Value::make_string(k.pattern);
    t["crushing"] = Value::make_table(ct);
  }
  // Written only when on: a run without upscaling keeps the configuration text it had.
  if (c.upscaling.factor != 1.0) {
    t["upscaling"] = Value::make_table(write_params(c.upscaling, upscaling_params()));
  }
  if (c.has_sample || !c.stages.empty()) {
    t["output"] = Value::make_table(output_table(c.output));
    if (c.has_sample) return t;
  }
  Table p;
  if (!c.particles.file.empty()) {
    p["file"] = Value::make_string(c.particles.file);
  } else {
    p["generate"] = Value::make_table(write_params(c.particles.generate, generate_params()));
  }
  t["particles"] = Value::make_table(p);
  if (!c.stages.empty()) return t;
  Table r;
  if (c.steps > 0) r["steps"] = cnt(c.steps);
  if (c.duration > 0.0) r["duration"] = num(c.duration);
  t["run"] = Value::make_table(r);
  t["output"] = Value::make_table(output_table(c.output));
  return t;
}

}  // namespace crushdem

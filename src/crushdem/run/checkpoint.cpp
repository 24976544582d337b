#include "crushdem/run/checkpoint.hpp"

#include <array>
#include <cstring>

#include "crushdem/core/build_info.hpp"
#include "crushdem/core/error.hpp"
#include "crushdem/experiments/protocol.hpp"
#include "crushdem/fracture/crushing.hpp"
#include "crushdem/io/config.hpp"
#include "crushdem/run/driver.hpp"
#include "crushdem/run/run_directory.hpp"

namespace crushdem {

namespace {

/// A JSON object as two lists of strings, keys and values.
void json_state(StateArchive& a, JsonObject& o) {
  std::vector<std::string> keys, values;
  for (const auto& [k, v] : o.fields) {
    keys.push_back(k);
    values.push_back(v);
  }
  a(keys, values);
  if (!a.loading()) return;
  o.fields.clear();
  for (std::size_t k = 0; k < keys.size() && k < values.size(); ++k) {
    o.fields.emplace_back(keys[k], values[k]);
  }
}

/// The version of a checkpoint's format tag, 0 if it is not one crushdem can read.
int checkpoint_version(const std::string& format) {
  for (int v = 1; v <= kStateVersion; ++v) {
    if (format == checkpoint_tag(v)) return v;
  }
  return 0;
}

}  // namespace

void RunPosition::state(StateArchive& a) {
  a.section("progress");
  a(part, begun, to_check, wall_seconds);
  // Saved as the format's seven parts, the wall loop's seconds within contact_forces (timing.json
  // splits them again from the resumed process on).
  constexpr auto kWalls = static_cast<std::size_t>(Part::WallForces);
  std::array<double, PartClock::kParts - 1> saved{};
  for (std::size_t k = 0, j = 0; k < PartClock::kParts; ++k) {
    if (k == kWalls) {
      saved[kWalls - 1] += part_seconds[k];
    } else {
      saved[j++] += part_seconds[k];
    }
  }
  a.since(2, saved, particle_steps);
  if (a.loading()) {
    for (std::size_t k = 0, j = 0; k < PartClock::kParts; ++k) {
      part_seconds[k] = k == kWalls ? 0.0 : saved[j++];
    }
  }
  a(has_sample_json);
  json_state(a, sample_json);
  const auto n = a.value<std::uint64_t>(stage_results.size());
  if (a.loading()) stage_results.assign(n, {});
  for (JsonObject& o : stage_results) json_state(a, o);
  a(warnings, ref0, ref, d50, has_crusher);
  a.since(8, builds);
  // An older format is always another build's: its resume is said as one.
  if (a.loading() && a.version() < 8) builds = {"a crushdem before checkpoint format 8"};
}

std::string this_build() {
  return std::string(CRUSHDEM_VERSION) + " (" + build_commit() + ")";
}

std::string note_build(std::vector<std::string>& builds, const std::string& current,
                       const std::string& what) {
  std::string warning;
  if (!builds.empty() && builds.back() != current) {
    // A change of build may change the physics (the CHANGELOG says which); the steps from here
    // on are this build's, and the run's results are no longer one build's.
    warning = "this run is " + what + " by crushdem " + current + "; it was run so far by " +
              builds.back() + ": its results from here on are this build's (CHANGELOG.md lists " +
              "what changed between them)";
  }
  if (builds.empty() || builds.back() != current) builds.push_back(current);
  return warning;
}

std::string checkpoint_tag(int version) {
  return "crushdem-checkpoint-" + std::to_string(version);
}

std::string checkpoint_bytes(const std::string& config_text, const RunPosition& position,
                             const Driver& driver, const Simulation& sim, const Crusher* crusher,
                             const Controller* running) {
  StateWriter out;
  out.tag(checkpoint_tag(kStateVersion).c_str());
  out.put(config_text);
  save_state(position, out);
  save_state(driver, out);
  save_state(sim, out);
  if (crusher) save_state(*crusher, out);
  if (running) save_state(*running, out);
  out.put(fnv1a64(out.bytes().data(), out.bytes().size()));
  return out.bytes();
}

OpenCheckpoint open_checkpoint(const std::string& path) {
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
                        "be resumed; start the run again with `crushdem-sand run ... --overwrite`");
    }
    bytes.resize(bytes.size() - sizeof saved);
  }
  OpenCheckpoint c;
  c.reader = std::make_unique<StateReader>(std::move(bytes), path);
  std::string format;
  c.reader->get(format);
  c.reader->set_version(version);
  c.reader->get(c.config_text);
  return c;
}

std::string saved_config_difference(const std::string& saved, const std::string& current,
                                    const std::filesystem::path& dir) {
  if (saved == current) return "";
  const std::string source = (dir / "checkpoint.bin").string();
  toml::Table again;
  try {
    again = to_toml(saved_run_config_from_toml(toml::parse(saved, source), source, dir.string()));
  } catch (const std::exception& e) {
    // Not readable as a configuration any more: certainly not the same run.
    return std::string("its saved configuration no longer reads (") + e.what() + ")";
  }
  if (toml::serialize(again) == current) return "";
  const std::string d = config_difference(
      again, toml::parse(current, (dir / "config.toml").string()), "the checkpoint");
  return d.empty() ? "the two differ once resolved" : d;
}

}  // namespace crushdem

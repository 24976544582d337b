// Named parameter sets: the model keys on which crushdem's set (the engine's defaults) and the
// reference study's Table 1 as printed differ. A configuration picks a set with the top-level key
// `parameters`; a key the file gives itself always wins over its set. Why crushdem's set differs
// from Table 1 (rotation blocked, d0 = 1.07 mm): docs/model.md 1.5 and 2.1, and the decision
// study of docs/crushing.md.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "crushdem/fracture/crushing.hpp"
#include "crushdem/integrate/simulation.hpp"
#include "crushdem/io/toml.hpp"

namespace crushdem {

/// The set a configuration without a `parameters` key gets.
inline constexpr const char* kDefaultParameterSet = "crushdem";

struct ParameterSet {
  std::string_view name;
  std::string_view doc;  // one line: what the set is
  // The values, as {"contact": {...}, "crushing": {...}}: only keys on which sets differ.
  toml::Table values;
};

/// Every named set, the default first.
const std::vector<ParameterSet>& parameter_sets();

/// "\"crushdem\" or \"table1\"": the names, for messages and docs.
std::string set_names();

/// The set named `name`; ConfigError naming `key`, the value and the names otherwise.
const ParameterSet& parameter_set(const std::string& name, const std::string& key = "parameters");

/// Which set a configuration used and which of its keys the file gave itself ("contact.rotation").
struct ParameterSetUse {
  std::string name = kDefaultParameterSet;
  bool named = false;  // the file gave `parameters`
  std::vector<std::string> given;
};

/// Sets the set's values in `contact` and `crushing`, before a file's own keys are read.
void apply_parameter_set(const ParameterSet& set, ContactConfig& contact, CrushingConfig& crushing);

/// The top-level key `parameters` of `root` read, its set applied to `contact` and `crushing`,
/// and the set's keys that `root` gives recorded.
ParameterSetUse read_parameter_set(const toml::Table& root, const std::string& source,
                                   ContactConfig& contact, CrushingConfig& crushing);

/// What `crushdem-sand check` prints: the set, and for each of its keys in use the value and
/// whether it came from the set or from the file. `crushing_on`: report the [crushing] keys.
std::vector<std::string> parameter_set_report(const ParameterSetUse& use,
                                              const ContactConfig& contact,
                                              const CrushingConfig& crushing, bool crushing_on);

}  // namespace crushdem

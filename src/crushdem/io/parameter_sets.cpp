#include "crushdem/io/parameter_sets.hpp"

#include <algorithm>

#include "crushdem/core/error.hpp"
#include "crushdem/io/param_io.hpp"

namespace crushdem {
namespace {

using toml::Table;
using toml::Value;

Table section(const char* key, Value value) {
  Table t;
  t[key] = std::move(value);
  return t;
}

Table values(const char* rotation, double d0) {
  Table t;
  t["contact"] = Value::make_table(section("rotation", Value::make_string(rotation)));
  t["crushing"] = Value::make_table(section("d0", Value::make_float(d0)));
  return t;
}

const Table& section_of(const ParameterSet& set, const std::string& name) {
  static const Table none;
  const auto it = set.values.find(name);
  return it == set.values.end() ? none : *it->second.table;
}

}  // namespace

std::string set_names() {
  std::string out;
  const auto& sets = parameter_sets();
  for (std::size_t k = 0; k < sets.size(); ++k) {
    out.append(k == 0 ? "" : (k + 1 == sets.size() ? " or " : ", "));
    out.append(1, '"').append(sets[k].name).append(1, '"');
  }
  return out;
}

const std::vector<ParameterSet>& parameter_sets() {
  static const std::vector<ParameterSet> sets = {
      {kDefaultParameterSet,
       "crushdem's set: Table 1 with rotation blocked and d0 = 1.07 mm (the decision study of "
       "docs/crushing.md; q_max 21.5 MPa against the study's 22.6 on four REV samples)",
       values("blocked", 1.07e-3)},
      {"table1",
       "Table 1 as the study printed it: free rotation (Table 1 names no rotation model) and d0 "
       "= d50 of the initial grains",
       values("free", 0.0)},
  };
  return sets;
}

const ParameterSet& parameter_set(const std::string& name, const std::string& key) {
  for (const ParameterSet& s : parameter_sets()) {
    if (s.name == name) return s;
  }
  throw ConfigError(bad_value(key, "\"" + name + "\"", "a parameter set: " + set_names()));
}

void apply_parameter_set(const ParameterSet& set, ContactConfig& contact,
                         CrushingConfig& crushing) {
  param_io::Section c(&section_of(set, "contact"), "contact", "parameter set");
  param_io::read_params(c, contact, contact_params());
  param_io::Section k(&section_of(set, "crushing"), "crushing", "parameter set");
  param_io::read_params(k, crushing, crushing_params());
}

ParameterSetUse read_parameter_set(const toml::Table& root, const std::string& source,
                                   ContactConfig& contact, CrushingConfig& crushing) {
  ParameterSetUse use;
  const auto it = root.find("parameters");
  if (it != root.end()) {
    const Value& v = it->second;
    const param_io::Section top(&root, "", source);
    if (v.type != toml::Type::String) {
      top.fail("parameters", v, "the name of a parameter set: " + set_names());
    }
    const auto& sets = parameter_sets();
    if (std::none_of(sets.begin(), sets.end(),
                     [&](const ParameterSet& s) { return s.name == v.str; })) {
      top.fail("parameters", v, "a parameter set: " + set_names());
    }
    use.name = v.str;
    use.named = true;
  }
  const ParameterSet& set = parameter_set(use.name);
  apply_parameter_set(set, contact, crushing);
  for (const auto& [name, keys] : set.values) {
    const auto sec = root.find(name);
    for (const auto& [key, value] : *keys.table) {
      if (sec != root.end() && sec->second.type == toml::Type::Table &&
          sec->second.table->count(key)) {
        use.given.push_back(name + "." + key);
      }
    }
  }
  return use;
}

std::vector<std::string> parameter_set_report(const ParameterSetUse& use,
                                              const ContactConfig& contact,
                                              const CrushingConfig& crushing, bool crushing_on) {
  const ParameterSet& set = parameter_set(use.name);
  std::vector<std::string> out;
  out.push_back("parameters = \"" + use.name + "\" (" +
                (use.named ? "named by the file" : "the default") + "): " + std::string(set.doc));
  const Table contact_now = param_io::write_params(contact, contact_params());
  const Table crushing_now = param_io::write_params(crushing, crushing_params());
  for (const auto& [name, keys] : set.values) {
    if (name == "crushing" && !crushing_on) continue;
    const Table& now = name == "contact" ? contact_now : crushing_now;
    for (const auto& [key, value] : *keys.table) {
      const std::string full = name + "." + key;
      bool given = false;
      for (const std::string& g : use.given) given = given || g == full;
      const auto v = now.find(key);
      const std::string shown = v == now.end() ? "?" : param_io::show(v->second);
      // Not given and not the set's: another key implied it (rolling_friction > 0 without a
      // rotation key means "rolling").
      const char* origin = given                            ? " (set by the file)"
                           : shown == param_io::show(value) ? " (from the set)"
                           : full == "contact.rotation"
                               ? " (implied by contact.rolling_friction > 0)"
                               : " (implied by other keys)";
      out.push_back("  " + full + " = " + shown + origin);
    }
  }
  return out;
}

}  // namespace crushdem

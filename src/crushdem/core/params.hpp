// Declarative parameter tables (in the manner of HOOMD-blue's ParameterDict and LAMMPS
// pair granular's coeffs_to_local): one row per configuration key of a struct, giving the TOML
// key, the member it sets, its unit, its range and a one-line description. The default is the
// member's value in a default-constructed struct. The TOML reader and writer, the range checks
// (validate_params), docs/configuration.md and the Python docstrings all come from the rows, so
// adding a key is one row. Pure data and checks, no I/O.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>
#include <variant>
#include <vector>

#include "crushdem/core/error.hpp"
#include "crushdem/core/types.hpp"

namespace crushdem {

/// A key with a fixed set of string values stored as an enum: how to read it from and write it
/// to its struct. `set` throws ConfigError naming `key` for a value not in `choices`.
template <class S>
struct ParamChoice {
  std::function<std::string(const S&)> get;
  std::function<void(S&, const std::string& value, const std::string& key)> set;
  std::string choices;  // for messages and docs, e.g. "\"hertz\" or \"rough\""
};

/// An enum value and its name in configuration files.
template <class E>
struct Named {
  E value;
  std::string_view name;
};

/// "\"a\", \"b\" or \"c\"": the names, for messages and docs.
template <class E, std::size_t N>
std::string choice_list(const std::array<Named<E>, N>& names) {
  std::string out;
  for (std::size_t k = 0; k < N; ++k) {
    out += k == 0 ? "" : (k + 1 == N ? " or " : ", ");
    out += "\"";
    out += names[k].name;
    out += "\"";
  }
  return out;
}

/// The name of `value` among `names` (empty if it has none).
template <class E, std::size_t N>
const char* name_of(const std::array<Named<E>, N>& names, E value) {
  for (const Named<E>& n : names) {
    if (n.value == value) return n.name.data();
  }
  return "";
}

/// The value named `s`; ConfigError naming `key`, the value and the names otherwise.
template <class E, std::size_t N>
E parse_named(const std::array<Named<E>, N>& names, const std::string& s, const std::string& key) {
  for (const Named<E>& n : names) {
    if (s == n.name) return n.value;
  }
  throw ConfigError(bad_value(key, "\"" + s + "\"", choice_list(names)));
}

/// A choice row for an enum member of S with named values.
template <class S, class E, std::size_t N>
ParamChoice<S> enum_choice(E S::*member, const std::array<Named<E>, N>& names) {
  return {[member, names](const S& s) { return std::string(name_of(names, s.*member)); },
          [member, names](S& s, const std::string& v, const std::string& key) {
            s.*member = parse_named(names, v, key);
          },
          choice_list(names)};
}

template <class S>
struct Param {
  using Number = double S::*;
  using Count = std::uint64_t S::*;
  using Flag = bool S::*;
  using Text = std::string S::*;
  using Triple = Vec3 S::*;  // [x, y, z]: a point or a direction
  std::string_view key;
  std::variant<Number, Count, Flag, Text, Triple, ParamChoice<S>> member;
  std::string_view unit;  // SI unit, "-" for a pure number, "" where none applies
  std::string_view doc;   // one line: what it is, where it comes from (STUDY / CHOICE ...)
  // Range of a Number (finite always; NaN never passes) or a Count: the check and the
  // expected-value text of its error message. No check when `ok` is null.
  bool (*ok)(double) = nullptr;
  std::string_view expected = {};
  // Shown as the default in the docs instead of the default-constructed struct's value (for a
  // key whose effective default depends on where it is read).
  std::string_view default_doc = {};
  // The key applies only where this holds (a servo target with a servo wall): written to
  // config.toml and range-checked only then; always when null.
  std::function<bool(const S&)> applies = {};
  // The values a physical material takes (a Number only): a valid value outside them gives a
  // warning, not an error (a deliberate numerical experiment may want it). None when null.
  bool (*plausible)(double) = nullptr;
  std::string_view plausible_range = {};
  // The key whose value `applies` reads (a field's rings: field_interval), where that is
  // another key: given without it where the row does not apply, the key is refused naming it.
  std::string_view needs = {};
};

template <class S>
using ParamTable = std::vector<Param<S>>;

/// Whether struct S is large enough to hold a Triple (a Vec3) member: only then is a Triple row
/// read or written (GCC warns about the member access it cannot prove unreachable otherwise).
template <class S>
inline constexpr bool kMayHoldTriple = sizeof(S) >= sizeof(Vec3);

/// A member pointer of a base (T Part::*) as one of the derived whole (T S::*).
template <class S, class T, class Part>
T S::*member_of_whole(T Part::*m) {
  return m;
}

/// The rows of a part's table as rows of the whole it is a base of (a contact law's keys as
/// keys of [contact]): member pointers of a base convert to member pointers of the derived.
template <class S, class Part>
void append_rows(ParamTable<S>& out, const ParamTable<Part>& rows) {
  static_assert(std::is_base_of_v<Part, S>, "the part must be a base of the whole");
  for (const Param<Part>& p : rows) {
    Param<S> q;
    q.key = p.key;
    q.unit = p.unit;
    q.doc = p.doc;
    q.ok = p.ok;
    q.expected = p.expected;
    q.default_doc = p.default_doc;
    q.plausible = p.plausible;
    q.plausible_range = p.plausible_range;
    q.needs = p.needs;
    if (p.applies) q.applies = [f = p.applies](const S& s) { return f(s); };
    std::visit(
        [&q](const auto& m) {
          using M = std::decay_t<decltype(m)>;
          if constexpr (std::is_same_v<M, ParamChoice<Part>>) {
            q.member = ParamChoice<S>{
                [g = m.get](const S& s) { return g(s); },
                [f = m.set](S& s, const std::string& v, const std::string& key) { f(s, v, key); },
                m.choices};
          } else {
            q.member = member_of_whole<S>(m);
          }
        },
        p.member);
    out.push_back(std::move(q));
  }
}

/// The range checks of `table` on `obj`; errors name "section.key", the value and the range.
template <class S>
void validate_params(const S& obj, const ParamTable<S>& table, const std::string& section) {
  for (const Param<S>& p : table) {
    if (p.applies && !p.applies(obj)) continue;
    double v = 0.0;
    // A point or direction is finite whatever else its row checks (an infinite origin would
    // place a body nowhere and a run would step forever).
    if (std::holds_alternative<typename Param<S>::Triple>(p.member)) {
      if constexpr (!kMayHoldTriple<S>) continue;
      const Vec3 t = obj.*std::get<typename Param<S>::Triple>(p.member);
      if (!std::isfinite(t.x) || !std::isfinite(t.y) || !std::isfinite(t.z)) {
        throw ConfigError(bad_value(
            section + "." + std::string(p.key),
            "[" + show_number(t.x) + ", " + show_number(t.y) + ", " + show_number(t.z) + "]",
            std::string(p.expected)));
      }
      continue;
    }
    if (!p.ok) continue;
    if (const auto* num = std::get_if<typename Param<S>::Number>(&p.member)) {
      v = obj.*(*num);
    } else if (const auto* cnt = std::get_if<typename Param<S>::Count>(&p.member)) {
      v = static_cast<double>(obj.*(*cnt));
    } else {
      continue;
    }
    if (!std::isfinite(v) || !p.ok(v)) {
      throw ConfigError(
          bad_value(section + "." + std::string(p.key), show_number(v), std::string(p.expected)));
    }
  }
}

/// The warnings for valid values outside what a physical material takes: "section.key = value is
/// outside RANGE" for each.
template <class S>
std::vector<std::string> plausibility_warnings(const S& obj, const ParamTable<S>& table,
                                               const std::string& section) {
  std::vector<std::string> out;
  for (const Param<S>& p : table) {
    if (!p.plausible || (p.applies && !p.applies(obj))) continue;
    const auto* num = std::get_if<typename Param<S>::Number>(&p.member);
    if (!num) continue;
    const double v = obj.*(*num);
    if (!p.plausible(v)) {
      out.push_back(section + "." + std::string(p.key) + " = " + show_number(v) +
                    " is outside what a grain material takes (" + std::string(p.plausible_range) +
                    "): the run goes on, check the value");
    }
  }
  return out;
}

}  // namespace crushdem

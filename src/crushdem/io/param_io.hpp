// Reading and writing configuration sections through their parameter tables
// (core/params.hpp): the Section reader (types checked, unknown keys reported with the file and
// line), read_params / write_params for a table, a table's rows as plain values (ParamRow, what
// the docs and Python show) and its Markdown reference. Used by io/config.cpp; a test drives it
// with a made-up table of its own.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <set>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "crushdem/core/error.hpp"
#include "crushdem/core/params.hpp"
#include "crushdem/io/shortest.hpp"
#include "crushdem/io/toml.hpp"

namespace crushdem::param_io {

using toml::Table;
using toml::Type;
using toml::Value;

inline std::string show(const Value& v) {
  switch (v.type) {
    case Type::String: return "\"" + v.str + "\"";
    case Type::Integer: return std::to_string(v.integer);
    case Type::Float: return show_number(v.real);
    case Type::Boolean: return v.boolean ? "true" : "false";
    case Type::Array: return "an array";
    case Type::Table: return "a table";
  }
  return "?";
}

/// Reads one section, remembering which keys were used so that unknown keys are reported.
class Section {
 public:
  Section(const Table* t, std::string prefix, std::string source)
      : t_(t), prefix_(std::move(prefix)), source_(std::move(source)) {}

  std::string key(const std::string& k) const { return prefix_.empty() ? k : prefix_ + "." + k; }
  std::string where(const Value& v) const {
    return v.line > 0 ? source_ + ":" + std::to_string(v.line) + ": " : source_ + ": ";
  }
  [[noreturn]] void fail(const std::string& k, const Value& v, const std::string& expected) const {
    throw ConfigError(where(v) + bad_value(key(k), show(v), expected));
  }
  const Value* find(const std::string& k) {
    known_.insert(k);
    if (!t_) return nullptr;
    auto it = t_->find(k);
    return it == t_->end() ? nullptr : &it->second;
  }
  void number(const std::string& k, double& out, const char* expected = "a number") {
    if (const Value* v = find(k)) {
      if (!v->is_number()) fail(k, *v, expected);
      out = v->as_number();
    }
  }
  /// `expected`: the range the value is checked against later, named here too, so that a value
  /// that is no integer at all (1e20, 2.5, -1) hears the same range as one outside it.
  void count(const std::string& k, std::uint64_t& out, const std::string& expected = "") {
    if (const Value* v = find(k)) {
      if (v->type != Type::Integer || v->integer < 0) {
        fail(k, *v, expected.empty() ? "an integer >= 0" : "an integer: " + expected);
      }
      out = static_cast<std::uint64_t>(v->integer);
    }
  }
  void boolean(const std::string& k, bool& out) {
    if (const Value* v = find(k)) {
      if (v->type != Type::Boolean) fail(k, *v, "true or false");
      out = v->boolean;
    }
  }
  void string(const std::string& k, std::string& out) {
    if (const Value* v = find(k)) {
      if (v->type != Type::String) fail(k, *v, "a string");
      out = v->str;
    }
  }
  void vec3(const std::string& k, double out[3], bool& present,
            const std::string& expected = "an array of 3 numbers [x, y, z] in m") {
    present = false;
    if (const Value* v = find(k)) {
      if (v->type != Type::Array || v->array.size() != 3 ||
          !std::all_of(v->array.begin(), v->array.end(),
                       [](const Value& x) { return x.is_number(); })) {
        fail(k, *v, expected);
      }
      for (int d = 0; d < 3; ++d) out[d] = v->array[static_cast<std::size_t>(d)].as_number();
      present = true;
    }
  }
  /// An array of numbers (at least one).
  void numbers(const std::string& k, std::vector<double>& out, const char* expected) {
    if (const Value* v = find(k)) {
      if (v->type != Type::Array || v->array.empty() ||
          !std::all_of(v->array.begin(), v->array.end(),
                       [](const Value& x) { return x.is_number(); })) {
        fail(k, *v, expected);
      }
      out.clear();
      for (const Value& x : v->array) out.push_back(x.as_number());
    }
  }
  /// An array of tables ([[k]] sections); returns one Section per element.
  std::vector<Section> table_array(const std::string& k) {
    std::vector<Section> out;
    if (const Value* v = find(k)) {
      if (v->type != Type::Array ||
          !std::all_of(v->array.begin(), v->array.end(),
                       [](const Value& x) { return x.type == Type::Table; })) {
        fail(k, *v, "an array of tables [[" + key(k) + "]]");
      }
      for (std::size_t i = 0; i < v->array.size(); ++i) {
        out.emplace_back(v->array[i].table.get(), key(k) + "[" + std::to_string(i) + "]", source_);
      }
    }
    return out;
  }
  Section sub(const std::string& k) {
    const Value* v = find(k);
    if (v && v->type != Type::Table) fail(k, *v, "a table [" + key(k) + "]");
    return Section(v ? v->table.get() : nullptr, key(k), source_);
  }
  bool has(const std::string& k) const { return t_ && t_->count(k); }
  /// The value of key `k` as written in the file ("given" where it is not there).
  std::string shown(const std::string& k) const {
    if (!t_) return "given";
    auto it = t_->find(k);
    return it == t_->end() ? "given" : show(it->second);
  }
  /// Throws for any key that no reader asked for.
  void finish() const {
    if (!t_) return;
    for (const auto& [k, v] : *t_) {
      if (!known_.count(k)) {
        std::string valid;
        for (const auto& n : known_) valid += (valid.empty() ? "" : ", ") + n;
        throw ConfigError(where(v) + "unknown key '" + key(k) + "'" +
                          (valid.empty() ? "" : " (valid keys: " + valid + ")"));
      }
    }
  }

 private:
  const Table* t_;
  std::string prefix_, source_;
  std::set<std::string> known_;
};

/// Every key of `table` that the section holds, into `obj` (types checked, errors naming the
/// key and line); the range checks follow in validate().
template <class S>
void read_params(Section& s, S& obj, const ParamTable<S>& table) {
  for (const Param<S>& p : table) {
    const std::string k(p.key);
    if (const auto* num = std::get_if<typename Param<S>::Number>(&p.member)) {
      s.number(k, obj.*(*num));
    } else if (const auto* cnt = std::get_if<typename Param<S>::Count>(&p.member)) {
      s.count(k, obj.*(*cnt), std::string(p.expected));
    } else if (const auto* flag = std::get_if<typename Param<S>::Flag>(&p.member)) {
      s.boolean(k, obj.*(*flag));
    } else if (const auto* text = std::get_if<typename Param<S>::Text>(&p.member)) {
      s.string(k, obj.*(*text));
    } else if (const auto* choice = std::get_if<ParamChoice<S>>(&p.member)) {
      std::string v = choice->get(obj);
      s.string(k, v);
      choice->set(obj, v, s.key(k));
    } else if constexpr (kMayHoldTriple<S>) {
      double v[3];
      bool present = false;
      if (p.expected.empty()) {
        s.vec3(k, v, present);
      } else {
        s.vec3(k, v, present, std::string(p.expected));
      }
      if (present) obj.*std::get<typename Param<S>::Triple>(p.member) = Vec3{v[0], v[1], v[2]};
    }
  }
}

/// Every key of `table` with its value in `obj`, as written to config.toml.
template <class S>
Table write_params(const S& obj, const ParamTable<S>& table) {
  Table t;
  for (const Param<S>& p : table) {
    if (p.applies && !p.applies(obj)) continue;
    const std::string k(p.key);
    if (const auto* num = std::get_if<typename Param<S>::Number>(&p.member)) {
      t[k] = Value::make_float(obj.*(*num));
    } else if (const auto* cnt = std::get_if<typename Param<S>::Count>(&p.member)) {
      t[k] = Value::make_integer(static_cast<std::int64_t>(obj.*(*cnt)));
    } else if (const auto* flag = std::get_if<typename Param<S>::Flag>(&p.member)) {
      t[k] = Value::make_bool(obj.*(*flag));
    } else if (const auto* text = std::get_if<typename Param<S>::Text>(&p.member)) {
      t[k] = Value::make_string(obj.*(*text));
    } else if (const auto* choice = std::get_if<ParamChoice<S>>(&p.member)) {
      t[k] = Value::make_string(choice->get(obj));
    } else if constexpr (kMayHoldTriple<S>) {
      const Vec3 v = obj.*std::get<typename Param<S>::Triple>(p.member);
      t[k] = Value::make_array(
          {Value::make_float(v.x), Value::make_float(v.y), Value::make_float(v.z)});
    }
  }
  return t;
}

/// Refuses a key the section gives where its row does not apply to `obj` (a servo target for a
/// fixed wall, a field's rings without its interval): almost always a forgotten switch, and a
/// silent run without what the key asked for otherwise. A row that names its switch (`needs`)
/// passes when the switch is given too, as off (a sweep's variant that turns it off and keeps
/// its keys); with `every_row`, a row without one is refused as well (a wall's and a body's
/// keys, which their mode and shape switch), else it passes (a stage's own switches, `steps`,
/// `unload`: their values are checked by the stage). `why(row)` says what was expected instead.
template <class S, class Why>
void refuse_unused_keys(const Section& s, const S& obj, const ParamTable<S>& table, bool every_row,
                        Why why) {
  for (const Param<S>& p : table) {
    const std::string k(p.key);
    if (!p.applies || p.applies(obj) || !s.has(k)) continue;
    if (p.needs.empty() ? !every_row : s.has(std::string(p.needs))) continue;
    throw ConfigError(bad_value(s.key(k), s.shown(k), why(p)));
  }
}

/// The shortest form that reads back exactly, with a plain exponent (2650, 3.2e10, 6e-7).
inline std::string doc_number(double v) {
  char buf[32];
  const auto res = shortest_chars(buf, buf + sizeof buf, v);
  std::string s(buf, static_cast<std::size_t>(res.ptr - buf));
  const std::size_t e = s.find('e');
  if (e == std::string::npos) return s;
  std::string mantissa = s.substr(0, e), exponent = s.substr(e + 1);
  const bool negative = !exponent.empty() && exponent[0] == '-';
  if (!exponent.empty() && (exponent[0] == '+' || exponent[0] == '-')) exponent.erase(0, 1);
  while (exponent.size() > 1 && exponent[0] == '0') exponent.erase(0, 1);
  return mantissa + "e" + (negative ? "-" : "") + exponent;
}

/// Pipes would end a Markdown table cell.
inline std::string cell(std::string_view text) {
  std::string out;
  for (char c : text) {
    if (c == '|') out += '\\';
    out += c;
  }
  return out;
}

/// One row of a table as plain values: what docs/configuration.md and Python show of it.
struct ParamRow {
  using Value = std::variant<double, std::uint64_t, bool, std::string, std::array<double, 3>>;
  std::string key;
  std::string type;  // the Python type: "float", "int", "bool", "str" (a text or a choice), "list"
  Value default_value;      // the member's value in a default-constructed struct
  std::string default_doc;  // shown instead of the value ("-": none, the key must be given)
  std::string unit, doc;
  std::string choices;   // a choice's values, e.g. "\"fixed\" or \"servo\"" (empty otherwise)
  bool checked = false;  // a range check, whose expected value is `expected`
  std::string expected;
  std::string plausible;  // the values outside which a run warns (empty: none)
};

/// The member type T of a pointer to member T S::*.
template <class M>
struct MemberOf;
template <class T, class S>
struct MemberOf<T S::*> {
  using type = T;
};

template <class S>
std::vector<ParamRow> param_rows(const ParamTable<S>& table) {
  static const S d{};  // the defaults (static: GCC 12 misreads a local as uninitialised)
  std::vector<ParamRow> rows;
  for (const Param<S>& p : table) {
    ParamRow r;
    r.key = p.key;
    r.default_doc = p.default_doc;
    r.unit = p.unit;
    r.doc = p.doc;
    r.checked = p.ok != nullptr;
    if (r.checked) r.expected = p.expected;
    if (p.plausible) r.plausible = p.plausible_range;
    std::visit(
        [&r](const auto& m) {
          using M = std::decay_t<decltype(m)>;
          if constexpr (std::is_same_v<M, ParamChoice<S>>) {
            r.type = "str";
            r.default_value = m.get(d);
            r.choices = m.choices;
          } else {
            using T = typename MemberOf<M>::type;
            // (A member larger than the struct is no member of it: GCC cannot prove the access
            // unreachable and warns, so it is not compiled.)
            if constexpr (sizeof(T) <= sizeof(S)) {
              const T& v = d.*m;
              if constexpr (std::is_same_v<T, double>) {
                r.type = "float";
                r.default_value = v;
              } else if constexpr (std::is_same_v<T, std::uint64_t>) {
                r.type = "int";
                r.default_value = v;
              } else if constexpr (std::is_same_v<T, bool>) {
                r.type = "bool";
                r.default_value = v;
              } else if constexpr (std::is_same_v<T, std::string>) {
                r.type = "str";
                r.default_value = v;
              } else {  // Vec3: [x, y, z]
                r.type = "list";
                r.default_value = std::array<double, 3>{v.x, v.y, v.z};
              }
            }
          }
        },
        p.member);
    rows.push_back(std::move(r));
  }
  return rows;
}

/// The docs' default of a row: its default_doc, or its value.
inline std::string default_text(const ParamRow& r) {
  if (!r.default_doc.empty()) return r.default_doc;
  if (const auto* num = std::get_if<double>(&r.default_value)) return doc_number(*num);
  if (const auto* cnt = std::get_if<std::uint64_t>(&r.default_value)) return std::to_string(*cnt);
  if (const auto* flag = std::get_if<bool>(&r.default_value)) return *flag ? "true" : "false";
  if (const auto* v = std::get_if<std::array<double, 3>>(&r.default_value)) {
    return "[" + doc_number((*v)[0]) + ", " + doc_number((*v)[1]) + ", " + doc_number((*v)[2]) +
           "]";
  }
  return "`\"" + std::get<std::string>(r.default_value) + "\"`";
}

/// A table's rows as the Markdown table of docs/configuration.md, then `extra_rows`.
inline std::string markdown(const std::vector<ParamRow>& rows,
                            const std::vector<std::string>& extra_rows = {}) {
  std::string out = "| key | default | unit | meaning |\n|---|---|---|---|\n";
  for (const ParamRow& r : rows) {
    std::string meaning = r.doc;
    if (!r.choices.empty()) meaning += "; one of " + r.choices;
    if (r.checked) meaning += "; expected: " + r.expected;
    if (!r.plausible.empty()) meaning += "; warns outside " + r.plausible;
    out +=
        "| `" + r.key + "` | " + default_text(r) + " | " + r.unit + " | " + cell(meaning) + " |\n";
  }
  for (const std::string& row : extra_rows) out += row + "\n";
  return out;
}

template <class S>
std::string markdown(const ParamTable<S>& table, const std::vector<std::string>& extra_rows = {}) {
  return markdown(param_rows(table), extra_rows);
}

}  // namespace crushdem::param_io

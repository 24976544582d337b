// TOML reading through toml++ (its parse tree converted to Value, with source lines) and the
// writer of crushdem's own files, see toml.hpp.
#include "crushdem/io/toml.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <utility>

#include "crushdem/core/error.hpp"
#include "crushdem/io/shortest.hpp"

// Header-only use in this one translation unit: no shared library at run time, and the Debian
// package and the fetched release build the same way.
#define TOML_HEADER_ONLY 1
#define TOML_EXCEPTIONS 1
#define TOML_ENABLE_FORMATTERS 0
#include <toml++/toml.h>

namespace crushdem::toml {

// ------------------------------------------------------------------------------------------------
// Value

Value::Value(const Value& other)
    : type(other.type),
      str(other.str),
      integer(other.integer),
      real(other.real),
      boolean(other.boolean),
      array(other.array),
      table(other.table ? std::make_shared<Table>(*other.table) : nullptr),
      line(other.line) {}

Value& Value::operator=(const Value& other) {
  if (this != &other) *this = Value(other);
  return *this;
}

namespace {

// Scalars carry no table; avoids one allocation per scalar.
Value scalar(Type type) {
  Value v;
  v.type = type;
  v.table.reset();
  return v;
}

}  // namespace

Value Value::make_string(std::string s) {
  Value v = scalar(Type::String);
  v.str = std::move(s);
  return v;
}

Value Value::make_integer(std::int64_t i) {
  Value v = scalar(Type::Integer);
  v.integer = i;
  return v;
}

Value Value::make_float(double d) {
  Value v = scalar(Type::Float);
  v.real = d;
  return v;
}

Value Value::make_bool(bool b) {
  Value v = scalar(Type::Boolean);
  v.boolean = b;
  return v;
}

Value Value::make_array(std::vector<Value> elements) {
  Value v = scalar(Type::Array);
  v.array = std::move(elements);
  return v;
}

Value Value::make_table(Table t) {
  Value v;
  *v.table = std::move(t);
  return v;
}

bool Value::is_number() const {
  return type == Type::Integer || type == Type::Float;
}

double Value::as_number() const {
  if (type == Type::Integer) return static_cast<double>(integer);
  if (type == Type::Float) return real;
  throw std::logic_error(std::string("toml value of type ") + type_name(type) + " is not a number");
}

namespace {

const Table& table_of(const Value& v) {
  static const Table kEmpty;  // tolerate a Table value whose pointer was reset by user code
  return v.table ? *v.table : kEmpty;
}

}  // namespace

bool operator==(const Value& a, const Value& b) {
  if (a.type != b.type) return false;
  switch (a.type) {
    case Type::String: return a.str == b.str;
    case Type::Integer: return a.integer == b.integer;
    case Type::Float: return a.real == b.real || (std::isnan(a.real) && std::isnan(b.real));
    case Type::Boolean: return a.boolean == b.boolean;
    case Type::Array: return a.array == b.array;
    case Type::Table: return table_of(a) == table_of(b);
  }
  return false;
}

const char* type_name(Type t) {
  switch (t) {
    case Type::String: return "string";
    case Type::Integer: return "integer";
    case Type::Float: return "float";
    case Type::Boolean: return "boolean";
    case Type::Array: return "array";
    case Type::Table: return "table";
  }
  return "unknown";
}

// ------------------------------------------------------------------------------------------------
// Character classes for the writer

namespace {

bool is_digit(char c) {
  return c >= '0' && c <= '9';
}
bool is_alpha(char c) {
  return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z');
}
bool is_bare_key_char(char c) {
  return is_alpha(c) || is_digit(c) || c == '_' || c == '-';
}
// TOML forbids raw control characters (except tab) in strings and comments.
bool is_control(char c) {
  const auto u = static_cast<unsigned char>(c);
  return (u < 0x20 && c != '\t') || u == 0x7f;
}

void write_string(std::string& out, std::string_view s) {
  out += '"';
  for (char c : s) {
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\b': out += "\\b"; break;
      case '\t': out += "\\t"; break;
      case '\n': out += "\\n"; break;
      case '\f': out += "\\f"; break;
      case '\r': out += "\\r"; break;
      default:
        if (is_control(c)) {
          char buf[8];
          std::snprintf(buf, sizeof buf, "\\u%04X", static_cast<unsigned>(c) & 0xffu);
          out += buf;
        } else {
          out += c;
        }
    }
  }
  out += '"';
}

void write_key(std::string& out, const std::string& key) {
  bool bare = !key.empty();
  for (char c : key) bare = bare && is_bare_key_char(c);
  if (bare) {
    out += key;
  } else {
    write_string(out, key);
  }
}

// The first n parts of a dotted key as it would be written in TOML, for messages and headers.
// ------------------------------------------------------------------------------------------------
// Reader: toml++'s tree converted to Value

std::string where(const std::string& source, const ::toml::source_region& at) {
  return source + ":" + std::to_string(at.begin.line) + ": ";
}

int line_of(const ::toml::node& node) {
  return static_cast<int>(node.source().begin.line);
}

Value convert(const ::toml::node& node, const std::string& key, const std::string& source,
              int depth);

Table convert_table(const ::toml::table& t, const std::string& path, const std::string& source,
                    int depth) {
  Table out;
  for (const auto& [k, child] : t) {
    const std::string name =
        path.empty() ? std::string(k.str()) : path + "." + std::string(k.str());
    out.emplace(std::string(k.str()), convert(child, name, source, depth + 1));
  }
  return out;
}

Value convert(const ::toml::node& node, const std::string& key, const std::string& source,
              int depth) {
  if (depth > kMaxNesting) {
    throw ConfigError(where(source, node.source()) + "'" + key.substr(0, 60) +
                      "...': tables and arrays nested more than " + std::to_string(kMaxNesting) +
                      " deep (no configuration goes beyond 4)");
  }
  Value v;
  switch (node.type()) {
    case ::toml::node_type::table:
      v = Value::make_table(convert_table(*node.as_table(), key, source, depth));
      break;
    case ::toml::node_type::array: {
      std::vector<Value> elements;
      const ::toml::array& a = *node.as_array();
      elements.reserve(a.size());
      for (size_t i = 0; i < a.size(); ++i) {
        elements.push_back(convert(a[i], key + "[" + std::to_string(i) + "]", source, depth + 1));
      }
      v = Value::make_array(std::move(elements));
      break;
    }
    case ::toml::node_type::string: v = Value::make_string(node.as_string()->get()); break;
    case ::toml::node_type::integer: v = Value::make_integer(node.as_integer()->get()); break;
    case ::toml::node_type::floating_point:
      v = Value::make_float(node.as_floating_point()->get());
      break;
    case ::toml::node_type::boolean: v = Value::make_bool(node.as_boolean()->get()); break;
    default:  // date, time, date-time: no configuration key takes one
      throw ConfigError(where(source, node.source()) + "'" + key +
                        "': dates and times are not supported; use a string or a number");
  }
  v.line = line_of(node);
  return v;
}

// ------------------------------------------------------------------------------------------------
// Serializer

void write_float(std::string& out, double d) {
  if (std::isnan(d)) {
    out += std::signbit(d) ? "-nan" : "nan";
  } else if (std::isinf(d)) {
    out += d < 0 ? "-inf" : "inf";
  } else {
    char buf[64];
    const auto res = shortest_chars(buf, buf + sizeof buf, d);  // shortest exact round trip
    const std::string_view s(buf, static_cast<size_t>(res.ptr - buf));
    out += s;
    // "1" would read back as an integer.
    if (s.find_first_of(".eE") == std::string_view::npos) out += ".0";
  }
}

void write_inline(std::string& out, const Value& v) {
  switch (v.type) {
    case Type::String: write_string(out, v.str); break;
    case Type::Integer: out += std::to_string(v.integer); break;
    case Type::Float: write_float(out, v.real); break;
    case Type::Boolean: out += v.boolean ? "true" : "false"; break;
    case Type::Array:
      out += '[';
      for (size_t i = 0; i < v.array.size(); ++i) {
        if (i > 0) out += ", ";
        write_inline(out, v.array[i]);
      }
      out += ']';
      break;
    case Type::Table: {
      const Table& t = table_of(v);
      out += '{';
      const char* sep = " ";
      for (const auto& [k, child] : t) {
        out += sep;
        write_key(out, k);
        out += " = ";
        write_inline(out, child);
        sep = ", ";
      }
      out += t.empty() ? "}" : " }";
      break;
    }
  }
}

bool is_table_array(const Value& v) {
  if (v.type != Type::Array || v.array.empty()) return false;
  for (const Value& e : v.array) {
    if (e.type != Type::Table) return false;
  }
  return true;
}

// Plain keys must precede every section header of the same table, hence two passes.
void write_body(std::string& out, const Table& t, const std::string& path) {
  for (const auto& [k, v] : t) {
    if (v.type == Type::Table || is_table_array(v)) continue;
    write_key(out, k);
    out += " = ";
    write_inline(out, v);
    out += '\n';
  }
  for (const auto& [k, v] : t) {
    if (v.type != Type::Table && !is_table_array(v)) continue;
    std::string child = path;
    if (!child.empty()) child += '.';
    write_key(child, k);
    if (v.type == Type::Table) {
      out += (out.empty() ? "[" : "\n[") + child + "]\n";
      write_body(out, table_of(v), child);
    } else {
      for (const Value& e : v.array) {
        out += (out.empty() ? "[[" : "\n[[") + child + "]]\n";
        write_body(out, table_of(e), child);
      }
    }
  }
}

/// toml++'s message for a key given twice prints a quoted key garbled ('"a a b" ' for "a b"):
/// the key as the line writes it instead, or the message as it is when the line is not found.
std::string parse_message(std::string_view text, const ::toml::parse_error& e) {
  std::string message(e.description());
  // Only a quoted key comes out garbled; a bare one is named well.
  if (message.find("cannot redefine existing") == std::string::npos ||
      message.find('"') == std::string::npos) {
    return message;
  }
  std::size_t begin = 0;
  for (std::uint32_t line = 1; line < e.source().begin.line; ++line) {
    begin = text.find('\n', begin);
    if (begin == std::string_view::npos) return message;
    ++begin;
  }
  std::string_view line = text.substr(begin, text.find('\n', begin) - begin);
  const std::size_t eq = line.find('=');
  if (eq == std::string_view::npos) return message;
  line = line.substr(0, eq);
  while (!line.empty() && (line.front() == ' ' || line.front() == '\t')) line.remove_prefix(1);
  while (!line.empty() && (line.back() == ' ' || line.back() == '\t')) line.remove_suffix(1);
  // A key = value line with a quoted key; anything else (an inline table) keeps the message.
  if (line.empty() || line.front() != '"' || line.back() != '"') return message;
  return "key '" + std::string(line) +
         "' is given twice in its table (TOML allows each key once; remove one)";
}

}  // namespace

Table parse(std::string_view text, const std::string& source_name) {
  try {
    const ::toml::table root = ::toml::parse(text, std::string_view(source_name));
    return convert_table(root, "", source_name, 0);
  } catch (const ::toml::parse_error& e) {
    throw ConfigError(where(source_name, e.source()) + parse_message(text, e));
  }
}

Table parse_file(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) {
    throw ConfigError("cannot read config file '" + path + "': it is a directory");
  }
  // A configuration is a few kilobytes; a device or a huge file is not one.
  constexpr std::uintmax_t kMaxBytes = std::uintmax_t{16} << 20;
  if (std::filesystem::exists(path, ec) && !std::filesystem::is_regular_file(path, ec)) {
    throw ConfigError("cannot read config file '" + path + "': not a regular file");
  }
  if (std::filesystem::exists(path, ec) && std::filesystem::file_size(path, ec) > kMaxBytes) {
    throw ConfigError("cannot read config file '" + path + "': larger than 16 MiB");
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ConfigError("cannot open config file '" + path + "'");
  const std::string text{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  if (in.bad()) throw ConfigError("cannot read config file '" + path + "'");
  return parse(text, path);
}

std::string serialize(const Table& root) {
  std::string out;
  write_body(out, root, "");
  return out;
}

}  // namespace crushdem::toml

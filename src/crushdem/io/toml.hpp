// TOML for configuration files and run directories: toml++ reads (TOML 1.0, errors with source
// and line), and the tree is handed on as plain Values that carry the line each value came from,
// so that config readers can point at the offending line. Dates and times are rejected with a
// clear error: no key takes one. The writer is crushdem's own: deterministic (sorted keys) and
// with floats in their shortest form that reads back to the same double.
//
// Values are plain data: copying a Value copies the whole subtree (the shared_ptr only exists to
// make the recursive type legal), so a copied table never aliases the original.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace crushdem::toml {

enum class Type { String, Integer, Float, Boolean, Array, Table };

struct Value;
/// Sorted keys, so that serialization and iteration order are deterministic.
using Table = std::map<std::string, Value>;

struct Value {
  Type type = Type::Table;
  std::string str;
  std::int64_t integer = 0;
  double real = 0.0;
  bool boolean = false;
  std::vector<Value> array;
  /// Non-null when type == Table. A default-constructed Value is an empty table ready to fill.
  std::shared_ptr<Table> table = std::make_shared<Table>();
  /// 1-based source line where the value was defined (0 if built in code); lets config readers
  /// point at the offending line when a value parses but is semantically wrong.
  int line = 0;

  Value() = default;
  Value(const Value& other);  // deep copy, see the file comment
  Value& operator=(const Value& other);
  Value(Value&&) noexcept = default;
  Value& operator=(Value&&) noexcept = default;
  ~Value() = default;

  static Value make_string(std::string s);
  static Value make_integer(std::int64_t i);
  static Value make_float(double d);
  static Value make_bool(bool b);
  static Value make_array(std::vector<Value> elements);
  static Value make_table(Table t = {});

  /// Integer or Float.
  bool is_number() const;
  /// Integer converted to double, or Float; throws std::logic_error for any other type.
  double as_number() const;
};

/// Structural equality: same type and content, `line` ignored, NaN equal to NaN (so that a
/// round trip through serialize() compares equal).
bool operator==(const Value& a, const Value& b);

/// "string", "integer", "float", "boolean", "array", "table".
const char* type_name(Type t);

/// The deepest nesting of tables and arrays a configuration may have (none goes beyond 4): a file
/// of dotted keys or headers 10^4 parts long, or a Python dict as deep, is an error rather than
/// unbounded recursion. toml++ bounds inline nesting itself.
inline constexpr int kMaxNesting = 64;

/// Parses a TOML document. Errors throw crushdem::ConfigError("SOURCE:LINE: what is wrong").
Table parse(std::string_view text, const std::string& source_name = "<string>");

/// Reads and parses a file; a missing or unreadable file throws ConfigError naming the path.
Table parse_file(const std::string& path);

/// Writes valid TOML that parse() reads back to an equal tree: plain values first, then
/// sub-tables as [a.b] sections and arrays of tables as [[a]] sections.
std::string serialize(const Table& root);

}  // namespace crushdem::toml

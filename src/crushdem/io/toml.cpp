// TOML 1.0 parser and serializer, see toml.hpp. The parser is a single-pass recursive descent
// over the text; the only state beyond the cursor is how each table came into existence, which
// the TOML rules need in order to tell "add to a table" from "redefine a table".
#include "crushdem/io/toml.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <stdexcept>
#include <unordered_map>
#include <unordered_set>
#include <utility>

#include "crushdem/core/error.hpp"

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
// Character classes and output helpers shared by parser (error messages) and serializer

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
// Characters that can make up a number, boolean or (rejected) date token.
bool is_token_char(char c) {
  return is_bare_key_char(c) || c == '+' || c == '.' || c == ':';
}
// TOML forbids raw control characters (except tab) in strings and comments.
bool is_control(char c) {
  const auto u = static_cast<unsigned char>(c);
  return (u < 0x20 && c != '\t') || u == 0x7f;
}

int digit_value(char c) {
  if (is_digit(c)) return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return 99;
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
std::string dotted(const std::vector<std::string>& parts, size_t n = std::string::npos) {
  std::string out;
  for (size_t i = 0; i < parts.size() && i < n; ++i) {
    if (i > 0) out += '.';
    write_key(out, parts[i]);
  }
  return out;
}

void append_utf8(std::string& out, std::uint32_t cp) {
  if (cp < 0x80) {
    out += static_cast<char>(cp);
  } else if (cp < 0x800) {
    out += static_cast<char>(0xc0 | (cp >> 6));
    out += static_cast<char>(0x80 | (cp & 0x3f));
  } else if (cp < 0x10000) {
    out += static_cast<char>(0xe0 | (cp >> 12));
    out += static_cast<char>(0x80 | ((cp >> 6) & 0x3f));
    out += static_cast<char>(0x80 | (cp & 0x3f));
  } else {
    out += static_cast<char>(0xf0 | (cp >> 18));
    out += static_cast<char>(0x80 | ((cp >> 12) & 0x3f));
    out += static_cast<char>(0x80 | ((cp >> 6) & 0x3f));
    out += static_cast<char>(0x80 | (cp & 0x3f));
  }
}

// ------------------------------------------------------------------------------------------------
// Parser

// How a table came into existence decides what may add to it later (TOML 1.0, "Table").
enum class Origin : std::uint8_t {
  kImplicit,  // parent created by a [a.b.c] header; may still be defined once by [a.b]
  kHeader,    // defined by its own [header] or [[header]]; no second definition
  kDotted,    // created by dotted keys; only further dotted keys of the same section extend it
  kInline,    // inline table: self-contained, nothing can be added outside the braces
};

class Parser {
 public:
  Parser(std::string_view text, const std::string& source) : s_(text), source_(source) {
    if (s_.substr(0, 3) == "\xEF\xBB\xBF") pos_ = 3;  // editors on Windows add a byte order mark
  }

  Table run() {
    check_utf8();
    Value root = Value::make_table();
    origin_[root.table.get()] = Origin::kHeader;
    current_ = root.table.get();
    while (true) {
      skip_ws();
      if (eof()) break;
      const char c = peek();
      if (c == '#') {
        skip_comment();
      } else if (c == '\n' || c == '\r') {
        consume_newline();
      } else if (c == '[') {
        parse_header(*root.table);
      } else {
        parse_keyval(*current_);
        expect_line_end("value");
      }
    }
    return std::move(*root.table);
  }

 private:
  [[noreturn]] void fail_at(int line, const std::string& what) const {
    throw ConfigError(source_ + ":" + std::to_string(line) + ": " + what);
  }
  [[noreturn]] void fail(const std::string& what) const { fail_at(line_, what); }

  // TOML documents must be valid UTF-8; checking once up front keeps string parsing byte-based.
  void check_utf8() const {
    int line = 1;
    for (size_t i = pos_; i < s_.size();) {
      const auto b = static_cast<unsigned char>(s_[i]);
      if (b < 0x80) {
        line += b == '\n';
        ++i;
        continue;
      }
      const size_t len = b >= 0xf8 ? 0 : b >= 0xf0 ? 4 : b >= 0xe0 ? 3 : b >= 0xc0 ? 2 : 0;
      bool ok = len != 0;
      std::uint32_t cp = b & (0x7f >> len);
      for (size_t k = 1; ok && k < len; ++k) {
        const auto c = static_cast<unsigned char>(i + k < s_.size() ? s_[i + k] : 0);
        ok = (c & 0xc0) == 0x80;
        cp = (cp << 6) | (c & 0x3f);
      }
      const std::uint32_t min = len == 2 ? 0x80 : len == 3 ? 0x800 : 0x10000;  // no overlongs
      if (!ok || cp > 0x10ffff || cp < min || (cp >= 0xd800 && cp <= 0xdfff)) {
        fail_at(line, "invalid UTF-8 byte sequence");
      }
      i += len;
    }
  }

  bool eof() const { return pos_ >= s_.size(); }
  char peek(size_t off = 0) const { return pos_ + off < s_.size() ? s_[pos_ + off] : '\0'; }
  bool at(std::string_view lit) const { return s_.substr(pos_, lit.size()) == lit; }
  bool at_newline() const { return !eof() && (peek() == '\n' || peek() == '\r'); }

  std::string describe_here() const {
    if (eof()) return "end of input";
    if (at_newline()) return "end of line";
    const char c = peek();
    if (is_control(c) || static_cast<unsigned char>(c) >= 0x80) {
      char buf[16];
      std::snprintf(buf, sizeof buf, "byte 0x%02X", static_cast<unsigned>(c) & 0xffu);
      return buf;
    }
    return std::string("'") + c + "'";
  }

  void skip_ws() {
    while (!eof() && (peek() == ' ' || peek() == '\t')) ++pos_;
  }

  void skip_comment() {
    ++pos_;  // '#'
    while (!eof() && peek() != '\n' && !(peek() == '\r' && peek(1) == '\n')) {
      if (is_control(peek())) fail("control character " + describe_here() + " in comment");
      ++pos_;
    }
  }

  void consume_newline() {
    if (peek() == '\r') {
      if (peek(1) != '\n') fail("carriage return not followed by a line feed");
      ++pos_;
    }
    ++pos_;
    ++line_;
  }

  // Whitespace, comments and newlines, as allowed between array elements.
  void skip_blank() {
    while (true) {
      skip_ws();
      if (!eof() && peek() == '#') {
        skip_comment();
      } else if (at_newline()) {
        consume_newline();
      } else {
        return;
      }
    }
  }

  void expect_line_end(const char* after) {
    skip_ws();
    if (!eof() && peek() == '#') skip_comment();
    if (eof()) return;
    if (!at_newline()) fail("unexpected " + describe_here() + " after " + after);
    consume_newline();
  }

  // ---- keys ----

  std::string parse_simple_key() {
    if (at("\"\"\"") || at("'''")) fail("multi-line strings cannot be used as keys");
    if (!eof() && (peek() == '"' || peek() == '\'')) return parse_string_line(peek());
    const size_t start = pos_;
    while (!eof() && is_bare_key_char(peek())) ++pos_;
    if (pos_ == start) fail("expected a key, found " + describe_here());
    return std::string(s_.substr(start, pos_ - start));
  }

  std::vector<std::string> parse_key() {
    std::vector<std::string> key{parse_simple_key()};
    while (true) {
      const size_t save = pos_;
      skip_ws();
      if (eof() || peek() != '.') {
        pos_ = save;
        return key;
      }
      ++pos_;
      skip_ws();
      key.push_back(parse_simple_key());
    }
  }

  Origin origin_of(const Value& v) const {
    const auto it = origin_.find(v.table.get());
    return it == origin_.end() ? Origin::kInline : it->second;  // unknown: inside inline data
  }

  // What an existing value is, for "cannot extend" messages.
  std::string what_is(const Value& v) const {
    if (v.type == Type::Table && origin_of(v) == Origin::kInline) return "an inline table";
    if (v.type == Type::Table) return "a table defined at line " + std::to_string(v.line);
    if (v.type == Type::Array) return "an array value, not an array of tables";
    return std::string("a ") + type_name(v.type);
  }

  Value new_table(int line, Origin origin) {
    Value t = Value::make_table();
    t.line = line;
    origin_[t.table.get()] = origin;
    return t;
  }

  // key = value, inserted into `target` (the current section or an inline table).
  void parse_keyval(Table& target) {
    const int line = line_;
    const std::vector<std::string> key = parse_key();
    skip_ws();
    if (eof() || peek() != '=') {
      fail("expected '=' after key '" + dotted(key) + "', found " + describe_here());
    }
    ++pos_;
    skip_ws();
    if (eof() || at_newline() || peek() == '#') fail("missing value for key '" + dotted(key) + "'");
    Value value = parse_value();

    Table* t = &target;
    for (size_t i = 0; i + 1 < key.size(); ++i) {
      auto it = t->find(key[i]);
      if (it == t->end()) {
        it = t->emplace(key[i], new_table(line, Origin::kDotted)).first;
      } else if (it->second.type != Type::Table || origin_of(it->second) != Origin::kDotted) {
        fail_at(line, "cannot set key '" + dotted(key) + "': '" + dotted(key, i + 1) + "' is " +
                          what_is(it->second));
      }
      t = it->second.table.get();
    }
    const auto it = t->find(key.back());
    if (it != t->end()) {
      fail_at(line, "duplicate key '" + dotted(key) + "' (first defined at line " +
                        std::to_string(it->second.line) + ")");
    }
    t->emplace(key.back(), std::move(value));
  }

  // [a.b] or [[a.b]]; makes the named table the target of the following key/value lines.
  void parse_header(Table& root) {
    ++pos_;
    const bool is_array = !eof() && peek() == '[';
    if (is_array) ++pos_;
    skip_ws();
    const std::vector<std::string> key = parse_key();
    const std::string name = dotted(key);
    skip_ws();
    if (!at(is_array ? "]]" : "]")) {
      fail(std::string("expected '") + (is_array ? "]]" : "]") + "' to close header '" + name +
           "', found " + describe_here());
    }
    pos_ += is_array ? 2 : 1;

    Table* t = &root;
    for (size_t i = 0; i + 1 < key.size(); ++i) {
      auto it = t->find(key[i]);
      if (it == t->end()) it = t->emplace(key[i], new_table(line_, Origin::kImplicit)).first;
      Value& v = it->second;
      if (v.type == Type::Table && origin_of(v) != Origin::kInline) {
        t = v.table.get();
      } else if (v.type == Type::Array && table_arrays_.count(&v.array) != 0) {
        t = v.array.back().table.get();  // [a.b] after [[a]] extends the last element of a
      } else {
        fail("cannot open table '" + name + "': '" + dotted(key, i + 1) + "' is " + what_is(v));
      }
    }

    auto it = t->find(key.back());
    if (!is_array) {
      if (it == t->end()) {
        it = t->emplace(key.back(), new_table(line_, Origin::kHeader)).first;
      } else if (it->second.type == Type::Table && origin_of(it->second) == Origin::kImplicit) {
        origin_[it->second.table.get()] = Origin::kHeader;
        it->second.line = line_;
      } else {
        fail("cannot define table '" + name + "': it is already " + what_is(it->second));
      }
      current_ = it->second.table.get();
    } else {
      if (it == t->end()) {
        Value arr = Value::make_array({});
        arr.line = line_;
        it = t->emplace(key.back(), std::move(arr)).first;
        table_arrays_.insert(&it->second.array);
      } else if (it->second.type != Type::Array || table_arrays_.count(&it->second.array) == 0) {
        fail("cannot define array of tables '" + name + "': it is already " + what_is(it->second));
      }
      Value element = new_table(line_, Origin::kHeader);
      current_ = element.table.get();  // the heap table survives the move into the array
      it->second.array.push_back(std::move(element));
    }
    expect_line_end("table header");
  }

  // ---- values ----

  Value parse_value() {
    const int line = line_;
    Value v;
    const char c = peek();
    if (eof()) {
      fail("expected a value, found end of input");
    } else if (at("\"\"\"") || at("'''")) {
      v = Value::make_string(parse_string_multiline(c));
    } else if (c == '"' || c == '\'') {
      v = Value::make_string(parse_string_line(c));
    } else if (c == '[') {
      v = parse_array();
    } else if (c == '{') {
      v = parse_inline_table();
    } else if (is_token_char(c)) {
      v = parse_token();
    } else {
      fail("expected a value, found " + describe_here());
    }
    v.line = line;
    return v;
  }

  Value parse_array() {
    const int line = line_;
    ++pos_;
    Value arr = Value::make_array({});
    while (true) {
      skip_blank();
      if (eof()) fail_at(line, "unterminated array (missing ']')");
      if (peek() == ']') break;
      arr.array.push_back(parse_value());
      skip_blank();
      if (eof()) fail_at(line, "unterminated array (missing ']')");
      if (peek() == ']') break;
      if (peek() != ',') fail("expected ',' or ']' in array, found " + describe_here());
      ++pos_;
    }
    ++pos_;
    return arr;
  }

  // The table itself is never entered in origin_, so origin_of() reports it as inline and
  // nothing outside the braces can add to it or to the dotted sub-tables it contains.
  Value parse_inline_table() {
    ++pos_;
    Value tbl = Value::make_table();
    skip_ws();
    if (!eof() && peek() == '}') {
      ++pos_;
      return tbl;
    }
    while (true) {
      skip_ws();
      if (!eof() && peek() == '}') fail("trailing comma is not allowed in an inline table");
      if (eof() || at_newline()) fail("unterminated inline table (must be on one line)");
      parse_keyval(*tbl.table);
      skip_ws();
      if (eof() || at_newline()) fail("unterminated inline table (must be on one line)");
      if (peek() == '}') break;
      if (peek() != ',') fail("expected ',' or '}' in inline table, found " + describe_here());
      ++pos_;
    }
    ++pos_;
    return tbl;
  }

  std::uint32_t parse_hex_escape(int digits) {
    std::uint32_t cp = 0;
    for (int i = 0; i < digits; ++i, ++pos_) {
      const int d = eof() ? 99 : digit_value(peek());
      if (d > 15) fail("escape needs " + std::to_string(digits) + " hex digits");
      cp = cp * 16 + static_cast<std::uint32_t>(d);
    }
    if (cp > 0x10ffff || (cp >= 0xd800 && cp <= 0xdfff)) {
      fail("escape does not name a Unicode scalar value");
    }
    return cp;
  }

  void parse_escape(std::string& out, bool multiline) {
    ++pos_;  // the backslash
    if (eof()) fail("unterminated string");
    const char c = peek();
    ++pos_;
    switch (c) {
      case 'b': out += '\b'; return;
      case 't': out += '\t'; return;
      case 'n': out += '\n'; return;
      case 'f': out += '\f'; return;
      case 'r': out += '\r'; return;
      case '"': out += '"'; return;
      case '\\': out += '\\'; return;
      case 'u': append_utf8(out, parse_hex_escape(4)); return;
      case 'U': append_utf8(out, parse_hex_escape(8)); return;
      default: break;
    }
    if (multiline && (c == ' ' || c == '\t' || c == '\n' || c == '\r')) {
      // Line-ending backslash: drop the newline and all whitespace up to the next content.
      --pos_;
      skip_ws();
      if (!at_newline()) fail("only whitespace may follow a line-ending backslash");
      while (true) {
        skip_ws();
        if (!at_newline()) return;
        consume_newline();
      }
    }
    if (c == '\n' || c == '\r') fail("unterminated string");
    fail(std::string("invalid escape sequence '\\") + c + "'");
  }

  // "basic" (escapes) or 'literal' (verbatim) string on one line.
  std::string parse_string_line(char quote) {
    ++pos_;
    std::string out;
    while (true) {
      if (eof() || at_newline())
        fail("unterminated string (missing " + std::string(1, quote) + ")");
      const char c = peek();
      if (c == quote) break;
      if (c == '\\' && quote == '"') {
        parse_escape(out, false);
        continue;
      }
      if (is_control(c)) fail("control character " + describe_here() + " in string");
      out += c;
      ++pos_;
    }
    ++pos_;
    return out;
  }

  // """basic""" or '''literal''' string that may span lines.
  std::string parse_string_multiline(char quote) {
    const int line = line_;
    pos_ += 3;
    if (at_newline()) consume_newline();  // a newline right after the opening quotes is trimmed
    std::string out;
    while (true) {
      if (eof()) fail_at(line, "unterminated multi-line string");
      const char c = peek();
      if (c == quote) {
        // Up to two quotes may sit right before the closing three ("""a"""" is a + '"').
        size_t n = 0;
        while (peek(n) == quote) ++n;
        if (n >= 3) {
          if (n > 5) fail("too many quotes at the end of a multi-line string");
          out.append(n - 3, quote);
          pos_ += n;
          return out;
        }
        out.append(n, quote);
        pos_ += n;
      } else if (c == '\\' && quote == '"') {
        parse_escape(out, true);
      } else if (at_newline()) {
        consume_newline();
        out += '\n';
      } else {
        if (is_control(c)) fail("control character " + describe_here() + " in string");
        out += c;
        ++pos_;
      }
    }
  }

  // Booleans, numbers, and dates (which are recognized only to be rejected clearly).
  Value parse_token() {
    const size_t start = pos_;
    while (!eof() && is_token_char(peek())) ++pos_;
    const std::string_view tok = s_.substr(start, pos_ - start);
    if (tok == "true") return Value::make_bool(true);
    if (tok == "false") return Value::make_bool(false);
    const bool date = tok.size() >= 5 && is_digit(tok[0]) && is_digit(tok[1]) && is_digit(tok[2]) &&
                      is_digit(tok[3]) && tok[4] == '-';
    if (date || tok.find(':') != std::string_view::npos) {
      fail("dates are not supported ('" + std::string(tok) + "'); use a string");
    }
    if (is_alpha(tok[0]) && tok != "inf" && tok != "nan") {
      fail("invalid value '" + std::string(tok) + "' (strings must be quoted)");
    }
    return parse_number(tok);
  }

  // Each '_' must sit between two digits of the given base.
  static bool digits_ok(std::string_view d, int base) {
    if (d.empty() || d.front() == '_' || d.back() == '_') return false;
    for (size_t i = 0; i < d.size(); ++i) {
      if (d[i] == '_') {
        if (d[i + 1] == '_') return false;
      } else if (digit_value(d[i]) >= base) {
        return false;
      }
    }
    return true;
  }

  Value parse_number(std::string_view tok) {
    const auto bad = [&](const std::string& why) {
      fail("invalid number '" + std::string(tok) + "'" + why);
    };
    std::string_view body = tok;
    const bool has_sign = body[0] == '+' || body[0] == '-';
    const bool negative = body[0] == '-';
    if (has_sign) body.remove_prefix(1);
    if (body == "inf" || body == "nan") {
      const double d = body == "inf" ? std::numeric_limits<double>::infinity()
                                     : std::numeric_limits<double>::quiet_NaN();
      return Value::make_float(negative ? -d : d);
    }

    if (body.size() >= 2 && body[0] == '0' &&
        (body[1] == 'x' || body[1] == 'o' || body[1] == 'b')) {
      if (has_sign) bad(": a sign is not allowed on hex, octal or binary integers");
      const int base = body[1] == 'x' ? 16 : body[1] == 'o' ? 8 : 2;
      const std::string_view digits = body.substr(2);
      if (!digits_ok(digits, base)) bad("");
      std::uint64_t acc = 0;
      const auto max = static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max());
      for (char c : digits) {
        if (c == '_') continue;
        const auto d = static_cast<std::uint64_t>(digit_value(c));
        if (acc > (max - d) / static_cast<std::uint64_t>(base)) bad(": out of 64-bit range");
        acc = acc * static_cast<std::uint64_t>(base) + d;
      }
      return Value::make_integer(static_cast<std::int64_t>(acc));
    }

    // Decimal: int-part [ '.' frac ] [ 'e' [sign] exp ]
    const size_t dot = body.find('.');
    const size_t exp = body.find_first_of("eE");
    const std::string_view int_part = body.substr(0, std::min(dot, exp));
    if (int_part.empty()) bad(dot == 0 ? ": a digit must come before '.'" : "");
    if (!digits_ok(int_part, 10)) bad("");
    if (int_part.size() > 1 && int_part[0] == '0') bad(": leading zeros are not allowed");
    bool is_float = false;
    if (dot != std::string_view::npos) {
      if (exp != std::string_view::npos && exp < dot) bad("");
      const std::string_view frac =
          body.substr(dot + 1, exp == std::string_view::npos ? exp : exp - dot - 1);
      if (!digits_ok(frac, 10)) bad(": a digit must follow '.'");
      is_float = true;
    }
    if (exp != std::string_view::npos) {
      std::string_view e = body.substr(exp + 1);
      if (!e.empty() && (e[0] == '+' || e[0] == '-')) e.remove_prefix(1);
      if (!digits_ok(e, 10)) bad(": invalid exponent");
      is_float = true;
    }

    std::string clean = negative ? "-" : "";  // from_chars rejects '+' and '_'
    for (char c : body) {
      if (c != '_') clean += c;
    }
    const char* first = clean.data();
    const char* last = first + clean.size();
    if (is_float) {
      double d = 0.0;
      const auto [ptr, ec] = std::from_chars(first, last, d);
      if (ec != std::errc() || ptr != last) bad(": out of range for a 64-bit float");
      return Value::make_float(d);
    }
    std::int64_t i = 0;
    const auto [ptr, ec] = std::from_chars(first, last, i);
    if (ec != std::errc() || ptr != last) bad(": out of 64-bit integer range");
    return Value::make_integer(i);
  }

  std::string_view s_;
  const std::string& source_;
  size_t pos_ = 0;
  int line_ = 1;
  Table* current_ = nullptr;                         // section receiving key/value lines
  std::unordered_map<const Table*, Origin> origin_;  // tables are heap objects: stable keys
  std::unordered_set<const std::vector<Value>*> table_arrays_;  // made by [[ ]], may grow
};

// ------------------------------------------------------------------------------------------------
// Serializer

void write_float(std::string& out, double d) {
  if (std::isnan(d)) {
    out += std::signbit(d) ? "-nan" : "nan";
  } else if (std::isinf(d)) {
    out += d < 0 ? "-inf" : "inf";
  } else {
    char buf[64];
    const auto res = std::to_chars(buf, buf + sizeof buf, d);  // shortest exact round trip
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

}  // namespace

Table parse(std::string_view text, const std::string& source_name) {
  return Parser(text, source_name).run();
}

Table parse_file(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) {
    throw ConfigError("cannot read config file '" + path + "': it is a directory");
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

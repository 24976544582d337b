// Tests for crushdem's side of TOML: toml++'s tree converted to Values (every node type, the line
// field), every class of error located by source and line, files that cannot be read, and the
// writer (parse(serialize(x)) == x) with its shortest number text. The grammar itself is toml++'s,
// tested by its own suite.
#include <gtest/gtest.h>

#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "crushdem/core/error.hpp"
#include "crushdem/io/shortest.hpp"
#include "crushdem/io/toml.hpp"
#include "fixtures.hpp"

namespace {

using crushdem::ConfigError;
using crushdem::toml::parse;
using crushdem::toml::serialize;
using crushdem::toml::Table;
using crushdem::toml::Type;
using crushdem::toml::Value;

// Returns the message of the ConfigError that parsing `text` must throw.
std::string parse_error(std::string_view text) {
  try {
    parse(text, "cfg.toml");
  } catch (const ConfigError& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected a ConfigError for:\n" << text;
  return "";
}

// Checks the message names the source and line and contains every given fragment.
void expect_error(std::string_view text, int line, std::initializer_list<const char*> parts) {
  const std::string msg = parse_error(text);
  const std::string where = "cfg.toml:" + std::to_string(line) + ": ";
  EXPECT_EQ(msg.rfind(where, 0), 0u) << "message: " << msg << "\nexpected prefix: " << where;
  for (const char* p : parts) EXPECT_NE(msg.find(p), std::string::npos) << msg << " lacks " << p;
}

const Value& at(const Table& t, const std::string& key) {
  const auto it = t.find(key);
  if (it == t.end()) throw std::out_of_range("missing key " + key);
  return it->second;
}
const Table& sub(const Table& t, const std::string& key) {
  return *at(t, key).table;
}

// toml++ reads the grammar (its own test suite covers it); crushdem converts toml++'s tree to
// Values. Each node type becomes its Type: integers stay 64-bit integers (not through a
// double), floats keep their sign, infinities and NaN, and tables, inline tables and arrays of
// tables become Tables; integer and float stay apart.
TEST(TomlConvert, EveryNodeTypeBecomesItsValue) {
  const Table t = parse(
      "s = 'x'\n"
      "i = 9007199254740993\n"  // 2^53 + 1: no double holds it
      "imin = -9223372036854775808\n"
      "one = 1\n"
      "onef = 1.0\n"
      "neg0 = -0.0\n"
      "ninf = -inf\n"
      "n = nan\n"
      "b = false\n"
      "a = [1, 2.5, 'y', true, [3], { k = 4 }]\n"
      "[t.u]\n"
      "v = 5\n"
      "[[w]]\n"
      "name = 'top'\n"
      "[w.servo]\n"
      "gain = 0.5\n"
      "[[w]]\n"
      "name = 'bottom'\n");
  EXPECT_EQ(t.size(), 12u);
  EXPECT_EQ(at(t, "s").type, Type::String);
  EXPECT_EQ(at(t, "s").str, "x");
  ASSERT_EQ(at(t, "i").type, Type::Integer);
  EXPECT_EQ(at(t, "i").integer, 9007199254740993LL);
  EXPECT_EQ(at(t, "imin").integer, std::numeric_limits<std::int64_t>::min());
  EXPECT_EQ(at(t, "one").type, Type::Integer);
  EXPECT_EQ(at(t, "onef").type, Type::Float);
  EXPECT_FALSE(at(t, "one") == at(t, "onef"));
  EXPECT_EQ(at(t, "one").as_number(), at(t, "onef").as_number());
  ASSERT_EQ(at(t, "neg0").type, Type::Float);
  EXPECT_TRUE(std::signbit(at(t, "neg0").real));
  EXPECT_EQ(at(t, "ninf").real, -std::numeric_limits<double>::infinity());
  EXPECT_TRUE(std::isnan(at(t, "n").real));
  EXPECT_EQ(at(t, "b").type, Type::Boolean);
  EXPECT_FALSE(at(t, "b").boolean);
  const std::vector<Value>& a = at(t, "a").array;
  ASSERT_EQ(at(t, "a").type, Type::Array);
  ASSERT_EQ(a.size(), 6u);
  const std::vector<Type> types = {Type::Integer, Type::Float, Type::String,
                                   Type::Boolean, Type::Array, Type::Table};
  for (std::size_t k = 0; k < a.size(); ++k) EXPECT_EQ(a[k].type, types[k]) << k;
  EXPECT_EQ(a[4].array.at(0).integer, 3);
  EXPECT_EQ(at(*a[5].table, "k").integer, 4);
  EXPECT_EQ(at(t, "t").type, Type::Table);
  EXPECT_EQ(at(sub(sub(t, "t"), "u"), "v").integer, 5);
  // Scalars carry no table; tables always do.
  EXPECT_EQ(at(t, "s").table, nullptr);
  ASSERT_NE(at(t, "t").table, nullptr);
  const Value& w = at(t, "w");
  ASSERT_EQ(w.type, Type::Array);
  ASSERT_EQ(w.array.size(), 2u);
  EXPECT_EQ(at(*w.array[0].table, "name").str, "top");
  EXPECT_DOUBLE_EQ(at(sub(*w.array[0].table, "servo"), "gain").real, 0.5);
  EXPECT_EQ(at(*w.array[1].table, "name").str, "bottom");
  EXPECT_EQ(w.array[1].table->count("servo"), 0u);
}

TEST(TomlParse, LineField) {
  const Table t = parse(
      "a = 1\n"        // 1
      "\n"             // 2
      "[sec]\n"        // 3
      "s = \"\"\"x\n"  // 4
      "y\"\"\"\n"      // 5
      "after = [\n"    // 6
      "  10,\n"        // 7
      "  20 ]\n"       // 8
      "d.e = 2\n"      // 9
      "[[arr]]\n"      // 10
      "[[arr]]\n"      // 11
      "v = 3\n");      // 12
  EXPECT_EQ(at(t, "a").line, 1);
  EXPECT_EQ(at(t, "sec").line, 3);
  EXPECT_EQ(at(sub(t, "sec"), "s").line, 4);
  EXPECT_EQ(at(sub(t, "sec"), "after").line, 6);
  EXPECT_EQ(at(sub(t, "sec"), "after").array[0].line, 7);
  EXPECT_EQ(at(sub(t, "sec"), "after").array[1].line, 8);
  EXPECT_EQ(at(sub(sub(t, "sec"), "d"), "e").line, 9);
  EXPECT_EQ(at(t, "arr").line, 10);
  EXPECT_EQ(at(t, "arr").array[0].line, 10);
  EXPECT_EQ(at(t, "arr").array[1].line, 11);
  EXPECT_EQ(at(*at(t, "arr").array[1].table, "v").line, 12);
  EXPECT_EQ(Value::make_integer(1).line, 0);
}

// ---- errors ----

TEST(TomlErrors, MessageIsSourceLineAndWhat) {
  EXPECT_EQ(parse_error("[p]\nradius = 1\n\n\nradius = 2\n").rfind("cfg.toml:5: ", 0), 0u);
  EXPECT_NE(parse_error("[p]\nradius = 1\n\n\nradius = 2\n").find("'radius'"), std::string::npos);
  try {
    parse("x = ", "<string>");
    ADD_FAILURE() << "expected a ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()).rfind("<string>:1: ", 0), 0u) << e.what();
  }
}

// One document per class of error toml++ must catch; each is located on its line. (The grammar
// itself is toml++'s and its own test suite's; these check that every class reaches the user as
// a ConfigError with the source and line.)
TEST(TomlErrors, EveryClassIsLocated) {
  expect_error("a = 1\nb = 2\na = 3\n", 3, {"'a'"});               // duplicate key
  expect_error("t = { a = 1, a = 2 }\n", 1, {"'a'"});              // duplicate in inline table
  expect_error("[s]\nk = 1\n[s.k]\n", 3, {"'s.k'"});               // value redefined as table
  expect_error("[a]\nx = 1\n[b]\n[a]\n", 4, {"'a'"});              // table defined twice
  expect_error("t = { a = 1 }\n[t.b]\n", 2, {"'t.b'", "inline"});  // inline tables are closed
  expect_error("arr = [1]\n[[arr]]\n", 2, {"'arr'"});              // array, then [[array]]
  expect_error("ok = 1\ns = \"abc\n", 2, {});                      // unterminated string
  expect_error("s = \"\\q\"\n", 1, {"\\q"});                       // unknown escape
  expect_error("s = \"\\uD800\"\n", 1, {"surrogate"});             // not a Unicode scalar
  expect_error("# bad \x7f comment\n", 1, {"comment"});            // control character
  expect_error("a = 1\ns = \"\xC3\"\n", 2, {"utf-8"});             // truncated UTF-8
  expect_error("n = 012\n", 1, {"leading zero"});                  // numbers
  expect_error("x = 1\nn = 1.\n", 2, {});
  expect_error("n = 1__0\n", 1, {"underscore"});
  expect_error("n = 9223372036854775808\n", 1, {"64 bits"});
  expect_error("n = 1e400\n", 1, {"1e400"});
  expect_error("s = hello\n", 1, {});  // unquoted string
  expect_error("b = True\n", 1, {});
  expect_error("x = 1\ny =\n", 2, {"expected value"});  // missing value
  expect_error("a = [1 2]\n", 1, {"']'"});              // arrays
  expect_error("t = { a = 1, }\n", 1, {"'}'"});         // trailing comma
  expect_error("a = 1\nb = 2 3\n", 2, {"'3'"});         // garbage after a value
  expect_error("[t\nx = 1\n", 1, {"']'"});              // unterminated header
  expect_error("a = 1\nradius 5\n", 2, {"'='"});        // missing '='
  expect_error("\"\"\"k\"\"\" = 1\n", 1, {"keys"});     // multi-line key
}

// Nesting is bounded (toml++ stops at 256 levels), so a hostile file cannot exhaust the stack
// of the reader or of the conversion to Values.
TEST(TomlErrors, DeepNestingIsAnErrorNotACrash) {
  const std::string deep = "a = " + std::string(20000, '[') + std::string(20000, ']') + "\n";
  expect_error(deep, 1, {"nest"});
  const std::string tables = "a = " + [] {
    std::string s;
    for (int i = 0; i < 20000; ++i) s += "{ b = ";
    s += "1";
    for (int i = 0; i < 20000; ++i) s += " }";
    return s;
  }() + "\n";
  expect_error(tables, 1, {"nest"});
  // Dotted keys and table headers of 10^4 parts (a 20 KB file): an error, not a crash.
  std::string dotted = "a", header = "[a";
  for (int i = 0; i < 10000; ++i) {
    dotted += ".k";
    header += ".k";
  }
  expect_error(dotted + " = 1\n", 1, {"nested more than 64"});
  expect_error(header + "]\nx = 1\n", 1, {"nested more than 64"});
}

// No key takes a date; toml++ reads them, crushdem refuses them with the key and line.
TEST(TomlErrors, DatesRejected) {
  expect_error("d = 1979-05-27\n", 1, {"'d'", "dates and times are not supported"});
  expect_error("x = 1\n[s]\nd = 1979-05-27T07:32:00Z\n", 3, {"'s.d'", "not supported"});
  expect_error("d = 1979-05-27 07:32:00\n", 1, {"not supported"});
  expect_error("t = [1, 07:32:00]\n", 1, {"'t[1]'", "not supported"});
}

// ---- files ----

// A file that cannot be read is named with the reason; the errors in one are located in it.
TEST(TomlFile, AFileThatCannotBeReadIsNamed) {
  const crushdem::testing::TempDir dir("toml");
  const auto message = [](const std::string& path) -> std::string {
    try {
      crushdem::toml::parse_file(path);
    } catch (const ConfigError& e) {
      return e.what();
    }
    ADD_FAILURE() << "read " << path;
    return "";
  };
  const std::string missing = (dir.path() / "missing.toml").string();
  EXPECT_EQ(message(missing), "cannot open config file '" + missing + "'");
  EXPECT_EQ(message(dir.path().string()),
            "cannot read config file '" + dir.path().string() + "': it is a directory");
}

TEST(TomlFile, ReadsFileAndUsesPathInErrors) {
  const crushdem::testing::TempDir dir("toml");
  const std::string path = (dir.path() / "cfg.toml").string();
  {
    std::ofstream out(path);
    out << "[sim]\ndt = 1e-6\n";
  }
  EXPECT_DOUBLE_EQ(at(sub(crushdem::toml::parse_file(path), "sim"), "dt").real, 1e-6);
  {
    std::ofstream out(path);
    out << "a = 1\na = 2\n";
  }
  try {
    crushdem::toml::parse_file(path);
    ADD_FAILURE() << "expected ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()).rfind(path + ":2: ", 0), 0u) << e.what();
  }
}

// ---- values ----

TEST(TomlValue, HelpersAndTypeNames) {
  EXPECT_EQ(Value::make_string("s").type, Type::String);
  EXPECT_EQ(Value::make_integer(3).integer, 3);
  EXPECT_EQ(Value::make_float(2.5).real, 2.5);
  EXPECT_TRUE(Value::make_bool(true).boolean);
  EXPECT_EQ(Value::make_array({Value::make_integer(1)}).array.size(), 1u);
  const Value t = Value::make_table({{"k", Value::make_integer(1)}});
  ASSERT_NE(t.table, nullptr);
  EXPECT_EQ(t.table->size(), 1u);
  EXPECT_NE(Value().table, nullptr);
  EXPECT_EQ(Value::make_float(2.5).as_number(), 2.5);
  EXPECT_EQ(Value::make_integer(-7).as_number(), -7.0);
  EXPECT_FALSE(Value::make_string("1").is_number());
  EXPECT_THROW((void)Value::make_string("1").as_number(), std::logic_error);
  EXPECT_THROW((void)Value::make_bool(true).as_number(), std::logic_error);
  EXPECT_STREQ(crushdem::toml::type_name(Type::String), "string");
  EXPECT_STREQ(crushdem::toml::type_name(Type::Integer), "integer");
  EXPECT_STREQ(crushdem::toml::type_name(Type::Float), "float");
  EXPECT_STREQ(crushdem::toml::type_name(Type::Boolean), "boolean");
  EXPECT_STREQ(crushdem::toml::type_name(Type::Array), "array");
  EXPECT_STREQ(crushdem::toml::type_name(Type::Table), "table");
}

TEST(TomlValue, CopyIsDeep) {
  Table defaults = parse("[sim]\ndt = 1.0\n");
  Table copy = defaults;
  (*copy.at("sim").table)["dt"] = Value::make_float(2.0);
  EXPECT_EQ(at(sub(defaults, "sim"), "dt").real, 1.0);
  EXPECT_EQ(at(sub(copy, "sim"), "dt").real, 2.0);
  EXPECT_FALSE(copy == defaults);

  Value assigned = Value::make_integer(0);
  assigned = Value::make_table(defaults);  // copy assignment must be deep as well
  (*assigned.table->at("sim").table)["dt"] = Value::make_float(3.0);
  EXPECT_EQ(at(sub(defaults, "sim"), "dt").real, 1.0);
  Value source = Value::make_table(defaults);
  assigned = source;
  source.table->clear();
  EXPECT_EQ(assigned.table->size(), 1u);
}

TEST(TomlValue, EqualityIgnoresLineButNotType) {
  Value a = Value::make_integer(1);
  Value b = Value::make_integer(1);
  b.line = 7;
  EXPECT_TRUE(a == b);
  EXPECT_FALSE(a == Value::make_float(1.0));
  EXPECT_TRUE(Value::make_float(std::nan("")) == Value::make_float(std::nan("")));
  EXPECT_FALSE(parse("a = [1, 2]") == parse("a = [1, 3]"));
  EXPECT_FALSE(parse("a = {x = 1}") == parse("a = {x = 1, y = 2}"));
}

// ---- serialization ----

const char* const kConfig = R"(# crushing test
title = "Single grain \"crush\" test"
seed = 12345
big = -9223372036854775808
dt = 1e-7
gravity = [0.0, 0.0, -9.81]
tags = ['a', "b\tc", "é ü"]
flags = [true, false]
matrix = [[1, 2], [3.5], []]
points = [{ x = 1, y = 2 }, { x = 3, y = 4 }]
mixed = [1, "two", { three = 3 }]
"weird key" = "x"

[material]
density = 2650.0
young = 7.0e10
poisson = 0.25
name = 'quartz'
weibull = { m = 3.0, sigma0 = 1.5e7, d0 = 0.001 }

[material."sub table".deep]
ok = true

[[walls]]
name = "top"
position = [0, 0, 0.01]
[walls.servo]
target_stress = 1e6
gain = 0.5
[[walls.servo.limits]]
v = 1
[[walls.servo.limits]]
v = 2

[[walls]]
name = "bottom"
fixed = true

[output]
dir = "out/run1"
every = 1000
empty_table = {}
fields = []
)";

TEST(TomlSerialize, RoundTripConfigDocument) {
  const Table original = parse(kConfig);
  const std::string text = serialize(original);
  const Table again = parse(text, "serialized");
  EXPECT_TRUE(again == original) << text;
  EXPECT_EQ(serialize(again), text);  // deterministic and stable
  // Spot checks that the structure really survived (guards against == being too lax).
  EXPECT_EQ(at(again, "walls").array.size(), 2u);
  EXPECT_EQ(at(sub(*at(again, "walls").array[0].table, "servo"), "limits").array.size(), 2u);
  EXPECT_EQ(at(again, "seed").type, Type::Integer);
  EXPECT_EQ(at(again, "dt").type, Type::Float);
  EXPECT_EQ(at(again, "gravity").array[0].type, Type::Float);
  EXPECT_EQ(at(again, "big").integer, std::numeric_limits<std::int64_t>::min());
  EXPECT_NE(text.find("[[walls]]"), std::string::npos) << text;
  EXPECT_NE(text.find("[walls.servo]"), std::string::npos) << text;
  EXPECT_NE(text.find("[material.\"sub table\".deep]"), std::string::npos) << text;
}

TEST(TomlSerialize, FloatsRoundTripExactlyAndStayFloats) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  std::vector<double> values = {0.0, -0.0, 1.0, -2.0, 0.1, 1.0 / 3.0, 1e16, 1e17, 1e300};
  values.insert(values.end(), {5e-324, 2.5e-8, 123456789012345678.0, 6.02214076e23});
  values.insert(values.end(), {-1.7976931348623157e308, kInf, -kInf, std::nan("")});
  for (double d : values) {
    Table t;
    t["x"] = Value::make_float(d);
    const std::string text = serialize(t);
    const Value back = at(parse(text), "x");
    ASSERT_EQ(back.type, Type::Float) << text;
    if (std::isnan(d)) {
      EXPECT_TRUE(std::isnan(back.real)) << text;
    } else {
      EXPECT_EQ(back.real, d) << text;
      EXPECT_EQ(std::signbit(back.real), std::signbit(d)) << text;
    }
  }
  Table t;
  t["i"] = Value::make_integer(1);
  t["f"] = Value::make_float(1.0);
  EXPECT_EQ(serialize(t), "f = 1.0\ni = 1\n");
}

TEST(TomlSerialize, StringsAndKeysAreEscaped) {
  Table t;
  const std::string nasty =
      std::string("q\" b\\ nl\n cr\r tab\t bell\x07 del\x7f nul") + '\0' + " \xC3\xA9 # [x] '''";
  t["s"] = Value::make_string(nasty);
  t["key with spaces"] = Value::make_string("v");
  t["dot.key"] = Value::make_string("v");
  t[""] = Value::make_string("empty key");
  t["quote\"key"] = Value::make_integer(1);
  const std::string text = serialize(t);
  const Table back = parse(text);
  EXPECT_TRUE(back == t) << text;
  EXPECT_EQ(at(back, "s").str, nasty);
}

TEST(TomlSerialize, BuiltInCodeTree) {
  Table inner;
  inner["k"] = Value::make_integer(5);
  Table root;
  root["arr_of_tables"] = Value::make_array({Value::make_table(inner), Value::make_table()});
  root["nested_arrays_of_tables"] =
      Value::make_array({Value::make_array({Value::make_table(inner)})});
  root["t"] =
      Value::make_table({{"child", Value::make_table(inner)}, {"x", Value::make_bool(false)}});
  root["z"] = Value::make_string("last");
  const std::string text = serialize(root);
  EXPECT_TRUE(parse(text) == root) << text;
  // Plain keys come before any section of the same table.
  EXPECT_LT(text.find("z = "), text.find("\n["));
}

}  // namespace

// The shortest form built from printf and strtod (what a standard library without floating-point
// to_chars gets, GCC 10's) is std::to_chars's, character for character: on powers of two (where
// the interval that reads back is not centred), powers of ten and their neighbours, integers,
// subnormals, the extremes and random bit patterns.
TEST(ShortestChars, ThePrintfFormIsToCharsOwn) {
  std::vector<double> v = {0.0,
                           -0.0,
                           1.0,
                           0.1,
                           0.3,
                           2650.0,
                           3.2e10,
                           6e-7,
                           1e-5,
                           1e-4,
                           1e-3,
                           1e21,
                           1e22,
                           1e23,
                           123456789012345680000.0,
                           std::numeric_limits<double>::max(),
                           std::numeric_limits<double>::min(),
                           std::numeric_limits<double>::denorm_min(),
                           std::numeric_limits<double>::epsilon()};
  for (int e = -1074; e <= 1023; ++e) v.push_back(std::ldexp(1.0, e));
  for (int e = -320; e <= 308; ++e) {
    const double p = std::pow(10.0, e);
    v.insert(v.end(), {p, std::nextafter(p, 0.0), std::nextafter(p, HUGE_VAL)});
  }
  for (int i = 0; i <= 2000; ++i) v.push_back(i * 0.25);
  std::mt19937_64 rng(20261206);
  for (int i = 0; i < 100000; ++i) {
    const std::uint64_t bits = rng();
    double d = 0.0;
    std::memcpy(&d, &bits, sizeof d);
    if (std::isfinite(d)) v.push_back(d);
  }
  int differ = 0;
  for (const double d : v) {
    char a[64], b[64];
    const auto ra = std::to_chars(a, a + sizeof a, d);
    const auto rb = crushdem::detail::shortest_chars_printf(b, b + sizeof b, d);
    const std::string sa(a, ra.ptr), sb(b, rb.ptr);
    if (sa != sb && ++differ <= 10) ADD_FAILURE() << "to_chars " << sa << ", printf form " << sb;
  }
  EXPECT_EQ(differ, 0) << "of " << v.size();
  char tiny[3];
  EXPECT_EQ(crushdem::detail::shortest_chars_printf(tiny, tiny + 3, 0.125).ec,
            std::errc::value_too_large);
}

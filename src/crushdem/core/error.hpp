// Error types shared by every module. A ConfigError always names the key (or file), the value
// that was given and what was expected, so that a user can fix the input without reading code.
#pragma once

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>

#include "crushdem/core/types.hpp"

namespace crushdem {

/// Invalid user input: configuration keys, files, arguments. Thrown before anything runs.
class ConfigError : public std::runtime_error {
 public:
  explicit ConfigError(const std::string& what) : std::runtime_error(what) {}
};

/// A number as it appears in error messages: the shortest form that reads back exactly.
inline std::string show_number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  // Prefer a shorter form when it round-trips (1e6 rather than 1000000.0000000001-style noise).
  for (int prec = 1; prec < 17; ++prec) {
    char shorter[32];
    std::snprintf(shorter, sizeof shorter, "%.*g", prec, v);
    if (std::strtod(shorter, nullptr) != v) continue;
    // %g writes 90 as 9e+01 and 3600 as 3.6e+03: below 10^6 a number reads better unexponented.
    if (std::strchr(shorter, 'e') != nullptr && std::fabs(v) >= 1.0 && std::fabs(v) < 1e6) {
      std::snprintf(shorter, sizeof shorter, "%.0f", v);
    }
    return shorter;
  }
  return buf;
}

/// A point or direction as in a configuration: "[x, y, z]" (appended piece by piece: GCC 12
/// warns falsely about "[" + std::string).
inline std::string show_vec(Vec3 v) {
  std::string out("[");
  out += show_number(v.x);
  out += ", ";
  out += show_number(v.y);
  out += ", ";
  out += show_number(v.z);
  return out + "]";
}

/// Builds the standard message "key 'K' = V: expected E".
inline std::string bad_value(const std::string& key, const std::string& value,
                             const std::string& expected) {
  return "key '" + key + "' = " + value + ": expected " + expected;
}

/// Throws ConfigError "key 'K' = V: expected E" unless `ok` (for numeric config checks).
inline void require_value(bool ok, const std::string& key, double value,
                          const std::string& expected) {
  if (!ok) throw ConfigError(bad_value(key, show_number(value), expected));
}

/// A state the engine cannot continue from (lost particle, NaN force, ...).
class RuntimeFailure : public std::runtime_error {
 public:
  explicit RuntimeFailure(const std::string& what) : std::runtime_error(what) {}
};

}  // namespace crushdem

// The shortest text of a double that reads back exactly: std::to_chars(first, last, v) where the
// standard library has it for floating point (GCC 11 on), and the same characters from printf
// and strtod where it has not (GCC 10, the compiler of the portable wheel built on Debian 11 by
// scripts/wheel_debian11.sh). A test holds the two equal.
#pragma once

#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

namespace crushdem {

namespace detail {

/// std::to_chars(first, last, v) built from printf ("%.*e", correctly rounded) and strtod:
///  - the digits: the fewest p for which a p-digit decimal reads back as v; of those, the
///    nearest to v (printf's rounding), or its neighbour where only that one reads back (at a
///    power of two the interval that reads back as v is not centred on it);
///  - the form: fixed or scientific (exponent of at least two digits), whichever is shorter
///    in those digits, fixed on a tie; an integer in fixed form with all its exact digits (2^60
///    is 1152921504606846976, not ...7000), as the standard library's to_chars writes them.
/// Finite v only (the callers write inf and nan themselves).
inline std::to_chars_result shortest_chars_printf(char* first, char* last, double v) {
  std::string out = std::signbit(v) ? "-" : "";
  const double a = std::fabs(v);
  std::string digits;
  int E = 0;  // a = digits[0].digits[1..] x 10^E
  char buf[40];
  // Whether the p digits dd, dd[0].dd[1..] x 10^ee, read back as a.
  const auto reads_back = [a](const std::string& dd, int ee) {
    const std::string t = dd + "e" + std::to_string(ee - (static_cast<int>(dd.size()) - 1));
    return std::strtod(t.c_str(), nullptr) == a;
  };
  for (int p = 1; p <= 17 && digits.empty(); ++p) {
    std::snprintf(buf, sizeof buf, "%.*e", p - 1, a);
    const std::string s(buf);
    const std::size_t e = s.find('e');
    const std::string d = s.substr(0, 1) + (p > 1 ? s.substr(2, e - 2) : "");
    const int exp10 = std::atoi(s.c_str() + e + 1);
    // The nearest p-digit decimal, then its neighbours one unit in its last digit up and down.
    std::vector<std::pair<std::string, int>> candidates = {{d, exp10}};
    std::string up = d;
    int k = p - 1;
    while (k >= 0 && up[static_cast<std::size_t>(k)] == '9')
      up[static_cast<std::size_t>(k--)] = '0';
    if (k < 0) {
      candidates.emplace_back("1" + up.substr(0, up.size() - 1), exp10 + 1);
    } else {
      ++up[static_cast<std::size_t>(k)];
      candidates.emplace_back(up, exp10);
    }
    std::string down = d;
    k = p - 1;
    while (k >= 0 && down[static_cast<std::size_t>(k)] == '0') {
      down[static_cast<std::size_t>(k--)] = '9';
    }
    if (k >= 0) {  // else below zero
      --down[static_cast<std::size_t>(k)];
      if (down[0] != '0') {
        candidates.emplace_back(down, exp10);
      } else if (p > 1) {  // 1000 - 1 = 0999: one digit fewer, kept at p with a 9 added
        candidates.emplace_back(down.substr(1) + "9", exp10 - 1);
      }
    }
    for (const auto& [cd, ce] : candidates) {
      if (reads_back(cd, ce)) {
        digits = cd;
        E = ce;
        break;
      }
    }
  }
  while (digits.size() > 1 && digits.back() == '0') digits.pop_back();
  const int p = static_cast<int>(digits.size());
  std::string sci = digits.substr(0, 1) + (p > 1 ? "." + digits.substr(1) : "") + "e" +
                    (E < 0 ? "-" : "+") + (std::abs(E) < 10 ? "0" : "") +
                    std::to_string(std::abs(E));
  // Fixed: as long as E + 1 digits for an integer (written with its exact digits only when
  // chosen, so that 1e308 is never printed in full), else digits around a point.
  const std::size_t fixed_size = E >= p - 1 ? static_cast<std::size_t>(E + 1)
                                 : E >= 0   ? static_cast<std::size_t>(p + 1)
                                            : static_cast<std::size_t>(p + 1 - E);
  if (fixed_size > sci.size()) {
    out += sci;
  } else if (E >= p - 1) {  // an integer: its exact digits, as to_chars writes them (not zeros)
    std::snprintf(buf, sizeof buf, "%.0f", a);
    out += buf;
  } else if (E >= 0) {
    out += digits.substr(0, static_cast<std::size_t>(E + 1)) + "." +
           digits.substr(static_cast<std::size_t>(E + 1));
  } else {
    out += "0." + std::string(static_cast<std::size_t>(-E - 1), '0') + digits;
  }
  if (static_cast<std::size_t>(last - first) < out.size())
    return {last, std::errc::value_too_large};
  for (const char c : out) *first++ = c;
  return {first, std::errc{}};
}

}  // namespace detail

/// The shortest characters of a finite v that read back as v (std::to_chars's).
inline std::to_chars_result shortest_chars(char* first, char* last, double v) {
#if defined(__cpp_lib_to_chars) && __cpp_lib_to_chars >= 201611L
  return std::to_chars(first, last, v);
#else
  return detail::shortest_chars_printf(first, last, v);
#endif
}

}  // namespace crushdem

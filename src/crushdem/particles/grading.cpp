#include "crushdem/particles/grading.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "crushdem/core/error.hpp"
#include "crushdem/core/random.hpp"
#include "crushdem/core/types.hpp"

namespace crushdem {

GradingCurve GradingCurve::ne34() {
  GradingCurve g;
  g.diameter = {0.12e-3, 0.15e-3, 0.18e-3, 0.21e-3, 0.23e-3, 0.25e-3, 0.27e-3};
  g.passing = {0.0, 0.10, 0.30, 0.50, 0.70, 0.90, 1.0};
  return g;
}

void GradingCurve::validate(const std::string& prefix) const {
  const std::string kd = prefix + ".diameter", kp = prefix + ".passing";
  if (diameter.size() < 2) {
    throw ConfigError(bad_value(kd, std::to_string(diameter.size()) + " sizes",
                                "at least 2 sieve sizes in m, increasing"));
  }
  if (passing.size() != diameter.size()) {
    throw ConfigError(bad_value(
        kp, std::to_string(passing.size()) + " values",
        "one fraction passing per size in " + kd + " (" + std::to_string(diameter.size()) + ")"));
  }
  for (std::size_t k = 0; k < diameter.size(); ++k) {
    if (!(diameter[k] > 0.0) || !std::isfinite(diameter[k]) ||
        (k > 0 && !(diameter[k] > diameter[k - 1]))) {
      throw ConfigError(bad_value(kd + "[" + std::to_string(k) + "]", show_number(diameter[k]),
                                  "positive sizes in m, strictly increasing"));
    }
    if (!(passing[k] >= 0.0 && passing[k] <= 1.0) || (k > 0 && passing[k] < passing[k - 1])) {
      throw ConfigError(bad_value(kp + "[" + std::to_string(k) + "]", show_number(passing[k]),
                                  "fractions in [0, 1] (not percent), non-decreasing"));
    }
  }
  if (passing.front() != 0.0) {
    throw ConfigError(bad_value(kp + "[0]", show_number(passing.front()),
                                "0: the first size must be the smallest grain"));
  }
  if (passing.back() != 1.0) {
    throw ConfigError(bad_value(kp + "[" + std::to_string(passing.size() - 1) + "]",
                                show_number(passing.back()),
                                "1: the last size must be the largest grain"));
  }
}

double GradingCurve::diameter_at(double fraction) const {
  for (std::size_t k = 1; k < diameter.size(); ++k) {
    if (fraction <= passing[k] && passing[k] > passing[k - 1]) {
      const double t = (fraction - passing[k - 1]) / (passing[k] - passing[k - 1]);
      return diameter[k - 1] + std::max(0.0, t) * (diameter[k] - diameter[k - 1]);
    }
  }
  return diameter.back();
}

double GradingCurve::passing_at(double d) const {
  if (d <= diameter.front()) return 0.0;
  if (d >= diameter.back()) return 1.0;
  for (std::size_t k = 1; k < diameter.size(); ++k) {
    if (d <= diameter[k]) {
      const double t = (d - diameter[k - 1]) / (diameter[k] - diameter[k - 1]);
      return passing[k - 1] + t * (passing[k] - passing[k - 1]);
    }
  }
  return 1.0;
}

namespace {

/// Number-weighted moments of the diameter: E[d^j] for j = 0..3 integrated over the curve with
/// number density w_k / V(d) per unit d in segment k (mass uniform in d). Returns the number
/// per unit mass-volume and the raw moments.
struct Moments {
  double number = 0.0;  // grains per m^3 of solid
  double m1 = 0.0, m2 = 0.0, m3 = 0.0;
};

Moments number_moments(const GradingCurve& g) {
  // Numerical integration (the segments are short; 2000 midpoints each is exact to ~1e-7).
  Moments mo;
  double s0 = 0, s1 = 0, s2 = 0, s3 = 0;
  for (std::size_t k = 1; k < g.diameter.size(); ++k) {
    const double w = g.passing[k] - g.passing[k - 1];
    if (w <= 0.0) continue;
    const double a = g.diameter[k - 1], b = g.diameter[k];
    const int n = 2000;
    const double h = (b - a) / n;
    for (int i = 0; i < n; ++i) {
      const double d = a + (i + 0.5) * h;
      const double dn = w / (b - a) * h / (kPi / 6.0 * d * d * d);  // grains per unit solid
      s0 += dn;
      s1 += dn * d;
      s2 += dn * d * d;
      s3 += dn * d * d * d;
    }
  }
  mo.number = s0;
  mo.m1 = s1 / s0;
  mo.m2 = s2 / s0;
  mo.m3 = s3 / s0;
  return mo;
}

}  // namespace

double GradingCurve::mean_grain_volume() const {
  return 1.0 / number_moments(*this).number;
}

double GradingCurve::radius_polydispersity() const {
  const Moments m = number_moments(*this);
  return std::sqrt(std::max(0.0, m.m2 - m.m1 * m.m1)) / m.m1;
}

double GradingCurve::radius_skewness() const {
  const Moments m = number_moments(*this);
  const double var = m.m2 - m.m1 * m.m1;
  if (var <= 0.0) return 0.0;
  const double third = m.m3 - 3.0 * m.m1 * m.m2 + 2.0 * m.m1 * m.m1 * m.m1;
  return third / std::pow(var, 1.5);
}

std::vector<double> draw_diameters(const GradingCurve& g, double solid_volume, std::uint64_t seed) {
  RandomStream rng(seed, 0x6AD1);
  std::vector<double> out;
  double carried = 0.0;  // volume by which earlier segments over- or undershot their share
  for (std::size_t k = 1; k < g.diameter.size(); ++k) {
    const double w = g.passing[k] - g.passing[k - 1];
    if (w <= 0.0) continue;
    const double a = g.diameter[k - 1], b = g.diameter[k];
    const double ia = 1.0 / (a * a), ib = 1.0 / (b * b);
    const double target = w * solid_volume - carried;
    double filled = 0.0;
    for (;;) {
      const double d = 1.0 / std::sqrt(ia - rng.uniform() * (ia - ib));
      const double v = kPi / 6.0 * d * d * d;
      // Take the grain if that brings the segment closer to its share than stopping would.
      if (filled + 0.5 * v > target) break;
      out.push_back(d);
      filled += v;
    }
    carried = filled - target;
  }
  return out;
}

std::vector<double> mass_passing(const std::vector<double>& diameters,
                                 const std::vector<double>& sieves) {
  return passing_with_fines(diameters, 0.0, sieves);
}

double diameter_at_fraction(const std::vector<double>& diameters, double fraction) {
  if (diameters.empty()) return 0.0;
  std::vector<double> d = diameters;
  std::sort(d.begin(), d.end());
  double total = 0.0;
  for (double x : d) total += x * x * x;
  double acc = 0.0;
  for (double x : d) {
    acc += x * x * x;
    if (acc >= fraction * total) return x;
  }
  return d.back();
}

std::vector<double> passing_with_fines(std::vector<double> diameters, double fines_volume,
                                       const std::vector<double>& sieves) {
  std::sort(diameters.begin(), diameters.end());
  std::vector<double> cum(diameters.size() + 1, 0.0);
  for (std::size_t i = 0; i < diameters.size(); ++i) {
    cum[i + 1] = cum[i] + kPi / 6.0 * diameters[i] * diameters[i] * diameters[i];
  }
  const double total = cum.back() + fines_volume;
  std::vector<double> out;
  out.reserve(sieves.size());
  for (double s : sieves) {
    const auto k = static_cast<std::size_t>(
        std::upper_bound(diameters.begin(), diameters.end(), s) - diameters.begin());
    out.push_back(total > 0 ? (cum[k] + fines_volume) / total : 0.0);
  }
  return out;
}

std::vector<double> log_sieves(double d_min, double d_max, int n) {
  std::vector<double> s;
  s.reserve(static_cast<std::size_t>(std::max(n, 0)));
  for (int k = 0; k < n; ++k) {
    s.push_back(d_min * std::pow(d_max / d_min, n > 1 ? static_cast<double>(k) / (n - 1) : 1.0));
  }
  return s;
}

double relative_breakage(const std::vector<double>& initial, const std::vector<double>& current,
                         double fines_volume, double d_min, double d_max, double D) {
  const int n = 400;
  const std::vector<double> sieves = log_sieves(d_min, d_max, n);
  const std::vector<double> F0 = passing_with_fines(initial, 0.0, sieves);
  const std::vector<double> F = passing_with_fines(current, fines_volume, sieves);
  double bt = 0.0, bp = 0.0;
  for (int k = 1; k < n; ++k) {
    // Trapezoids in log d.
    const double h = std::log(sieves[k] / sieves[k - 1]);
    const auto Fu = [&](int j) { return std::pow(sieves[j] / d_max, 3.0 - D); };
    bt += 0.5 * h * ((F[k] - F0[k]) + (F[k - 1] - F0[k - 1]));
    bp += 0.5 * h * ((Fu(k) - F0[k]) + (Fu(k - 1) - F0[k - 1]));
  }
  return bp > 0 ? bt / bp : 0.0;
}

double random_close_packing_fraction(const GradingCurve& g) {
  const double delta = g.radius_polydispersity();
  const double S = g.radius_skewness();
  return 0.634 + 0.0658 * delta + 0.0857 * S * delta * delta;
}

double densest_void_ratio(const GradingCurve& g, double side) {
  const double phi = random_close_packing_fraction(g) * (1.0 - 0.6 * g.diameter_at(0.5) / side);
  return 1.0 / phi - 1.0;
}

}  // namespace crushdem

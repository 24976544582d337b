// Grading curves (particle-size distributions by mass) and drawing grains from them
// (docs/model.md 4.1).
//
// A grading curve is piecewise linear in the mass fraction passing P(d) between sieve sizes
// d_0 < d_1 < ... < d_K with P(d_0) = 0 and P(d_K) = 1. Within a segment the mass is spread
// uniformly in d, so the number density of grains is proportional to d^-3 there; a diameter is
// drawn from it by the inverse of its CDF,
//
//   F(d) = (d_a^-2 - d^-2) / (d_a^-2 - d_b^-2),   d = (d_a^-2 - u (d_a^-2 - d_b^-2))^-1/2.
//
// Each segment is filled to its share of the solid volume, so the sample matches the curve at
// every sieve size up to the volume of one grain.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace crushdem {

struct GradingCurve {
  std::vector<double> diameter;  // sieve sizes [m], strictly increasing
  std::vector<double> passing;   // mass fraction passing at each size [-], 0 ... 1
  /// The NE34-like curve of docs/model.md 4.1 (d50 = 0.21 mm), a CHOICE.
  static GradingCurve ne34();
  /// Throws ConfigError naming `prefix`.diameter / `prefix`.passing.
  void validate(const std::string& prefix) const;
  /// Diameter at a mass fraction passing (linear interpolation), e.g. d50 = at(0.5).
  double diameter_at(double fraction) const;
  /// Mass fraction passing at diameter d.
  double passing_at(double d) const;
  /// Mean grain volume by number [m^3] and the moments of the radius by number (for the
  /// random-close-packing estimate).
  double mean_grain_volume() const;
  double radius_polydispersity() const;  // std / mean of the radius by number
  double radius_skewness() const;        // third standardised moment of the radius by number
};

/// Diameters drawn by mass until their volume reaches `solid_volume`, segment by segment.
/// Deterministic for a seed; returned in drawing order.
std::vector<double> draw_diameters(const GradingCurve& g, double solid_volume, std::uint64_t seed);

/// Mass fraction of `diameters` passing each of `sieves` (grains with d <= sieve).
std::vector<double> mass_passing(const std::vector<double>& diameters,
                                 const std::vector<double>& sieves);

/// Mass fraction passing each sieve (increasing), counting `fines_volume` (removed fragments, in
/// m^3 of solid) as finer than every sieve. O((N + S) log N).
std::vector<double> passing_with_fines(std::vector<double> diameters, double fines_volume,
                                       const std::vector<double>& sieves);

/// Relative breakage B_r (Einav 2007): the area between the current and the initial grading
/// curve over the area between the ultimate and the initial one, on a log-d axis from d_min to
/// d_max. Ultimate grading F_u(d) = (d / d_max)^(3 - D), fractal dimension D = 2.6 (CHOICE).
/// Removed fragments count as finer than d_min.
double relative_breakage(const std::vector<double>& initial, const std::vector<double>& current,
                         double fines_volume, double d_min, double d_max, double D = 2.6);

/// `n` sieve sizes spaced evenly in log d from d_min to d_max.
std::vector<double> log_sieves(double d_min, double d_max, int n);

/// Mass-weighted diameter at a fraction passing of a set of grains (d50 for fraction 0.5).
double diameter_at_fraction(const std::vector<double>& diameters, double fraction);

/// Solid fraction of a random close packing of spheres with this size distribution, from the
/// empirical fit of Desmond & Weeks (Phys. Rev. E 90, 022204, 2014):
///   phi_RCP = 0.634 + 0.0658 delta + 0.0857 S delta^2,
/// delta the polydispersity and S the skewness of the radius. A frictionless packing does not
/// get denser than this, so a target void ratio below 1/phi_RCP - 1 cannot be prepared.
double random_close_packing_fraction(const GradingCurve& g);

/// The densest void ratio a random packing of this grading reaches in a cube of side L between
/// flat walls: phi_RCP (1 - 6 c d50 / L), where the layer along each wall packs looser. c = 0.1
/// (a layer d50/2 thick about 20 % looser) is our fit to frictionless compactions of the NE34
/// curve in cubes 6 to 19 grains wide (crushdem measured e = 0.69 at 6.6 d50); an estimate for
/// rejecting impossible targets, not a prediction.
double densest_void_ratio(const GradingCurve& g, double side);

}  // namespace crushdem

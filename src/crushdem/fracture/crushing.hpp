// Grain crushing (docs/model.md 2; Ciantia et al. 2015, 2019): a strength per grain with a size
// effect and variability, the contact-stress criterion, and splitting into the fragments of a
// pattern, all inside the engine's topology phase.
//
//   sigma_lim = sigma_lim0 (d / d0)^(-3/m) f(var)        drawn when the grain is created
//   sigma     = max_c F_n / (pi r' delta)                 over its contacts, walls included
//   a grain with d >= d_c breaks when sigma >= sigma_lim  (instant failure)
//
// A broken grain is replaced by the pattern's fragments, oriented along the normal of its contact
// with the largest F_n and turned about it by a random angle; fragments take v + omega x r and
// omega, a new strength, and no contact history; fragments with d < d_min are removed. The
// removed volume and mass are accounted exactly.
//
// Time-dependent failure (docs/model.md 3, Lei et al.; crack_growth = true): every crushable grain
// carries a crack of half-length a, seeded uniform in [0.001 d, 0.5 d] when the grain is created
// (its own random stream), growing at v = v0 (sigma / sigma_lim)^n; the grain fails (cause
// "crack") when a >= 0.5 d. During dynamic DEM a grows by v times the time since the last check;
// across an off-DEM ageing jump by v times the jump (ageing/ageing_jump.hpp). The law itself is
// fracture/crack_growth.hpp.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "crushdem/core/params.hpp"
#include "crushdem/core/random.hpp"
#include "crushdem/fracture/pattern.hpp"
#include "crushdem/fracture/strength.hpp"
#include "crushdem/integrate/simulation.hpp"

namespace crushdem {

struct CrushingConfig {
  bool enabled = false;
  double sigma_lim0 = 3.75e9;  // limit contact stress at d0 [Pa] (STUDY, Table 1)
  double weibull_m = 12.0;     // Weibull modulus m [-] (STUDY)
  double var = 0.38;           // strength variability [-] (STUDY)
  StrengthDistribution distribution = StrengthDistribution::Normal;  // "normal" | "uniform"
  // Reference diameter [m]: crushdem's parameter set (the default, io/parameter_sets.hpp);
  // 0 = d50 of the initial grains (Table 1 as printed, `parameters = "table1"`).
  double d0 = 1.07e-3;
  std::string r_prime = "R_star";  // "R_star" (CHOICE) | "2R_star"
  double dc_ratio = 0.55;          // d_c = dc_ratio * d50 of the initial grains (STUDY)
  double d_min = 0.01e-3;          // fragments smaller than this are removed [m] (STUDY)
  std::uint64_t interval = 1;      // steps between criterion checks
  std::uint64_t seed = 1;          // strength and orientation streams
  std::string pattern;             // file of "radius_fraction x y z" rows; empty = default 14
  // Density scaling of small fragments (docs/model.md 1.4, off by default): a fragment smaller
  // than the smallest initial grain d_ref gets density rho (d_ref / d)^2, which keeps the time
  // step at the initial sample's. Changes only inertia; keep the inertial number below 1e-3.
  bool density_scaling = false;
  bool crack_growth = false;  // time-dependent failure by crack growth
  double v0 = 0.1;            // reference crack velocity [m/s] (STUDY)
  double n = 60.0;            // stress-corrosion index [-] (STUDY)
  // Not a key: set by particle upscaling ([upscaling], io/config.hpp). The reference diameter in
  // use is d0_factor times d0 (or times the initial d50 when d0 = 0).
  double d0_factor = 1.0;
  void validate() const;  // keys "crushing.<key>"
  double r_prime_factor() const { return r_prime == "2R_star" ? 2.0 : 1.0; }
};

const char* to_string(StrengthDistribution d);

/// The keys of [crushing] (core/params.hpp); `enabled` and `pattern` are read apart (a present
/// section turns crushing on; a pattern path is relative to the configuration file).
const ParamTable<CrushingConfig>& crushing_params();

enum class BreakCause { Instant, Crack };
const char* to_string(BreakCause c);

struct BreakageEvent {
  double time = 0.0;
  std::uint64_t step = 0;
  ParticleId id = 0;
  double diameter = 0.0;
  Vec3 position;  // the grain's centre when it broke [m]
  BreakCause cause = BreakCause::Instant;
  double sigma = 0.0, sigma_lim = 0.0;  // [Pa] at failure
  std::vector<ParticleId> fragments;    // retained fragments
  int removed_fragments = 0;            // fragments below d_min
};

class Crusher {
 public:
  Crusher(const CrushingConfig& cfg, SplitPattern pattern);

  /// Registers the strength field, fixes d0 and d_c from the grains present (the initial
  /// grading), draws a strength for every grain without one (in id order), and turns on
  /// contact-load tracking in the simulation.
  void begin(Simulation& sim);
  /// Breaks every grain that qualifies now (instant failure), all in one topology phase.
  std::vector<BreakageEvent> apply(Simulation& sim);
  /// Splits the grains at these indices in one topology phase (any cause).
  std::vector<BreakageEvent> split(Simulation& sim, const std::vector<std::size_t>& which,
                                   BreakCause cause);
  /// The same with a cause per grain (index, cause).
  std::vector<BreakageEvent> split(Simulation& sim,
                                   std::vector<std::pair<std::size_t, BreakCause>> grains);
  /// Strength of a new grain of diameter d (draws from the strength stream).
  double draw_strength(double d);

  /// Crack velocity v0 (sigma / sigma_lim)^n of grain i at the current contact load (0 for a
  /// grain that cannot break or without a crack).
  double crack_velocity(const Simulation& sim, std::size_t i) const;
  std::size_t crack_field() const { return crack_field_; }
  /// The time of the last crushing check (cracks grow by v times the time since); a device
  /// that runs the checks itself keeps it and gives it back.
  double last_check_time() const { return last_check_time_; }
  void set_last_check_time(double t) { last_check_time_ = t; }
  /// Share of the crushable grains (d >= d_c) whose particle stress sigma is at least `ratio`
  /// of their strength at the current contact load: at n = 60 the grains above about 0.72 are
  /// those that can fail by crack growth within a day (docs/model.md 3).
  double loaded_share(const Simulation& sim, double ratio) const;
  /// The crushable grains at or over their strength (sigma >= sigma_lim) at the current
  /// contact load, and the largest sigma / sigma_lim among all crushable grains: at the start of
  /// a test, the grains a sample prepared without crushing hands over already failing.
  struct OverStrength {
    std::size_t grains = 0;
    double max_ratio = 0.0;
  };
  OverStrength over_strength(const Simulation& sim) const;

  double d0() const { return d0_; }
  double d_c() const { return d_c_; }
  double d50_initial() const { return d50_; }
  /// Density of a new fragment of diameter d (scaled or the material's).
  double fragment_density(double d) const;
  const std::vector<double>& initial_diameters() const { return initial_d_; }
  double removed_volume() const { return removed_volume_; }
  double removed_mass() const { return removed_mass_; }
  std::uint64_t breakages(BreakCause c) const { return count_[static_cast<int>(c)]; }
  std::size_t strength_field() const { return strength_field_; }
  const CrushingConfig& config() const { return cfg_; }
  const SplitPattern& pattern() const { return pattern_; }
  /// Random streams, reference sizes and accounting (the per-grain strengths and cracks are
  /// particle fields, saved with the Simulation). Loading it replaces begin() on resume.
  void state(StateArchive& a);

 private:
  CrushingConfig cfg_;
  SplitPattern pattern_;
  RandomStream strength_rng_, orientation_rng_, crack_rng_;
  std::size_t strength_field_ = 0, crack_field_ = 0;
  double last_check_time_ = 0.0;
  double draw_crack(double d);
  double d0_ = 0.0, d_c_ = 0.0, d50_ = 0.0, d_ref_ = 0.0, rho_ = 0.0;
  std::vector<double> initial_d_;
  double removed_volume_ = 0.0, removed_mass_ = 0.0;
  std::uint64_t count_[2] = {0, 0};
};

}  // namespace crushdem

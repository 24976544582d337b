#include "crushdem/fracture/crushing.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "crushdem/core/deterministic.hpp"
#include "crushdem/core/error.hpp"
#include "crushdem/fracture/crack_growth.hpp"
#include "crushdem/particles/grading.hpp"

namespace crushdem {

namespace {

constexpr std::uint64_t kStrengthStream = 0x57E1;
constexpr std::uint64_t kOrientationStream = 0x0E1A;
constexpr std::uint64_t kCrackStream = 0xC4AC;

void require(bool ok, const std::string& key, double v, const std::string& expected) {
  require_value(ok, "crushing." + key, v, expected);
}

}  // namespace

namespace {
constexpr std::array<Named<StrengthDistribution>, 2> kDistributionNames = {
    {{StrengthDistribution::Normal, "normal"}, {StrengthDistribution::Uniform, "uniform"}}};
}  // namespace

const char* to_string(StrengthDistribution d) {
  return name_of(kDistributionNames, d);
}

const char* to_string(BreakCause c) {
  return c == BreakCause::Crack ? "crack" : "instant";
}

void CrushingConfig::validate() const {
  validate_params(*this, crushing_params(), "crushing");
  require(var >= 0.0 && (distribution == StrengthDistribution::Normal ? var < 10.0 : var < 1.0),
          "var", var,
          distribution == StrengthDistribution::Normal
              ? "a variability >= 0"
              : "a variability in [0, 1) (f is uniform on [1 - var, 1 + var])");
  if (r_prime != "R_star" && r_prime != "2R_star") {
    throw ConfigError(
        bad_value("crushing.r_prime", "\"" + r_prime + "\"", "\"R_star\" or \"2R_star\""));
  }
}

const ParamTable<CrushingConfig>& crushing_params() {
  using K = CrushingConfig;
  const auto positive = [](double v) { return v > 0.0; };
  const auto non_negative = [](double v) { return v >= 0.0; };
  static const ParamTable<K> table = {
      {"enabled",
       &K::enabled,
       "",
       "false keeps the section but turns crushing off",
       nullptr,
       {},
       "true"},
      {"sigma_lim0",
       &K::sigma_lim0,
       "Pa",
       "limit contact stress at d0 (STUDY)",
       positive,
       "a positive limit stress in Pa",
       {},
       {},
       [](double v) { return v >= 1e6 && v <= 1e11; },
       "1e6 to 1e11 Pa"},
      {"weibull_m",
       &K::weibull_m,
       "-",
       "Weibull modulus m: strength ~ (d / d0)^(-3/m) (STUDY)",
       positive,
       "a positive Weibull modulus",
       {},
       {},
       [](double v) { return v >= 0.5 && v <= 50.0; },
       "0.5 to 50"},
      {"var", &K::var, "-",
       "strength variability (STUDY); < 1 with the uniform distribution (checked in validate)"},
      {"distribution", enum_choice(&K::distribution, kDistributionNames), "",
       "f ~ normal(1, var) truncated to [0.05, 1 + 3 var] (CHOICE), or `\"uniform\"` on "
       "[1 - var, 1 + var]"},
      {"d0", &K::d0, "m",
       "reference diameter; 0 = d50 of the grains present when the test starts. The default, "
       "1.07 mm, is crushdem's parameter set (CHOICE, docs/model.md 2.1: a d50 grain of NE34 "
       "breaks at F / d^2 = 0.50 GPa); `parameters = \"table1\"` gives 0",
       non_negative, "a reference diameter in m (0 = d50 of the initial grains)"},
      {"r_prime",
       ParamChoice<K>{[](const K& k) { return k.r_prime; },
                      [](K& k, const std::string& v, const std::string&) { k.r_prime = v; },
                      "\"R_star\" or \"2R_star\""},
       "",
       "r' in the contact stress: `\"R_star\"` (Hertz contact area, CHOICE) or `\"2R_star\"` "
       "(PFC)"},
      {"dc_ratio", &K::dc_ratio, "-",
       "comminution limit d_c = dc_ratio x initial d50; smaller grains never break (STUDY)",
       non_negative, "a ratio d_c / d50 >= 0"},
      {"d_min", &K::d_min, "m",
       "fragments smaller than this are removed (volume and mass accounted) (STUDY)", non_negative,
       "a diameter in m (>= 0)"},
      {"interval", &K::interval, "", "steps between criterion checks", positive,
       "a number of steps >= 1"},
      {"seed", &K::seed, "", "strength, orientation and crack random streams"},
      {"density_scaling", &K::density_scaling, "",
       "fragments smaller than the smallest initial grain d_ref get density rho (d_ref / d)^2, "
       "so the time step stays at the initial sample's (docs/model.md 1.4); only inertia "
       "changes: keep the reported inertial number below 1e-3. Removed mass is then counted at "
       "the material density"},
      {"crack_growth", &K::crack_growth, "",
       "time-dependent failure (docs/model.md 3): each crushable grain gets a crack a0 ~ "
       "uniform[0.001 d, 0.5 d] when created and fails (cause `crack`) when a >= 0.5 d; needed "
       "by `age` stages"},
      {"v0",
       &K::v0,
       "m/s",
       "reference crack velocity in v = v0 (sigma / sigma_lim)^n (STUDY)",
       positive,
       "a positive crack velocity in m/s",
       {},
       {},
       [](double v) { return v >= 1e-15 && v <= 1e4; },
       "1e-15 to 1e4 m/s: cracks run below sound"},
      {"n",
       &K::n,
       "-",
       "stress-corrosion index (STUDY)",
       positive,
       "a positive stress-corrosion index",
       {},
       {},
       [](double v) { return v >= 1.0 && v <= 300.0; },
       "1 to 300"},
  };
  return table;
}

Crusher::Crusher(const CrushingConfig& cfg, SplitPattern pattern)
    : cfg_(cfg),
      pattern_(std::move(pattern)),
      strength_rng_(cfg.seed, kStrengthStream),
      orientation_rng_(cfg.seed, kOrientationStream),
      crack_rng_(cfg.seed, kCrackStream) {
  pattern_.validate("crushing.pattern");
}

double Crusher::draw_strength(double d) {
  const double f = strength_factor(strength_rng_, cfg_.distribution, cfg_.var);
  return size_scaled_strength(cfg_.sigma_lim0, d, d0_, cfg_.weibull_m, f);
}

double Crusher::draw_crack(double d) {
  if (!cfg_.crack_growth || d < d_c_) return std::numeric_limits<double>::quiet_NaN();
  return crack_rng_.uniform(0.001 * d, 0.5 * d);
}

void Crusher::begin(Simulation& sim) {
  ParticleStore& p = sim.particles();
  strength_field_ = p.add_field("sigma_lim", std::numeric_limits<double>::quiet_NaN());
  crack_field_ = p.add_field("crack_a", std::numeric_limits<double>::quiet_NaN());
  initial_d_ = p.diameters();
  d50_ = diameter_at_fraction(initial_d_, 0.5);
  d0_ = (cfg_.d0 > 0.0 ? cfg_.d0 : d50_) * cfg_.d0_factor;
  d_c_ = cfg_.dc_ratio * d50_;
  d_ref_ = initial_d_.empty() ? 0.0 : *std::min_element(initial_d_.begin(), initial_d_.end());
  rho_ = sim.config().material.density;
  std::vector<std::size_t> order(p.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return p.id[a] < p.id[b]; });
  std::vector<double>& s = p.field(strength_field_);
  for (std::size_t i : order) {
    if (std::isnan(s[i])) s[i] = draw_strength(2.0 * p.radius[i]);
  }
  std::vector<double>& a = p.field(crack_field_);
  for (std::size_t i : order) {
    if (std::isnan(a[i])) a[i] = draw_crack(2.0 * p.radius[i]);
  }
  sim.track_contact_load(cfg_.r_prime_factor());
  last_check_time_ = sim.time();
}

double Crusher::crack_velocity(const Simulation& sim, std::size_t i) const {
  const ParticleStore& p = sim.particles();
  const double a = p.field(crack_field_)[i];
  if (!cfg_.crack_growth || std::isnan(a) || 2.0 * p.radius[i] < d_c_) return 0.0;
  const ContactLoad& load = sim.contact_load();
  if (load.sigma.size() != p.size() || !(load.sigma[i] > 0.0)) return 0.0;
  return crushdem::crack_velocity(cfg_.v0, load.sigma[i], p.field(strength_field_)[i], cfg_.n);
}

double Crusher::loaded_share(const Simulation& sim, double ratio) const {
  const ParticleStore& p = sim.particles();
  const ContactLoad& load = sim.contact_load();
  const std::vector<double>& strength = p.field(strength_field_);
  std::size_t crushable = 0, above = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (2.0 * p.radius[i] < d_c_) continue;
    ++crushable;
    const double sigma = load.sigma.size() == p.size() ? load.sigma[i] : 0.0;
    if (sigma >= ratio * strength[i]) ++above;
  }
  return crushable ? static_cast<double>(above) / static_cast<double>(crushable) : 0.0;
}

Crusher::OverStrength Crusher::over_strength(const Simulation& sim) const {
  const ParticleStore& p = sim.particles();
  const ContactLoad& load = sim.contact_load();
  const std::vector<double>& strength = p.field(strength_field_);
  OverStrength out;
  if (load.sigma.size() != p.size()) return out;
  for (std::size_t i = 0; i < p.size(); ++i) {
    if (2.0 * p.radius[i] < d_c_) continue;
    out.max_ratio = std::max(out.max_ratio, load.sigma[i] / strength[i]);
    if (load.sigma[i] >= strength[i]) ++out.grains;
  }
  return out;
}

double Crusher::fragment_density(double d) const {
  if (!cfg_.density_scaling || d >= d_ref_) return rho_;
  return rho_ * (d_ref_ / d) * (d_ref_ / d);
}

std::vector<BreakageEvent> Crusher::apply(Simulation& sim) {
  const PartScope timed(sim.part_clock(), Part::Crushing);
  sim.compute_forces();  // no-op when the forces (and loads) are current
  ParticleStore& p = sim.particles();
  const ContactLoad& load = sim.contact_load();
  const std::vector<double>& s = p.field(strength_field_);
  // Cracks grow by v times the time since the last check (the load of this step). This runs
  // every check (every step by default): one parallel pass, each grain on its own, then the
  // failures gathered in index order.
  const double elapsed = sim.time() - last_check_time_;
  last_check_time_ = sim.time();
  std::vector<double>& a = p.field(crack_field_);
  const std::size_t N = p.size();
  std::vector<GrainFailure> fails(N, GrainFailure::None);
  const bool crack_growth = cfg_.crack_growth;
#pragma omp parallel for schedule(static) if (worth_threading(N))
  for (std::ptrdiff_t ii = 0; ii < static_cast<std::ptrdiff_t>(N); ++ii) {
    const auto i = static_cast<std::size_t>(ii);
    fails[i] = crushing_check(p.radius[i], d_c_, load.sigma[i], s[i], crack_growth, cfg_.v0, cfg_.n,
                              elapsed, a[i]);
  }
  std::vector<std::pair<std::size_t, BreakCause>> grains;
  for (std::size_t i = 0; i < N; ++i) {
    if (fails[i] != GrainFailure::None) {
      grains.emplace_back(
          i, fails[i] == GrainFailure::Instant ? BreakCause::Instant : BreakCause::Crack);
    }
  }
  if (grains.empty()) return {};
  return split(sim, std::move(grains));
}

std::vector<BreakageEvent> Crusher::split(Simulation& sim, const std::vector<std::size_t>& which,
                                          BreakCause cause) {
  std::vector<std::pair<std::size_t, BreakCause>> grains;
  grains.reserve(which.size());
  for (std::size_t i : which) grains.emplace_back(i, cause);
  return split(sim, std::move(grains));
}

std::vector<BreakageEvent> Crusher::split(Simulation& sim,
                                          std::vector<std::pair<std::size_t, BreakCause>> grains) {
  ParticleStore& p = sim.particles();
  // Parents in id order, so that the random draws do not depend on the storage order.
  std::sort(grains.begin(), grains.end(),
            [&](const auto& a, const auto& b) { return p.id[a.first] < p.id[b.first]; });
  grains.erase(std::unique(grains.begin(), grains.end(),
                           [](const auto& a, const auto& b) { return a.first == b.first; }),
               grains.end());
  std::vector<std::size_t> which;
  which.reserve(grains.size());
  for (const auto& g : grains) which.push_back(g.first);
  const ContactLoad& load = sim.contact_load();
  const bool have_load = load.sigma.size() == p.size();
  TopologyChange change;
  std::vector<BreakageEvent> events;
  std::vector<std::size_t> kept_per_event;
  double mass_before = 0.0, removed_volume = 0.0;
  for (std::size_t g = 0; g < which.size(); ++g) {
    const std::size_t i = which[g];
    const BreakCause cause = grains[g].second;
    const double R = p.radius[i];
    const double rho = p.mass[i] / (4.0 / 3.0 * kPi * R * R * R);
    mass_before += p.mass[i];
    BreakageEvent ev;
    ev.time = sim.time();
    ev.step = sim.step_count();
    ev.id = p.id[i];
    ev.diameter = 2.0 * R;
    ev.position = {p.x[i], p.y[i], p.z[i]};
    ev.cause = cause;
    ev.sigma = have_load ? load.sigma[i] : 0.0;
    ev.sigma_lim = p.field(strength_field_)[i];
    // Local frame: e_z along the normal of the contact with the largest F_n (a random direction
    // for a grain without contact), turned about it by a random angle.
    Vec3 ez{0.0, 0.0, 1.0};
    if (have_load && load.F_n_max[i] > 0.0) {
      ez = Vec3{load.nx[i], load.ny[i], load.nz[i]};
    } else {
      const double cz = orientation_rng_.uniform(-1.0, 1.0);
      const double ph = orientation_rng_.uniform(0.0, 2.0 * kPi);
      const double sz = std::sqrt(std::max(0.0, 1.0 - cz * cz));
      ez = Vec3{sz * std::cos(ph), sz * std::sin(ph), cz};
    }
    ez = (1.0 / norm(ez)) * ez;
    const Vec3 a = std::abs(ez.x) < 0.9 ? Vec3{1.0, 0.0, 0.0} : Vec3{0.0, 1.0, 0.0};
    Vec3 ex = a - dot(a, ez) * ez;
    ex = (1.0 / norm(ex)) * ex;
    const Vec3 ey = cross(ez, ex);
    const double theta = orientation_rng_.uniform(0.0, 2.0 * kPi);
    const Vec3 e1 = std::cos(theta) * ex + std::sin(theta) * ey;
    const Vec3 e2 = std::cos(theta) * ey - std::sin(theta) * ex;
    const Vec3 c{p.x[i], p.y[i], p.z[i]};
    const Vec3 v{p.vx[i], p.vy[i], p.vz[i]};
    const Vec3 w{p.wx[i], p.wy[i], p.wz[i]};
    std::size_t kept = 0;
    double retained = 0.0;
    for (std::size_t k = 0; k < pattern_.size(); ++k) {
      const double r = pattern_.radius[k] * R;
      if (2.0 * r < cfg_.d_min) {
        ++ev.removed_fragments;
        continue;
      }
      const Vec3 u = pattern_.position[k];
      const Vec3 arm = R * (u.x * e1 + u.y * e2 + u.z * ez);
      NewParticle np;
      np.parent = p.id[i];
      np.position = c + arm;
      np.velocity = v + cross(w, arm);
      np.angular_velocity = w;
      np.radius = r;
      np.density = cfg_.density_scaling ? fragment_density(2.0 * r) : rho;
      np.extra.assign(std::max(strength_field_, crack_field_) + 1,
                      std::numeric_limits<double>::quiet_NaN());
      np.extra[strength_field_] = draw_strength(2.0 * r);
      np.extra[crack_field_] = draw_crack(2.0 * r);
      change.add.push_back(np);
      retained += r * r * r;
      ++kept;
    }
    removed_volume += 4.0 / 3.0 * kPi * (R * R * R - retained);
    kept_per_event.push_back(kept);
    events.push_back(ev);
  }
  change.remove = which;
  // Mass of the new fragments as the store computes it, so retained + removed is exact.
  const std::size_t n_before = p.size() - which.size();
  const std::vector<ParticleId> ids = sim.apply_topology(change);
  double mass_after = 0.0;
  for (std::size_t k = n_before; k < p.size(); ++k) mass_after += p.mass[k];
  // With density scaling the stored masses are not the grains' true masses: count the removed
  // volume at the material density instead.
  removed_mass_ += cfg_.density_scaling ? rho_ * removed_volume : mass_before - mass_after;
  removed_volume_ += removed_volume;
  std::size_t at = 0;
  for (std::size_t e = 0; e < events.size(); ++e) {
    events[e].fragments.assign(ids.begin() + static_cast<std::ptrdiff_t>(at),
                               ids.begin() + static_cast<std::ptrdiff_t>(at + kept_per_event[e]));
    at += kept_per_event[e];
  }
  for (const BreakageEvent& e : events) ++count_[static_cast<int>(e.cause)];
  return events;
}

void Crusher::state(StateArchive& a) {
  a.section("crusher");
  a(strength_rng_.engine(), orientation_rng_.engine(), crack_rng_.engine());
  strength_field_ = static_cast<std::size_t>(a.value(static_cast<std::uint64_t>(strength_field_)));
  crack_field_ = static_cast<std::size_t>(a.value(static_cast<std::uint64_t>(crack_field_)));
  a(last_check_time_, d0_, d_c_, d50_, d_ref_, rho_, removed_volume_, removed_mass_);
  a(initial_d_, count_[0], count_[1]);
}

}  // namespace crushdem

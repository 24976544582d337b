#include "crushdem/experiments/protocol.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "crushdem/ageing/ageing_jump.hpp"
#include "crushdem/core/deterministic.hpp"
#include "crushdem/core/error.hpp"
#include "crushdem/fracture/crushing.hpp"
#include "crushdem/particles/generate.hpp"

namespace crushdem {

namespace {

/// Every servo wall within `tol` of its target.
bool servo_walls_at_target(const Walls& w, double tol) {
  for (int k = 0; k < kNumWalls; ++k) {
    const WallConfig& c = w.config(k);
    if (c.mode != WallMode::Servo) continue;
    if (!(std::abs(w.stress(k) / c.target_stress - 1.0) <= tol)) return false;
  }
  return true;
}

}  // namespace

// ---------------------------------------------------------------------------------------------

double SampleConfig::cube_side() const {
  if (side > 0.0) return side;
  if (count > 0) {
    return std::cbrt(static_cast<double>(count) * grading.mean_grain_volume() * (1.0 + void_ratio));
  }
  return 4e-3;
}

namespace {
constexpr double kLoosestVoidRatio = 1.2;
}  // namespace

void SampleConfig::validate(const SimulationConfig& sim) const {
  grading.validate("sample.grading");
  if (side != 0.0 && count != 0) {
    throw ConfigError(
        "sample: give either 'sample.side' (the cube side in m) or 'sample.count' (about how "
        "many grains), not both");
  }
  require_value(side >= 0.0 && std::isfinite(side), "sample.side", side, "a cube side in m (> 0)");
  // A random packing of spheres brought to equilibrium is not looser than about e = 0.8-1.0
  // (random loose packing of frictional spheres); the preparation cannot reach more.
  require_value(void_ratio > 0.0 && void_ratio < kLoosestVoidRatio, "sample.void_ratio", void_ratio,
                "a void ratio in (0, " + show_number(kLoosestVoidRatio) +
                    "): random packings of spheres in equilibrium are not looser than about "
                    "e = 0.8-1.0");
  const double e_min = densest_void_ratio(grading, cube_side());
  if (void_ratio < e_min) {
    throw ConfigError(bad_value(
        "sample.void_ratio", show_number(void_ratio),
        "a void ratio this grading can reach in this cube: random close packing gives about e = " +
            show_number(std::round(e_min * 1000.0) / 1000.0) +
            " here (Desmond & Weeks 2014, with a looser layer along the walls), and no random "
            "packing is denser: more grains than fit (a wider cube packs denser)"));
  }
  require_value(tolerance > 0.0 && tolerance < 0.1, "sample.tolerance", tolerance,
                "a void-ratio tolerance in (0, 0.1)");
  require_value(stress > 0.0 && std::isfinite(stress), "sample.stress", stress,
                "a positive isotropic stress in Pa");
  require_value(friction_start >= sim.material.friction && friction_start <= 2.0,
                "sample.friction_start", friction_start,
                "a friction coefficient in [material.friction, 2] to start the preparation from");
  require_value(friction_factor > 0.0 && friction_factor < 1.0, "sample.friction_factor",
                friction_factor, "a factor in (0, 1)");
  require_value(placement_fraction > 0.0 && placement_fraction <= 0.3, "sample.placement_fraction",
                placement_fraction, "a solid fraction in (0, 0.3] (random placement jams above)");
  require_value(max_speed > 0.0 && std::isfinite(max_speed), "sample.max_speed", max_speed,
                "a positive speed in m/s");
  require_value(unbalanced > 0.0 && unbalanced < 1.0, "sample.unbalanced", unbalanced,
                "an unbalanced-force ratio in (0, 1)");
  require_value(stress_tolerance > 0.0 && stress_tolerance < 0.5, "sample.stress_tolerance",
                stress_tolerance, "a relative tolerance in (0, 0.5)");
  if (check_interval == 0) throw ConfigError(bad_value("sample.check_interval", "0", "> 0 steps"));
  if (max_steps == 0) throw ConfigError(bad_value("sample.max_steps", "0", "> 0 steps"));
  const double L = cube_side();
  const double d_max = grading.diameter.back();
  if (L < 5.0 * d_max) {
    throw ConfigError(
        bad_value(side > 0 ? "sample.side" : "sample.count",
                  side > 0 ? show_number(side) : std::to_string(count),
                  "a cube at least 5 largest grains wide (side >= " + show_number(5.0 * d_max) +
                      " m; this gives " + show_number(L) + " m)"));
  }
  const double n = L * L * L / (1.0 + void_ratio) / grading.mean_grain_volume();
  if (n > 5e7) {
    throw ConfigError(bad_value(
        side > 0 ? "sample.side" : "sample.count",
        side > 0 ? show_number(side) : std::to_string(count),
        "a sample of at most 5e7 grains (this is about " + show_number(std::round(n)) + ")"));
  }
}

LooseCloud make_loose_cloud(const SampleConfig& cfg) {
  const double L = cfg.cube_side();
  const double Vs = L * L * L / (1.0 + cfg.void_ratio);
  const std::vector<double> d = draw_diameters(cfg.grading, Vs, cfg.seed);
  double vol = 0.0;
  for (double x : d) vol += kPi / 6.0 * x * x * x;
  LooseCloud c;
  c.side = std::cbrt(vol / cfg.placement_fraction);
  std::vector<double> radii(d.size());
  for (std::size_t i = 0; i < d.size(); ++i) radii[i] = 0.5 * d[i];
  const std::array<double, 6> box{0.0, c.side, 0.0, c.side, 0.0, c.side};
  for (const PlacedSphere& s : random_sequential_addition(radii, box, cfg.seed)) {
    c.position.push_back(s.position);
    c.radius.push_back(s.radius);
  }
  return c;
}

// ---------------------------------------------------------------------------------------------

double inertial_number(const Walls& w, double d50, double density) {
  double rate = 0.0;
  for (int a = 0; a < 3; ++a) {
    const double L = w.length(a);
    if (L > 0)
      rate = std::max(rate, std::abs(w.state(2 * a).velocity - w.state(2 * a + 1).velocity) / L);
  }
  double p = 0.0;
  for (int k = 0; k < kNumWalls; ++k) p += w.stress(k) / kNumWalls;
  if (!(p > 0.0)) return std::numeric_limits<double>::quiet_NaN();
  return rate * d50 * std::sqrt(density / p);
}

// ---------------------------------------------------------------------------------------------

PreparationController::PreparationController(const SampleConfig& cfg, double material_friction)
    : cfg_(cfg), mu_material_(material_friction) {}

void PreparationController::begin(Simulation& sim) {
  Walls& w = sim.walls();
  for (int k = 0; k < kNumWalls; ++k) {
    WallConfig& c = w.config(k);
    c.mode = WallMode::Servo;
    c.target_stress = cfg_.stress;
    c.max_speed = cfg_.max_speed;
  }
  w.update_velocities(sim.current_dt());
  mu_ = cfg_.friction_start;
  sim.set_friction(mu_);
  start_step_ = sim.step_count();
  phase_ = Phase::Compact;
}

bool PreparationController::update(Simulation& sim) {
  const double Vs = sim.particles().solid_volume();
  e_ = (sim.walls().volume() - Vs) / Vs;
  const std::uint64_t done = sim.step_count() - start_step_;
  if (done >= cfg_.max_steps) {
    throw RuntimeFailure("sample preparation did not finish within sample.max_steps = " +
                         std::to_string(cfg_.max_steps) + " steps (e = " + show_number(e_) +
                         ", preparation friction " + show_number(mu_) +
                         "); raise sample.max_steps or sample.max_speed");
  }
  const bool at_stress = servo_walls_at_target(sim.walls(), cfg_.stress_tolerance);
  const double ub = unbalanced_force_ratio(sim);
  const bool equilibrium = at_stress && ub <= cfg_.unbalanced;
  const double e_target = cfg_.void_ratio;
  switch (phase_) {
    case Phase::Compact:
      // Restore the material friction a little before the target: the packing still settles.
      if (e_ <= e_target + 0.5 * cfg_.tolerance) {
        mu_found_ = mu_;
        sim.set_friction(mu_material_);
        phase_ = Phase::Settle;
      } else if (equilibrium) {
        if (mu_ == 0.0) {
          throw RuntimeFailure(
              "sample.void_ratio = " + show_number(e_target) +
              " cannot be reached: even frictionless compaction to sample.stress stops at e = " +
              show_number(e_) + " with this grading and box; ask for a looser sample");
        }
        mu_ *= cfg_.friction_factor;
        if (mu_ < 1e-3) mu_ = 0.0;
        sim.set_friction(mu_);
      }
      return false;
    case Phase::Settle:
      if (!equilibrium) return false;
      if (std::abs(e_ - e_target) > cfg_.tolerance) {
        warning_ = "prepared void ratio " + show_number(e_) +
                   " differs from sample.void_ratio = " + show_number(e_target) +
                   " by more than sample.tolerance = " + show_number(cfg_.tolerance) +
                   (e_ < e_target ? " (too dense: raise sample.friction_start)" : " (too loose)");
      }
      phase_ = Phase::Done;
      return true;
    case Phase::Done: return true;
  }
  return true;
}

Measurement PreparationController::columns(const Simulation& sim) const {
  return {{"friction", sim.contact_params().mu},
          {"phase", static_cast<double>(static_cast<int>(phase_))}};
}

// ---------------------------------------------------------------------------------------------

const char* to_string(StageKind k) {
  switch (k) {
    case StageKind::Isotropic: return "isotropic";
    case StageKind::Oedometric: return "oedometric";
    case StageKind::Triaxial: return "triaxial";
    case StageKind::Hold: return "hold";
    case StageKind::Age: return "age";
  }
  return "?";
}

StageKind parse_stage_kind(const std::string& s, const std::string& key) {
  if (s == "isotropic") return StageKind::Isotropic;
  if (s == "oedometric") return StageKind::Oedometric;
  if (s == "triaxial") return StageKind::Triaxial;
  if (s == "hold") return StageKind::Hold;
  if (s == "age") return StageKind::Age;
  throw ConfigError(bad_value(key, "\"" + s + "\"",
                              "\"isotropic\", \"oedometric\", \"triaxial\", \"hold\" or \"age\""));
}

void StageConfig::validate(const std::string& prefix) const {
  auto key = [&](const char* k) { return prefix + "." + k; };
  auto positive = [&](const char* k, double v, const char* what) {
    require_value(v > 0.0 && std::isfinite(v), key(k), v, what);
  };
  switch (kind) {
    case StageKind::Isotropic: positive("stress", stress, "a positive stress in Pa"); break;
    case StageKind::Oedometric:
      positive("stress", stress, "a positive target vertical stress in Pa");
      require_value(std::isfinite(strain_rate) && std::abs(strain_rate) < 1e4, key("strain_rate"),
                    strain_rate,
                    "an axial strain rate in 1/s (> 0 loading, < 0 unloading, 0 servo)");
      break;
    case StageKind::Triaxial:
      positive("sigma_3", sigma_3, "a positive confining stress in Pa");
      positive("strain_rate", strain_rate, "a positive axial strain rate in 1/s");
      require_value(axial_strain > 0.0 && axial_strain < 0.9, key("axial_strain"), axial_strain,
                    "a final axial strain in (0, 0.9)");
      require_value(stop_q >= 0.0 && std::isfinite(stop_q), key("stop_q"), stop_q,
                    "a deviator stress in Pa to stop at (0 = not used)");
      break;
    case StageKind::Hold:
    case StageKind::Age:
      if (axial != "fixed" && axial != "servo") {
        throw ConfigError(bad_value(key("axial"), "\"" + axial + "\"", "\"fixed\" or \"servo\""));
      }
      if (lateral != "fixed" && lateral != "servo") {
        throw ConfigError(
            bad_value(key("lateral"), "\"" + lateral + "\"", "\"fixed\" or \"servo\""));
      }
      if (axial == "servo") positive("axial_stress", axial_stress, "a positive stress in Pa");
      if (lateral == "servo") {
        positive("lateral_stress", lateral_stress, "a positive stress in Pa");
      }
      if (kind == StageKind::Age) {
        positive("duration", duration, "a positive ageing time in s (the relaxation clock)");
        if (min_cycles == 0) throw ConfigError(bad_value(key("min_cycles"), "0", "> 0 steps"));
        if (n_break == 0) throw ConfigError(bad_value(key("n_break"), "0", "> 0 grains"));
        if (record_interval == 0) {
          throw ConfigError(bad_value(key("record_interval"), "0", "> 0 steps"));
        }
      } else if ((steps == 0) == !(duration > 0.0)) {
        throw ConfigError(prefix + ": a hold stage needs exactly one of '" + key("steps") +
                          "' (> 0) or '" + key("duration") + "' (> 0 s)");
      }
      require_value(std::isfinite(duration) && duration >= 0.0, key("duration"), duration,
                    "a time in s");
      break;
  }
  require_value(tolerance > 0.0 && tolerance < 0.5, key("tolerance"), tolerance,
                "a relative stress tolerance in (0, 0.5)");
  require_value(unbalanced > 0.0 && unbalanced < 1.0, key("unbalanced"), unbalanced,
                "an unbalanced-force ratio in (0, 1)");
  require_value(max_strain_rate >= 0.0 && std::isfinite(max_strain_rate), key("max_strain_rate"),
                max_strain_rate, "a servo strain-rate limit in 1/s (0 = automatic)");
  if (check_interval == 0) throw ConfigError(bad_value(key("check_interval"), "0", "> 0 steps"));
  if (max_steps == 0) throw ConfigError(bad_value(key("max_steps"), "0", "> 0 steps"));
}

StageController::StageController(const StageConfig& cfg, double d50, Crusher* crusher)
    : cfg_(cfg), d50_(d50), crusher_(crusher) {
  if (cfg_.kind == StageKind::Age && !crusher_) {
    throw ConfigError("stage '" + cfg_.label() +
                      "': an \"age\" stage needs [crushing] with crack_growth = true");
  }
  res_.name = cfg_.label();
  res_.kind = to_string(cfg_.kind);
}

void StageController::set_servo(Walls& w, int k, double stress) const {
  WallConfig& c = w.config(k);
  c.mode = WallMode::Servo;
  c.target_stress = stress;
  c.max_speed = 0.5 * cfg_.servo_strain_rate() * w.length(wall_axis(k));
}

double StageConfig::servo_strain_rate() const {
  if (max_strain_rate > 0.0) return max_strain_rate;
  return kind == StageKind::Triaxial ? std::max(10.0, 2.0 * strain_rate) : 10.0;
}

void StageController::begin(Simulation& sim) {
  Walls& w = sim.walls();
  ref_ = StrainReference::from(w);
  start_step_ = sim.step_count();
  start_time_ = sim.time();
  for (int k = 0; k < kNumWalls; ++k) {
    w.config(k).mode = WallMode::Fixed;
    w.config(k).velocity = 0.0;
  }
  const double Lz = w.length(2);
  switch (cfg_.kind) {
    case StageKind::Isotropic:
      for (int k = 0; k < kNumWalls; ++k) set_servo(w, k, cfg_.stress);
      break;
    case StageKind::Oedometric:
      if (cfg_.strain_rate == 0.0) {
        set_servo(w, 5, cfg_.stress);
      } else {
        w.config(5).mode = WallMode::Velocity;
        w.config(5).velocity = -cfg_.strain_rate * Lz;  // the top moves down in compression
      }
      break;
    case StageKind::Triaxial:
      for (int k = 0; k < 4; ++k) set_servo(w, k, cfg_.sigma_3);
      w.config(4).mode = WallMode::Velocity;
      w.config(4).velocity = 0.5 * cfg_.strain_rate * Lz;
      w.config(5).mode = WallMode::Velocity;
      w.config(5).velocity = -0.5 * cfg_.strain_rate * Lz;
      break;
    case StageKind::Hold:
    case StageKind::Age:
      if (cfg_.axial == "servo") set_servo(w, 5, cfg_.axial_stress);
      if (cfg_.lateral == "servo") {
        for (int k = 0; k < 4; ++k) set_servo(w, k, cfg_.lateral_stress);
      }
      break;
  }
  w.update_velocities(sim.current_dt());
  ageing_time_ = 0.0;
  observe(sim);
  if (cfg_.kind == StageKind::Age) start_phase(sim);
  // A target already met at the start ends the stage at its first check: almost always a
  // target on the wrong side (an unloading stage that should load, or the reverse).
  std::string met;
  const double sv = w.axial_stress(), q = sv - w.lateral_stress();
  if (cfg_.kind == StageKind::Oedometric && ((cfg_.strain_rate > 0.0 && sv >= cfg_.stress) ||
                                             (cfg_.strain_rate < 0.0 && sv <= cfg_.stress))) {
    met = "its target stress " + show_number(cfg_.stress) + " Pa is met at the start (axial " +
          "stress " + show_number(sv) + " Pa; strain_rate > 0 loads to the target, < 0 unloads)";
  }
  if (cfg_.kind == StageKind::Triaxial && cfg_.stop_q > 0.0 && q >= cfg_.stop_q) {
    met = "its stop_q " + show_number(cfg_.stop_q) +
          " Pa is met at the start (q = " + show_number(q) + " Pa)";
  }
  if (!met.empty()) {
    met += ": the stage ends at once";
    res_.warning += (res_.warning.empty() ? "" : "; ") + met;
    std::fprintf(stderr, "[crushdem] warning: stage '%s': %s\n", res_.name.c_str(), met.c_str());
  }
}

void StageController::start_phase(const Simulation& sim) {
  phase_start_ = sim.step_count();
  phase_volume_ = sim.walls().volume();
  phase_lateral_ = cfg_.lateral == "servo" ? cfg_.lateral_stress : sim.walls().lateral_stress();
  if (on_phase_record) on_phase_record(phase_record(sim));
}

std::string StageController::progress_note() const {
  if (cfg_.kind != StageKind::Age) return "";
  char b[128];
  std::snprintf(b, sizeof b, "phase %llu  ageing time %.4g s of %.4g s",
                static_cast<unsigned long long>(res_.dynamic_phases), ageing_time_, cfg_.duration);
  return b;
}

Measurement StageController::phase_record(const Simulation& sim) const {
  const Walls& w = sim.walls();
  const double sa = w.axial_stress(), sr = w.lateral_stress();
  Measurement m;
  m.emplace_back("dynamic_phase", static_cast<double>(res_.dynamic_phases));
  m.emplace_back("cycle", static_cast<double>(sim.step_count() - phase_start_));
  m.emplace_back("ageing_time_s", ageing_time_);
  m.emplace_back("time_s", sim.time());
  m.emplace_back("axial_stress_Pa", sa);
  m.emplace_back("lateral_stress_Pa", sr);
  m.emplace_back("deviator_stress_Pa", sa - sr);
  m.emplace_back("confining_fluctuation", phase_lateral_ > 0 ? sr / phase_lateral_ - 1.0 : 0.0);
  m.emplace_back("volumetric_strain_phase", 1.0 - w.volume() / phase_volume_);
  m.emplace_back("axial_strain_phase", stage_axial_strain(sim));
  m.emplace_back("unbalanced_force_ratio", unbalanced_force_ratio(sim));
  m.emplace_back("breakages_instant",
                 crusher_ ? static_cast<double>(crusher_->breakages(BreakCause::Instant)) : 0.0);
  m.emplace_back("breakages_crack",
                 crusher_ ? static_cast<double>(crusher_->breakages(BreakCause::Crack)) : 0.0);
  m.emplace_back("n_particles", static_cast<double>(sim.particles().size()));
  return m;
}

double StageController::stage_axial_strain(const Simulation& sim) const {
  return ref_.length[2] > 0 ? 1.0 - sim.walls().length(2) / ref_.length[2] : 0.0;
}

void StageController::observe(const Simulation& sim) {
  const Walls& w = sim.walls();
  const double sa = w.axial_stress(), sr = w.lateral_stress();
  const double q = sa - sr;
  if (!observed_ || q > res_.q_max) {
    observed_ = true;
    res_.q_max = q;
    res_.axial_strain_at_q_max = stage_axial_strain(sim);
    res_.sigma_3_at_q_max = sr;
    res_.friction_angle_deg = q > 0 && sr > 0 ? std::asin(q / (q + 2.0 * sr)) * 180.0 / kPi : 0.0;
  }
  res_.K0 = sa > 0 ? sr / sa : 0.0;
  if (cfg_.kind == StageKind::Triaxial) {
    for (int k = 0; k < 4; ++k) {
      res_.max_lateral_stress_error =
          std::max(res_.max_lateral_stress_error, std::abs(w.stress(k) / cfg_.sigma_3 - 1.0));
    }
  }
  if (cfg_.kind == StageKind::Oedometric) {
    for (int a = 0; a < 2; ++a) {
      res_.max_lateral_strain =
          std::max(res_.max_lateral_strain, std::abs(1.0 - w.length(a) / ref_.length[a]));
    }
  }
  const double I = inertial_number(w, d50_, sim.config().material.density);
  if (I > res_.max_inertial_number) res_.max_inertial_number = I;
  if (I > 1e-3 && !warned_inertia_) {
    warned_inertia_ = true;
    char buf[320];
    std::snprintf(buf, sizeof buf,
                  "inertial number %.3g exceeds 1e-3 in stage '%s' at t = %.4e s: the test is not "
                  "quasi-static (lower strain_rate or max_strain_rate)",
                  I, res_.name.c_str(), sim.time());
    res_.warning = buf;
    std::fprintf(stderr, "[crushdem] warning: %s\n", buf);
  }
}

bool StageController::update(Simulation& sim) {
  res_.steps = sim.step_count() - start_step_;
  observe(sim);
  const Walls& w = sim.walls();
  auto finish = [&](const char* why) {
    res_.end_reason = why;
    return true;
  };
  auto equilibrium = [&]() {
    return servo_walls_at_target(w, cfg_.tolerance) &&
           unbalanced_force_ratio(sim) <= cfg_.unbalanced;
  };
  switch (cfg_.kind) {
    case StageKind::Isotropic:
      if (equilibrium()) return finish("equilibrium");
      break;
    case StageKind::Oedometric: {
      const double sv = w.axial_stress();
      if (cfg_.strain_rate == 0.0 && equilibrium()) return finish("equilibrium");
      if (cfg_.strain_rate > 0.0 && sv >= cfg_.stress) return finish("target stress");
      if (cfg_.strain_rate < 0.0 && sv <= cfg_.stress) return finish("target stress");
      break;
    }
    case StageKind::Triaxial:
      if (cfg_.stop_q > 0.0 && w.axial_stress() - w.lateral_stress() >= cfg_.stop_q) {
        return finish("target q");
      }
      if (stage_axial_strain(sim) >= cfg_.axial_strain) {
        if (cfg_.stop_q > 0.0) {
          res_.warning += (res_.warning.empty() ? "" : "; ") +
                          std::string("q never reached stop_q before the final axial strain");
        }
        return finish("target axial strain");
      }
      break;
    case StageKind::Age: {
      const std::uint64_t cycle = sim.step_count() - phase_start_;
      if (on_phase_record && (cycle % cfg_.record_interval == 0 || cycle >= cfg_.min_cycles)) {
        on_phase_record(phase_record(sim));
      }
      if (cycle >= cfg_.min_cycles) {
        // End of a dynamic phase: record it, then jump the ageing clock (walls still).
        ++res_.dynamic_phases;
        if (on_dynamic_phase_end) on_dynamic_phase_end(sim, ageing_time_, res_.dynamic_phases - 1);
        res_.ageing_time = ageing_time_;
        if (ageing_time_ >= cfg_.duration) return finish("target ageing time");
        const AgeingJump j =
            ageing_jump(sim, *crusher_, cfg_.n_break, cfg_.duration - ageing_time_);
        ageing_time_ = j.dt >= cfg_.duration - ageing_time_ ? cfg_.duration : ageing_time_ + j.dt;
        start_phase(sim);
      }
      break;
    }
    case StageKind::Hold:
      if (cfg_.steps > 0 && res_.steps >= cfg_.steps) return finish("duration");
      if (cfg_.duration > 0.0 && sim.time() - start_time_ >= cfg_.duration * (1.0 - 1e-12)) {
        return finish("duration");
      }
      break;
  }
  if (res_.steps >= cfg_.max_steps) {
    res_.warning += (res_.warning.empty() ? "" : "; ") + std::string("stopped at max_steps = ") +
                    std::to_string(cfg_.max_steps) + " before its end condition";
    std::fprintf(stderr, "[crushdem] warning: stage '%s' %s\n", res_.name.c_str(),
                 res_.warning.c_str());
    return finish("max_steps");
  }
  return false;
}

std::uint64_t StageController::steps_to_check(Simulation& sim) {
  const std::uint64_t done = sim.step_count() - start_step_;
  std::uint64_t n = cfg_.check_interval - done % cfg_.check_interval;
  if (cfg_.kind == StageKind::Hold) {
    if (cfg_.steps > 0) n = std::min(n, cfg_.steps - std::min(cfg_.steps, done));
    if (cfg_.duration > 0.0) {
      const double left = std::ceil((start_time_ + cfg_.duration - sim.time()) / sim.dt());
      n = std::min(n, static_cast<std::uint64_t>(std::max(1.0, left)));
    }
  }
  if (cfg_.kind == StageKind::Age) {
    const std::uint64_t in_phase = sim.step_count() - phase_start_;
    if (in_phase < cfg_.min_cycles) n = std::min(n, cfg_.min_cycles - in_phase);
    n = std::min(n, cfg_.record_interval - in_phase % cfg_.record_interval);
  }
  return std::max<std::uint64_t>(n, 1);
}

std::uint64_t PreparationController::steps_to_check(Simulation& sim) {
  const std::uint64_t done = sim.step_count() - start_step_;
  return cfg_.check_interval - done % cfg_.check_interval;
}

Measurement StageController::columns(const Simulation& sim) const {
  return {{"stage_axial_strain", stage_axial_strain(sim)},
          {"inertial_number", inertial_number(sim.walls(), d50_, sim.config().material.density)}};
}

// --- checkpoints -------------------------------------------------------------------------------

void PreparationController::save_state(StateWriter& out) const {
  out.tag("preparation");
  out.put(mu_);
  out.put(mu_found_);
  out.put(e_);
  out.put(phase_);
  out.put(start_step_);
  out.put(warning_);
}

void PreparationController::load_state(StateReader& in) {
  in.tag("preparation");
  in.get(mu_);
  in.get(mu_found_);
  in.get(e_);
  in.get(phase_);
  in.get(start_step_);
  in.get(warning_);
}

void StageController::save_state(StateWriter& out) const {
  out.tag("stage");
  out.put(ageing_time_);
  out.put(phase_start_);
  out.put(phase_volume_);
  out.put(phase_lateral_);
  out.put(ref_);
  out.put(start_step_);
  out.put(start_time_);
  out.put(warned_inertia_);
  out.put(observed_);
  for (const std::string* t : {&res_.name, &res_.kind, &res_.end_reason, &res_.warning}) {
    out.put(*t);
  }
  out.put(res_.steps);
  out.put(res_.dynamic_phases);
  for (const double v :
       {res_.q_max, res_.axial_strain_at_q_max, res_.sigma_3_at_q_max, res_.friction_angle_deg,
        res_.K0, res_.max_inertial_number, res_.max_lateral_stress_error, res_.max_lateral_strain,
        res_.ageing_time}) {
    out.put(v);
  }
}

void StageController::load_state(StateReader& in) {
  in.tag("stage");
  in.get(ageing_time_);
  in.get(phase_start_);
  in.get(phase_volume_);
  in.get(phase_lateral_);
  in.get(ref_);
  in.get(start_step_);
  in.get(start_time_);
  in.get(warned_inertia_);
  in.get(observed_);
  for (std::string* t : {&res_.name, &res_.kind, &res_.end_reason, &res_.warning}) in.get(*t);
  in.get(res_.steps);
  in.get(res_.dynamic_phases);
  for (double* v : {&res_.q_max, &res_.axial_strain_at_q_max, &res_.sigma_3_at_q_max,
                    &res_.friction_angle_deg, &res_.K0, &res_.max_inertial_number,
                    &res_.max_lateral_stress_error, &res_.max_lateral_strain, &res_.ageing_time}) {
    in.get(*v);
  }
}

}  // namespace crushdem

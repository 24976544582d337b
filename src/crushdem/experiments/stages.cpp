#include "crushdem/experiments/stages.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "crushdem/ageing/ageing_jump.hpp"
#include "crushdem/core/error.hpp"
#include "crushdem/fracture/crushing.hpp"

namespace crushdem {

// --- kinds and their keys ----------------------------------------------------------------------

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
  for (const StageKind k : kStageKinds) {
    if (s == to_string(k)) return k;
  }
  throw ConfigError(bad_value(key, "\"" + s + "\"",
                              "\"isotropic\", \"oedometric\", \"triaxial\", \"hold\" or \"age\""));
}

namespace {

using Row = Param<StageConfig>;

const char* wall_control_name(WallControl c) {
  return c == WallControl::Servo ? "servo" : "fixed";
}

WallControl parse_wall_control(const std::string& v, const std::string& key) {
  if (v == "fixed") return WallControl::Fixed;
  if (v == "servo") return WallControl::Servo;
  throw ConfigError(bad_value(key, "\"" + v + "\"", "\"fixed\" or \"servo\""));
}

bool positive(double v) {
  return v > 0.0;
}
bool at_least_one(double v) {
  return v >= 1.0;
}
bool non_negative(double v) {
  return v >= 0.0;
}

// Rows that several kinds share.
const Row kServoTolerance{"tolerance",
                          &StageConfig::tolerance,
                          "-",
                          "equilibrium: every servo wall within this relative error of its target",
                          [](double v) { return v > 0.0 && v < 0.5; },
                          "a relative stress tolerance in (0, 0.5)"};
const Row kUnbalanced{"unbalanced",
                      &StageConfig::unbalanced,
                      "-",
                      "equilibrium: unbalanced-force ratio below this",
                      [](double v) { return v > 0.0 && v < 1.0; },
                      "an unbalanced-force ratio in (0, 1)"};
const Row kMaxStrainRate{
    "max_strain_rate",
    &StageConfig::max_strain_rate,
    "1/s",
    "servo speed limit as a strain rate: each servo wall moves at most max_strain_rate x L / 2; "
    "0 = 10 /s, and for triaxial lateral walls at least 2 strain_rate",
    non_negative,
    "a servo strain-rate limit in 1/s (0 = automatic)"};
const Row kCheckInterval{"check_interval",
                         &StageConfig::check_interval,
                         "",
                         "steps between end-condition checks",
                         at_least_one,
                         "> 0 steps"};
const Row kMaxSteps{"max_steps",  &StageConfig::max_steps,
                    "",           "the stage stops (with a warning) after this many steps",
                    at_least_one, "> 0 steps"};

// How the walls of one axis are held (`member`: axial or lateral), as a string choice.
template <WallControl StageConfig::*member>
ParamChoice<StageConfig> wall_control_choice() {
  return {[](const StageConfig& c) -> std::string { return wall_control_name(c.*member); },
          [](StageConfig& c, const std::string& v, const std::string& key) {
            c.*member = parse_wall_control(v, key);
          },
          "\"fixed\" or \"servo\""};
}

const Row kAxial{"axial", wall_control_choice<&StageConfig::axial>(), "",
                 "the top wall: fixed, or servo-controlled to axial_stress"};
const Row kLateral{"lateral", wall_control_choice<&StageConfig::lateral>(), "",
                   "the four lateral walls: fixed, or servo-controlled to lateral_stress"};
const Row kAxialStress{"axial_stress",
                       &StageConfig::axial_stress,
                       "Pa",
                       "servo target of the top wall (with axial = \"servo\")",
                       nullptr,
                       {},
                       "-",
                       [](const StageConfig& c) { return c.axial == WallControl::Servo; }};
const Row kLateralStress{"lateral_stress",
                         &StageConfig::lateral_stress,
                         "Pa",
                         "servo target of the lateral walls (with lateral = \"servo\")",
                         nullptr,
                         {},
                         "-",
                         [](const StageConfig& c) { return c.lateral == WallControl::Servo; }};

ParamTable<StageConfig> with_common(std::initializer_list<Row> own) {
  ParamTable<StageConfig> t(own);
  for (const Row& r : {kServoTolerance, kUnbalanced, kMaxStrainRate, kCheckInterval, kMaxSteps}) {
    t.push_back(r);
  }
  return t;
}

}  // namespace

const ParamTable<StageConfig>& stage_params(StageKind kind) {
  static const ParamTable<StageConfig> isotropic = with_common({
      {"stress", &StageConfig::stress, "Pa", "target stress of all six servo walls", positive,
       "a positive stress in Pa", "-"},
  });
  static const ParamTable<StageConfig> oedometric = with_common({
      {"stress", &StageConfig::stress, "Pa", "target vertical stress", positive,
       "a positive target vertical stress in Pa", "-"},
      {"strain_rate", &StageConfig::strain_rate, "1/s",
       "axial strain rate: > 0 loads until sigma_v >= stress, < 0 unloads until sigma_v <= "
       "stress, 0 servo-controls the top to stress until equilibrium",
       [](double v) { return std::abs(v) < 1e4; },
       "an axial strain rate in 1/s (> 0 loading, < 0 unloading, 0 servo)"},
  });
  static const ParamTable<StageConfig> triaxial = with_common({
      {"sigma_3", &StageConfig::sigma_3, "Pa",
       "confining stress held by the four lateral servo walls", positive,
       "a positive confining stress in Pa", "-"},
      {"strain_rate", &StageConfig::strain_rate, "1/s",
       "axial strain rate (compression); both axial walls move", positive,
       "a positive axial strain rate in 1/s", "-"},
      {"axial_strain", &StageConfig::axial_strain, "-",
       "the stage ends at this axial strain (from its start)",
       [](double v) { return v > 0.0 && v < 0.9; }, "a final axial strain in (0, 0.9)", "-"},
      {"stop_q", &StageConfig::stop_q, "Pa",
       "> 0: the stage ends when q reaches it (then a hold keeps the axial strain)", non_negative,
       "a deviator stress in Pa to stop at (0 = not used)"},
  });
  static const ParamTable<StageConfig> hold = with_common({
      kAxial,
      kLateral,
      kAxialStress,
      kLateralStress,
      {"steps",
       &StageConfig::steps,
       "",
       "length of the hold in steps (or give duration)",
       nullptr,
       {},
       "-",
       [](const StageConfig& c) { return c.steps > 0; }},
      {"duration", &StageConfig::duration, "s", "length of the hold in DEM time (or give steps)",
       non_negative, "a time in s", "-", [](const StageConfig& c) { return c.duration > 0.0; }},
  });
  static const ParamTable<StageConfig> age = with_common({
      kAxial,
      kLateral,
      kAxialStress,
      kLateralStress,
      {"duration", &StageConfig::duration, "s",
       "target ageing time (the relaxation clock; DEM time is reported apart)", positive,
       "a positive ageing time in s (the relaxation clock)", "-"},
      {"min_cycles", &StageConfig::min_cycles, "", "steps of each dynamic phase (STUDY)",
       at_least_one, "> 0 steps"},
      {"n_break", &StageConfig::n_break, "",
       "grains brought to failure by each ageing jump (STUDY)", at_least_one, "> 0 grains"},
      {"record_interval", &StageConfig::record_interval, "",
       "steps between rows of phases.csv within each dynamic phase (the study's Figure 2)",
       at_least_one, "> 0 steps"},
  });
  switch (kind) {
    case StageKind::Isotropic: return isotropic;
    case StageKind::Oedometric: return oedometric;
    case StageKind::Triaxial: return triaxial;
    case StageKind::Hold: return hold;
    case StageKind::Age: return age;
  }
  return isotropic;
}

void StageConfig::validate(const std::string& prefix) const {
  validate_params(*this, stage_params(kind), prefix);
  auto key = [&](const char* k) { return prefix + "." + k; };
  if (kind == StageKind::Hold || kind == StageKind::Age) {
    if (axial == WallControl::Servo) {
      require_value(axial_stress > 0.0 && std::isfinite(axial_stress), key("axial_stress"),
                    axial_stress, "a positive stress in Pa");
    }
    if (lateral == WallControl::Servo) {
      require_value(lateral_stress > 0.0 && std::isfinite(lateral_stress), key("lateral_stress"),
                    lateral_stress, "a positive stress in Pa");
    }
  }
  if (kind == StageKind::Hold && (steps == 0) == !(duration > 0.0)) {
    throw ConfigError(prefix + ": a hold stage needs exactly one of '" + key("steps") +
                      "' (> 0) or '" + key("duration") + "' (> 0 s)");
  }
}

double StageConfig::servo_strain_rate() const {
  if (max_strain_rate > 0.0) return max_strain_rate;
  return kind == StageKind::Triaxial ? std::max(10.0, 2.0 * strain_rate) : 10.0;
}

// --- Stage -------------------------------------------------------------------------------------

Stage::Stage(const StageConfig& cfg, double d50) : cfg_(cfg), d50_(d50) {
  res_.name = cfg_.label();
  res_.kind = to_string(cfg_.kind);
}

void Stage::set_servo(Walls& w, int k, double stress) const {
  WallConfig& c = w.config(k);
  c.mode = WallMode::Servo;
  c.target_stress = stress;
  c.max_speed = 0.5 * cfg_.servo_strain_rate() * w.length(wall_axis(k));
}

double Stage::stage_axial_strain(const Simulation& sim) const {
  return ref_.length[2] > 0 ? 1.0 - sim.walls().length(2) / ref_.length[2] : 0.0;
}

void Stage::add_warning(const std::string& w) {
  res_.warning += (res_.warning.empty() ? "" : "; ") + w;
}

void Stage::begin(Simulation& sim) {
  Walls& w = sim.walls();
  ref_ = StrainReference::from(w);
  start_step_ = sim.step_count();
  start_time_ = sim.time();
  for (int k = 0; k < kNumWalls; ++k) {
    w.config(k).mode = WallMode::Fixed;
    w.config(k).velocity = 0.0;
  }
  set_walls(w);
  w.update_velocities(sim.current_dt());
  observe(sim);
  // A target already met at the start ends the stage at its first check: almost always a
  // target on the wrong side (an unloading stage that should load, or the reverse).
  std::string met = target_met_at_start(w);
  if (!met.empty()) {
    met += ": the stage ends at once";
    add_warning(met);
    std::fprintf(stderr, "[crushdem] warning: stage '%s': %s\n", res_.name.c_str(), met.c_str());
  }
}

void Stage::observe(const Simulation& sim) {
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
  observe_kind(w);
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

bool Stage::update(Simulation& sim) {
  res_.steps = sim.step_count() - start_step_;
  observe(sim);
  if (const char* why = end_reason(sim)) {
    res_.end_reason = why;
    return true;
  }
  if (res_.steps >= cfg_.max_steps) {
    add_warning("stopped at max_steps = " + std::to_string(cfg_.max_steps) +
                " before its end condition");
    std::fprintf(stderr, "[crushdem] warning: stage '%s' %s\n", res_.name.c_str(),
                 res_.warning.c_str());
    res_.end_reason = "max_steps";
    return true;
  }
  return false;
}

std::uint64_t Stage::steps_to_check(Simulation& sim) {
  const std::uint64_t done = sim.step_count() - start_step_;
  const std::uint64_t n = limit_steps(sim, cfg_.check_interval - done % cfg_.check_interval);
  return std::max<std::uint64_t>(n, 1);
}

Measurement Stage::columns(const Simulation& sim) const {
  return {{"stage_axial_strain", stage_axial_strain(sim)},
          {"inertial_number", inertial_number(sim.walls(), d50_, sim.config().material.density)}};
}

void Stage::save_phase(StateWriter& out) const {
  out.put(0.0);
  out.put(std::uint64_t{0});
  out.put(0.0);
  out.put(0.0);
}

void Stage::load_phase(StateReader& in) {
  double ageing_time = 0.0, volume = 0.0, lateral = 0.0;
  std::uint64_t start = 0;
  in.get(ageing_time);
  in.get(start);
  in.get(volume);
  in.get(lateral);
}

void Stage::save_state(StateWriter& out) const {
  out.tag("stage");
  save_phase(out);
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

void Stage::load_state(StateReader& in) {
  in.tag("stage");
  load_phase(in);
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

// --- isotropic ---------------------------------------------------------------------------------

namespace {
bool at_equilibrium(const Simulation& sim, const StageConfig& cfg) {
  return servo_walls_at_target(sim.walls(), cfg.tolerance) &&
         unbalanced_force_ratio(sim) <= cfg.unbalanced;
}
}  // namespace

void IsotropicStage::set_walls(Walls& w) {
  for (int k = 0; k < kNumWalls; ++k) set_servo(w, k, cfg_.stress);
}

const char* IsotropicStage::end_reason(Simulation& sim) {
  return at_equilibrium(sim, cfg_) ? "equilibrium" : nullptr;
}

// --- oedometric --------------------------------------------------------------------------------

void OedometricStage::set_walls(Walls& w) {
  if (cfg_.strain_rate == 0.0) {
    set_servo(w, 5, cfg_.stress);
  } else {
    w.config(5).mode = WallMode::Velocity;
    w.config(5).velocity = -cfg_.strain_rate * w.length(2);  // the top moves down in compression
  }
}

const char* OedometricStage::end_reason(Simulation& sim) {
  const double sv = sim.walls().axial_stress();
  if (cfg_.strain_rate == 0.0 && at_equilibrium(sim, cfg_)) return "equilibrium";
  if (cfg_.strain_rate > 0.0 && sv >= cfg_.stress) return "target stress";
  if (cfg_.strain_rate < 0.0 && sv <= cfg_.stress) return "target stress";
  return nullptr;
}

std::string OedometricStage::target_met_at_start(const Walls& w) const {
  const double sv = w.axial_stress();
  if ((cfg_.strain_rate > 0.0 && sv >= cfg_.stress) ||
      (cfg_.strain_rate < 0.0 && sv <= cfg_.stress)) {
    return "its target stress " + show_number(cfg_.stress) + " Pa is met at the start (axial " +
           "stress " + show_number(sv) + " Pa; strain_rate > 0 loads to the target, < 0 unloads)";
  }
  return "";
}

void OedometricStage::observe_kind(const Walls& w) {
  for (int a = 0; a < 2; ++a) {
    res_.max_lateral_strain =
        std::max(res_.max_lateral_strain, std::abs(1.0 - w.length(a) / ref_.length[a]));
  }
}

// --- triaxial ----------------------------------------------------------------------------------

void TriaxialStage::set_walls(Walls& w) {
  const double Lz = w.length(2);
  for (int k = 0; k < 4; ++k) set_servo(w, k, cfg_.sigma_3);
  w.config(4).mode = WallMode::Velocity;
  w.config(4).velocity = 0.5 * cfg_.strain_rate * Lz;
  w.config(5).mode = WallMode::Velocity;
  w.config(5).velocity = -0.5 * cfg_.strain_rate * Lz;
}

const char* TriaxialStage::end_reason(Simulation& sim) {
  const Walls& w = sim.walls();
  if (cfg_.stop_q > 0.0 && w.axial_stress() - w.lateral_stress() >= cfg_.stop_q) {
    return "target q";
  }
  if (stage_axial_strain(sim) >= cfg_.axial_strain) {
    if (cfg_.stop_q > 0.0) add_warning("q never reached stop_q before the final axial strain");
    return "target axial strain";
  }
  return nullptr;
}

std::string TriaxialStage::target_met_at_start(const Walls& w) const {
  const double q = w.axial_stress() - w.lateral_stress();
  if (cfg_.stop_q > 0.0 && q >= cfg_.stop_q) {
    return "its stop_q " + show_number(cfg_.stop_q) +
           " Pa is met at the start (q = " + show_number(q) + " Pa)";
  }
  return "";
}

void TriaxialStage::observe_kind(const Walls& w) {
  for (int k = 0; k < 4; ++k) {
    res_.max_lateral_stress_error =
        std::max(res_.max_lateral_stress_error, std::abs(w.stress(k) / cfg_.sigma_3 - 1.0));
  }
}

// --- hold --------------------------------------------------------------------------------------

namespace {
void hold_walls(const StageConfig& cfg, Walls& w,
                const std::function<void(Walls&, int, double)>& servo) {
  if (cfg.axial == WallControl::Servo) servo(w, 5, cfg.axial_stress);
  if (cfg.lateral == WallControl::Servo) {
    for (int k = 0; k < 4; ++k) servo(w, k, cfg.lateral_stress);
  }
}
}  // namespace

void HoldStage::set_walls(Walls& w) {
  hold_walls(cfg_, w, [this](Walls& ww, int k, double s) { set_servo(ww, k, s); });
}

const char* HoldStage::end_reason(Simulation& sim) {
  if (cfg_.steps > 0 && res_.steps >= cfg_.steps) return "duration";
  if (cfg_.duration > 0.0 && sim.time() - start_time_ >= cfg_.duration * (1.0 - 1e-12)) {
    return "duration";
  }
  return nullptr;
}

std::uint64_t HoldStage::limit_steps(Simulation& sim, std::uint64_t n) const {
  const std::uint64_t done = sim.step_count() - start_step_;
  if (cfg_.steps > 0) n = std::min(n, cfg_.steps - std::min(cfg_.steps, done));
  if (cfg_.duration > 0.0) {
    const double left = std::ceil((start_time_ + cfg_.duration - sim.time()) / sim.dt());
    n = std::min(n, static_cast<std::uint64_t>(std::max(1.0, left)));
  }
  return n;
}

// --- age ---------------------------------------------------------------------------------------

AgeStage::AgeStage(const StageConfig& cfg, double d50, Crusher* crusher)
    : Stage(cfg, d50), crusher_(crusher) {
  if (!crusher_) {
    throw ConfigError("stage '" + cfg_.label() +
                      "': an \"age\" stage needs [crushing] with crack_growth = true");
  }
}

void AgeStage::set_walls(Walls& w) {
  hold_walls(cfg_, w, [this](Walls& ww, int k, double s) { set_servo(ww, k, s); });
}

void AgeStage::begin(Simulation& sim) {
  ageing_time_ = 0.0;
  Stage::begin(sim);
  start_phase(sim);
}

void AgeStage::start_phase(const Simulation& sim) {
  phase_start_ = sim.step_count();
  phase_volume_ = sim.walls().volume();
  phase_lateral_ =
      cfg_.lateral == WallControl::Servo ? cfg_.lateral_stress : sim.walls().lateral_stress();
  if (on_phase_record) on_phase_record(phase_record(sim));
}

std::string AgeStage::progress_note() const {
  char b[128];
  std::snprintf(b, sizeof b, "phase %llu  ageing time %.4g s of %.4g s",
                static_cast<unsigned long long>(res_.dynamic_phases), ageing_time_, cfg_.duration);
  return b;
}

Measurement AgeStage::phase_record(const Simulation& sim) const {
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
                 static_cast<double>(crusher_->breakages(BreakCause::Instant)));
  m.emplace_back("breakages_crack", static_cast<double>(crusher_->breakages(BreakCause::Crack)));
  m.emplace_back("n_particles", static_cast<double>(sim.particles().size()));
  return m;
}

const char* AgeStage::end_reason(Simulation& sim) {
  const std::uint64_t cycle = sim.step_count() - phase_start_;
  if (on_phase_record && (cycle % cfg_.record_interval == 0 || cycle >= cfg_.min_cycles)) {
    on_phase_record(phase_record(sim));
  }
  if (cycle < cfg_.min_cycles) return nullptr;
  // End of a dynamic phase: record it, then jump the ageing clock (walls still).
  ++res_.dynamic_phases;
  if (on_dynamic_phase_end) on_dynamic_phase_end(sim, ageing_time_, res_.dynamic_phases - 1);
  res_.ageing_time = ageing_time_;
  if (ageing_time_ >= cfg_.duration) return "target ageing time";
  const double left = cfg_.duration - ageing_time_;
  const AgeingJump j = ageing_jump(sim, *crusher_, cfg_.n_break, left);
  ageing_time_ = j.dt >= left ? cfg_.duration : ageing_time_ + j.dt;
  start_phase(sim);
  return nullptr;
}

bool AgeStage::reads_grains(const Simulation& sim) const {
  return sim.step_count() - phase_start_ >= cfg_.min_cycles;
}

std::uint64_t AgeStage::limit_steps(Simulation& sim, std::uint64_t n) const {
  const std::uint64_t in_phase = sim.step_count() - phase_start_;
  if (in_phase < cfg_.min_cycles) n = std::min(n, cfg_.min_cycles - in_phase);
  return std::min(n, cfg_.record_interval - in_phase % cfg_.record_interval);
}

void AgeStage::save_phase(StateWriter& out) const {
  out.put(ageing_time_);
  out.put(phase_start_);
  out.put(phase_volume_);
  out.put(phase_lateral_);
}

void AgeStage::load_phase(StateReader& in) {
  in.get(ageing_time_);
  in.get(phase_start_);
  in.get(phase_volume_);
  in.get(phase_lateral_);
}

// -----------------------------------------------------------------------------------------------

std::unique_ptr<Stage> make_stage(const StageConfig& cfg, double d50, Crusher* crusher) {
  switch (cfg.kind) {
    case StageKind::Isotropic: return std::make_unique<IsotropicStage>(cfg, d50);
    case StageKind::Oedometric: return std::make_unique<OedometricStage>(cfg, d50);
    case StageKind::Triaxial: return std::make_unique<TriaxialStage>(cfg, d50);
    case StageKind::Hold: return std::make_unique<HoldStage>(cfg, d50);
    case StageKind::Age: return std::make_unique<AgeStage>(cfg, d50, crusher);
  }
  return nullptr;
}

}  // namespace crushdem

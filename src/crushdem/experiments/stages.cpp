#include "crushdem/experiments/stages.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "crushdem/core/error.hpp"
#include "crushdem/walls/body_config.hpp"
#include "crushdem/walls/body_probe.hpp"

namespace crushdem {

// --- kinds and the rows they share -------------------------------------------------------------

const StageKind& stage_kind(const std::string& name, const std::string& key) {
  for (const StageKind* k : stage_kinds()) {
    if (k->name == name) return *k;
  }
  throw ConfigError(bad_value(key, "\"" + name + "\"", stage_kind_names()));
}

std::string stage_kind_names() {
  const auto& kinds = stage_kinds();
  std::string s;
  for (std::size_t i = 0; i < kinds.size(); ++i) {
    if (i > 0) s += i + 1 == kinds.size() ? " or " : ", ";
    s += '"';
    s += kinds[i]->name;
    s += '"';
  }
  return s;
}

namespace {

using Row = Param<StageConfig>;

constexpr std::array<Named<WallControl>, 2> kWallControlNames = {
    {{WallControl::Fixed, "fixed"}, {WallControl::Servo, "servo"}}};
constexpr std::array<Named<HeadControl>, 2> kHeadControlNames = {
    {{HeadControl::Held, "held"}, {HeadControl::Load, "load"}}};

bool positive(double v) {
  return v > 0.0;
}
bool at_least_one(double v) {
  return v >= 1.0;
}

// The rows every kind has.
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
    [](double v) { return v >= 0.0; },
    "a servo strain-rate limit in 1/s (0 = automatic)"};
const Row kCheckInterval{
    "check_interval", &StageConfig::check_interval, "", "steps between end-condition checks",
    at_least_one,     "a number of steps >= 1"};
const Row kMaxSteps{"max_steps",  &StageConfig::max_steps,
                    "",           "the stage stops (with a warning) after this many steps",
                    at_least_one, "a number of steps >= 1"};

const Row kAxial{"axial", enum_choice(&StageConfig::axial, kWallControlNames), "",
                 "the top wall: fixed, or servo-controlled to axial_stress"};
const Row kLateral{"lateral", enum_choice(&StageConfig::lateral, kWallControlNames), "",
                   "the four lateral walls (a chamber sample: the chamber's wall): fixed, or "
                   "servo-controlled to lateral_stress"};
const Row kAxialStress{"axial_stress",
                       &StageConfig::axial_stress,
                       "Pa",
                       "servo target of the top wall (with axial = \"servo\")",
                       positive,
                       "a positive stress in Pa",
                       "-",
                       [](const StageConfig& c) { return c.axial == WallControl::Servo; },
                       nullptr,
                       {},
                       "axial"};
const Row kLateralStress{"lateral_stress",
                         &StageConfig::lateral_stress,
                         "Pa",
                         "servo target of the lateral walls (with lateral = \"servo\")",
                         positive,
                         "a positive stress in Pa",
                         "-",
                         [](const StageConfig& c) { return c.lateral == WallControl::Servo; },
                         nullptr,
                         {},
                         "lateral"};

}  // namespace

ParamTable<StageConfig> stage_table(std::initializer_list<Param<StageConfig>> own) {
  ParamTable<StageConfig> t(own);
  for (const Row& r : {kServoTolerance, kUnbalanced, kMaxStrainRate, kCheckInterval, kMaxSteps}) {
    t.push_back(r);
  }
  return t;
}

ParamTable<StageConfig> held_walls_stage_table(std::initializer_list<Param<StageConfig>> own) {
  ParamTable<StageConfig> t = {kAxial, kLateral, kAxialStress, kLateralStress};
  t.insert(t.end(), own.begin(), own.end());
  for (const Row& r : stage_table({})) t.push_back(r);
  return t;
}

ParamTable<StageConfig> pile_head_rows() {
  return {
      {"body",
       &StageConfig::body,
       "",
       "a pile (a [[body]]'s name) held as `head` says; in an age stage its shaft and the grains "
       "about it are recorded at every ageing event (pile_ageing.csv, pile_shaft.csv, "
       "pile_rings.csv); empty = none",
       nullptr,
       {},
       "",
       [](const StageConfig& c) { return !c.body.empty(); }},
      {"head",
       enum_choice(&StageConfig::head, kHeadControlNames),
       "",
       "with a body: the pile's head held where it is, or servo-controlled to head_load (0: the "
       "load taken off, the pile free to rebound)",
       nullptr,
       {},
       "",
       [](const StageConfig& c) { return !c.body.empty(); },
       nullptr,
       {},
       "body"},
      {"head_load",
       &StageConfig::head_load,
       "N",
       "the whole pile's head load with head = \"load\" (a quarter chamber's pile carries its "
       "quarter)",
       [](double v) { return v >= 0.0; },
       "a load >= 0 in N",
       "",
       [](const StageConfig& c) { return c.head == HeadControl::Load; },
       nullptr,
       {},
       "head"},
  };
}

ParamTable<StageConfig> with_pile_head(ParamTable<StageConfig> table) {
  const ParamTable<StageConfig> head = pile_head_rows();
  table.insert(table.begin() + 4, head.begin(), head.end());  // after axial ... lateral_stress
  return table;
}

void check_pile_head(const StageConfig& c, const std::string& prefix) {
  if (c.body.empty() && c.head != HeadControl::Held) {
    throw ConfigError(bad_value(prefix + ".head", "\"load\"",
                                "a `body` (the pile whose head it holds) beside it"));
  }
}

void check_probed_body(const StageConfig& c, const std::vector<BodyConfig>& bodies,
                       const std::string& prefix) {
  if (c.body.empty()) return;
  for (std::size_t j = 0; j < bodies.size(); ++j) {
    const BodyConfig& b = bodies[j];
    if (b.name != c.body) continue;
    // The stages set its motion; one of its own would move it before them (a servo would push
    // a parked pile into the grains) and be lost at the first.
    if (b.mode != WallMode::Fixed) {
      throw ConfigError(bad_value("body[" + std::to_string(j) + "].mode",
                                  "\"" + std::string(to_string(b.mode)) + "\"",
                                  "\"fixed\" for a body a stage drives (" + prefix +
                                      " names it; its stages set how it moves)"));
    }
    const Body made = b.make(0.0);
    if (!probe_supports(made.shape)) {
      throw ConfigError(
          bad_value(prefix + ".body", "\"" + c.body + "\"",
                    "a translating cone, pile, disk or cylinder_outside (this body is a " +
                        std::string(to_string(b.kind)) +
                        (b.motion == BodyMotion::Dilate ? " that dilates)" : ")")));
    }
    return;
  }
  std::string names;
  for (const BodyConfig& b : bodies) names += (names.empty() ? "\"" : ", \"") + b.name + "\"";
  throw ConfigError(
      bad_value(prefix + ".body", "\"" + c.body + "\"",
                "the name of a [[body]]" +
                    (names.empty() ? std::string(" (there is none)") : " (" + names + ")")));
}

BodyProbe probe_stage_body(const Simulation& sim, const StageConfig& c) {
  const Walls& w = sim.walls();
  return probe_body(w, stage_body_index(w, c), sim.wall_contacts(), sim.particles(),
                    c.sleeve_length, static_cast<int>(c.bins));
}

void write_shaft_rows(StageOutputs& out, const std::string& file, const BodyProbe& p,
                      const Measurement& lead) {
  for (std::size_t j = 0; j < p.sigma_r.size(); ++j) {
    Measurement b = lead;
    b.emplace_back("bin", static_cast<double>(j));
    b.emplace_back("height_m", (static_cast<double>(j) + 0.5) * p.bin_height);
    b.emplace_back("sigma_r_Pa", p.sigma_r[j]);
    b.emplace_back("tau_Pa", p.tau[j]);
    b.emplace_back("contacts", static_cast<double>(p.bin_contacts[j]));
    out.write(file, b);
  }
}

void write_ring_rows(StageOutputs& out, const std::string& file,
                     const std::vector<RingStress>& rings, const Measurement& lead,
                     const char* place, double offset, bool body_volume) {
  for (const RingStress& r : rings) {
    Measurement b = lead;
    b.emplace_back("ring", static_cast<double>(r.ring));
    b.emplace_back("bin", static_cast<double>(r.bin));
    b.emplace_back("r_in_m", r.r_in);
    b.emplace_back("r_out_m", r.r_out);
    b.emplace_back(place, r.height + offset);
    b.emplace_back("sigma_rr_Pa", r.sigma_rr);
    b.emplace_back("sigma_tt_Pa", r.sigma_tt);
    b.emplace_back("sigma_zz_Pa", r.sigma_zz);
    b.emplace_back("tau_rz_Pa", r.tau_rz);
    b.emplace_back("grains", static_cast<double>(r.grains));
    if (body_volume) b.emplace_back("body_volume_m3", r.body_volume);
    out.write(file, b);
  }
}

int stage_body_index(const Walls& w, const StageConfig& c) {
  for (int k = kNumWalls; k < w.size(); ++k) {
    if (w.name(k) == c.body) return k;
  }
  throw ConfigError("stage '" + c.label() + "': no [[body]] named \"" + c.body + "\"");
}

void StageConfig::validate(const std::string& prefix) const {
  validate_params(*this, kind->params, prefix);
  if (kind->check) kind->check(*this, prefix);
}

std::string StageConfig::label() const {
  return name.empty() ? std::string(kind->name) : name;
}

std::unique_ptr<Stage> make_stage(const StageConfig& cfg, double d50, Crusher* crusher) {
  return cfg.kind->make(cfg, d50, crusher);
}

// --- Stage -------------------------------------------------------------------------------------

Stage::Stage(const StageConfig& cfg, double d50) : cfg_(cfg), d50_(d50) {
  res_.name = cfg_.label();
  res_.kind = std::string(cfg_.kind->name);
}

void Stage::attach(StageOutputs& outputs, std::size_t index) {
  outputs_ = &outputs;
  index_ = index;
}

void Stage::set_servo(Walls& w, int k, double stress) const {
  WallConfig& c = w.config(k);
  c.mode = WallMode::Servo;
  c.target_stress = stress;
  const double rate = cfg_.max_strain_rate > 0.0 ? cfg_.max_strain_rate : automatic_servo_rate();
  c.max_speed = 0.5 * rate * w.extent(k);
}

void Stage::set_held_walls(Walls& w) const {
  if (cfg_.axial == WallControl::Servo) set_servo(w, 5, cfg_.axial_stress);
  if (cfg_.lateral == WallControl::Servo) {
    for (const int k : w.lateral_walls()) set_servo(w, k, cfg_.lateral_stress);
  }
}

void Stage::set_head(Walls& w) const {
  if (cfg_.body.empty()) return;
  const int k = stage_body_index(w, cfg_);
  WallConfig& c = w.config(k);
  c.velocity = 0.0;
  if (cfg_.head == HeadControl::Held) {
    c.mode = WallMode::Fixed;
    return;
  }
  servo_head(w, cfg_.head_load);
}

void Stage::servo_head(Walls& w, double load) const {
  const int k = stage_body_index(w, cfg_);
  // The servo holds the sector's share of the load over the body's own area, at most as fast
  // as the top platen's servo may move (max_strain_rate x the sample's height / 2).
  set_servo(w, k, load * w.sector() / w.area(k));
  const double rate = cfg_.max_strain_rate > 0.0 ? cfg_.max_strain_rate : automatic_servo_rate();
  w.config(k).max_speed = 0.5 * rate * w.length(2);
}

bool Stage::at_equilibrium(const Simulation& sim) const {
  return servo_walls_at_target(sim.walls(), cfg_.tolerance) &&
         unbalanced_force_ratio(sim) <= cfg_.unbalanced;
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
  // The box's walls and a chamber's: fixed, until the kind sets them.
  std::vector<int> held = {0, 1, 2, 3, 4, 5};
  if (w.chamber() >= 0) held.push_back(w.chamber());
  for (const int k : held) {
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
  if (at_max_steps(sim)) {
    const std::string why =
        "stopped at max_steps = " + std::to_string(cfg_.max_steps) + " before its end condition";
    add_warning(why);
    std::fprintf(stderr, "[crushdem] warning: stage '%s' %s\n", res_.name.c_str(), why.c_str());
    stop_early(sim);
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

void Stage::phase_state(StateArchive& a) {
  double ageing_time = 0.0, volume = 0.0, lateral = 0.0;
  std::uint64_t start = 0;
  a(ageing_time, start, volume, lateral);
}

void Stage::state(StateArchive& a) {
  a.section("stage");
  phase_state(a);
  a(ref_, start_step_, start_time_, warned_inertia_, observed_);
  a(res_.name, res_.kind, res_.end_reason, res_.warning, res_.steps, res_.dynamic_phases);
  a(res_.q_max, res_.axial_strain_at_q_max, res_.sigma_3_at_q_max, res_.friction_angle_deg, res_.K0,
    res_.max_inertial_number, res_.max_lateral_stress_error, res_.max_lateral_strain,
    res_.ageing_time);
}

}  // namespace crushdem

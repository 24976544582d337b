// The age stage, off-DEM ageing (docs/model.md 3.1; needs [crushing] crack_growth): dynamic
// phases of min_cycles steps (walls as `axial` / `lateral` say) alternate with ageing jumps
// (ageing/ageing_jump.hpp) that grow every crack at its frozen velocity until n_break grains
// would fail, until the ageing clock has advanced `duration` or reached `until` (ageing time, not
// DEM time; the clock runs on from the age stages before). Its own files: events.csv (a row at
// the end of every dynamic phase) and phases.csv (a row every record_interval cycles of each
// phase). With a `body` (a pile, held as `head` says), at the end of every dynamic phase:
// pile_ageing.csv (its loads and the contact forces near it), pile_shaft.csv (the radial and shear
// stress on its shaft by bin) and pile_rings.csv (the stress in rings of grains about it,
// experiments/pile_field.hpp).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "crushdem/ageing/ageing_jump.hpp"
#include "crushdem/core/error.hpp"
#include "crushdem/experiments/pile_field.hpp"
#include "crushdem/experiments/stages.hpp"
#include "crushdem/fracture/crushing.hpp"

namespace crushdem {
namespace {

class AgeStage final : public Stage {
 public:
  /// crusher: its cracks grow; required.
  AgeStage(const StageConfig& cfg, double d50, Crusher* crusher)
      : Stage(cfg, d50), crusher_(crusher) {
    if (!crusher_) {
      throw ConfigError("stage '" + cfg_.label() +
                        "': an \"age\" stage needs [crushing] with crack_growth = true");
    }
  }

  void begin(Simulation& sim) override {
    ageing_time_ = ageing_clock_;
    Stage::begin(sim);
    start_phase(sim);
  }

  double ageing_clock_now() const override { return ageing_time_; }

  /// The share of the stage done, for progress lines (ageing_progress); never back, as a shorter
  /// jump would lower the estimate. A resume does not keep the first jump.
  double fraction(const Simulation&) const override {
    shown_ =
        std::max(shown_, ageing_progress(ageing_time_ - ageing_clock_, target() - ageing_clock_,
                                         first_jump_, res_.dynamic_phases));
    return shown_;
  }

  /// The dynamic phase and the ageing time against its duration.
  std::string progress_note() const override {
    char b[128];
    std::snprintf(b, sizeof b, "phase %llu  ageing time %.4g s of %.4g s",
                  static_cast<unsigned long long>(res_.dynamic_phases), ageing_time_, target());
    return b;
  }

 protected:
  void set_walls(Walls& w) override {
    set_held_walls(w);
    set_head(w);
  }

  const char* end_reason(Simulation& sim) override {
    const std::uint64_t cycle = sim.step_count() - phase_start_;
    if (cycle % cfg_.record_interval == 0 || cycle >= cfg_.min_cycles) record_phase(sim);
    if (cycle < cfg_.min_cycles) return nullptr;
    // End of a dynamic phase: record it, then jump the ageing clock (walls still).
    ++res_.dynamic_phases;
    record_event(sim, res_.dynamic_phases - 1);
    res_.ageing_time = ageing_time_ - ageing_clock_;
    if (ageing_time_ >= target()) return "target ageing time";
    const double left = target() - ageing_time_;
    const AgeingJump j = ageing_jump(sim, *crusher_, cfg_.n_break, left);
    ageing_time_ = j.dt >= left ? target() : ageing_time_ + j.dt;
    if (first_jump_ == 0.0) first_jump_ = ageing_time_ - ageing_clock_;
    if (StageOutputs* out = outputs()) out->set_ageing_clock(ageing_time_);
    start_phase(sim);
    return nullptr;
  }

  /// The end of a dynamic phase reads and changes the grains (events row, ageing jump).
  bool reads_grains(const Simulation& sim) const override {
    return sim.step_count() - phase_start_ >= cfg_.min_cycles;
  }

  std::uint64_t limit_steps(Simulation& sim, std::uint64_t n) const override {
    const std::uint64_t in_phase = sim.step_count() - phase_start_;
    if (in_phase < cfg_.min_cycles) n = std::min(n, cfg_.min_cycles - in_phase);
    return std::min(n, cfg_.record_interval - in_phase % cfg_.record_interval);
  }

  void phase_state(StateArchive& a) override {
    a(ageing_time_, phase_start_, phase_volume_, phase_lateral_);
  }

 private:
  void start_phase(const Simulation& sim) {
    phase_start_ = sim.step_count();
    phase_volume_ = sim.walls().volume();
    phase_lateral_ =
        cfg_.lateral == WallControl::Servo ? cfg_.lateral_stress : sim.walls().lateral_stress();
    record_phase(sim);
  }

  // A row of phases.csv (the study's Figure 2: what a jump disturbs), from cycle 0 (just after
  // the ageing jump, before the grains it brought to failure split) to the phase's last cycle.
  void record_phase(const Simulation& sim) const {
    StageOutputs* out = outputs();
    if (!out) return;
    const Walls& w = sim.walls();
    const double sa = w.axial_stress(), sr = w.lateral_stress();
    Measurement m;
    m.emplace_back("stage", static_cast<double>(index()));
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
    out->write("phases.csv", m);
  }

  // A row of events.csv at the end of dynamic phase `phase`; every event is a checkpoint.
  void record_event(const Simulation& sim, std::uint64_t phase) const {
    StageOutputs* out = outputs();
    if (!out) return;
    Measurement m;
    m.emplace_back("ageing_time_s", ageing_time_);
    m.emplace_back("stage", static_cast<double>(index()));
    m.emplace_back("dynamic_phase", static_cast<double>(phase));
    for (auto& kv : out->measure(sim)) m.push_back(kv);
    out->write("events.csv", m);
    if (!cfg_.body.empty()) record_pile(sim, phase, *out);
    out->snapshot();
    out->request_checkpoint();
  }

  // The pile's rows at the end of a dynamic phase (pile_ageing.csv, pile_shaft.csv,
  // pile_rings.csv): its loads as the whole pile's (a sector's divided by its fraction).
  void record_pile(const Simulation& sim, std::uint64_t phase, StageOutputs& out) const {
    const BodyProbe p = probe_stage_body(sim, cfg_);
    const int k = stage_body_index(sim.walls(), cfg_);
    const PileField f = measure_pile_field(sim, k, static_cast<int>(cfg_.rings), cfg_.field_radius,
                                           static_cast<int>(cfg_.bins));
    auto head = [&](Measurement& m) {
      m.emplace_back("ageing_time_s", ageing_time_);
      m.emplace_back("stage", static_cast<double>(index()));
      m.emplace_back("dynamic_phase", static_cast<double>(phase));
    };
    Measurement m;
    head(m);
    m.emplace_back("head_position_m", sim.walls().position(k));
    m.emplace_back("head_load_N", (p.tip_load + p.shaft_load) / p.sector);
    m.emplace_back("shaft_load_N", p.shaft_load / p.sector);
    m.emplace_back("base_load_N", p.tip_load / p.sector);
    m.emplace_back("shaft_contacts", static_cast<double>(p.shaft_contacts));
    m.emplace_back("near_contacts", static_cast<double>(f.near_contacts));
    m.emplace_back("mean_Fn_near_N", f.mean_Fn);
    m.emplace_back("std_Fn_near_N", f.std_Fn);
    m.emplace_back("mean_Ft_near_N", f.mean_Ft);
    m.emplace_back("std_Ft_near_N", f.std_Ft);
    for (auto& kv : out.measure(sim)) m.push_back(kv);
    out.write("pile_ageing.csv", m);
    Measurement lead;
    head(lead);
    write_shaft_rows(out, "pile_shaft.csv", p, lead);
    write_ring_rows(out, "pile_rings.csv", f.rings, lead, "height_m", 0.0);
  }

  /// The ageing clock this stage ages to [s].
  double target() const { return cfg_.until > 0.0 ? cfg_.until : ageing_clock_ + cfg_.duration; }

  Crusher* crusher_;
  double ageing_time_ = 0.0;
  double first_jump_ = 0.0;     // the ageing of this stage's first jump [s], for fraction() only
  mutable double shown_ = 0.0;  // the largest fraction() returned
  std::uint64_t phase_start_ = 0;
  double phase_volume_ = 0.0;   // box volume at cycle 0 of the current phase [m^3]
  double phase_lateral_ = 0.0;  // reference of the confining fluctuation [Pa]
};

}  // namespace

double ageing_progress(double t, double span, double first_jump, std::uint64_t phases) {
  if (!(span > 0.0)) return 1.0;
  double f = std::log1p(t) / std::log1p(span);
  const auto k = static_cast<double>(phases);
  if (first_jump > 0.0 && k >= 2.0 && t > first_jump && t < span) {
    const double per_jump = std::log(t / first_jump) / (k - 1.0);
    f = std::max(f, k / (k + 1.0 + std::log(span / t) / per_jump));
  }
  return f;
}

const StageKind& age_stage_kind() {
  static const StageKind kind{
      .name = "age",
      .description =
          "off-DEM ageing (docs/model.md 3.1; needs [crushing] with crack_growth): "
          "dynamic phases of `min_cycles` steps alternate with ageing jumps until the "
          "ageing clock reaches `duration`",
      .params = with_pile_head(held_walls_stage_table({
          {"duration", &StageConfig::duration, "s",
           "ageing time this stage adds (the relaxation clock; DEM time is reported apart); or "
           "give until",
           [](double v) { return v > 0.0; }, "a positive ageing time in s (the relaxation clock)",
           "-", [](const StageConfig& c) { return c.until == 0.0; }},  // until not given
          {"until", &StageConfig::until, "s",
           "the run's ageing clock (summed over its age stages) this stage ages to; or give "
           "duration (a pile aged to 1 h, 1 day, 1 week, each load-tested by a branch)",
           [](double v) { return v > 0.0; }, "a positive ageing time in s", "-",
           [](const StageConfig& c) { return c.until != 0.0; }},  // given: NaN, < 0 refused
          {"min_cycles", &StageConfig::min_cycles, "", "steps of each dynamic phase (STUDY)",
           [](double v) { return v >= 1.0; }, "a number of steps >= 1"},
          {"n_break", &StageConfig::n_break, "",
           "grains brought to failure by each ageing jump (STUDY)",
           [](double v) { return v >= 1.0; }, "a number of grains >= 1"},
          {"record_interval", &StageConfig::record_interval, "",
           "steps between rows of phases.csv within each dynamic phase (the study's Figure 2)",
           [](double v) { return v >= 1.0; }, "a number of steps >= 1"},
          {"bins",
           &StageConfig::bins,
           "",
           "with a body: slices along the shaft (pile_shaft.csv) and from its tip to the top "
           "wall (pile_rings.csv)",
           [](double v) { return v >= 1.0 && v <= 1e4; },
           "a number of bins in [1, 10000]",
           "",
           [](const StageConfig& c) { return !c.body.empty(); },
           nullptr,
           {},
           "body"},
          {"rings",
           &StageConfig::rings,
           "",
           "with a body: rings of grains about it (pile_rings.csv)",
           [](double v) { return v >= 1.0 && v <= 1e3; },
           "a number of rings in [1, 1000]",
           "",
           [](const StageConfig& c) { return !c.body.empty(); },
           nullptr,
           {},
           "body"},
          {"field_radius",
           &StageConfig::field_radius,
           "-",
           "with a body: the outer ring's radius in shaft radii (rings geometric from the shaft); "
           "also the reach of the near-field contact statistics",
           [](double v) { return v > 1.0 && v <= 1e3; },
           "a radius in (1, 1000] shaft radii",
           "",
           [](const StageConfig& c) { return !c.body.empty(); },
           nullptr,
           {},
           "body"},
      })),
      .make = make_stage_of<AgeStage>,
      .check =
          [](const StageConfig& c, const std::string& prefix) {
            if ((c.duration > 0.0) == (c.until > 0.0)) {
              throw ConfigError(prefix + ": an age stage needs exactly one of '" + prefix +
                                ".duration' (the ageing it adds, > 0 s) or '" + prefix +
                                ".until' (the run's ageing clock to reach, > 0 s)");
            }
            check_pile_head(c, prefix);
          },
      .check_bodies = check_probed_body,
      .needs_crack_growth = true,
  };
  return kind;
}

}  // namespace crushdem

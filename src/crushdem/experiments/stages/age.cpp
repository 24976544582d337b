// The age stage, off-DEM ageing (docs/model.md 3.1; needs [crushing] crack_growth): dynamic
// phases of min_cycles steps (walls as `axial` / `lateral` say) alternate with ageing jumps
// (ageing/ageing_jump.hpp) that grow every crack at its frozen velocity until n_break grains
// would fail, until the ageing clock reaches `duration` (ageing time, not DEM time). Its own
// files: events.csv (a row at the end of every dynamic phase) and phases.csv (a row every
// record_interval cycles of each phase).
#include <algorithm>
#include <cstdio>
#include <string>

#include "crushdem/ageing/ageing_jump.hpp"
#include "crushdem/core/error.hpp"
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
    ageing_time_ = 0.0;
    Stage::begin(sim);
    start_phase(sim);
  }

  /// The dynamic phase and the ageing time against its duration.
  std::string progress_note() const override {
    char b[128];
    std::snprintf(b, sizeof b, "phase %llu  ageing time %.4g s of %.4g s",
                  static_cast<unsigned long long>(res_.dynamic_phases), ageing_time_,
                  cfg_.duration);
    return b;
  }

 protected:
  void set_walls(Walls& w) override { set_held_walls(w); }

  const char* end_reason(Simulation& sim) override {
    const std::uint64_t cycle = sim.step_count() - phase_start_;
    if (cycle % cfg_.record_interval == 0 || cycle >= cfg_.min_cycles) record_phase(sim);
    if (cycle < cfg_.min_cycles) return nullptr;
    // End of a dynamic phase: record it, then jump the ageing clock (walls still).
    ++res_.dynamic_phases;
    record_event(sim, res_.dynamic_phases - 1);
    res_.ageing_time = ageing_time_;
    if (ageing_time_ >= cfg_.duration) return "target ageing time";
    const double left = cfg_.duration - ageing_time_;
    const AgeingJump j = ageing_jump(sim, *crusher_, cfg_.n_break, left);
    ageing_time_ = j.dt >= left ? cfg_.duration : ageing_time_ + j.dt;
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
    out->request_checkpoint();
  }

  Crusher* crusher_;
  double ageing_time_ = 0.0;
  std::uint64_t phase_start_ = 0;
  double phase_volume_ = 0.0;   // box volume at cycle 0 of the current phase [m^3]
  double phase_lateral_ = 0.0;  // reference of the confining fluctuation [Pa]
};

}  // namespace

const StageKind& age_stage_kind() {
  static const StageKind kind{
      .name = "age",
      .description =
          "off-DEM ageing (docs/model.md 3.1; needs [crushing] with crack_growth): "
          "dynamic phases of `min_cycles` steps alternate with ageing jumps until the "
          "ageing clock reaches `duration`",
      .params = held_walls_stage_table({
          {"duration", &StageConfig::duration, "s",
           "target ageing time (the relaxation clock; DEM time is reported apart)",
           [](double v) { return v > 0.0; }, "a positive ageing time in s (the relaxation clock)",
           "-"},
          {"min_cycles", &StageConfig::min_cycles, "", "steps of each dynamic phase (STUDY)",
           [](double v) { return v >= 1.0; }, "> 0 steps"},
          {"n_break", &StageConfig::n_break, "",
           "grains brought to failure by each ageing jump (STUDY)",
           [](double v) { return v >= 1.0; }, "> 0 grains"},
          {"record_interval", &StageConfig::record_interval, "",
           "steps between rows of phases.csv within each dynamic phase (the study's Figure 2)",
           [](double v) { return v >= 1.0; }, "> 0 steps"},
      }),
      .make = make_stage_of<AgeStage>,
      .needs_crack_growth = true,
  };
  return kind;
}

}  // namespace crushdem

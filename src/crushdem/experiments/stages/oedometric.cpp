// The oedometric stage: lateral walls and the bottom fixed; the top moves at `strain_rate` (> 0
// loading, < 0 unloading) until the vertical stress reaches `stress`; strain_rate = 0
// servo-controls the top to `stress` until equilibrium.
#include <algorithm>
#include <cmath>
#include <string>

#include "crushdem/core/error.hpp"
#include "crushdem/experiments/stages.hpp"

namespace crushdem {
namespace {

class OedometricStage final : public Stage {
 public:
  using Stage::Stage;

  void begin(Simulation& sim) override {
    Stage::begin(sim);
    sigma_v0_ = sim.walls().axial_stress();
  }

  /// Driven at a strain rate: the way to the target stress on a log scale (compression curves
  /// are about straight in log stress). Servo-controlled (an equilibrium), or resumed (the
  /// start's stress is not saved): none.
  double fraction(const Simulation& sim) const override {
    const double sv = sim.walls().axial_stress();
    if (cfg_.strain_rate == 0.0 || !(sigma_v0_ > 0.0) || !(sv > 0.0)) return std::nan("");
    return std::log(sv / sigma_v0_) / std::log(cfg_.stress / sigma_v0_);
  }

 protected:
  void set_walls(Walls& w) override {
    if (cfg_.strain_rate == 0.0) {
      set_servo(w, 5, cfg_.stress);
    } else {
      w.config(5).mode = WallMode::Velocity;
      w.config(5).velocity = -cfg_.strain_rate * w.length(2);  // the top moves down in compression
    }
  }

  const char* end_reason(Simulation& sim) override {
    const double sv = sim.walls().axial_stress();
    if (cfg_.strain_rate == 0.0 && at_equilibrium(sim)) return "equilibrium";
    if (cfg_.strain_rate > 0.0 && sv >= cfg_.stress) return "target stress";
    if (cfg_.strain_rate < 0.0 && sv <= cfg_.stress) return "target stress";
    return nullptr;
  }

  std::string target_met_at_start(const Walls& w) const override {
    const double sv = w.axial_stress();
    if ((cfg_.strain_rate > 0.0 && sv >= cfg_.stress) ||
        (cfg_.strain_rate < 0.0 && sv <= cfg_.stress)) {
      return "its target stress " + show_number(cfg_.stress) + " Pa is met at the start (axial " +
             "stress " + show_number(sv) + " Pa; strain_rate > 0 loads to the target, < 0 unloads)";
    }
    return "";
  }

  void observe_kind(const Walls& w) override {
    for (int a = 0; a < 2; ++a) {
      res_.max_lateral_strain =
          std::max(res_.max_lateral_strain, std::abs(1.0 - w.length(a) / ref_.length[a]));
    }
  }

 private:
  double sigma_v0_ = 0.0;  // at the start, for progress lines only (not saved) [Pa]
};

}  // namespace

const StageKind& oedometric_stage_kind() {
  static const StageKind kind{
      .name = "oedometric",
      .description =
          "lateral walls and the bottom fixed; the top moves at `strain_rate`, or is "
          "servo-controlled (strain_rate = 0)",
      .params = stage_table({
          {"stress", &StageConfig::stress, "Pa", "target vertical stress",
           [](double v) { return v > 0.0; }, "a positive target vertical stress in Pa", "-"},
          {"strain_rate", &StageConfig::strain_rate, "1/s",
           "axial strain rate: > 0 loads until sigma_v >= stress, < 0 unloads until sigma_v <= "
           "stress, 0 servo-controls the top to stress until equilibrium",
           [](double v) { return std::abs(v) < 1e4; },
           "an axial strain rate in 1/s (> 0 loading, < 0 unloading, 0 servo)"},
      }),
      .make = make_stage_of<OedometricStage>,
  };
  return kind;
}

}  // namespace crushdem

// The triaxial stage: lateral walls servo-controlled to sigma_3, both axial walls moving at
// strain_rate (compression), until `axial_strain` (from the stage start) or until q >= stop_q
// (> 0).
#include <algorithm>
#include <cmath>
#include <string>

#include "crushdem/core/error.hpp"
#include "crushdem/experiments/stages.hpp"

namespace crushdem {
namespace {

class TriaxialStage final : public Stage {
 public:
  using Stage::Stage;

  double fraction(const Simulation& sim) const override {
    return stage_axial_strain(sim) / cfg_.axial_strain;
  }

 protected:
  void set_walls(Walls& w) override {
    const double Lz = w.length(2);
    for (const int k : w.lateral_walls()) set_servo(w, k, cfg_.sigma_3);
    w.config(4).mode = WallMode::Velocity;
    w.config(4).velocity = 0.5 * cfg_.strain_rate * Lz;
    w.config(5).mode = WallMode::Velocity;
    w.config(5).velocity = -0.5 * cfg_.strain_rate * Lz;
  }

  const char* end_reason(Simulation& sim) override {
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

  std::string target_met_at_start(const Walls& w) const override {
    const double q = w.axial_stress() - w.lateral_stress();
    if (cfg_.stop_q > 0.0 && q >= cfg_.stop_q) {
      return "its stop_q " + show_number(cfg_.stop_q) +
             " Pa is met at the start (q = " + show_number(q) + " Pa)";
    }
    return "";
  }

  void observe_kind(const Walls& w) override {
    for (const int k : w.lateral_walls()) {
      res_.max_lateral_stress_error =
          std::max(res_.max_lateral_stress_error, std::abs(w.stress(k) / cfg_.sigma_3 - 1.0));
    }
  }

  // Dilation must not outrun the lateral walls.
  double automatic_servo_rate() const override {
    return std::max(Stage::automatic_servo_rate(), 2.0 * cfg_.strain_rate);
  }
};

}  // namespace

const StageKind& triaxial_stage_kind() {
  static const StageKind kind{
      .name = "triaxial",
      .description =
          "four lateral walls servo-controlled to `sigma_3`, both axial walls moving "
          "at `strain_rate`",
      .params = stage_table({
          {"sigma_3", &StageConfig::sigma_3, "Pa",
           "confining stress held by the four lateral servo walls",
           [](double v) { return v > 0.0; }, "a positive confining stress in Pa", "-"},
          {"strain_rate", &StageConfig::strain_rate, "1/s",
           "axial strain rate (compression); both axial walls move",
           [](double v) { return v > 0.0; }, "a positive axial strain rate in 1/s", "-"},
          {"axial_strain", &StageConfig::axial_strain, "-",
           "the stage ends at this axial strain (from its start)",
           [](double v) { return v > 0.0 && v < 0.9; }, "a final axial strain in (0, 0.9)", "-"},
          {"stop_q", &StageConfig::stop_q, "Pa",
           "> 0: the stage ends when q reaches it (then a hold keeps the axial strain)",
           [](double v) { return v >= 0.0; }, "a deviator stress in Pa to stop at (0 = not used)"},
      }),
      .make = make_stage_of<TriaxialStage>,
  };
  return kind;
}

}  // namespace crushdem

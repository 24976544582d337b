// The isotropic stage: all six walls servo-controlled to `stress`, until equilibrium.
#include "crushdem/experiments/stages.hpp"

namespace crushdem {
namespace {

class IsotropicStage final : public Stage {
 public:
  using Stage::Stage;

 protected:
  void set_walls(Walls& w) override {
    for (const int k : w.sample_walls()) set_servo(w, k, cfg_.stress);
  }
  const char* end_reason(Simulation& sim) override {
    return at_equilibrium(sim) ? "equilibrium" : nullptr;
  }
};

}  // namespace

const StageKind& isotropic_stage_kind() {
  static const StageKind kind{
      .name = "isotropic",
      .description = "all walls (a chamber's too) servo-controlled to `stress`, until equilibrium",
      .params = stage_table({
          {"stress", &StageConfig::stress, "Pa", "target stress of all six servo walls",
           [](double v) { return v > 0.0; }, "a positive stress in Pa", "-"},
      }),
      .make = make_stage_of<IsotropicStage>,
  };
  return kind;
}

}  // namespace crushdem

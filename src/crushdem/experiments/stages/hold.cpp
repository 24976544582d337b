// The hold stage: the walls keep still or are servo-controlled (`axial`, `lateral`), for `steps`
// or `duration` of DEM time; a pile named by `body` held as `head` says (its head load taken off
// after installation, say). With `settle`, the hold ends as soon as the sample has settled, and
// steps or duration is the longest it lasts.
#include <algorithm>
#include <cmath>
#include <string>

#include "crushdem/core/error.hpp"
#include "crushdem/experiments/stages.hpp"

namespace crushdem {
namespace {

class HoldStage final : public Stage {
 public:
  using Stage::Stage;

 protected:
  void set_walls(Walls& w) override {
    set_held_walls(w);
    set_head(w);
  }

 public:
  double fraction(const Simulation& sim) const override {
    if (cfg_.steps > 0) {
      return static_cast<double>(sim.step_count() - start_step_) / static_cast<double>(cfg_.steps);
    }
    return (sim.time() - start_time_) / cfg_.duration;
  }

 protected:
  const char* end_reason(Simulation& sim) override {
    if (cfg_.settle && at_equilibrium(sim)) return "settled";
    if (cfg_.steps > 0 && res_.steps >= cfg_.steps) return "duration";
    if (cfg_.duration > 0.0 && sim.time() - start_time_ >= cfg_.duration * (1.0 - 1e-12)) {
      return "duration";
    }
    return nullptr;
  }

  std::uint64_t limit_steps(Simulation& sim, std::uint64_t n) const override {
    const std::uint64_t done = sim.step_count() - start_step_;
    if (cfg_.steps > 0) n = std::min(n, cfg_.steps - std::min(cfg_.steps, done));
    if (cfg_.duration > 0.0) {
      const double left = std::ceil((start_time_ + cfg_.duration - sim.time()) / sim.dt());
      n = std::min(n, static_cast<std::uint64_t>(std::max(1.0, left)));
    }
    return n;
  }
};

}  // namespace

const StageKind& hold_stage_kind() {
  static const StageKind kind{
      .name = "hold",
      .description = "the walls fixed or servo-controlled, for `steps` or `duration` (exactly one)",
      .params = with_pile_head(held_walls_stage_table({
          {"steps",
           &StageConfig::steps,
           "",
           "length of the hold in steps (or give duration)",
           nullptr,
           {},
           "-",
           [](const StageConfig& c) { return c.steps > 0; }},
          {"duration", &StageConfig::duration, "s",
           "length of the hold in DEM time (or give steps)", [](double v) { return v >= 0.0; },
           "a time in s", "-", [](const StageConfig& c) { return c.duration > 0.0; }},
          {"settle",
           &StageConfig::settle,
           "",
           "end as soon as every servo target is met to `tolerance` (a zero target, a head load "
           "taken off, to `tolerance` times the largest target) and the unbalanced-force ratio is "
           "below `unbalanced`; `steps` or `duration` is then the longest the hold lasts",
           nullptr,
           {},
           {},
           [](const StageConfig& c) { return c.settle; }},
      })),
      .make = make_stage_of<HoldStage>,
      .check =
          [](const StageConfig& c, const std::string& prefix) {
            if ((c.steps == 0) == !(c.duration > 0.0)) {
              throw ConfigError(prefix + ": a hold stage needs exactly one of '" + prefix +
                                ".steps' (> 0) or '" + prefix + ".duration' (> 0 s)");
            }
            check_pile_head(c, prefix);
          },
      .check_bodies = check_probed_body,
  };
  return kind;
}

}  // namespace crushdem

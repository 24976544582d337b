// The hold stage: the walls keep still or are servo-controlled (`axial`, `lateral`), for `steps`
// or `duration` of DEM time; a pile named by `body` held as `head` says (its head load taken off
// after installation, say). With `settle`, the hold ends as soon as the sample has settled, and
// steps or duration is the longest it lasts. With `profile_bins`, a chamber sample's stress
// profile with depth is written at its end (stress_profile.csv: a chamber at rest, K0 by depth).
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "crushdem/core/error.hpp"
#include "crushdem/experiments/pile_field.hpp"
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
  void begin(Simulation& sim) override {
    if (cfg_.profile_bins > 0 && sim.walls().chamber() < 0) {
      throw ConfigError(bad_value("stage '" + cfg_.label() + "'.profile_bins",
                                  std::to_string(cfg_.profile_bins),
                                  "0 for this sample: a stress profile is a chamber sample's "
                                  "(a [sample] with shape = \"cylinder\", or its sample.txt)"));
    }
    Stage::begin(sim);
  }

  /// The profile at the stage's end reads the contacts, brought from a device at the check that
  /// ends the stage (with `settle`, any check may: the settled state is seen there first).
  bool reads_grains(const Simulation& sim) const override {
    return cfg_.profile_bins > 0 && (cfg_.settle || at_its_length(sim));
  }

  double fraction(const Simulation& sim) const override {
    if (cfg_.steps > 0) {
      return static_cast<double>(sim.step_count() - start_step_) / static_cast<double>(cfg_.steps);
    }
    return (sim.time() - start_time_) / cfg_.duration;
  }

 protected:
  const char* end_reason(Simulation& sim) override {
    const char* reason = nullptr;
    if (cfg_.settle && at_equilibrium(sim)) {
      reason = "settled";
    } else if (at_its_length(sim)) {
      reason = "duration";
    }
    if (reason && cfg_.profile_bins > 0) record_profile(sim);
    return reason;
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

 private:
  /// `steps` or `duration` done.
  bool at_its_length(const Simulation& sim) const {
    return (cfg_.steps > 0 && sim.step_count() - start_step_ >= cfg_.steps) ||
           (cfg_.duration > 0.0 && sim.time() - start_time_ >= cfg_.duration * (1.0 - 1e-12));
  }

  /// stress_profile.csv: the core's stress by slice, from the bottom platen up.
  void record_profile(const Simulation& sim) const {
    StageOutputs* out = outputs();
    if (!out) return;
    const Walls& w = sim.walls();
    const double core = cfg_.profile_radius * w.chamber_radius();
    for (const RingStress& r :
         measure_chamber_profile(sim, core, static_cast<int>(cfg_.profile_bins))) {
      const double z = w.position(4) + r.height;
      Measurement m;
      m.emplace_back("stage", static_cast<double>(index()));
      m.emplace_back("time_s", sim.time());
      m.emplace_back("bin", static_cast<double>(r.bin));
      m.emplace_back("z_m", z);
      m.emplace_back("depth_m", w.position(5) - z);
      m.emplace_back("core_radius_m", core);
      m.emplace_back("sigma_rr_Pa", r.sigma_rr);
      m.emplace_back("sigma_tt_Pa", r.sigma_tt);
      m.emplace_back("sigma_zz_Pa", r.sigma_zz);
      m.emplace_back("tau_rz_Pa", r.tau_rz);
      // K = sigma_rr / sigma_zz: NaN in a slice that carries no vertical stress.
      m.emplace_back("K", r.sigma_zz > 0.0 ? r.sigma_rr / r.sigma_zz
                                           : std::numeric_limits<double>::quiet_NaN());
      m.emplace_back("grains", static_cast<double>(r.grains));
      out->write("stress_profile.csv", m);
    }
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
          {"profile_bins", &StageConfig::profile_bins, "",
           "a chamber sample's stress profile with depth at the hold's end (stress_profile.csv): "
           "the Love-Weber stress of the grains within `profile_radius` of the axis in this many "
           "slices from the bottom platen to the top one, with K = sigma_rr / sigma_zz; 0 = none",
           [](double v) { return v >= 0.0 && v <= 1e4; }, "a number of slices in [0, 10000]", "",
           [](const StageConfig& c) { return c.profile_bins > 0; }},
          {"profile_radius",
           &StageConfig::profile_radius,
           "",
           "the profile's core, in chamber radii (the grains beyond it, the chamber wall's "
           "layers, are left out)",
           [](double v) { return v > 0.0 && v <= 1.0; },
           "a fraction of the radius in (0, 1]",
           "",
           [](const StageConfig& c) { return c.profile_bins > 0; },
           nullptr,
           {},
           "profile_bins"},
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

// The penetrate stage (docs/chamber.md): a [[body]] (a cone, a pile, a flat punch or a bare
// shaft) driven into the grains at a constant `velocity` until it has travelled `depth`, the
// box's walls held as `axial` and `lateral` say and every other body as configured; with
// `from_top` it starts with its tip level with the top wall (the sample's surface). Its own files,
// a row every record_interval steps: penetration.csv (travel, tip position, q_c, f_s, the loads on
// the tip and the shaft, with the run's measurements) and shaft_profile.csv (the radial and shear
// stress on the shaft by bins along it: walls/body_probe.hpp). With `stroke` the body is jacked:
// it advances `stroke` at `velocity`, stands still for `pause` (held where it is, as a jack that
// grips it), and so on until `depth`.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "crushdem/core/error.hpp"
#include "crushdem/experiments/stages.hpp"
#include "crushdem/walls/body_config.hpp"
#include "crushdem/walls/body_probe.hpp"

namespace crushdem {
namespace {

/// The standard friction sleeve: 150 cm^2 on a 35.7 mm cone (ISO 22476-1), 133.7 mm long.
constexpr double kSleeveDiameters = 0.1337 / 0.0357;

int body_index(const Walls& w, const std::string& name) {
  for (int k = kNumWalls; k < w.size(); ++k) {
    if (w.name(k) == name) return k;
  }
  throw ConfigError("penetrate stage: no [[body]] named \"" + name + "\"");
}

class PenetrateStage final : public Stage {
 public:
  using Stage::Stage;

  void begin(Simulation& sim) override {
    Stage::begin(sim);
    Walls& w = sim.walls();
    const int k = body_index(w, cfg_.body);
    if (w.sector() < 1.0) {  // a sector: the body on its axis, the z axis
      const BodyPart& tip = w.shape(k).part[0];
      if (tip.origin.x != 0.0 || tip.origin.y != 0.0 || tip.axis.x != 0.0 || tip.axis.y != 0.0) {
        throw ConfigError(bad_value("stage '" + cfg_.label() + "'.body", "\"" + cfg_.body + "\"",
                                    "a body on the z axis (origin [0, 0, z], axis [0, 0, 1]): "
                                    "the sample is a sector of a chamber about that axis"));
      }
    }
    if (cfg_.from_top) {
      // Down its direction until the tip is level with the top wall: the sample's surface.
      const BodyShape& b = w.shape(k);
      const double tip_z = placed_part(b.part[0], w.position(k), b.motion, b.dilate).origin.z;
      if (!(b.motion.z < 0.0) || !(tip_z >= w.position(5))) {
        throw ConfigError(bad_value(
            "stage '" + cfg_.label() + "'.from_top", "true",
            "false for this body: from_top lowers a body moving down (direction with z < 0) "
            "from above the top wall (its tip is at z = " +
                show_number(tip_z) + " m, the top wall at " + show_number(w.position(5)) + " m)"));
      }
      w.state(k).position += (tip_z - w.position(5)) / -b.motion.z;
      sim.invalidate();  // the wall contacts are found again for the body's new place
    }
    q_start_ = w.position(k);
    next_stop_ = cfg_.stroke > 0.0 ? std::min(cfg_.stroke, cfg_.depth) : cfg_.depth;
    move(sim, true);
    record(sim);
  }

  std::string progress_note() const override {
    char b[128];
    std::snprintf(b, sizeof b, "travel %.4g m of %.4g m  q_c %.4g Pa", travel_, cfg_.depth, q_c_);
    return b;
  }

  /// A record reads the grains' positions and their contacts with the body.
  bool reads_grains(const Simulation& sim) const override {
    const Walls& w = sim.walls();
    // (at every record, at a stroke's end, at a pause's end and at the depth)
    return (sim.step_count() - start_step_) % cfg_.record_interval == 0 ||
           (!pausing_ &&
            w.position(body_index(w, cfg_.body)) - q_start_ >= next_stop_ * (1.0 - 1e-12)) ||
           (pausing_ && sim.time() >= pause_end_ * (1.0 - 1e-15));
  }

  void state(StateArchive& a) override {
    Stage::state(a);
    a.section("penetration");
    a(q_start_, travel_, q_c_, next_stop_, pause_end_, pausing_, strokes_);
  }

 protected:
  void set_walls(Walls& w) override { set_held_walls(w); }

  const char* end_reason(Simulation& sim) override {
    Walls& w = sim.walls();
    const int k = body_index(w, cfg_.body);
    travel_ = w.position(k) - q_start_;
    const bool done = travel_ >= cfg_.depth * (1.0 - 1e-12);
    bool event = done;
    if (pausing_ && sim.time() >= pause_end_ * (1.0 - 1e-15)) {  // the next stroke
      pausing_ = false;
      next_stop_ = std::min(next_stop_ + cfg_.stroke, cfg_.depth);
      move(sim, true);
      event = true;
    } else if (!pausing_ && !done && travel_ >= next_stop_ * (1.0 - 1e-12)) {  // a stroke's end
      pausing_ = true;
      ++strokes_;
      pause_end_ = sim.time() + cfg_.pause;
      move(sim, false);
      event = true;
    }
    if ((sim.step_count() - start_step_) % cfg_.record_interval == 0 || event) record(sim);
    if (!done) return nullptr;
    move(sim, false);  // the body stops where it is; the next stage finds it still
    return "depth reached";
  }

  std::uint64_t limit_steps(Simulation& sim, std::uint64_t n) const override {
    const std::uint64_t done = sim.step_count() - start_step_;
    n = std::min(n, cfg_.record_interval - done % cfg_.record_interval);
    // The last steps land on the stroke's end or the depth, or on the end of a pause.
    const double left = pausing_ ? std::ceil((pause_end_ - sim.time()) / sim.dt())
                                 : std::ceil((next_stop_ - travel_) / (cfg_.velocity * sim.dt()));
    return std::min(n, static_cast<std::uint64_t>(std::max(1.0, left)));
  }

 private:
  void record(const Simulation& sim) {
    const Walls& w = sim.walls();
    const int k = body_index(w, cfg_.body);
    travel_ = w.position(k) - q_start_;
    const double R = w.shape(k).part[0].radius;
    const double sleeve = cfg_.sleeve_length > 0.0 ? cfg_.sleeve_length : kSleeveDiameters * 2 * R;
    const BodyProbe p =
        probe_body(w, k, sim.wall_contacts(), sim.particles(), sleeve, static_cast<int>(cfg_.bins));
    q_c_ = p.q_c();
    StageOutputs* out = outputs();
    if (!out) return;
    Measurement m;
    m.emplace_back("stage", static_cast<double>(index()));
    m.emplace_back("travel_m", travel_);
    m.emplace_back("tip_x_m", p.tip.x);
    m.emplace_back("tip_y_m", p.tip.y);
    m.emplace_back("tip_z_m", p.tip.z);
    m.emplace_back("q_c_Pa", q_c_);
    m.emplace_back("f_s_Pa", p.f_s());
    m.emplace_back("tip_load_N", p.tip_load);
    m.emplace_back("shaft_load_N", p.shaft_load);
    m.emplace_back("sleeve_load_N", p.sleeve_load);
    m.emplace_back("tip_contacts", static_cast<double>(p.tip_contacts));
    m.emplace_back("shaft_contacts", static_cast<double>(p.shaft_contacts));
    m.emplace_back("moving", pausing_ || travel_ >= cfg_.depth * (1.0 - 1e-12) ? 0.0 : 1.0);
    m.emplace_back("strokes", static_cast<double>(strokes_));
    for (auto& kv : out->measure(sim)) m.push_back(kv);  // time_s, step, the walls, crushing
    out->write("penetration.csv", m);
    for (std::size_t j = 0; j < p.sigma_r.size(); ++j) {
      Measurement b;
      b.emplace_back("stage", static_cast<double>(index()));
      b.emplace_back("time_s", sim.time());
      b.emplace_back("travel_m", travel_);
      b.emplace_back("bin", static_cast<double>(j));
      b.emplace_back("height_m", (static_cast<double>(j) + 0.5) * p.bin_height);
      b.emplace_back("sigma_r_Pa", p.sigma_r[j]);
      b.emplace_back("tau_Pa", p.tau[j]);
      b.emplace_back("contacts", static_cast<double>(p.bin_contacts[j]));
      out->write("shaft_profile.csv", b);
    }
  }

  // The body driven at `velocity` (moving) or held still where it is.
  void move(Simulation& sim, bool moving) {
    Walls& w = sim.walls();
    WallConfig& c = w.config(body_index(w, cfg_.body));
    c.mode = moving ? WallMode::Velocity : WallMode::Fixed;
    c.velocity = moving ? cfg_.velocity : 0.0;
    w.update_velocities(sim.current_dt());
  }

  double q_start_ = 0.0;       // the body's degree of freedom at the start [m]
  double next_stop_ = 0.0;     // the travel where the body next stops: a stroke's end or depth [m]
  double pause_end_ = 0.0;     // the time a pause ends [s]
  bool pausing_ = false;       // between strokes
  std::uint64_t strokes_ = 0;  // strokes completed
  double travel_ = 0.0;        // since the start [m]
  double q_c_ = 0.0;           // at the last record [Pa]
};

}  // namespace

const StageKind& penetrate_stage_kind() {
  static const StageKind kind{
      .name = "penetrate",
      .description =
          "a [[body]] (cone, pile, flat punch, shaft) driven at `velocity` for `depth`; q_c, f_s "
          "and the shaft's radial stress recorded (penetration.csv, shaft_profile.csv)",
      .params = held_walls_stage_table({
          {"body",
           &StageConfig::body,
           "",
           "the [[body]] driven (its `name`): a translating cone, pile, disk or "
           "cylinder_outside",
           nullptr,
           {},
           "-"},
          {"velocity", &StageConfig::velocity, "m/s",
           "penetration rate along the body's `direction` (the standard CPT's is 0.02 m/s; DEM "
           "chambers push faster while the inertial number stays low)",
           [](double v) { return v > 0.0; }, "a positive velocity in m/s", "-"},
          {"depth", &StageConfig::depth, "m", "how far the body travels in this stage",
           [](double v) { return v > 0.0; }, "a positive travel in m", "-"},
          {"record_interval", &StageConfig::record_interval, "",
           "steps between rows of penetration.csv and shaft_profile.csv",
           [](double v) { return v >= 1.0; }, "> 0 steps"},
          {"bins", &StageConfig::bins, "", "bins along the shaft in shaft_profile.csv",
           [](double v) { return v >= 1.0 && v <= 1e4; }, "a number of bins in [1, 10000]"},
          {"from_top", &StageConfig::from_top, "",
           "at the start, lower the body along its direction until its tip is level with the top "
           "wall (the top of a prepared cube or chamber sample): travel is then depth below it"},
          {"stroke", &StageConfig::stroke, "m",
           "jacking: the body advances `stroke`, stands still for `pause`, and again, until "
           "`depth` (the mini-piles of calibration chambers are jacked in strokes); 0 = one "
           "continuous push",
           [](double v) { return v >= 0.0; }, "a stroke length >= 0 in m"},
          {"pause", &StageConfig::pause, "s",
           "how long the body is held still (where it is, not unloaded) between strokes",
           [](double v) { return v >= 0.0; }, "a time >= 0 in s"},
          {"sleeve_length", &StageConfig::sleeve_length, "m",
           "friction sleeve above the tip for f_s; 0 = 3.75 shaft diameters (150 cm^2 on a "
           "35.7 mm cone, ISO 22476-1)",
           [](double v) { return v >= 0.0; }, "a length >= 0 in m"},
      }),
      .make = make_stage_of<PenetrateStage>,
      .check_bodies =
          [](const StageConfig& c, const std::vector<BodyConfig>& bodies,
             const std::string& prefix) {
            for (const BodyConfig& b : bodies) {
              if (b.name != c.body) continue;
              const Body made = b.make(0.0);
              if (!probe_supports(made.shape)) {
                throw ConfigError(bad_value(
                    prefix + ".body", "\"" + c.body + "\"",
                    "a translating cone, pile, disk or cylinder_outside (this body is a " +
                        std::string(to_string(b.kind)) +
                        (b.motion == BodyMotion::Dilate ? " that dilates)" : ")")));
              }
              return;
            }
            std::string names;
            for (const BodyConfig& b : bodies)
              names += (names.empty() ? "\"" : ", \"") + b.name + "\"";
            throw ConfigError(bad_value(
                prefix + ".body", "\"" + c.body + "\"",
                "the name of a [[body]]" +
                    (names.empty() ? std::string(" (there is none)") : " (" + names + ")")));
          },
  };
  return kind;
}

}  // namespace crushdem

// The penetrate stage (docs/chamber.md): a [[body]] (a cone, a pile, a flat punch or a bare
// shaft) driven into the grains at a constant `velocity` until it has travelled `depth`, the
// box's walls held as `axial` and `lateral` say and every other body as configured; with
// `from_top` it starts with its tip level with the top wall (the sample's surface). Its own files,
// a row every record_interval steps: penetration.csv (travel, tip position, q_c, f_s, the loads on
// the tip and the shaft, with the run's measurements) and shaft_profile.csv (the radial and shear
// stress on the shaft by bins along it: walls/body_probe.hpp); with `field_interval`, also
// penetration_field.csv (the stress in rings of grains about the body from the bottom platen to
// the top one: experiments/pile_field.hpp). With `stroke` the body is jacked:
// it advances `stroke` at `velocity`, stands still for `pause` (held where it is, as a jack that
// grips it, or with `unload` its head load taken off so that it may rebound, as the Grenoble
// chamber's mini-piles were unloaded between strokes), and so on until `depth`. The load_test
// kind (a pile's static load test) is here too: it drives a body the same way.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "crushdem/core/error.hpp"
#include "crushdem/experiments/pile_field.hpp"
#include "crushdem/experiments/stages.hpp"
#include "crushdem/walls/body_config.hpp"
#include "crushdem/walls/body_probe.hpp"

namespace crushdem {
namespace {

constexpr std::array<Named<LoadDirection>, 2> kLoadDirectionNames = {
    {{LoadDirection::Compression, "compression"}, {LoadDirection::Tension, "tension"}}};

/// A driven body must be named (hold and age name one only when they hold a pile).
void check_driven_body(const StageConfig& c, const std::vector<BodyConfig>& bodies,
                       const std::string& prefix) {
  if (c.body.empty()) {
    throw ConfigError(bad_value(prefix + ".body", "\"\"", "the name of the [[body]] it drives"));
  }
  check_probed_body(c, bodies, prefix);
  for (const BodyConfig& b : bodies) {
    // A shaft without a tip has no leading end (body_geometry.hpp): the grains under it would
    // pass inside it as it advanced, unseen.
    if (b.name == c.body && b.kind == BodyKind::CylinderOutside) {
      throw ConfigError(bad_value(prefix + ".body", "\"" + c.body + "\"",
                                  "a body with a leading end to drive: a cone, a pile or a disk "
                                  "(this one is a bare cylinder_outside, which grains under it "
                                  "would pass into; a pile is a shaft on a tip)"));
    }
    // The field's rings are about the vertical line through the tip (measure_body_field).
    if (b.name == c.body && c.field_interval > 0) {
      const Vec3 m = b.make(0.0).shape.motion;
      if (!(std::abs(m.z) >= norm(m) * (1.0 - 1e-12))) {
        throw ConfigError(bad_value(prefix + ".field_interval", std::to_string(c.field_interval),
                                    "0 for this body: the stress field is taken in rings about a "
                                    "vertical axis, and body \"" +
                                        c.body + "\" does not move along z"));
      }
    }
  }
}

/// Body `c.body` driven at `velocity` along its direction (0: held still where it is).
void drive_body(Simulation& sim, const StageConfig& c, double velocity) {
  Walls& w = sim.walls();
  WallConfig& b = w.config(stage_body_index(w, c));
  b.mode = velocity != 0.0 ? WallMode::Velocity : WallMode::Fixed;
  b.velocity = velocity;
  w.update_velocities(sim.current_dt());
}

class PenetrateStage final : public Stage {
 public:
  using Stage::Stage;

  void begin(Simulation& sim) override {
    Stage::begin(sim);
    Walls& w = sim.walls();
    const int k = stage_body_index(w, cfg_);
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
    {  // the tip must end above the bottom platen
      const BodyShape& b = w.shape(k);
      const double tip_z = placed_part(b.part[0], w.position(k), b.motion, b.dilate).origin.z;
      const double end_z = tip_z + cfg_.depth * b.motion.z;
      if (b.motion.z < 0.0 && end_z <= w.position(4)) {
        throw ConfigError(bad_value("stage '" + cfg_.label() + "'.depth", show_number(cfg_.depth),
                                    "a travel that keeps the tip above the bottom platen (it "
                                    "would end at z = " +
                                        show_number(end_z) + " m, the platen is at " +
                                        show_number(w.position(4)) + " m)"));
      }
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

  double fraction(const Simulation& sim) const override { return travel_now(sim) / cfg_.depth; }

  /// A record reads the grains' positions and their contacts with the body.
  bool reads_grains(const Simulation& sim) const override {
    // (at every record, at a stroke's end, at a pause's end, at the depth and at max_steps)
    return (sim.step_count() - start_step_) % cfg_.record_interval == 0 || at_max_steps(sim) ||
           (!pausing_ && travel_now(sim) >= next_stop_ * (1.0 - 1e-12)) ||
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
    const int k = stage_body_index(w, cfg_);
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
      if (cfg_.unload) {
        unload(sim);
      } else {
        move(sim, false);
      }
      event = true;
    }
    if ((sim.step_count() - start_step_) % cfg_.record_interval == 0 || event) record(sim);
    if (!done) return nullptr;
    move(sim, false);  // the body stops where it is; the next stage finds it still
    return "depth reached";
  }

  void stop_early(Simulation& sim) override {
    record(sim, true);  // the stage's last state, as at its depth
    pausing_ = false;
    move(sim, false);
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
  // A row of penetration.csv and shaft_profile.csv, and the field when it is due or `last`;
  // each at most once a step (a stage cut by max_steps records again after end_reason).
  void record(const Simulation& sim, bool last = false) {
    last = last || travel_now(sim) >= cfg_.depth * (1.0 - 1e-12);
    const bool field = cfg_.field_interval > 0 && field_step_ != sim.step_count() &&
                       ((sim.step_count() - start_step_) % cfg_.field_interval == 0 || last);
    if (row_step_ == sim.step_count() && !field) return;
    travel_ = travel_now(sim);
    const BodyProbe p = probe_stage_body(sim, cfg_);
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
    if (row_step_ != sim.step_count()) {
      row_step_ = sim.step_count();
      for (auto& kv : out->measure(sim)) m.push_back(kv);  // time_s, step, the walls, crushing
      out->write("penetration.csv", m);
      write_shaft_rows(
          *out, "shaft_profile.csv", p,
          {{"stage", static_cast<double>(index())}, {"time_s", sim.time()}, {"travel_m", travel_}});
    }
    if (field) {
      field_step_ = sim.step_count();
      record_field(sim, p, *out);
    }
  }

  double travel_now(const Simulation& sim) const {
    return sim.walls().position(stage_body_index(sim.walls(), cfg_)) - q_start_;
  }

  // penetration_field.csv: the stress in rings of grains about the body, platen to platen.
  void record_field(const Simulation& sim, const BodyProbe& p, StageOutputs& out) const {
    const int k = stage_body_index(sim.walls(), cfg_);
    write_ring_rows(out, "penetration_field.csv",
                    measure_body_field(sim, k, static_cast<int>(cfg_.rings), cfg_.field_radius,
                                       static_cast<int>(cfg_.field_bins)),
                    {{"stage", static_cast<double>(index())},
                     {"time_s", sim.time()},
                     {"travel_m", travel_},
                     {"tip_z_m", p.tip.z}},
                    "z_m", sim.walls().position(4), true);
  }

  // The body driven at `velocity` (moving) or held still where it is.
  void move(Simulation& sim, bool moving) { drive_body(sim, cfg_, moving ? cfg_.velocity : 0.0); }

  // Between strokes with `unload`: the head servo-controlled to zero load, free to rebound.
  void unload(Simulation& sim) {
    Walls& w = sim.walls();
    w.config(stage_body_index(w, cfg_)).velocity = 0.0;
    servo_head(w, 0.0);
    w.update_velocities(sim.current_dt());
  }

  double q_start_ = 0.0;       // the body's degree of freedom at the start [m]
  double next_stop_ = 0.0;     // the travel where the body next stops: a stroke's end or depth [m]
  double pause_end_ = 0.0;     // the time a pause ends [s]
  bool pausing_ = false;       // between strokes
  std::uint64_t strokes_ = 0;  // strokes completed
  double travel_ = 0.0;        // since the start [m]
  double q_c_ = 0.0;           // at the last record [Pa]
  // The steps of the last row and field record (within one update only: not saved).
  std::uint64_t row_step_ = ~std::uint64_t{0}, field_step_ = ~std::uint64_t{0};
};

// The load test (docs/pile.md): the pile driven at `velocity` on into the grains (compression)
// or back out of them (tension) until its head has travelled `displacement`, the box's walls
// held as `axial` and `lateral` say. load_test.csv gets a row every record_interval steps: the
// head displacement and the whole pile's head, shaft and base loads, positive in the test's
// direction (a sector's loads divided by its fraction of the circle). The capacity is the
// largest running median of the head load over `capacity_window` rows (a test of fewer rows: the
// median of those), with the shaft and base loads and the displacement of the median row
// (summary.json): a grain that splits under the tip gives a row a spike (its fragments start
// overlapping the tip) that is not the pile's capacity.
class LoadTestStage final : public Stage {
 public:
  using Stage::Stage;

  void begin(Simulation& sim) override {
    Stage::begin(sim);
    q_start_ = sim.walls().position(stage_body_index(sim.walls(), cfg_));
    drive_body(sim, cfg_, sign() * cfg_.velocity);
    record(sim);
  }

  std::string progress_note() const override {
    char b[128];
    std::snprintf(b, sizeof b, "head %.4g m of %.4g m  Q %.4g N (max %.4g N)", travel_,
                  cfg_.displacement, load_, res_.capacity);
    return b;
  }

  double fraction(const Simulation& sim) const override {
    return head_travel(sim) / cfg_.displacement;
  }

  bool reads_grains(const Simulation& sim) const override {
    return (sim.step_count() - start_step_) % cfg_.record_interval == 0 || at_max_steps(sim) ||
           head_travel(sim) >= cfg_.displacement * (1.0 - 1e-12);
  }

  void state(StateArchive& a) override {
    Stage::state(a);
    a.section("load_test");
    a(q_start_, travel_, load_, res_.capacity, res_.shaft_at_capacity, res_.base_at_capacity,
      res_.displacement_at_capacity, recent_);
  }

 protected:
  void set_walls(Walls& w) override { set_held_walls(w); }

  const char* end_reason(Simulation& sim) override {
    travel_ = head_travel(sim);
    const bool done = travel_ >= cfg_.displacement * (1.0 - 1e-12);
    if ((sim.step_count() - start_step_) % cfg_.record_interval == 0 || done) record(sim);
    if (!done) return nullptr;
    drive_body(sim, cfg_, 0.0);  // held where the test left it
    finish_capacity();
    return "displacement reached";
  }

  void stop_early(Simulation& sim) override {
    if (row_step_ != sim.step_count()) record(sim);  // the test's last state
    drive_body(sim, cfg_, 0.0);
    finish_capacity();
  }

  std::uint64_t limit_steps(Simulation& sim, std::uint64_t n) const override {
    const std::uint64_t done = sim.step_count() - start_step_;
    n = std::min(n, cfg_.record_interval - done % cfg_.record_interval);
    const double left =
        std::ceil((cfg_.displacement - head_travel(sim)) / (cfg_.velocity * sim.dt()));
    return std::min(n, static_cast<std::uint64_t>(std::max(1.0, left)));
  }

 private:
  double sign() const { return cfg_.direction == LoadDirection::Compression ? 1.0 : -1.0; }
  double head_travel(const Simulation& sim) const {
    return sign() * (sim.walls().position(stage_body_index(sim.walls(), cfg_)) - q_start_);
  }

  void record(const Simulation& sim) {
    row_step_ = sim.step_count();
    travel_ = head_travel(sim);
    const BodyProbe p = probe_stage_body(sim, cfg_);
    const double whole = sign() / p.sector;  // the whole pile's, in the test's direction
    const double base = whole * p.tip_load, shaft = whole * p.shaft_load;
    load_ = base + shaft;
    track_capacity({load_, shaft, base, travel_});

    StageOutputs* out = outputs();
    if (!out) return;
    Measurement m;
    m.emplace_back("stage", static_cast<double>(index()));
    m.emplace_back("ageing_time_s", ageing_clock_);
    m.emplace_back("direction", sign());
    m.emplace_back("head_displacement_m", travel_);
    m.emplace_back("head_load_N", load_);
    m.emplace_back("shaft_load_N", shaft);
    m.emplace_back("base_load_N", base);
    m.emplace_back("tip_contacts", static_cast<double>(p.tip_contacts));
    m.emplace_back("shaft_contacts", static_cast<double>(p.shaft_contacts));
    for (auto& kv : out->measure(sim)) m.push_back(kv);
    out->write("load_test.csv", m);
  }

  // The median row of the last capacity_window rows (by head load), once there are that many:
  // the capacity when it is the largest so far.
  void track_capacity(const std::array<double, 4>& row) {
    recent_.insert(recent_.end(), row.begin(), row.end());
    const std::size_t n = cfg_.capacity_window;
    if (recent_.size() > 4 * n) recent_.erase(recent_.begin(), recent_.begin() + 4);
    if (recent_.size() == 4 * n) take_median(n);
  }

  // A test of fewer rows than capacity_window: the median of the rows there are (a capacity of
  // 0 would pass for a measured one), with a warning.
  void finish_capacity() {
    const std::size_t rows = recent_.size() / 4;
    if (rows == 0 || rows >= cfg_.capacity_window) return;
    take_median(rows);
    const std::string why =
        "load_test.csv has " + std::to_string(rows) +
        " rows, fewer than capacity_window = " + std::to_string(cfg_.capacity_window) +
        ": the capacity is their median (a lower record_interval gives the "
        "window its rows)";
    add_warning(why);
    std::fprintf(stderr, "[crushdem] warning: stage '%s': %s\n", res_.name.c_str(), why.c_str());
  }

  // The median row (by head load) of the last n rows: the capacity when it is the largest so far.
  void take_median(std::size_t n) {
    std::vector<std::size_t> rows(n);
    const std::size_t first = recent_.size() / 4 - n;
    for (std::size_t i = 0; i < n; ++i) rows[i] = first + i;
    std::nth_element(rows.begin(), rows.begin() + n / 2, rows.end(),
                     [&](std::size_t a, std::size_t b) { return recent_[4 * a] < recent_[4 * b]; });
    const double* median = &recent_[4 * rows[n / 2]];
    if (median[0] <= res_.capacity) return;
    res_.capacity = median[0];
    res_.shaft_at_capacity = median[1];
    res_.base_at_capacity = median[2];
    res_.displacement_at_capacity = median[3];
  }

  double q_start_ = 0.0;        // the body's degree of freedom at the start [m]
  double travel_ = 0.0;         // the head's, in the test's direction [m]
  double load_ = 0.0;           // the head load at the last record [N]
  std::vector<double> recent_;  // the last rows: head, shaft and base load, displacement
  std::uint64_t row_step_ = ~std::uint64_t{0};  // the last row's step (within one update)
};

}  // namespace

const StageKind& penetrate_stage_kind() {
  static const StageKind kind{
      .name = "penetrate",
      .description =
          "a [[body]] (cone, pile, flat punch) driven at `velocity` for `depth`; q_c, f_s "
          "and the shaft's radial stress recorded (penetration.csv, shaft_profile.csv; the "
          "stress field about it in penetration_field.csv)",
      .params = held_walls_stage_table({
          {"body",
           &StageConfig::body,
           "",
           "the [[body]] driven (its `name`): a translating cone, pile or disk",
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
           [](double v) { return v >= 1.0; }, "a number of steps >= 1"},
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
           "how long the body stands still between strokes (held where it is, or with `unload` "
           "at zero head load)",
           [](double v) { return v >= 0.0; }, "a time >= 0 in s"},
          {"unload",
           &StageConfig::unload,
           "",
           "between strokes, take the head load off (the body servo-controlled to zero load, "
           "free to rebound, as the Grenoble chamber's mini-piles were unloaded) instead of "
           "holding the body where it is; needs `stroke` and `pause`",
           nullptr,
           {},
           {},
           [](const StageConfig& c) { return c.unload; }},
          {"sleeve_length", &StageConfig::sleeve_length, "m",
           "friction sleeve above the tip for f_s; 0 = 3.75 shaft diameters (150 cm^2 on a "
           "35.7 mm cone, ISO 22476-1)",
           [](double v) { return v >= 0.0; }, "a length >= 0 in m"},
          {"field_interval",
           &StageConfig::field_interval,
           "",
           "steps between records of the stress field about the body (penetration_field.csv: "
           "rings of grains from its axis, platen to platen), and at the stage's last step; a "
           "multiple of record_interval; a body moving along z; 0 = none",
           nullptr,
           "a number of steps, a multiple of record_interval (0 = none)",
           {},
           [](const StageConfig& c) { return c.field_interval > 0; }},
          {"rings",
           &StageConfig::rings,
           "",
           "with field_interval: rings of equal width from the body's axis (ring 0 holds the "
           "sand under the tip)",
           [](double v) { return v >= 1.0 && v <= 1e3; },
           "a number of rings in [1, 1000]",
           "",
           [](const StageConfig& c) { return c.field_interval > 0; },
           nullptr,
           {},
           "field_interval"},
          {"field_radius",
           &StageConfig::field_radius,
           "-",
           "with field_interval: the outer ring's radius in shaft radii",
           [](double v) { return v > 0.0 && v <= 1e3; },
           "a radius in (0, 1000] shaft radii",
           "",
           [](const StageConfig& c) { return c.field_interval > 0; },
           nullptr,
           {},
           "field_interval"},
          {"field_bins",
           &StageConfig::field_bins,
           "",
           "with field_interval: slices of the field from the bottom platen to the top one",
           [](double v) { return v >= 1.0 && v <= 1e4; },
           "a number of slices in [1, 10000]",
           "",
           [](const StageConfig& c) { return c.field_interval > 0; },
           nullptr,
           {},
           "field_interval"},
      }),
      .make = make_stage_of<PenetrateStage>,
      .check =
          [](const StageConfig& c, const std::string& prefix) {
            if (c.field_interval % c.record_interval != 0) {
              throw ConfigError(
                  bad_value(prefix + ".field_interval", std::to_string(c.field_interval),
                            "a multiple of record_interval (" + std::to_string(c.record_interval) +
                                " steps), so that the field is taken at a record"));
            }
            if (c.unload && !(c.stroke > 0.0 && c.pause > 0.0)) {
              throw ConfigError(bad_value(prefix + ".unload", "true",
                                          "false without strokes: unloading between strokes "
                                          "needs `stroke` > 0 and `pause` > 0 beside it"));
            }
          },
      .check_bodies = check_driven_body,
  };
  return kind;
}

const StageKind& load_test_stage_kind() {
  static const StageKind kind{
      .name = "load_test",
      .description =
          "a static load test of a pile: the [[body]] driven at `velocity` on (compression) or "
          "out (tension) until its head has moved `displacement`; head, shaft and base loads "
          "recorded (load_test.csv) and the capacity in summary.json",
      .params = held_walls_stage_table({
          {"body", &StageConfig::body, "", "the pile (a [[body]]'s name)", nullptr, {}, "-"},
          {"direction", enum_choice(&StageConfig::direction, kLoadDirectionNames), "",
           "compression pushes the pile on along its direction, tension pulls it back out"},
          {"velocity", &StageConfig::velocity, "m/s",
           "head displacement rate (displacement-controlled, as a static load test's jack)",
           [](double v) { return v > 0.0; }, "a positive velocity in m/s", "-"},
          {"displacement", &StageConfig::displacement, "m",
           "how far the head moves (the capacity is the largest head load on the way; 10 % of "
           "the pile's diameter is the usual failure criterion in compression)",
           [](double v) { return v > 0.0; }, "a positive head displacement in m", "-"},
          {"record_interval", &StageConfig::record_interval, "",
           "steps between rows of load_test.csv", [](double v) { return v >= 1.0; },
           "a number of steps >= 1"},
          {"capacity_window", &StageConfig::capacity_window, "",
           "rows of load_test.csv whose median head load the capacity is the largest of (one "
           "row's dynamic swing, a force chain giving way or a grain split under the tip, is no "
           "capacity); 1 = the largest row",
           [](double v) { return v >= 1.0 && v <= 1e3; }, "a number of rows in [1, 1000]"},
      }),
      .make = make_stage_of<LoadTestStage>,
      .check_bodies = check_driven_body,
  };
  return kind;
}

}  // namespace crushdem

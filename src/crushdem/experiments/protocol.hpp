// Laboratory tests as controllers acting on a Simulation (docs/model.md 4.1, 4.2, 4.5).
//
// A test is a sequence of stages; each stage sets the six walls (fixed, moving, or
// servo-controlled) and says when it is finished. Sample preparation is a controller of the same
// kind. Nothing here subclasses the engine: a controller is called between steps, every
// `check_interval` steps, reads the state and changes wall modes, targets or the friction
// coefficient.
//
// Axial is z; lateral is x and y. Strain rates are positive in compression and prescribed as
// constant wall speeds: v = strain_rate * L_z at the start of the stage (a constant displacement
// rate, as in a loading frame).
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "crushdem/experiments/measurements.hpp"
#include "crushdem/integrate/simulation.hpp"
#include "crushdem/particles/grading.hpp"

namespace crushdem {

// ---------------------------------------------------------------------------------------------
// Sample preparation
// ---------------------------------------------------------------------------------------------

/// A cube of grains drawn from a grading curve, compacted by servo walls to `stress` with a
/// preparation friction lowered step by step until the void ratio reaches `void_ratio`; the
/// material friction is then restored and the sample brought to equilibrium.
struct SampleConfig {
  GradingCurve grading = GradingCurve::ne34();
  double side = 0.0;             // cube side at the target void ratio [m] (0: 4 mm unless count)
  std::uint64_t count = 0;       // approximate number of grains (sets the side) instead of side
  double void_ratio = 0.65;      // target e [-] (STUDY)
  double tolerance = 0.005;      // accepted |e - void_ratio| [-]
  double stress = 100e3;         // isotropic stress of the prepared sample [Pa] (docs/model.md 4.1)
  std::uint64_t seed = 1;        // grain sizes and positions
  double friction_start = 0.5;   // preparation friction to start from [-]
  double friction_factor = 0.6;  // each lowering multiplies it by this [-]
  double placement_fraction = 0.3;      // solid fraction of the initial loose cloud [-]
  double max_speed = 0.3;               // wall speed limit during preparation [m/s]
  double unbalanced = 5e-3;             // equilibrium: unbalanced-force ratio below this [-]
  double stress_tolerance = 0.01;       // equilibrium: every wall within this of `stress` [-]
  std::uint64_t check_interval = 1000;  // steps between checks
  std::uint64_t max_steps = 50000000;   // give up (error) after this many steps
  void validate(const SimulationConfig& sim) const;  // keys "sample.<key>"
  double cube_side() const;  // the side the sample has at the target void ratio
};

// ---------------------------------------------------------------------------------------------
// Test stages
// ---------------------------------------------------------------------------------------------

enum class StageKind { Isotropic, Oedometric, Triaxial, Hold, Age };
const char* to_string(StageKind k);
StageKind parse_stage_kind(const std::string& s, const std::string& key);

struct StageConfig {
  StageKind kind = StageKind::Isotropic;
  std::string name;  // for the outputs; defaults to the kind
  // isotropic: all six walls servo-controlled to `stress`, until equilibrium.
  // oedometric: lateral walls and the bottom fixed; the top moves at `strain_rate` (> 0 loading,
  //   < 0 unloading) until the vertical stress reaches `stress`; strain_rate = 0 servo-controls
  //   the top to `stress` until equilibrium.
  double stress = 0.0;       // [Pa]
  double strain_rate = 0.0;  // axial [1/s]
  // triaxial: lateral walls servo-controlled to sigma_3, both axial walls moving at strain_rate
  //   (compression), until `axial_strain` (from the stage start) or until q >= stop_q (> 0).
  double sigma_3 = 0.0;       // [Pa]
  double axial_strain = 0.0;  // [-]
  double stop_q = 0.0;        // [Pa], 0 = not used
  // hold: the walls keep still or are servo-controlled, for `steps` or `duration`.
  // age (off-DEM ageing, docs/model.md 3.1; needs [crushing] crack_growth): dynamic phases of
  //   min_cycles steps (walls as `axial` / `lateral` say) alternate with ageing jumps that grow
  //   every crack at its frozen velocity until n_break grains would fail, until the ageing clock
  //   reaches `duration` (ageing time, not DEM time).
  std::string axial = "fixed";    // "fixed" | "servo"
  std::string lateral = "fixed";  // "fixed" | "servo"
  double axial_stress = 0.0;      // [Pa] for axial = "servo"
  double lateral_stress = 0.0;    // [Pa] for lateral = "servo"
  std::uint64_t steps = 0;
  double duration = 0.0;                 // [s]
  std::uint64_t min_cycles = 150000;     // age: steps per dynamic phase (STUDY)
  std::uint64_t n_break = 30;            // age: grains brought to failure per jump (STUDY)
  std::uint64_t record_interval = 1000;  // age: steps between rows of phases.csv within a phase
  // Equilibrium (isotropic, servo oedometric) and limits.
  double tolerance = 0.002;      // every servo wall within this relative error of its target
  double unbalanced = 1e-3;      // and the unbalanced-force ratio below this
  double max_strain_rate = 0.0;  // servo speed limit as a strain rate [1/s]: each servo wall
                                 // moves at most max_strain_rate * L / 2. 0 = automatic: 10 /s
                                 // (I ~ 3e-4 at 100 kPa), and for triaxial lateral walls at least
                                 // 2 strain_rate (dilation must not outrun them)
  double servo_strain_rate() const;
  std::uint64_t check_interval = 200;
  std::uint64_t max_steps = 20000000;  // the stage ends (with a warning) after this many steps
  void validate(const std::string& prefix) const;
  std::string label() const { return name.empty() ? to_string(kind) : name; }
};

// ---------------------------------------------------------------------------------------------
// Controllers
// ---------------------------------------------------------------------------------------------

/// Inertial number I = eps_dot d50 sqrt(rho / p) (docs/model.md 1.4), from the wall velocities
/// (largest strain rate of the three axes) and the mean wall stress; NaN when p <= 0.
double inertial_number(const Walls& w, double d50, double density);

/// Every controller: begin() once, then update() after every steps_to_check() steps until it
/// returns true. It may change walls and friction; it never steps the simulation itself.
class Controller {
 public:
  virtual ~Controller() = default;
  virtual void begin(Simulation& sim) = 0;
  virtual bool update(Simulation& sim) = 0;
  virtual std::uint64_t steps_to_check(Simulation& sim) = 0;
  /// Extra columns for the time series (stage-specific), in a fixed order.
  virtual Measurement columns(const Simulation& sim) const = 0;
  /// What begin() and update() have set up and counted so far (checkpoints); load_state()
  /// replaces begin() when a run resumes.
  virtual void save_state(StateWriter& out) const = 0;
  virtual void load_state(StateReader& in) = 0;
};

/// The place a grain cloud starts from, drawn from the grading (sizes) and placed without
/// overlap in a loose cube with its lower corner at the origin.
struct LooseCloud {
  std::vector<Vec3> position;
  std::vector<double> radius;
  double side = 0.0;  // loose cube side [m]
};
LooseCloud make_loose_cloud(const SampleConfig& cfg);

class PreparationController final : public Controller {
 public:
  PreparationController(const SampleConfig& cfg, double material_friction);
  void begin(Simulation& sim) override;
  bool update(Simulation& sim) override;
  std::uint64_t steps_to_check(Simulation& sim) override;
  Measurement columns(const Simulation& sim) const override;
  void save_state(StateWriter& out) const override;
  void load_state(StateReader& in) override;
  double preparation_friction() const { return mu_found_; }
  double void_ratio() const { return e_; }
  /// Empty when the target was reached; otherwise what went wrong.
  const std::string& warning() const { return warning_; }

 private:
  enum class Phase { Compact, Settle, Done };
  SampleConfig cfg_;
  double mu_material_;
  double mu_ = 0.0, mu_found_ = 0.0, e_ = 0.0;
  Phase phase_ = Phase::Compact;
  std::uint64_t start_step_ = 0;
  std::string warning_;
};

/// Results of one stage, for summary.json.
struct StageResult {
  std::string name, kind, end_reason, warning;
  std::uint64_t steps = 0;
  double q_max = 0.0, axial_strain_at_q_max = 0.0, sigma_3_at_q_max = 0.0;
  double friction_angle_deg = 0.0;  // peak, from sin(phi) = q / (q + 2 sigma_3)
  double K0 = 0.0;                  // lateral / vertical wall stress at the end
  double max_inertial_number = 0.0;
  double max_lateral_stress_error = 0.0;  // triaxial: max |sigma_lateral / sigma_3 - 1|
  double max_lateral_strain = 0.0;        // oedometric: max |lateral strain|
  std::uint64_t dynamic_phases = 0;       // age
  double ageing_time = 0.0;               // age: the ageing clock at the end [s]
};

class Crusher;

class StageController final : public Controller {
 public:
  /// d50: of the sample, for the inertial number. crusher: needed by an "age" stage.
  StageController(const StageConfig& cfg, double d50, Crusher* crusher = nullptr);
  /// Called at the end of every dynamic phase of an "age" stage (ageing clock, phase index).
  std::function<void(const Simulation&, double, std::uint64_t)> on_dynamic_phase_end;
  /// Called every record_interval cycles of each dynamic phase, from cycle 0 (just after the
  /// ageing jump, before the grains it brought to failure split) to its last cycle, with a
  /// phase_record() row (the study's Figure 2: what a jump disturbs).
  std::function<void(const Measurement&)> on_phase_record;
  /// The row for phases.csv at the current state (age stages).
  Measurement phase_record(const Simulation& sim) const;
  void begin(Simulation& sim) override;
  bool update(Simulation& sim) override;
  std::uint64_t steps_to_check(Simulation& sim) override;
  Measurement columns(const Simulation& sim) const override;
  void save_state(StateWriter& out) const override;
  void load_state(StateReader& in) override;
  const StageResult& result() const { return res_; }
  /// Where the stage stands, for progress lines: for an age stage the dynamic phase and the
  /// ageing time against its duration; empty for the others (their lines give the stresses).
  std::string progress_note() const;
  /// Called for every time-series row (tracks peaks and limits at output resolution too).
  void observe(const Simulation& sim);

 private:
  void set_servo(Walls& w, int k, double stress) const;
  double stage_axial_strain(const Simulation& sim) const;
  StageConfig cfg_;
  double d50_;
  Crusher* crusher_ = nullptr;
  double ageing_time_ = 0.0;
  std::uint64_t phase_start_ = 0;
  double phase_volume_ = 0.0;   // box volume at cycle 0 of the current phase [m^3]
  double phase_lateral_ = 0.0;  // reference of the confining fluctuation [Pa]
  void start_phase(const Simulation& sim);
  StrainReference ref_;
  std::uint64_t start_step_ = 0;
  double start_time_ = 0.0;
  bool warned_inertia_ = false;
  bool observed_ = false;
  StageResult res_;
};

}  // namespace crushdem

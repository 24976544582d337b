// Test stages (docs/model.md 4.2, 4.5, 3.1): one class per kind, each a Controller that sets
// the six walls (fixed, moving, or servo-controlled) at its start and says when it is finished.
//   isotropic   all six walls servo-controlled to `stress`, until equilibrium
//   oedometric  lateral walls and the bottom fixed; the top moves at `strain_rate` (> 0 loading,
//               < 0 unloading) until the vertical stress reaches `stress`; strain_rate = 0
//               servo-controls the top to `stress` until equilibrium
//   triaxial    lateral walls servo-controlled to sigma_3, both axial walls moving at
//               strain_rate (compression), until `axial_strain` (from the stage start) or until
//               q >= stop_q (> 0)
//   hold        the walls keep still or are servo-controlled, for `steps` or `duration`
//   age         off-DEM ageing (needs [crushing] crack_growth): dynamic phases of min_cycles
//               steps (walls as `axial` / `lateral` say) alternate with ageing jumps that grow
//               every crack at its frozen velocity until n_break grains would fail, until the
//               ageing clock reaches `duration` (ageing time, not DEM time)
// Axial is z; lateral is x and y. Strain rates are positive in compression and prescribed as
// constant wall speeds: v = strain_rate * L_z at the start of the stage (a constant displacement
// rate, as in a loading frame). Each kind's keys are one parameter table (stage_params).
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "crushdem/core/params.hpp"
#include "crushdem/experiments/protocol.hpp"

namespace crushdem {

enum class StageKind { Isotropic, Oedometric, Triaxial, Hold, Age };
const char* to_string(StageKind k);
StageKind parse_stage_kind(const std::string& s, const std::string& key);
inline constexpr StageKind kStageKinds[] = {StageKind::Isotropic, StageKind::Oedometric,
                                            StageKind::Triaxial, StageKind::Hold, StageKind::Age};

/// How the walls of an axis are held during a hold or age stage.
enum class WallControl { Fixed, Servo };

/// The keys of one [[stage]] table; each kind reads the rows of its own table (stage_params).
struct StageConfig {
  StageKind kind = StageKind::Isotropic;
  std::string name;                          // for the outputs; defaults to the kind
  double stress = 0.0;                       // isotropic, oedometric [Pa]
  double strain_rate = 0.0;                  // oedometric, triaxial: axial [1/s]
  double sigma_3 = 0.0;                      // triaxial [Pa]
  double axial_strain = 0.0;                 // triaxial [-]
  double stop_q = 0.0;                       // triaxial [Pa], 0 = not used
  WallControl axial = WallControl::Fixed;    // hold, age
  WallControl lateral = WallControl::Fixed;  // hold, age
  double axial_stress = 0.0;                 // [Pa] for axial = servo
  double lateral_stress = 0.0;               // [Pa] for lateral = servo
  std::uint64_t steps = 0;                   // hold
  double duration = 0.0;                     // hold [s of DEM time], age [s of ageing time]
  std::uint64_t min_cycles = 150000;         // age: steps per dynamic phase (STUDY)
  std::uint64_t n_break = 30;                // age: grains brought to failure per jump (STUDY)
  std::uint64_t record_interval = 1000;      // age: steps between rows of phases.csv
  // Equilibrium (isotropic, servo oedometric) and limits: every kind.
  double tolerance = 0.002;      // every servo wall within this relative error of its target
  double unbalanced = 1e-3;      // and the unbalanced-force ratio below this
  double max_strain_rate = 0.0;  // servo speed limit as a strain rate [1/s]; 0 = automatic
  std::uint64_t check_interval = 200;
  std::uint64_t max_steps = 20000000;  // the stage ends (with a warning) after this many steps
  /// The servo speed limit as a strain rate: max_strain_rate, or automatically 10 /s (I ~ 3e-4
  /// at 100 kPa), and for triaxial lateral walls at least 2 strain_rate (dilation must not
  /// outrun them).
  double servo_strain_rate() const;
  /// The ranges of the kind's table, then the checks that join keys; errors name prefix.key.
  void validate(const std::string& prefix) const;
  std::string label() const { return name.empty() ? to_string(kind) : name; }
};

/// The keys of a stage kind, `type` and `name` aside (every kind has those).
const ParamTable<StageConfig>& stage_params(StageKind kind);

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

/// What every stage kind shares: its start (walls fixed, then the kind's set_walls), the peaks
/// and limits it tracks (observe), its end (the kind's end condition, or max_steps) and its
/// saved state. A kind overrides set_walls and end_reason, and where it needs to the rest.
class Stage : public Controller {
 public:
  /// d50: of the sample, for the inertial number.
  Stage(const StageConfig& cfg, double d50);
  void begin(Simulation& sim) override;
  bool update(Simulation& sim) override;
  std::uint64_t steps_to_check(Simulation& sim) override;
  /// A stage's check reads the walls, the clock and the unbalanced-force ratio.
  bool reads_grains(const Simulation&) const override { return false; }
  Measurement columns(const Simulation& sim) const override;
  void save_state(StateWriter& out) const override;
  void load_state(StateReader& in) override;
  const StageResult& result() const { return res_; }
  /// Where the stage stands, for progress lines (empty: the lines give the stresses).
  virtual std::string progress_note() const { return ""; }
  /// Called for every time-series row (tracks peaks and limits at output resolution too).
  void observe(const Simulation& sim);

 protected:
  /// Sets the walls of this kind at the start (they are all fixed before).
  virtual void set_walls(Walls& w) = 0;
  /// Why the stage ends now, or null to go on (checked every check_interval steps).
  virtual const char* end_reason(Simulation& sim) = 0;
  /// A target already met at the start (a warning: almost always one on the wrong side).
  virtual std::string target_met_at_start(const Walls&) const { return ""; }
  /// What the kind tracks beyond the peak (observe).
  virtual void observe_kind(const Walls&) {}
  /// The steps to the next check, at most n.
  virtual std::uint64_t limit_steps(Simulation&, std::uint64_t n) const { return n; }
  /// The age stage's phase state in the saved layout (zeros for the other kinds, so that every
  /// kind saves the same fields).
  virtual void save_phase(StateWriter& out) const;
  virtual void load_phase(StateReader& in);

  void set_servo(Walls& w, int k, double stress) const;
  double stage_axial_strain(const Simulation& sim) const;
  void add_warning(const std::string& w);
  const StageConfig cfg_;
  StageResult res_;
  StrainReference ref_;
  std::uint64_t start_step_ = 0;
  double start_time_ = 0.0;

 private:
  double d50_;
  bool warned_inertia_ = false;
  bool observed_ = false;
};

class IsotropicStage final : public Stage {
 public:
  using Stage::Stage;

 protected:
  void set_walls(Walls& w) override;
  const char* end_reason(Simulation& sim) override;
};

class OedometricStage final : public Stage {
 public:
  using Stage::Stage;

 protected:
  void set_walls(Walls& w) override;
  const char* end_reason(Simulation& sim) override;
  std::string target_met_at_start(const Walls& w) const override;
  void observe_kind(const Walls& w) override;
};

class TriaxialStage final : public Stage {
 public:
  using Stage::Stage;

 protected:
  void set_walls(Walls& w) override;
  const char* end_reason(Simulation& sim) override;
  std::string target_met_at_start(const Walls& w) const override;
  void observe_kind(const Walls& w) override;
};

class HoldStage final : public Stage {
 public:
  using Stage::Stage;

 protected:
  void set_walls(Walls& w) override;
  const char* end_reason(Simulation& sim) override;
  std::uint64_t limit_steps(Simulation& sim, std::uint64_t n) const override;
};

/// The on-off ageing loop (docs/model.md 3.1): a dynamic phase of min_cycles steps, then an
/// ageing jump (ageing/ageing_jump.hpp), until the ageing clock reaches `duration`.
class AgeStage final : public Stage {
 public:
  /// crusher: its cracks grow; required.
  AgeStage(const StageConfig& cfg, double d50, Crusher* crusher);
  /// Called at the end of every dynamic phase (ageing clock, phase index).
  std::function<void(const Simulation&, double, std::uint64_t)> on_dynamic_phase_end;
  /// Called every record_interval cycles of each dynamic phase, from cycle 0 (just after the
  /// ageing jump, before the grains it brought to failure split) to its last cycle, with a
  /// phase_record() row (the study's Figure 2: what a jump disturbs).
  std::function<void(const Measurement&)> on_phase_record;
  /// The row for phases.csv at the current state.
  Measurement phase_record(const Simulation& sim) const;
  void begin(Simulation& sim) override;
  /// The dynamic phase and the ageing time against its duration.
  std::string progress_note() const override;

 protected:
  void set_walls(Walls& w) override;
  const char* end_reason(Simulation& sim) override;
  /// The end of a dynamic phase reads and changes the grains (events row, ageing jump).
  bool reads_grains(const Simulation& sim) const override;
  std::uint64_t limit_steps(Simulation& sim, std::uint64_t n) const override;
  void save_phase(StateWriter& out) const override;
  void load_phase(StateReader& in) override;

 private:
  void start_phase(const Simulation& sim);
  Crusher* crusher_;
  double ageing_time_ = 0.0;
  std::uint64_t phase_start_ = 0;
  double phase_volume_ = 0.0;   // box volume at cycle 0 of the current phase [m^3]
  double phase_lateral_ = 0.0;  // reference of the confining fluctuation [Pa]
};

/// The stage of cfg.kind. crusher: needed by an age stage (ConfigError without one).
std::unique_ptr<Stage> make_stage(const StageConfig& cfg, double d50, Crusher* crusher);

}  // namespace crushdem

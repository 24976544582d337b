// Test stages (docs/model.md 4.2, 4.5, 3.1): each a Controller that sets the six walls (fixed,
// moving, or servo-controlled) at its start and says when it is finished. A stage kind is one
// unit: its class, its parameter table, its description and how it is made are one `StageKind`
// entry, defined in the kind's own file (experiments/stages/KIND.cpp) and listed in
// stage_kinds() below. The reader and writer of [[stage]], docs/configuration.md, the Python
// laboratory functions and the runner all work from that entry, so a new kind is its file, its
// line in the list and its regenerated docs (ARCHITECTURE.md).
// Axial is z; lateral is x and y. Strain rates are positive in compression and prescribed as
// constant wall speeds: v = strain_rate * L_z at the start of the stage (a constant displacement
// rate, as in a loading frame).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "crushdem/core/params.hpp"
#include "crushdem/experiments/pile_field.hpp"
#include "crushdem/experiments/protocol.hpp"
#include "crushdem/walls/body_probe.hpp"

namespace crushdem {

class Crusher;
class StageOutputs;
class Stage;
struct StageKind;
struct BodyConfig;

/// How the walls of an axis are held during a hold or age stage.
enum class WallControl { Fixed, Servo };
/// How a pile's head is held while it ages: where it is, or at a head load (0: taken off).
enum class HeadControl { Held, Load };
/// Which way a load test moves the pile: on along its direction, or back out of the grains.
enum class LoadDirection { Compression, Tension };

/// The keys of one [[stage]] table. Every kind reads, writes and checks only the rows of its own
/// table (StageKind::params); the members are shared so that the tables stay plain rows.
struct StageConfig {
  const StageKind* kind = nullptr;           // `type`
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
  double until = 0.0;                 // age: the run's ageing clock to reach [s]; 0 = use duration
  std::uint64_t min_cycles = 150000;  // age: steps per dynamic phase (STUDY)
  std::uint64_t n_break = 30;         // age: grains brought to failure per jump (STUDY)
  std::uint64_t record_interval = 1000;  // age, penetrate: steps between rows of its files
  std::string body;                      // penetrate: the [[body]] driven
  double velocity = 0.0;                 // penetrate [m/s]
  double depth = 0.0;                    // penetrate: travel [m]
  std::uint64_t bins = 20;               // penetrate: bins along the shaft
  double sleeve_length = 0.0;            // penetrate [m]; 0 = 3.75 shaft diameters
  bool from_top = false;                 // penetrate: start with the tip at the top wall
  bool settle = false;                   // hold: end once settled (steps/duration the most)
  std::uint64_t profile_bins = 0;        // hold: slices of the stress profile at its end; 0 = none
  double profile_radius = 0.5;           // hold: the profile's core [chamber radii]
  double stroke = 0.0;                   // penetrate: jacking stroke [m]; 0 = continuous
  double pause = 0.0;                    // penetrate: the body held still between strokes [s]
  bool unload = false;  // penetrate: the head load taken off between strokes, not held still
  HeadControl head = HeadControl::Held;  // hold, age: the pile named by `body`
  double head_load = 0.0;                // [N] the whole pile's, with head = "load"
  std::uint64_t rings = 6;               // age, penetrate: rings of grains about the body
  double field_radius = 8.0;             // age, penetrate: the outer ring's radius [shaft radii]
  std::uint64_t field_interval = 0;      // penetrate: steps between field records; 0 = none
  std::uint64_t field_bins = 20;         // penetrate: the field's slices, platen to platen
  LoadDirection direction = LoadDirection::Compression;  // load_test
  double displacement = 0.0;                             // load_test: head travel [m]
  std::uint64_t capacity_window = 5;  // load_test: records whose median the capacity is taken of
  // Equilibrium (isotropic, servo oedometric) and limits: every kind.
  double tolerance = 0.002;      // every servo wall within this relative error of its target
  double unbalanced = 1e-3;      // and the unbalanced-force ratio below this
  double max_strain_rate = 0.0;  // servo speed limit as a strain rate [1/s]; 0 = automatic
  std::uint64_t check_interval = 200;
  std::uint64_t max_steps = 20000000;  // the stage ends (with a warning) after this many steps
  /// The ranges of the kind's table, then the kind's checks that join keys; errors name
  /// prefix.key.
  void validate(const std::string& prefix) const;
  std::string label() const;
};

/// A stage kind, whole: what the configuration reader and writer, the docs, Python and the
/// runner need of it.
struct StageKind {
  std::string_view name;           // the `type` of a [[stage]]
  std::string_view description;    // one line: docs/configuration.md, Python docstrings
  ParamTable<StageConfig> params;  // its keys, `type` and `name` aside (stage_table())
  /// The stage of this kind. d50: of the sample (inertial number); crusher: the run's, null
  /// without [crushing].
  std::unique_ptr<Stage> (*make)(const StageConfig& cfg, double d50, Crusher* crusher) = nullptr;
  /// The checks that join keys (the ranges are the rows'); errors name prefix.key. May be null.
  void (*check)(const StageConfig& cfg, const std::string& prefix) = nullptr;
  /// The checks against the run's [[body]] tables (a stage that drives one); may be null.
  void (*check_bodies)(const StageConfig& cfg, const std::vector<BodyConfig>& bodies,
                       const std::string& prefix) = nullptr;
  bool needs_crack_growth = false;  // needs [crushing] with crack_growth = true
};

// The kinds, in the order of the docs: each is defined in experiments/stages/KIND.cpp.
const StageKind& isotropic_stage_kind();
const StageKind& oedometric_stage_kind();
const StageKind& triaxial_stage_kind();
const StageKind& hold_stage_kind();
const StageKind& age_stage_kind();
const StageKind& penetrate_stage_kind();
const StageKind& load_test_stage_kind();

inline const std::vector<const StageKind*>& stage_kinds() {
  static const std::vector<const StageKind*> kinds = {
      &isotropic_stage_kind(), &oedometric_stage_kind(), &triaxial_stage_kind(),
      &hold_stage_kind(),      &age_stage_kind(),        &penetrate_stage_kind(),
      &load_test_stage_kind(),
  };
  return kinds;
}

/// The kind named `name`; ConfigError naming `key` and the kinds otherwise.
const StageKind& stage_kind(const std::string& name, const std::string& key = "type");
/// The kinds' names as a message's expected value: "\"isotropic\", ... or \"age\"".
std::string stage_kind_names();

/// A kind's table: its own rows, then those every kind has (tolerance, unbalanced,
/// max_strain_rate, check_interval, max_steps).
ParamTable<StageConfig> stage_table(std::initializer_list<Param<StageConfig>> own);
/// The same, with the rows of walls held fixed or by servo first (axial, lateral and their
/// servo targets), as a hold or age stage has them.
ParamTable<StageConfig> held_walls_stage_table(std::initializer_list<Param<StageConfig>> own);
/// The rows of a pile held while the sand rests (hold, age): `body` (optional), `head`,
/// `head_load`.
ParamTable<StageConfig> pile_head_rows();
/// `table` with the pile head's rows after its held walls' rows (hold, age).
ParamTable<StageConfig> with_pile_head(ParamTable<StageConfig> table);
/// The share of an age stage done, for its progress lines: `t` of `span` seconds of ageing
/// done, the first jump `first_jump` s long (0: none yet, or not known after a resume),
/// `phases` dynamic phases finished (each followed by a jump). The ageing done on a log1p
/// scale, or, when larger, the share of the phases done (each takes about the same wall-clock):
/// the jumps grow about geometrically, so after two the phases left are about the log-time left
/// over the log-time per jump so far. The first alone undercounts a relaxation whose first jumps
/// are fractions of a second (0.4 % at the second phase of eleven); the second alone a run whose
/// first jump is long and the next short.
double ageing_progress(double t, double span, double first_jump, std::uint64_t phases);
/// A pile's head held at a load needs the pile (`body`); ConfigError naming prefix.head.
void check_pile_head(const StageConfig& c, const std::string& prefix);
/// StageKind::check_bodies of a stage that names a [[body]] it probes (penetrate, load_test; hold
/// and age when they name one): the body exists and probe_supports() it.
void check_probed_body(const StageConfig& c, const std::vector<BodyConfig>& bodies,
                       const std::string& prefix);
/// The body a stage names, probed (walls/body_probe.hpp) with the stage's `bins` and
/// `sleeve_length` (0: the standard sleeve, 3.75 shaft diameters).
BodyProbe probe_stage_body(const Simulation& sim, const StageConfig& c);
/// A row of `file` per bin of the probe's shaft: the columns of `lead`, then bin, height_m
/// (the bin's middle above the shaft's start), sigma_r_Pa, tau_Pa and contacts.
void write_shaft_rows(StageOutputs& out, const std::string& file, const BodyProbe& p,
                      const Measurement& lead);
/// A row of `file` per ring and slice (experiments/pile_field.hpp): the columns of `lead`, then
/// ring, bin, r_in_m, r_out_m, the slice's middle (its height + `offset`, named `place`),
/// sigma_rr_Pa, sigma_tt_Pa, sigma_zz_Pa, tau_rz_Pa, grains and, with `body_volume`, the body's
/// share of the cell (body_volume_m3).
void write_ring_rows(StageOutputs& out, const std::string& file,
                     const std::vector<RingStress>& rings, const Measurement& lead,
                     const char* place, double offset, bool body_volume = false);
/// Index of the body named `name` in `w` (ConfigError naming the stage's body key otherwise).
int stage_body_index(const Walls& w, const StageConfig& c);

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
  double ageing_time = 0.0;               // age: the ageing this stage added [s]
  // load_test (whole pile, positive in the test's direction; at the largest head load Q):
  double capacity = 0.0, shaft_at_capacity = 0.0, base_at_capacity = 0.0;  // [N]
  double displacement_at_capacity = 0.0;                                   // [m]
};

/// The run's result files as a stage sees them: the runner attaches every stage to one of these
/// (Stage::attach), so that a kind with files of its own (the age stage's events.csv and
/// phases.csv) writes them without the runner knowing the kind.
class StageOutputs {
 public:
  virtual ~StageOutputs() = default;
  /// Appends `row` to the result file `file` (created at its first row).
  virtual void write(const std::string& file, const Measurement& row) = 0;
  /// The run's measurements of the state (strains from the test's start; with [crushing] the
  /// crushing columns), for a row of a stage's own file.
  virtual Measurement measure(const Simulation& sim) const = 0;
  /// A checkpoint once the current check is over (an ageing event).
  virtual void request_checkpoint() = 0;
  /// The run's ageing clock now [s]: the time later ParaView frames add to the DEM time.
  virtual void set_ageing_clock(double ageing_time) = 0;
  /// A ParaView frame of the state now (the end of a dynamic phase).
  virtual void snapshot() = 0;
};

/// What every stage kind shares: its start (walls fixed, then the kind's set_walls), the peaks
/// and limits it tracks (observe), its end (the kind's end condition, or max_steps) and its
/// saved state. A kind overrides set_walls and end_reason, and where it needs to the rest.
class Stage : public Controller {
 public:
  /// d50: of the sample, for the inertial number.
  Stage(const StageConfig& cfg, double d50);
  /// The run's files, and the index of this stage in the run (the `stage` column).
  void attach(StageOutputs& outputs, std::size_t index);
  /// The run's ageing clock at this stage's start: the ageing of the age stages before it [s].
  void set_ageing_clock(double t) { ageing_clock_ = t; }
  /// The run's ageing clock now [s]: the clock at the start, which an age stage advances.
  virtual double ageing_clock_now() const { return ageing_clock_; }
  void begin(Simulation& sim) override;
  bool update(Simulation& sim) override;
  std::uint64_t steps_to_check(Simulation& sim) override;
  /// A stage's check reads the walls, the clock and the unbalanced-force ratio.
  bool reads_grains(const Simulation&) const override { return false; }
  Measurement columns(const Simulation& sim) const override;
  void state(StateArchive& a) override;
  const StageResult& result() const { return res_; }
  /// Where the stage stands, for progress lines (empty: the lines give the stresses).
  virtual std::string progress_note() const { return ""; }
  /// The share of the stage done, in [0, 1], for progress lines (their ETA); NaN where the stage
  /// ends on a state (an equilibrium) rather than a distance, a time or a strain.
  virtual double fraction(const Simulation&) const { return std::nan(""); }
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
  /// The stage ends at max_steps, before its own end condition: a kind that drives a body stops
  /// it here, so that the next stage finds it still, as after the kind's own end.
  virtual void stop_early(Simulation&) {}
  /// Whether this check is the one that ends the stage at max_steps (a kind that records its
  /// last state in stop_early reads the grains then).
  bool at_max_steps(const Simulation& sim) const {
    return sim.step_count() - start_step_ >= cfg_.max_steps;
  }
  /// The steps to the next check, at most n.
  virtual std::uint64_t limit_steps(Simulation&, std::uint64_t n) const { return n; }
  /// The servo speed limit as a strain rate when max_strain_rate = 0 [1/s] (10 /s: I ~ 3e-4 at
  /// 100 kPa).
  virtual double automatic_servo_rate() const { return 10.0; }
  /// The age stage's phase state in the saved layout, declared as state() declares the rest
  /// (zeros for the other kinds, so that every kind saves the same fields).
  virtual void phase_state(StateArchive& a);

  void set_servo(Walls& w, int k, double stress) const;
  /// The top and the lateral walls as `axial` and `lateral` say (hold, age).
  void set_held_walls(Walls& w) const;
  /// The pile named by `body` held as `head` says (nothing without a body).
  void set_head(Walls& w) const;
  /// The pile named by `body` servo-controlled to the whole pile's head load `load` [N].
  void servo_head(Walls& w, double load) const;
  /// Every servo wall within tolerance of its target and the unbalanced-force ratio below
  /// `unbalanced`.
  bool at_equilibrium(const Simulation& sim) const;
  double stage_axial_strain(const Simulation& sim) const;
  void add_warning(const std::string& w);
  /// The run's files (null when the stage runs outside a run) and this stage's index.
  StageOutputs* outputs() const { return outputs_; }
  std::size_t index() const { return index_; }
  const StageConfig cfg_;
  StageResult res_;
  StrainReference ref_;
  std::uint64_t start_step_ = 0;
  double start_time_ = 0.0;
  double ageing_clock_ = 0.0;  // the run's ageing clock at the start [s]

 private:
  double d50_;
  StageOutputs* outputs_ = nullptr;
  std::size_t index_ = 0;
  bool warned_inertia_ = false;
  bool observed_ = false;
};

/// The stage of cfg.kind. crusher: needed by a kind with needs_crack_growth (ConfigError
/// without one).
std::unique_ptr<Stage> make_stage(const StageConfig& cfg, double d50, Crusher* crusher);

/// StageKind::make for the class T, constructed from (cfg, d50) or, when it takes one, (cfg,
/// d50, crusher).
template <class T>
std::unique_ptr<Stage> make_stage_of(const StageConfig& cfg, double d50, Crusher* crusher) {
  if constexpr (std::is_constructible_v<T, const StageConfig&, double, Crusher*>) {
    return std::make_unique<T>(cfg, d50, crusher);
  } else {
    return std::make_unique<T>(cfg, d50);
  }
}

}  // namespace crushdem

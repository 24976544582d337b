// The time-stepping engine: particles, neighbour list, contacts, walls and the integrator.
//
// One step (velocity Verlet, docs/model.md 1.4):
//   1. half kick   v += dt/2 F/m,  w += dt/2 T/I      (forces of the previous step)
//   2. drift       x += dt v;  walls move
//   3. rebuild the neighbour list if anything moved more than half the skin
//   4. forces      grain-grain (half list, fixed-order gather) and grain-wall
//   5. local damping  F_j -= alpha |F_j| sign(v_j), per component, forces and torques
//   6. half kick;  servo walls choose their velocity for the next step
// Particles are inserted or removed only in apply_topology(), between steps. Experiments
// compose a Simulation with controllers; they never subclass it.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "crushdem/contact/contact_model.hpp"
#include "crushdem/contact/contact_stress.hpp"
#include "crushdem/core/part_clock.hpp"
#include "crushdem/integrate/contact_history.hpp"
#include "crushdem/integrate/integrator.hpp"
#include "crushdem/integrate/pair_loop.hpp"
#include "crushdem/integrate/time_step.hpp"
#include "crushdem/neighbor/neighbor_list.hpp"
#include "crushdem/neighbor/pruned_list.hpp"
#include "crushdem/particles/particle_store.hpp"
#include "crushdem/walls/body_config.hpp"
#include "crushdem/walls/walls.hpp"

namespace crushdem {

struct DampingConfig {
  double local_alpha = 0.7;  // alpha_d of PFC local damping (CHOICE); 0 turns it off
};

struct NeighborConfig {
  double skin = 0.0;           // Verlet skin [m]; 0 = 0.5 * smallest radius at the first build
  bool sort_particles = true;  // reorder particles in cell order at each rebuild (cache locality)
  bool prune = true;           // pair loop walks a pruned copy of the list (PrunedList; speed only)
};

/// A uniform body force on every grain, its weight m g (none by default: the study's tests
/// are at stresses where the grains' weight is negligible).
struct GravityConfig {
  Vec3 g;  // [m/s^2], e.g. [0, 0, -9.81]
  bool on() const { return g.x != 0.0 || g.y != 0.0 || g.z != 0.0; }
};

/// The keys of [damping], [neighbor] and [gravity] (core/params.hpp); [timestep]: time_step.hpp.
const ParamTable<DampingConfig>& damping_params();
const ParamTable<NeighborConfig>& neighbor_params();
const ParamTable<GravityConfig>& gravity_params();

struct SimulationConfig {
  MaterialConfig material;
  ContactConfig contact;
  DampingConfig damping;
  TimestepConfig timestep;
  NeighborConfig neighbor;
  GravityConfig gravity;
  std::array<WallConfig, kNumWalls> walls{};
  std::vector<BodyConfig> bodies;  // rigid bodies besides the box ([[body]])
  void validate() const;           // throws ConfigError naming the key
};

/// A grain-grain or grain-wall contact as seen from outside (for output and Python).
struct ContactRecord {
  ParticleId id_i = 0;
  ParticleId id_j = 0;  // for a wall contact: the wall index 0..5
  bool is_wall = false;
  double delta = 0.0;  // overlap [m]
  double F_n = 0.0;    // elastic normal force [N]
  Vec3 normal;         // unit normal from i towards j (or into the wall)
  Vec3 F_t;            // tangential force on i [N]
  Vec3 M_r;            // rolling-resistance moment on i [N m] (zero when off, and at walls)
};

class Simulation {
 public:
  explicit Simulation(const SimulationConfig& cfg);

  const SimulationConfig& config() const { return cfg_; }
  ParticleStore& particles() { return p_; }
  const ParticleStore& particles() const { return p_; }
  Walls& walls() { return walls_; }
  const Walls& walls() const { return walls_; }
  const NeighborList& neighbors() const { return nl_; }
  const PrunedList& pruned_neighbors() const { return pair_loop_.pruned(); }
  /// The contact law (contact/contact_model.hpp): its sub-models and their parameters.
  const ContactLaw& contact_law() const { return law_; }
  const ContactParams& contact_params() const { return law_.params(); }
  /// The contact history per neighbour entry and the wall contacts (a device copy reads and
  /// writes them between steps).
  ContactHistory& history() { return history_; }
  const ContactHistory& history() const { return history_; }
  WallContacts& wall_contacts() { return wc_; }
  const WallContacts& wall_contacts() const { return wc_; }

  /// Adds one grain with the configured density; returns its id.
  ParticleId add_particle(Vec3 position, double radius, Vec3 velocity = {},
                          Vec3 angular_velocity = {});
  /// Adds grains given from outside (Python, a user's program) with the configured density, or
  /// none: each must have a positive radius, finite position and velocity, and a centre inside
  /// the walls that overlaps none by more than a tenth of its radius (a grain far into a wall
  /// meets it with an enormous force). ConfigError names the first grain that fails.
  std::vector<ParticleId> add_particles(std::vector<NewParticle> grains);
  /// The explicit topology phase: removals and insertions, then a forced neighbour rebuild.
  std::vector<ParticleId> apply_topology(const TopologyChange& change);
  /// Incremented by every change of the grains' indices or the lists (topology, rebuild,
  /// invalidate, load_state): a device copy made at another value is stale.
  std::uint64_t layout_version() const { return layout_version_; }

  void step(std::uint64_t n = 1);
  double time() const { return time_; }
  std::uint64_t step_count() const { return steps_; }
  /// The step the next call to step() uses (computes it if automatic).
  double dt();
  void set_dt(double dt);  // fixes the step (overrides automatic)
  /// Chooses the automatic step now from `stiffness_time`, the contact term reduced elsewhere
  /// (a device's copy of this state): what dt() chooses when due, without the host's list.
  /// Nothing with a fixed step (set_dt()).
  void choose_dt(double stiffness_time);
  /// Changes the grain-grain friction coefficient from the next step on (sample preparation
  /// lowers it, then restores the material's); stored tangential forces above the new Coulomb
  /// limit are capped at the next force evaluation.
  void set_friction(double mu);
  double current_dt() const { return time_step_.value(); }  // the step last used (0 before)
  const TimeStep& time_step() const { return time_step_; }

  /// Touching contacts at the current state (grain-grain then grain-wall).
  std::vector<ContactRecord> contacts() const;
  /// Number of grain-grain contacts with positive overlap.
  std::size_t num_contacts() const;
  double kinetic_energy() const;
  /// The resultant of contact and wall forces on each grain before local damping (the store's
  /// fx, fy, fz hold the damped force the integrator uses). Axis 0, 1, 2.
  const std::vector<double>& resultant_force(int axis) const {
    return axis == 0 ? fu_x_ : (axis == 1 ? fu_y_ : fu_z_);
  }
  std::vector<double>& resultant_force(int axis) {
    return axis == 0 ? fu_x_ : (axis == 1 ? fu_y_ : fu_z_);
  }
  /// Per-grain contact load for crushing (docs/model.md 2.1; contact/contact_stress.hpp), filled
  /// by each force evaluation once track_contact_load(k) is on: the largest F_n / (pi r' delta)
  /// over the grain's contacts (walls included) with r' = k R* (R* = R for a wall), the largest
  /// F_n and the unit normal of that contact, pointing from the grain towards the contact.
  void track_contact_load(double r_prime_factor);  // 0 turns tracking off
  double contact_load_factor() const { return load_factor_; }
  const ContactLoad& contact_load() const { return load_; }
  ContactLoad& contact_load() { return load_; }

  /// Everything a step depends on, bit for bit: particles, neighbour list (a list rebuilt at
  /// another step would sum forces in another order), contact history and last forces, walls,
  /// clock, time-step state, friction and contact-load tracking. A Simulation built from the same
  /// configuration and loaded with this state continues exactly as the saved one would have.
  void state(StateArchive& a);

  /// Bytes held by the engine's arrays (particles, neighbour list, contacts).
  std::size_t memory_bytes() const;

  /// Love-Weber stress tensor over the box volume, row-major 3x3 [Pa] (compression positive).
  std::array<double, 9> love_weber_stress() const;

  /// Forces (and neighbour list) are recomputed before the next step; call after editing
  /// positions or radii from outside.
  void invalidate();
  /// Computes forces for the current state without moving anything (for inspection); does
  /// nothing if they are already up to date (each evaluation advances tangential history).
  void compute_forces();
  /// Whether the forces and the neighbour list are those of the current state.
  bool forces_current() const { return forces_valid_ && nl_valid_; }
  /// Rebuilds the neighbour list and wall contacts now (history carried over), as a step does
  /// when grains have moved too far; throws RuntimeFailure naming a grain with a non-finite
  /// position or one outside the box.
  void rebuild_neighbors();
  /// The Verlet skin in force [m] (chosen at the first build when neighbor.skin is 0).
  double skin() const { return skin_; }

  /// The state a device copy advanced, put back: the clock, the step and its bookkeeping, and
  /// that the forces (and list) are those of the current state.
  void set_clock(double time, std::uint64_t steps, const TimeStep& time_step);

  /// Scalars a device reduced over its copy of the state at step `step` (Chrono DEM-Engine's
  /// inspectors): read by the controllers' checks instead of the host arrays, which a device
  /// run brings up to date only when something needs them (backend/stepper.hpp). Not state.
  struct Inspection {
    std::uint64_t step = ~std::uint64_t{0};  // none yet
    double resultant_sum = 0.0;              // sum over grains of |resultant force| [N]
    double pair_F_n_sum = 0.0;               // sum of the elastic F_n of touching grain pairs [N]
    double pairs = 0.0;                      // touching grain pairs
  };
  const Inspection& inspection() const { return inspection_; }
  void set_inspection(const Inspection& i) { inspection_ = i; }
  /// The inspection when it is of the current step, else null.
  const Inspection* current_inspection() const {
    return inspection_.step == steps_ ? &inspection_ : nullptr;
  }

  /// Wall-clock time by part of the step (integration, neighbour search, contact forces here;
  /// the crusher and the run driver charge theirs to the same clock). Not part of the state.
  PartClock& part_clock() { return part_clock_; }

  /// Time-step estimates (exposed for tests and reporting).
  double rayleigh_dt() const;
  double stiffness_dt() const;
  /// The step the automatic choice would take now (timestep.rayleigh_fraction and safety),
  /// whether or not the step is fixed: a fixed step above it is likely unstable.
  double automatic_dt();
  /// automatic_dt() with its contact term given (stiffness_dt() of the same state).
  double automatic_dt_with(double stiffness_time) const;
  /// The configured normal law outside the force loops (reporting, time step).
  NormalForce normal_force(double delta, double R_star, bool wall) const;

 private:
  /// The message for grain i found beyond wall k, with the likely cause.
  std::string left_the_box(std::size_t i, int k) const;
  void check_loaded_state() const;
  ContactRecord pair_record(std::size_t e) const;
  /// drift_next: also the next step's first half kick and drift (into next_drift_).
  void evaluate_forces(double increment_dt, bool kick, bool drift_next = false);
  /// Every wall contact's load (few; in entry order): R* = R, the normal points into the wall.
  void wall_contact_load();

  SimulationConfig cfg_;
  ContactLaw law_;
  ParticleStore p_;
  NeighborList nl_;
  Walls walls_;
  WallContacts wc_;
  ContactHistory history_;
  CpuPairLoop pair_loop_;
  TimeStep time_step_;
  std::vector<double> fu_x_, fu_y_, fu_z_;  // undamped resultant force per grain
  // The next step's kick and drift, done by this step's gather pass: set only before another
  // step of the same step() call, which consumes it first thing (so nothing else sees it).
  std::optional<DriftMaxima> next_drift_;
  double skin_ = 0.0;
  bool forces_valid_ = false;
  bool nl_valid_ = false;
  double time_ = 0.0;
  std::uint64_t steps_ = 0;
  std::uint64_t layout_version_ = 0;
  double load_factor_ = 0.0;
  ContactLoad load_;
  Inspection inspection_;
  PartClock part_clock_;
};

}  // namespace crushdem

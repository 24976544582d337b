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

#include "crushdem/contact/contact_config.hpp"
#include "crushdem/core/part_clock.hpp"
#include "crushdem/core/work_shares.hpp"
#include "crushdem/neighbor/neighbor_list.hpp"
#include "crushdem/neighbor/pruned_list.hpp"
#include "crushdem/particles/particle_store.hpp"
#include "crushdem/walls/walls.hpp"

namespace crushdem {

struct DampingConfig {
  double local_alpha = 0.7;  // alpha_d of PFC local damping (CHOICE); 0 turns it off
  void validate() const;
};

struct TimestepConfig {
  double dt = 0.0;  // fixed step [s]; 0 = automatic
  double rayleigh_fraction =
      0.2;              // automatic: dt <= fraction * Rayleigh time of the smallest grain
  double safety = 0.3;  // automatic: dt <= safety * min_i sqrt(m_i / sum k_i)
  std::uint64_t update_interval = 1000;  // automatic: steps between re-evaluations
  void validate() const;
};

struct NeighborConfig {
  double skin = 0.0;           // Verlet skin [m]; 0 = 0.5 * smallest radius at the first build
  bool sort_particles = true;  // reorder particles in cell order at each rebuild (cache locality)
  bool prune = true;           // pair loop walks a pruned copy of the list (PrunedList; speed only)
  void validate() const;
};

/// The keys of [damping], [timestep] and [neighbor] (core/params.hpp).
const ParamTable<DampingConfig>& damping_params();
const ParamTable<TimestepConfig>& timestep_params();
const ParamTable<NeighborConfig>& neighbor_params();

struct SimulationConfig {
  MaterialConfig material;
  ContactConfig contact;
  DampingConfig damping;
  TimestepConfig timestep;
  NeighborConfig neighbor;
  std::array<WallConfig, kNumWalls> walls{};
  void validate() const;  // throws ConfigError naming the key
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

namespace detail {
// Per grain copies for the CPU pair loop, refreshed at every force evaluation: a partner's
// position and radius, and its velocity and spin, each in one cache line. Read from the
// struct-of-arrays store, a partner costs ten lines (one per array); the pair loop is bound by
// those reads, not by its arithmetic.
struct alignas(32) PackedPosition {
  double x, y, z, r;
};
struct alignas(64) PackedVelocity {
  double vx, vy, vz, wx, wy, wz, inv_mass, pad;
};
// The pair loop's force and torque sums, one cache line per grain for the same reason (a
// partner's six sums would be six lines); gather_and_damp() adds the walls and moves them to the
// store.
struct alignas(64) PackedForce {
  double fx, fy, fz, tx, ty, tz, pad0, pad1;
};
}  // namespace detail

class Simulation {
 public:
  explicit Simulation(const SimulationConfig& cfg);

  const SimulationConfig& config() const { return cfg_; }
  ParticleStore& particles() { return p_; }
  const ParticleStore& particles() const { return p_; }
  Walls& walls() { return walls_; }
  const Walls& walls() const { return walls_; }
  const NeighborList& neighbors() const { return nl_; }
  const PrunedList& pruned_neighbors() const { return prune_; }
  const ContactParams& contact_params() const { return cp_; }

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

  void step(std::uint64_t n = 1);
  double time() const { return time_; }
  std::uint64_t step_count() const { return steps_; }
  /// The step the next call to step() uses (computes it if automatic).
  double dt();
  void set_dt(double dt);  // fixes the step (overrides automatic)
  /// Changes the grain-grain friction coefficient from the next step on (sample preparation
  /// lowers it, then restores the material's); stored tangential forces above the new Coulomb
  /// limit are capped at the next force evaluation.
  void set_friction(double mu);
  double current_dt() const { return dt_; }  // the step last used (0 before the first)

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
  /// Per-grain contact load for crushing (docs/model.md 2.1), filled by each force evaluation once
  /// track_contact_load(k) is on: sigma = max over the grain's contacts (walls included) of
  /// F_n / (pi r' delta) with r' = k R* (R* = R for a wall); the largest F_n and the unit normal
  /// of that contact, pointing from the grain towards the contact.
  struct ContactLoad {
    std::vector<double> sigma, F_n_max, nx, ny, nz;
  };
  void track_contact_load(double r_prime_factor);  // 0 turns tracking off
  const ContactLoad& contact_load() const { return load_; }

  /// Everything a step depends on, bit for bit: particles, neighbour list (a list rebuilt at
  /// another step would sum forces in another order), contact history and last forces, walls,
  /// clock, time-step state, friction and contact-load tracking. A Simulation built from the same
  /// configuration and loaded with this state continues exactly as the saved one would have.
  void save_state(StateWriter& out) const;
  void load_state(StateReader& in);

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

  /// Wall-clock time by part of the step (integration, neighbour search, contact forces here;
  /// the crusher and the run driver charge theirs to the same clock). Not part of the state.
  PartClock& part_clock() { return part_clock_; }

  /// Time-step estimates (exposed for tests and reporting).
  double rayleigh_dt() const;
  double stiffness_dt() const;
  /// The step the automatic choice would take now (timestep.rayleigh_fraction and safety),
  /// whether or not the step is fixed: a fixed step above it is likely unstable.
  double automatic_dt();

 private:
  friend class GpuStepper;
  struct PairHistory {
    ParticleId a, b;  // a < b
    double x, y, z;   // the vector on a (tangential force, or rolling moment)
    bool operator<(const PairHistory& o) const { return a < o.a || (a == o.a && b < o.b); }
  };
  struct WallHistory {
    ParticleId id;
    int wall;
    double x, y, z;
  };
  void capture_history();
  /// Per-entry vectors (on the owner) keyed by particle ids, sorted; zero vectors are skipped.
  void capture_pair_vectors(const std::vector<double>& x, const std::vector<double>& y,
                            const std::vector<double>& z, std::vector<PairHistory>& out) const;
  /// Puts saved vectors back on the entries of the new list and marks those entries touching.
  void restore_pair_vectors(const std::vector<PairHistory>& saved, std::vector<double>& x,
                            std::vector<double>& y, std::vector<double>& z);
  ContactRecord pair_record(std::size_t e) const;
  /// The configured normal law outside the force loops (reporting, time step).
  NormalForce normal_force(double delta, double R_star, bool wall) const;
  void rebuild_neighbors();
  bool rolling() const { return cp_.mu_r > 0.0; }
  template <class Law, bool Rolling>
  void pair_forces(const Law& law, double increment_dt);
  template <class Law>
  void wall_forces(const Law& law, double increment_dt);
  struct Drift {
    double since_build2;  // largest squared displacement since the last neighbour build [m^2]
    double step2;         // largest squared displacement in this step [m^2]
  };
  /// drift_next: also the next step's first half kick and drift (into next_drift_).
  void evaluate_forces(double increment_dt, bool kick, bool drift_next = false);
  void gather_and_damp(bool kick, bool drift_next);
  template <bool kDamp, bool kKick, bool kDrift>
  Drift gather_grains();
  Drift kick_drift();
  /// Whether dt() re-evaluates the automatic time step at step number `step`.
  bool dt_due(std::uint64_t step) const;

  SimulationConfig cfg_;
  ContactParams cp_;
  ParticleStore p_;
  NeighborList nl_;
  PrunedList prune_;
  Walls walls_;
  WallContacts wc_;
  // Per neighbour entry: tangential history (force on the owner) and the reaction on the partner.
  std::vector<double> ft_x_, ft_y_, ft_z_;
  // Per neighbour entry, only with rolling resistance on: the rolling moment on the owner.
  std::vector<double> mr_x_, mr_y_, mr_z_;
  std::vector<std::uint8_t> touching_;
  std::vector<double> fu_x_, fu_y_, fu_z_;  // undamped resultant force per grain
  std::vector<detail::PackedPosition> packed_pos_;
  std::vector<detail::PackedVelocity> packed_vel_;
  std::vector<detail::PackedForce> packed_force_;
  WorkShares pair_shares_;  // the pair loop's column shares, one loop per colour
  // kick_drift() writes the packed copies as it updates the store, saving the pair loop a pass
  // over eleven arrays; any other path (first evaluation, rebuild, topology) repacks. Likewise
  // gather_and_damp() zeroes the sums it reads, for the next pair loop.
  bool packed_fresh_ = false;
  bool packed_force_zero_ = false;
  // The next step's kick and drift, done by this step's gather pass: set only before another
  // step of the same step() call, which consumes it first thing (so nothing else sees it).
  std::optional<Drift> next_drift_;
  std::vector<std::uint32_t> wall_offsets_;  // CSR: wall entries of particle i
  std::vector<PairHistory> saved_pairs_;
  std::vector<PairHistory> saved_rolling_;
  std::vector<WallHistory> saved_walls_;
  bool history_saved_ = false;
  double skin_ = 0.0;
  double dt_ = 0.0;
  bool dt_fixed_ = false;
  std::uint64_t dt_computed_at_ = 0;
  bool dt_valid_ = false;
  bool forces_valid_ = false;
  bool nl_valid_ = false;
  double time_ = 0.0;
  std::uint64_t steps_ = 0;
  double load_factor_ = 0.0;
  ContactLoad load_;
  PartClock part_clock_;
};

}  // namespace crushdem

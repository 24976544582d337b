// Struct-of-arrays particle storage (Cabana style).
//
// Every per-particle quantity is its own contiguous array so that kernels stream through memory
// and the same layout maps onto GPU memory. Particles carry a stable 64-bit id that is never
// reused and the id of the particle they came from (lineage). Particles are inserted and removed
// only through apply(TopologyChange), one explicit phase that compacts the arrays; indices are
// therefore unstable across that phase and anything kept across it (contact history) is keyed by
// id. Modules that need more per-particle state (strength, crack length, ...) register named
// extra fields, which are compacted with the rest.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "crushdem/core/state_io.hpp"
#include "crushdem/core/types.hpp"

namespace crushdem {

/// A particle to be inserted in the next topology phase.
struct NewParticle {
  ParticleId parent = kNoParent;
  Vec3 position;
  Vec3 velocity;
  Vec3 angular_velocity;
  double radius = 0.0;
  double density = 0.0;
  /// Values of the extra fields, by field index; missing entries take the field's default.
  std::vector<double> extra;
};

/// Removals (by current index) and insertions applied together by ParticleStore::apply.
struct TopologyChange {
  std::vector<std::size_t> remove;
  std::vector<NewParticle> add;
  bool empty() const { return remove.empty() && add.empty(); }
};

class ParticleStore {
 public:
  std::size_t size() const { return id.size(); }

  /// Registers a named per-particle field (value `init` for existing and future particles
  /// unless given). Returns its index; registering an existing name returns the same index.
  std::size_t add_field(const std::string& name, double init);
  std::size_t field_index(const std::string& name) const;  // throws if unknown
  bool has_field(const std::string& name) const;
  std::vector<double>& field(std::size_t k) { return extra_[k]; }
  const std::vector<double>& field(std::size_t k) const { return extra_[k]; }
  const std::vector<std::string>& field_names() const { return extra_names_; }

  /// Inserts and removes particles; survivors keep their relative order, new particles are
  /// appended in the order given and receive fresh ids. Returns the ids given to the new ones.
  std::vector<ParticleId> apply(const TopologyChange& change);

  /// Reorders all arrays so that new index k holds old index order[k] (spatial sorting).
  void permute(const std::vector<std::size_t>& order);

  /// The id the next inserted particle will get (ids are never reused).
  ParticleId next_id() const { return next_id_; }
  /// Used when restoring a saved state: ids below `next` are considered taken.
  void set_next_id(ParticleId next) { next_id_ = next; }

  /// Inserts one particle with a given id (loading files); the id must not be used yet.
  void insert_with_id(ParticleId pid, const NewParticle& p);

  double total_mass() const;
  /// Sum of the grain volumes 4/3 pi r^3 [m^3] (thread-count independent).
  double solid_volume() const;
  /// Grain diameters 2 r, in storage order [m].
  std::vector<double> diameters() const;
  /// Every array, the extra fields and the id counter, bit for bit (checkpoints:
  /// core/state_io.hpp's save_state() and load_state()).
  void state(StateArchive& a);

  /// Changes a radius keeping the density (mass and inertia follow). Call
  /// Simulation::invalidate() afterwards.
  void set_radius(std::size_t i, double r);

  // --- the arrays (public: kernels read and write them directly) ---
  std::vector<ParticleId> id, parent;
  std::vector<double> x, y, z;      // position [m]
  std::vector<double> vx, vy, vz;   // velocity [m/s]
  std::vector<double> wx, wy, wz;   // angular velocity [rad/s]
  std::vector<double> fx, fy, fz;   // force [N]
  std::vector<double> tx, ty, tz;   // torque [N m]
  std::vector<double> radius;       // [m]
  std::vector<double> mass;         // [kg]
  std::vector<double> inv_mass;     // [1/kg]
  std::vector<double> inv_inertia;  // 1 / (2/5 m R^2) [1/(kg m^2)]

 private:
  void push_back(ParticleId pid, const NewParticle& p);
  template <class Fn>
  void for_each_array(Fn&& fn);

  ParticleId next_id_ = 0;
  std::vector<std::string> extra_names_;
  std::vector<double> extra_init_;
  std::vector<std::vector<double>> extra_;
};

}  // namespace crushdem

// The integrator's time step (docs/model.md 1.4): fixed, or automatic, the smaller of
//
//   rayleigh_fraction x T_R,   T_R = pi r sqrt(rho / G) / (0.1631 nu + 0.8766)  (smallest grain)
//   safety x min_i sqrt(m_i / sum_c k_c),   k_c = k_n + k_t of each contact of grain i,
//
// re-evaluated every `update_interval` steps and after any change of the particles.
#pragma once

#include <cstdint>
#include <functional>

#include "crushdem/contact/hertz.hpp"
#include "crushdem/contact/material.hpp"
#include "crushdem/core/state_io.hpp"
#include "crushdem/neighbor/neighbor_list.hpp"
#include "crushdem/particles/particle_store.hpp"
#include "crushdem/walls/walls.hpp"

namespace crushdem {

struct TimestepConfig {
  double dt = 0.0;  // fixed step [s]; 0 = automatic
  double rayleigh_fraction =
      0.2;              // automatic: dt <= fraction * Rayleigh time of the smallest grain
  double safety = 0.3;  // automatic: dt <= safety * min_i sqrt(m_i / sum k_i)
  std::uint64_t update_interval = 1000;  // automatic: steps between re-evaluations
};

/// The keys of [timestep] (core/params.hpp).
const ParamTable<TimestepConfig>& timestep_params();

/// The step in force and when it was chosen.
class TimeStep {
 public:
  explicit TimeStep(const TimestepConfig& cfg = {});
  /// Whether the automatic step is to be chosen again before step number `step`.
  bool due(std::uint64_t step) const {
    return !fixed_ && (!valid_ || step - computed_at_ >= update_interval_);
  }
  /// The automatic step `dt`, chosen at step number `step`.
  void choose(double dt, std::uint64_t step) {
    dt_ = dt;
    valid_ = true;
    computed_at_ = step;
  }
  /// Fixes the step (no automatic choice from now on).
  void fix(double dt) {
    dt_ = dt;
    fixed_ = true;
  }
  /// The particles changed: an automatic step is chosen again before the next step.
  void invalidate() { valid_ = false; }
  double value() const { return dt_; }
  bool fixed() const { return fixed_; }
  std::uint64_t computed_at() const { return computed_at_; }
  /// The step and its bookkeeping, bit for bit (checkpoints).
  void state(StateArchive& a);

 private:
  std::uint64_t update_interval_ = 1000;
  double dt_ = 0.0;
  bool fixed_ = false;
  std::uint64_t computed_at_ = 0;
  bool valid_ = false;
};

/// The Rayleigh time of the smallest grain (each grain its own density: fragments and
/// density-scaled grains may differ); infinite without grains.
double rayleigh_time(const ParticleStore& p, const MaterialConfig& material);

/// The normal law outside the force loops: F_n and k_n of a contact of overlap delta and
/// effective radius R* (a wall contact: R* = R).
using NormalLawAt = std::function<NormalForce(double delta, double R_star, bool wall)>;

/// min_i sqrt(m_i / sum k_i) over the grains with contacts, k = (1 + k_t / k_n) k_n of each
/// grain-grain contact of the list and each wall contact; infinite when none touches.
double stiffness_time(const ParticleStore& p, const NeighborList& nl, const WallContacts& wc,
                      const Walls& walls, double tangential_ratio, const NormalLawAt& normal);

}  // namespace crushdem

// The CPU engine's grain-grain contact loop. Each pair of the half list is evaluated once with
// pair_contact() (contact/contact_kernel.hpp, the kernel the device step runs too) and both
// grains' sums are updated directly, with no atomics and no reaction buffer: grains are grouped
// into columns of (y, z) cells, coloured so that the columns of one colour share no grain; the
// nine colours run one after another, each colour's columns in parallel, in shares balanced by
// work that an idle thread takes from the back of (core/work_shares.hpp). Within a column the
// touching pairs are collected into fixed-size batches, evaluated in vector lanes and scattered
// into both grains' sums in collect order, so the result is that of a pair-by-pair loop, bit for
// bit, on any number of threads. How the batches, the pruned list and the fast and exact kernel
// paths were chosen, with what each measured: docs/performance.md.
//
// The loop owns what only it reads: the packed per-grain copies of positions and velocities
// (the integrator writes them as it updates the store, saving the loop a pass over eleven
// arrays), the force and torque sums (one cache line per grain, which the integrator's gather
// takes and zeroes), the work shares, the pruned list and each thread's batches.
#pragma once

#include <cstddef>
#include <memory>
#include <vector>

#include "crushdem/contact/contact_model.hpp"
#include "crushdem/contact/contact_stress.hpp"
#include "crushdem/core/work_shares.hpp"
#include "crushdem/integrate/contact_history.hpp"
#include "crushdem/neighbor/neighbor_list.hpp"
#include "crushdem/neighbor/pruned_list.hpp"
#include "crushdem/particles/particle_store.hpp"

namespace crushdem {

namespace detail {
// Per grain copies for the pair loop: a partner's position and radius, and its velocity and
// spin, each in one cache line. Read from the struct-of-arrays store, a partner costs ten lines
// (one per array); the pair loop is bound by those reads, not by its arithmetic.
struct alignas(32) PackedPosition {
  double x, y, z, r;
};
struct alignas(64) PackedVelocity {
  double vx, vy, vz, wx, wy, wz, inv_mass, pad;
};
// The pair loop's force and torque sums, one cache line per grain for the same reason (a
// partner's six sums would be six lines).
struct alignas(64) PackedForce {
  double fx, fy, fz, tx, ty, tz, pad0, pad1;
};
// A thread's batch of touching pairs (pair_loop.cpp).
struct PairBatch;
// Two batches per thread slot (the fixed-size one, and one grown for a grain with more list
// entries than it holds), each made by its thread on first use and kept between steps. Scratch,
// not state: a copy takes none of the source's. Held here, not as thread_local objects, which
// need glibc's __cxa_thread_atexit_impl (2.18, newer than the portable wheel's glibc).
struct PairBatches {
  PairBatches();
  ~PairBatches();
  PairBatches(const PairBatches& /*other*/);
  PairBatches& operator=(const PairBatches& /*other*/);
  PairBatches(PairBatches&&) noexcept;
  PairBatches& operator=(PairBatches&&) noexcept;
  std::vector<std::unique_ptr<PairBatch>> slots;
};
}  // namespace detail

class CpuPairLoop {
 public:
  /// Evaluates every pair of `nl` with the contact law (its history in `history` advanced by the
  /// step h; 0 refreshes the current state without an increment) and adds each contact to both
  /// grains' sums (force_sums()). With `load` (crushing), it is sized to the grains and filled
  /// with each grain's contact load, r' = load_factor R*. prune: the configuration's
  /// neighbor.prune. The loop is instantiated for every combination of sub-models
  /// (with_law()), so choosing one costs no branch in the inner loop.
  void evaluate(const ContactLaw& law, double h, const ParticleStore& p, const NeighborList& nl,
                bool prune, ContactHistory& history, ContactLoad* load, double load_factor);

  /// The packed copies, which the integrator may write as it moves the grains (then
  /// mark_packed(); anything else that changes positions or velocities leaves them stale and
  /// the loop repacks).
  std::vector<detail::PackedPosition>& positions() { return positions_; }
  std::vector<detail::PackedVelocity>& velocities() { return velocities_; }
  void mark_packed() { packed_fresh_ = true; }
  void mark_stale() { packed_fresh_ = false; }
  /// The sums of the last evaluation (eight doubles per grain: fx fy fz tx ty tz and padding);
  /// whoever takes them zeroes them and says so (mark_sums_zero()), or the loop zeroes them.
  std::vector<detail::PackedForce>& force_sums() { return sums_; }
  void mark_sums_zero() { sums_zero_ = true; }
  PrunedList& pruned() { return pruned_; }
  const PrunedList& pruned() const { return pruned_; }
  std::size_t memory_bytes() const;

 private:
  template <class Model>
  void evaluate_model(const Model& model, double h, const ParticleStore& p, const NeighborList& nl,
                      bool prune, ContactHistory& history, ContactLoad* load, double load_factor);

  std::vector<detail::PackedPosition> positions_;
  std::vector<detail::PackedVelocity> velocities_;
  std::vector<detail::PackedForce> sums_;
  WorkShares shares_;  // the column shares, one loop per colour
  detail::PairBatches batches_;
  PrunedList pruned_;
  bool packed_fresh_ = false;
  bool sums_zero_ = false;
};

}  // namespace crushdem

// Dynamic pruning of the Verlet list: the entries that can touch within the next steps.
//
// The Verlet list holds every pair closer than r_i + r_j + skin, and the skin must cover all
// motion until the next rebuild (2 max|dx| <= skin). In a dense, slowly moving packing most of
// that room is never used: on the peer reference problem (11,500 grains at 5 MPa, skin 37.5 um)
// the list holds 4.66 entries per grain, 3.01 of them touching. The pair loop tests every entry
// at every step. A pruned list keeps, per grain, only the entries with a gap below a small inner
// skin s (gap = |x_j - x_i| - r_i - r_j < s); it stays complete while the grains have together
// moved less than s since it was made:
//     gap(t) >= gap(t0) - |dx_i| - |dx_j| >= s - 2 D > 0   while 2 D < s,
// with D a bound on any grain's displacement since t0 (the sum over steps of the largest step
// displacement). GROMACS prunes its pair list in the same way (Pall et al. 2020, J. Chem. Phys.
// 153, 134110, "dynamic pruning"). Here it changes no result: an entry left out was found not
// touching when the list was made (its touch flag then cleared, with its history if it had just
// separated) and cannot touch until the list is remade, so visiting it would only write 0 over
// 0; the kept entries are visited in list order, so the force sums are bit-identical with or
// without pruning, and on any number of threads.
//
// The pair loop fills the list while it walks the full list (PruneMode::Build), so making it
// costs one extra compare and store per entry; the entries of grain i are written at
// offsets[i] .. offsets[i] + count[i] of the Verlet list's own CSR ranges, by the thread that
// owns i, without a prefix sum. The inner skin is chosen at each build from the current speed
// so that a list lasts about kTargetSteps steps; it is clamped to [skin / 1000, skin], and a
// list whose inner skin would reach the full skin is not made (PruneMode::Full).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "crushdem/neighbor/neighbor_list.hpp"

namespace crushdem {

/// How the pair loop walks a grain's entries this step.
enum class PruneMode : std::uint8_t {
  Full,   // the whole Verlet range, no pruned list kept
  Build,  // the whole Verlet range, writing the pruned list as it goes
  Use,    // the pruned list only
};

class PrunedList {
 public:
  using Index = NeighborList::Index;
  struct Entry {
    Index e;  // the Verlet list entry (its history and touch flag)
    Index j;  // the partner, neighbors[e], copied so that the walk reads one array
  };
  /// Steps a list should last at the current speed (each build costs a walk of the full list).
  static constexpr double kTargetSteps = 32.0;

  /// Chooses the mode of the coming pair loop and, for Build, sizes the arrays and sets the
  /// inner skin. enabled: the configuration's neighbor.prune; repacked: the pair loop's position
  /// copies were refreshed from the store (positions may have changed outside the integrator).
  PruneMode begin(const NeighborList& nl, bool enabled, bool repacked);
  /// The integrator's largest grain displacement in one step [m], measured from the positions
  /// the last pair loop saw (so a position changed by hand counts too); infinite when unknown.
  void add_step(double step_displacement) {
    drift_ += step_displacement;
    last_step_ = step_displacement;
    ++steps_;
  }
  /// Forget the list (a state loaded from a checkpoint may carry the same build count).
  void invalidate() { valid_ = false; }

  double inner_skin() const { return inner_skin_; }
  std::size_t builds() const { return builds_; }
  /// Entries kept, summed over grains (0 when no list is kept).
  std::size_t size() const;
  std::size_t memory_bytes() const {
    return entries.capacity() * sizeof(Entry) + count.capacity() * sizeof(Index);
  }

  std::vector<Entry> entries;  // grain i's at [offsets[i], offsets[i] + count[i]) of the list
  std::vector<Index> count;

 private:
  bool valid_ = false;
  std::size_t nl_build_ = 0;  // NeighborList::builds() when the list was made
  double inner_skin_ = 0.0;   // s [m]
  double drift_ = 0.0;        // D [m]
  double last_step_ = 0.0;    // the last add_step() [m]
  std::uint64_t steps_ = 0;   // steps since the list was made
  std::size_t builds_ = 0;
};

}  // namespace crushdem

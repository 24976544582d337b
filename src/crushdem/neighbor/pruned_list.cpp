#include "crushdem/neighbor/pruned_list.hpp"

#include <algorithm>
#include <cmath>

namespace crushdem {

PruneMode PrunedList::begin(const NeighborList& nl, bool enabled, bool repacked) {
  // Complete while 2 D < s (strict: a gap of exactly 0 is not a contact, but nothing is gained
  // by relying on it).
  if (valid_ && !repacked && nl.builds() == nl_build_ && 2.0 * drift_ < inner_skin_) {
    return PruneMode::Use;
  }
  // The speed: the last step's displacement, or the mean over the list that just expired if
  // that was larger (the steps of a vibrating packing differ).
  double rate = last_step_;
  if (valid_ && steps_ > 0) rate = std::max(rate, drift_ / static_cast<double>(steps_));
  valid_ = false;
  drift_ = 0.0;
  steps_ = 0;
  const double skin = nl.skin();
  // The floor keeps the inner skin far above the rounding of the gap (1e-16 of r_i + r_j).
  const double s = std::max(2.0 * kTargetSteps * rate, 1e-3 * skin);
  if (!enabled || !(s < skin)) return PruneMode::Full;  // also a NaN or infinite rate
  inner_skin_ = s;
  nl_build_ = nl.builds();
  valid_ = true;
  ++builds_;
  entries.resize(nl.num_pairs());
  count.resize(nl.num_particles());
  return PruneMode::Build;
}

std::size_t PrunedList::size() const {
  if (!valid_) return 0;
  std::size_t n = 0;
  for (const Index c : count) n += c;
  return n;
}

}  // namespace crushdem

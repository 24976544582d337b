// Where a run's wall-clock time goes, by part of the step (timing.json: seconds_by_part).
// Every second from the clock's construction to the last reading belongs to exactly one part:
// entering a part pauses the one it was entered from (a neighbour rebuild inside a split counts as
// neighbour search, not twice). Read from the host thread only, outside parallel regions; it
// never influences the results.
#pragma once

#include <array>
#include <chrono>
#include <cstddef>
#include <string_view>

namespace crushdem {

enum class Part : int {
  Other = 0,       // controllers, measurements and whatever is not named below
  Integration,     // velocity Verlet kick-drift, wall motion
  NeighborSearch,  // cell list + Verlet list rebuilds (with the particle sort)
  ContactForces,   // grain-grain laws, gather, damping
  WallForces,      // the grain-body laws (the box's walls and every [[body]])
  Crushing,        // the strength check, crack growth, splits and the topology phase
  Ageing,          // off-DEM ageing jumps
  Output,          // CSV rows, VTK snapshots, checkpoints
  Count
};

inline constexpr std::array<std::string_view, static_cast<std::size_t>(Part::Count)> kPartNames = {
    "other",       "integration", "neighbor_search", "contact_forces",
    "wall_forces", "crushing",    "ageing_jump",     "output"};

class PartClock {
 public:
  using clock = std::chrono::steady_clock;
  static constexpr std::size_t kParts = static_cast<std::size_t>(Part::Count);

  PartClock() : since_(clock::now()) {}

  /// Makes `p` the running part; returns the part it replaces (give it back to leave()).
  Part enter(Part p) {
    charge();
    const Part before = current_;
    current_ = p;
    return before;
  }
  void leave(Part previous) {
    charge();
    current_ = previous;
  }
  /// Seconds per part so far (the running part included up to now).
  std::array<double, kParts> seconds() {
    charge();
    return seconds_;
  }
  /// Adds earlier totals (a resumed run's time before this process).
  void add(const std::array<double, kParts>& s) {
    for (std::size_t k = 0; k < kParts; ++k) seconds_[k] += s[k];
  }

 private:
  void charge() {
    const auto now = clock::now();
    seconds_[static_cast<std::size_t>(current_)] +=
        std::chrono::duration<double>(now - since_).count();
    since_ = now;
  }
  std::array<double, kParts> seconds_{};
  Part current_ = Part::Other;
  clock::time_point since_;
};

/// Charges the enclosing scope to one part.
class PartScope {
 public:
  PartScope(PartClock& c, Part p) : c_(c), before_(c.enter(p)) {}
  ~PartScope() { c_.leave(before_); }
  PartScope(const PartScope&) = delete;
  PartScope& operator=(const PartScope&) = delete;

 private:
  PartClock& c_;
  Part before_;
};

}  // namespace crushdem

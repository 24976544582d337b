// Contiguous shares of a parallel loop that threads finish by taking work from each other.
//
// A loop whose items may run on any thread in any order (the columns of one colour of the pair
// loop) is split into one contiguous share per thread, balanced by an estimate of the work, so
// that a thread keeps to its own part of the data. The estimate is never exact, and on a shared
// machine one core may run slower than the other for a while; a thread whose share is done
// therefore takes items, one at a time, from the back of the other shares. Which thread runs an
// item never changes a result (the caller's contract), only the time.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>

namespace crushdem {

class WorkShares {
 public:
  WorkShares() = default;
  // Scheduling state only, empty between loops: a copy starts empty.
  WorkShares(const WorkShares& /*other*/) {}
  WorkShares& operator=(const WorkShares& /*other*/) { return *this; }

  /// Outside a parallel region: room for `groups` loops (run one after another) of up to
  /// `threads` shares each, all empty.
  void reset(std::size_t groups, std::size_t threads) {
    if (groups * threads > capacity_) {
      capacity_ = groups * threads;
      slots_ = std::make_unique<Slot[]>(capacity_);
    }
    threads_ = threads;
    for (std::size_t k = 0; k < capacity_; ++k) slots_[k].range.store(0, std::memory_order_relaxed);
  }

  /// Thread t's share of loop g: items [first, last). Set by thread t before it takes from it;
  /// until then the share reads as empty to the others (an item is taken only from a share that
  /// holds it, so nothing runs twice, and nothing is missed: t takes its share in full).
  void set(std::size_t g, std::size_t t, std::uint32_t first, std::uint32_t last) {
    slot(g, t).store(pack(first, last), std::memory_order_release);
  }

  /// The next item of loop g for thread t of `team`: the front of its own share, else the back
  /// of the nearest other share that holds one. False when every share of the loop is empty.
  bool next(std::size_t g, std::size_t t, std::size_t team, std::uint32_t& item) {
    if (take(slot(g, t), true, item)) return true;
    for (std::size_t d = 1; d < team; ++d) {
      if (take(slot(g, (t + d) % team), false, item)) return true;
    }
    return false;
  }

 private:
  struct alignas(64) Slot {  // one cache line each: owners do not share lines
    std::atomic<std::uint64_t> range{0};
  };
  static std::uint64_t pack(std::uint32_t first, std::uint32_t last) {
    return static_cast<std::uint64_t>(first) | (static_cast<std::uint64_t>(last) << 32);
  }
  std::atomic<std::uint64_t>& slot(std::size_t g, std::size_t t) {
    return slots_[g * threads_ + t].range;
  }
  static bool take(std::atomic<std::uint64_t>& s, bool front, std::uint32_t& item) {
    std::uint64_t r = s.load(std::memory_order_acquire);
    for (;;) {
      const auto first = static_cast<std::uint32_t>(r);
      const auto last = static_cast<std::uint32_t>(r >> 32);
      if (first >= last) return false;
      const std::uint64_t taken = front ? pack(first + 1, last) : pack(first, last - 1);
      if (s.compare_exchange_weak(r, taken, std::memory_order_acq_rel, std::memory_order_acquire)) {
        item = front ? first : last - 1;
        return true;
      }
    }
  }
  std::unique_ptr<Slot[]> slots_;
  std::size_t capacity_ = 0, threads_ = 0;
};

}  // namespace crushdem

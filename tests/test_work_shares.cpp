// WorkShares (core/work_shares.hpp): every item of a loop runs exactly once whatever the timing,
// and a slow thread's share is finished by the others.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <thread>
#include <vector>

#include "crushdem/core/deterministic.hpp"
#include "crushdem/core/work_shares.hpp"

namespace crushdem {
namespace {

TEST(WorkShares, EveryItemRunsOnceAndASlowThreadsShareIsShared) {
  constexpr std::size_t kThreads = 4, kGroups = 3;
  constexpr std::uint32_t kItems = 400;
  WorkShares shares;
  for (int round = 0; round < 3; ++round) {  // reused between loops, as the pair loop does
    shares.reset(kGroups, kThreads);
    std::vector<std::atomic<int>> runs(kGroups * kItems);
    std::vector<std::atomic<int>> by_thread(kGroups * kThreads);
    std::atomic<std::size_t> team_seen{1};
#pragma omp parallel num_threads(kThreads)
    {
      const auto t = static_cast<std::size_t>(thread_index());
      const auto team = static_cast<std::size_t>(team_size());
      team_seen = team;
      // Every share set before any loop starts, as the pair loop does (a share set late reads
      // as empty to the others: correct, but nothing would be taken from it).
      for (std::size_t g = 0; g < kGroups; ++g) {
        // Thread 0 owns most of each loop and is slow; the others own a few items each.
        const std::uint32_t first = t == 0 ? 0 : 300 + static_cast<std::uint32_t>(t - 1) * 34;
        const std::uint32_t last = t == 0 ? 300 : (t + 1 == team ? kItems : first + 34);
        if (team == kThreads) {
          shares.set(g, t, first, last);
        } else if (t == 0) {
          shares.set(g, 0, 0, kItems);  // another team size: one share holds everything
        }
      }
#pragma omp barrier
      for (std::size_t g = 0; g < kGroups; ++g) {
        std::uint32_t item = 0;
        while (shares.next(g, t, team, item)) {
          ++runs[g * kItems + item];
          ++by_thread[g * kThreads + t];
          if (t == 0) std::this_thread::sleep_for(std::chrono::microseconds(200));
        }
#pragma omp barrier
      }
    }
    for (std::size_t k = 0; k < runs.size(); ++k) ASSERT_EQ(runs[k].load(), 1) << "item " << k;
    if (team_seen == kThreads) {
      for (std::size_t g = 0; g < kGroups; ++g) {
        // The slow thread ran well under its own 300 items: the others took from its share.
        EXPECT_LT(by_thread[g * kThreads].load(), 250) << "loop " << g;
      }
    }
  }
}

TEST(WorkShares, CopiesStartEmpty) {
  WorkShares a;
  a.reset(1, 1);
  a.set(0, 0, 0, 10);
  WorkShares b = a;
  b.reset(1, 1);
  std::uint32_t item = 0;
  EXPECT_FALSE(b.next(0, 0, 1, item));
  EXPECT_TRUE(a.next(0, 0, 1, item));
  EXPECT_EQ(item, 0u);
}

}  // namespace
}  // namespace crushdem

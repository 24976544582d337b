// Reductions and sorts whose result does not depend on the number of threads.
// Results must be bit-identical on 1 and 2 threads (a last-bit difference changes which grain
// breaks first), so sums over particles are taken in fixed-size blocks whose partial sums are
// added in block order, never in thread order.
#pragma once

#include <algorithm>
#include <cstddef>
#include <vector>

#ifdef _OPENMP
#include <omp.h>
#endif

namespace crushdem {

/// This thread's number and the size of its team (0 and 1 outside a parallel region or without
/// OpenMP).
inline int thread_index() {
#ifdef _OPENMP
  return omp_get_thread_num();
#else
  return 0;
#endif
}
inline int team_size() {
#ifdef _OPENMP
  return omp_get_num_threads();
#else
  return 1;
#endif
}

/// The largest team a parallel region may get here (1 without OpenMP).
inline int max_team_size() {
#ifdef _OPENMP
  return omp_get_max_threads();
#else
  return 1;
#endif
}

/// Thread t's contiguous share [first, last) of n items among `threads`, as `schedule(static)`
/// deals them (the first n % threads shares one item longer), for a loop that must know its
/// range before it starts.
struct Share {
  std::size_t first, last;
};
inline Share static_share(std::size_t n, std::size_t threads, std::size_t t) {
  const std::size_t q = n / threads, r = n % threads;
  const std::size_t first = t * q + (t < r ? t : r);
  return {first, first + q + (t < r ? 1 : 0)};
}

inline constexpr std::size_t kReductionBlock = 1024;

/// Below this many items a loop runs on one thread: forking and joining a team costs more than
/// the work, and far more when the cores are shared (threads spin at the barriers). Results do
/// not depend on it (every loop is deterministic for any thread count).
/// (Tests set it to 0 to exercise the threaded paths on small systems.)
inline std::size_t& threading_threshold() {
  static std::size_t items = 1024;
  return items;
}
inline bool worth_threading(std::size_t items) {
  return items >= threading_threshold();
}

/// Sum f(i) for i in [0, n) with a thread-count independent summation order.
template <class F>
double deterministic_sum(std::size_t n, F&& f) {
  const std::size_t nblocks = (n + kReductionBlock - 1) / kReductionBlock;
  std::vector<double> partial(nblocks, 0.0);
#pragma omp parallel for schedule(static) if (worth_threading(n))
  for (std::ptrdiff_t b = 0; b < static_cast<std::ptrdiff_t>(nblocks); ++b) {
    const std::size_t lo = static_cast<std::size_t>(b) * kReductionBlock;
    const std::size_t hi = lo + kReductionBlock < n ? lo + kReductionBlock : n;
    double s = 0.0;
    for (std::size_t i = lo; i < hi; ++i) s += f(i);
    partial[static_cast<std::size_t>(b)] = s;
  }
  double total = 0.0;
  for (double p : partial) total += p;
  return total;
}

/// Maximum of f(i) over [0, n) (max is order independent; parallel for speed).
template <class F>
double parallel_max(std::size_t n, double init, F&& f) {
  double m = init;
#pragma omp parallel for schedule(static) reduction(max : m) if (worth_threading(n))
  for (std::ptrdiff_t i = 0; i < static_cast<std::ptrdiff_t>(n); ++i) {
    const double v = f(static_cast<std::size_t>(i));
    if (v > m) m = v;
  }
  return m;
}

/// Sorts v as std::stable_sort(v, less) does, to the same order (a stable sort's is unique):
/// one block per thread sorted at once, then the blocks merged pairwise (std::merge keeps the
/// left block's equal elements first).
template <class T, class Less>
void parallel_stable_sort(std::vector<T>& v, Less less) {
  const std::size_t n = v.size();
  const auto parts = worth_threading(n) ? static_cast<std::size_t>(max_team_size()) : 1;
  if (parts < 2) {
    std::stable_sort(v.begin(), v.end(), less);
    return;
  }
  std::vector<std::size_t> bound(parts + 1);
  for (std::size_t k = 0; k <= parts; ++k) bound[k] = n * k / parts;
  const auto at = [&](std::vector<T>& a, std::size_t k) {
    return a.begin() + static_cast<std::ptrdiff_t>(bound[std::min(k, parts)]);
  };
#pragma omp parallel for schedule(static, 1)
  for (std::ptrdiff_t k = 0; k < static_cast<std::ptrdiff_t>(parts); ++k) {
    const auto b = static_cast<std::size_t>(k);
    std::stable_sort(at(v, b), at(v, b + 1), less);
  }
  std::vector<T> out(n);
  for (std::size_t width = 1; width < parts; width *= 2) {
    const std::size_t pairs = (parts + 2 * width - 1) / (2 * width);
#pragma omp parallel for schedule(static, 1)
    for (std::ptrdiff_t q = 0; q < static_cast<std::ptrdiff_t>(pairs); ++q) {
      const std::size_t k = static_cast<std::size_t>(q) * 2 * width;
      // A last block without a partner is copied (merged with an empty range).
      std::merge(at(v, k), at(v, k + width), at(v, k + width), at(v, k + 2 * width), at(out, k),
                 less);
    }
    v.swap(out);
  }
}

}  // namespace crushdem

// x^p on [0, 1] by cubic Hermite interpolation on a uniform grid (values and exact derivatives
// at the nodes). The rough-surface law raises a ratio to a fixed non-integer power for most
// contacts; std::pow there cost a third of a step. The interpolant is exact at the nodes,
// including 0 and 1 (the regime transitions of the law). Over the middle regime of the law it is
// within 1e-11 relative of x^p; in the lowest regime within 1e-11 relative where the force
// exceeds 1e-3 of the transition load and within 3e-9 of that load everywhere (checked by
// tests/test_rough_law.cpp).
//
// The table is immutable and shared: PowerTable is a plain view (pointer + constants), so a
// kernel can copy it by value on the host or the device.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>

#include "crushdem/core/types.hpp"

namespace crushdem {

/// x^p from a table of 2 (n + 1) nodes (PowerTable) that starts at nodes + first, written
/// without branches so that a vector loop can evaluate it in every lane (`first` rather than a
/// second pointer: a vector gather has one base address and an index per lane).
CD_HD_INLINE double power_table_lookup(const double* nodes, int first, int n, double inv_h,
                                       double x) {
  const double s = x * inv_h;
  // The interval, clamped to [0, n - 1]. s is clamped before it becomes an int (a double outside
  // int's range, or NaN, has no int value); inside [0, n] that changes nothing.
  const double n_d = static_cast<double>(n);
  const double s_in = s >= 0.0 ? (s <= n_d ? s : n_d) : 0.0;
  int k = static_cast<int>(s_in);
  k = k >= n ? n - 1 : k;
  const double t = s - static_cast<double>(k);
  const int at = first + 2 * k;
  const double f0 = nodes[at], m0 = nodes[at + 1], f1 = nodes[at + 2], m1 = nodes[at + 3];
  const double cubic =
      f0 + t * (m0 + t * ((3.0 * (f1 - f0) - 2.0 * m0 - m1) + t * (2.0 * (f0 - f1) + m0 + m1)));
  // First interval: the cubic would overshoot below zero for p > 3 (x^p is so flat there);
  // the chord is non-negative and monotone, off by less than h^p (3e-9 for p = 2.6, the
  // smallest exponent of the two (k1, k2) pairs; 1e-19 for p = 5.7).
  return k == 0 ? f1 * t : cubic;
}

struct PowerTable {
  const double* nodes = nullptr;  // 2 (n + 1) values: x_k^p and p x_k^(p-1) h, k = 0..n
  int n = 0;                      // intervals
  double inv_h = 0.0;
  double p = 0.0;

  CD_HD double operator()(double x) const { return power_table_lookup(nodes, 0, n, inv_h, x); }
};

/// A block of table nodes on the host that a law's evaluator reads: where it is and how many
/// doubles it holds (a device backend copies it into its own memory and hands the evaluator
/// that copy).
struct TableBlock {
  const double* host = nullptr;
  std::size_t count = 0;
};

/// The tables of x^p1 and x^p2 in one block, the second right after the first:
/// second.nodes == first.nodes + 2 (n + 1), so a kernel can choose between them with an offset.
/// Built once per pair of exponents and kept for the process lifetime; a copy to another memory
/// must keep that layout.
std::array<PowerTable, 2> power_table_pair(double p1, double p2);

}  // namespace crushdem

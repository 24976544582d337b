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

#include <cmath>

#include "crushdem/core/types.hpp"

namespace crushdem {

struct PowerTable {
  const double* nodes = nullptr;  // 2 (n + 1) values: x_k^p and p x_k^(p-1) h, k = 0..n
  int n = 0;                      // intervals
  double inv_h = 0.0;
  double p = 0.0;

  CD_HD double operator()(double x) const {
    const double s = x * inv_h;
    int k = static_cast<int>(s);
    k = k < 0 ? 0 : (k >= n ? n - 1 : k);
    const double t = s - static_cast<double>(k);
    const double* d = nodes + 2 * k;
    // First interval: the cubic would overshoot below zero for p > 3 (x^p is so flat there);
    // the chord is non-negative and monotone, off by less than h^p (3e-9 for p = 2.6, the
    // smallest exponent of the two (k1, k2) pairs; 1e-19 for p = 5.7).
    if (k == 0) return d[2] * t;
    const double f0 = d[0], m0 = d[1], f1 = d[2], m1 = d[3];
    return f0 +
           t * (m0 + t * ((3.0 * (f1 - f0) - 2.0 * m0 - m1) + t * (2.0 * (f0 - f1) + m0 + m1)));
  }
};

/// The shared table for exponent p (built once per exponent, kept for the process lifetime).
PowerTable power_table(double p);

}  // namespace crushdem

// Local (non-viscous) damping as in PFC (Itasca), the damping of the reference study
// (docs/model.md 1.4): each component of a grain's unbalanced force and moment loses the fraction
// alpha of its magnitude against the direction of the matching velocity component,
//
//   F_d = F - alpha |F| sign(v),    sign(0) = 0 (a component at rest is not damped).
//
// Shared by the CPU step (Simulation::gather_and_damp) and the GPU gather kernel.
#pragma once

#include <cmath>

#include "crushdem/core/types.hpp"

namespace crushdem {

/// Branch-free: the sign of a velocity component is random, so a branch on it is mispredicted
/// about half the time. The result equals `v > 0 ? F - alpha |F| : (v < 0 ? F + alpha |F| : F)`
/// bit for bit (products with +1, -1 and 0 are exact, and F - (-a) equals F + a), NaN velocities
/// included (no damping).
CD_HD inline double local_damping(double F, double v, double alpha) {
  const double sign_v = static_cast<double>(v > 0.0) - static_cast<double>(v < 0.0);
  return F - alpha * std::fabs(F) * sign_v;
}

}  // namespace crushdem

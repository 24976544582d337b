// The per-grain rules of one step of velocity Verlet with PFC local damping (docs/model.md
// 1.4), written once for every backend: the CPU engine's integration passes
// (integrate/integrator.cpp) and the device step (backend/device_step.hpp, also run by its host
// emulation) call these, so the two cannot drift apart.
//
//   half kick   v += (h/2) F / m,   w = s w + s (h/2) T / I
//   drift       x += h v
//   damping     F_j -= alpha |F_j| sign(v_j), each component of force and torque
//               (local_damping.hpp), before the second half kick
//
// s is ContactParams::spin_scale: 1 for free spins, 0 to hold every spin at zero (rotation
// blocked); either way the products are exact, so s = 1 changes no bit. A squared displacement
// that is NaN (a grain thrown out by a step too large for its stiffness) is made infinite before
// any maximum is taken, so that no backend can lose it: the neighbour rebuild then runs and
// reports the grain.
#pragma once

#include <limits>

#include "crushdem/core/types.hpp"
#include "crushdem/integrate/local_damping.hpp"

namespace crushdem {

/// One half kick of a grain's velocity and spin (in place): a = (h/2) / m, b = s (h/2) / I.
CD_HD_INLINE void half_kick(double hh, double spin_scale, double inv_mass, double inv_inertia,
                            Vec3 F, Vec3 T, double& vx, double& vy, double& vz, double& wx,
                            double& wy, double& wz) {
  const double a = hh * inv_mass, b = spin_scale * (hh * inv_inertia);
  vx += a * F.x;
  vy += a * F.y;
  vz += a * F.z;
  wx = spin_scale * wx + b * T.x;
  wy = spin_scale * wy + b * T.y;
  wz = spin_scale * wz + b * T.z;
}

/// The drift of one coordinate over the step h.
CD_HD_INLINE double drifted(double x, double h, double v) {
  return x + h * v;
}

/// The NaN rule: a squared displacement for a maximum, NaN made infinite.
CD_HD_INLINE double checked_square_displacement(double d2) {
  return d2 == d2 ? d2 : std::numeric_limits<double>::infinity();
}

/// The squared displacement of a grain at (x, y, z) from (x0, y0, z0), NaN made infinite.
CD_HD_INLINE double square_displacement(double x, double y, double z, double x0, double y0,
                                        double z0) {
  const double dx = x - x0, dy = y - y0, dz = z - z0;
  return checked_square_displacement(dx * dx + dy * dy + dz * dz);
}

/// A grain's force and torque after local damping against its velocity and spin.
CD_HD_INLINE void damp(double alpha, Vec3 v, Vec3 w, Vec3& F, Vec3& T) {
  F = {local_damping(F.x, v.x, alpha), local_damping(F.y, v.y, alpha),
       local_damping(F.z, v.z, alpha)};
  T = {local_damping(T.x, w.x, alpha), local_damping(T.y, w.y, alpha),
       local_damping(T.z, w.z, alpha)};
}

}  // namespace crushdem

// The geometry and control rules of the six box walls, written once for every backend (the CPU
// engine, the device step and its host emulation): which axis and side a wall is on, its outward
// normal, the gap between a wall and a grain centre, and the servo law (docs/model.md 4.2)
//
//   v_out = g (sigma_measured - sigma_target),  g = alpha A / (sum k_n dt),
//
// clamped to the wall's maximum speed; v_out points along the outward normal, so a wall that
// carries too much stress retreats. Pure, header-only, host and device.
#pragma once

#include <cmath>

#include "crushdem/core/types.hpp"

namespace crushdem {

inline constexpr int kNumWalls = 6;

/// Wall k (0..5: xmin, xmax, ymin, ymax, zmin, zmax) lies across axis k / 2.
CD_HD inline int wall_axis(int k) {
  return k / 2;
}
/// The low wall of its axis (k even) faces the -axis direction.
CD_HD inline bool wall_is_low(int k) {
  return k % 2 == 0;
}
/// The axis component of wall k's outward normal (-1 for a low wall, +1 for a high one).
CD_HD inline double wall_outward_sign(int k) {
  return wall_is_low(k) ? -1.0 : 1.0;
}
/// Outward unit normal of wall k (from the sample into the wall).
CD_HD inline Vec3 wall_outward_normal(int k) {
  Vec3 n{};
  const double s = wall_outward_sign(k);
  if (wall_axis(k) == 0) n.x = s;
  if (wall_axis(k) == 1) n.y = s;
  if (wall_axis(k) == 2) n.z = s;
  return n;
}
/// The velocity vector of wall k moving at `velocity` along its coordinate axis.
CD_HD inline Vec3 wall_velocity_vector(int k, double velocity) {
  return velocity * wall_outward_normal(k) * wall_outward_sign(k);
}
/// Distance from wall k (plane coordinate `wall_position`) to a grain centre, positive on the
/// sample's side; the grain touches the wall when it is below its radius.
CD_HD inline double wall_gap(int k, double wall_position, double cx, double cy, double cz) {
  const int a = wall_axis(k);
  const double c = a == 0 ? cx : (a == 1 ? cy : cz);
  return wall_is_low(k) ? c - wall_position : wall_position - c;
}

/// The servo law: the velocity of a body's degree of freedom for the next step, from its normal
/// force, its current area, its contacts' summed k_n and the step h; without contacts (or before
/// the first step) the body approaches or retreats at full speed, and stays where it is when
/// its target is met exactly (a zero target, a pile's head load taken off, with the pile free
/// of the grains). outward_sign: +1 where an
/// increasing coordinate moves the surface away from the grains, -1 where towards them.
CD_HD inline double servo_velocity(double outward_sign, double normal_force, double area,
                                   double stiffness, double h, double target_stress,
                                   double servo_alpha, double max_speed) {
  const double error = normal_force / area - target_stress;
  double v_out;
  if (stiffness > 0.0 && h > 0.0) {
    v_out = servo_alpha * area / (stiffness * h) * error;
  } else {
    v_out = error > 0.0 ? max_speed : (error < 0.0 ? -max_speed : 0.0);
  }
  v_out = v_out < -max_speed ? -max_speed : (max_speed < v_out ? max_speed : v_out);
  return outward_sign * v_out;
}

/// The servo law for box wall k: its velocity along its coordinate axis.
CD_HD inline double servo_wall_velocity(int k, double normal_force, double area, double stiffness,
                                        double h, double target_stress, double servo_alpha,
                                        double max_speed) {
  return servo_velocity(wall_outward_sign(k), normal_force, area, stiffness, h, target_stress,
                        servo_alpha, max_speed);
}

}  // namespace crushdem

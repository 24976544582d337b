// Rolling resistance: an elastic-perfectly-plastic moment spring (docs/model.md 1.5; the
// rolling-resistance linear model of PFC, `rrlinear`; Iwashita & Oda 1998, J. Eng. Mech. 124(3);
// model C of Ai et al. 2011, Powder Technol. 206, without its dashpot: local damping acts on
// the torques already).
//
//   M_r <- rot(M_r) - k_r dtheta_b,   k_r = k_t R*^2,   |M_r| <= mu_r R* F_n
//
// dtheta_b = (w_i - w_j) dt minus its twisting part along n: the relative bending rotation of
// body i with respect to body j over the step. M_r is the moment on i (j receives -M_r); k_t is
// the tangent tangential stiffness of the contact (Mindlin), R* the effective radius. Not in the
// study's Table 1: off (mu_r = 0) by default, and used for grain-grain contacts only (the walls
// are frictionless by default, and a moment from a flat wall would have no lever to resist).
#pragma once

#include "crushdem/contact/tangential.hpp"
#include "crushdem/core/types.hpp"

namespace crushdem {

/// Returns the new rolling moment on body 1. dw = w_1 - w_2 [rad/s]; n the unit contact normal;
/// k_t the tangential stiffness [N/m]; mu_r the rolling friction coefficient [-].
CD_HD inline Vec3 rolling_moment(Vec3 M_r, Vec3 n, Vec3 dw, double dt, double k_t, double R_star,
                                 double mu_r, double F_n) {
  const Vec3 dtheta = dt * dw;
  const Vec3 dtheta_b = dtheta - dot(dtheta, n) * n;
  return contact_plane_spring(M_r, n, dtheta_b, k_t * R_star * R_star, mu_r * R_star * F_n);
}

}  // namespace crushdem

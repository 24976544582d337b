// Contact stress used by the crushing criterion (docs/model.md 2.1; Ciantia et al. 2015):
//   sigma_c = F_n / (pi r' delta),
// r' = R* (CHOICE: pi R* delta = pi a^2 is the Hertz contact area) or 2 R* (PFC's effective
// radius); R* = R against a wall; delta the total overlap. A grain's contact load is the largest
// sigma_c over its contacts (walls included), with the largest elastic F_n and that contact's
// normal, which orients the split. Lives with the contact laws because every backend's force
// loop evaluates it (fracture/ decides what it means).
#pragma once

#include <vector>

#include "crushdem/core/types.hpp"

namespace crushdem {

CD_HD inline double contact_stress(double F_n, double r_prime, double delta) {
  return delta > 0.0 ? F_n / (kPi * r_prime * delta) : 0.0;
}

/// The same for a grain pair in the force loops (CPU and GPU), with inv_pi_k = 1 / (pi r'/R*)
/// computed once per run: F_n inv_pi_k / (R* delta).
CD_HD inline double pair_contact_stress(double F_n, double inv_pi_k, double R_star, double delta) {
  return delta > 0.0 ? F_n * inv_pi_k / (R_star * delta) : 0.0;
}

/// Per grain contact load, filled by each force evaluation while crushing tracks it: the largest
/// sigma_c, the largest elastic F_n and the unit normal of that contact, pointing from the grain
/// towards the contact.
struct ContactLoad {
  std::vector<double> sigma, F_n_max, nx, ny, nz;
};

/// The maxima rule of the contact load, the same for every backend: one contact of stress `sig`,
/// elastic normal force F_n and normal n (from the grain towards the contact) taken into a
/// grain's running maxima. Maxima do not depend on the order of the contacts, except that a tie
/// in F_n keeps the first normal.
CD_HD inline void take_contact_load(double& S, double& F_max, double& nx, double& ny, double& nz,
                                    double sig, double F_n, Vec3 n) {
  if (sig > S) S = sig;
  if (F_n > F_max) {
    F_max = F_n;
    nx = n.x;
    ny = n.y;
    nz = n.z;
  }
}

}  // namespace crushdem

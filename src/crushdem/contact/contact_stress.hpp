// Contact stress used by the crushing criterion (docs/model.md 2.1; Ciantia et al. 2015):
//   sigma_c = F_n / (pi r' delta),
// r' = R* (CHOICE: pi R* delta = pi a^2 is the Hertz contact area) or 2 R* (PFC's effective
// radius); R* = R against a wall; delta the total overlap. Lives with the contact laws because the
// force loops evaluate it (fracture decides what it means).
#pragma once

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

}  // namespace crushdem

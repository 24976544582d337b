// Viscous contact damping (optional; off by default, model-notes 1.4 uses local damping).
//
// Tsuji et al. (1992), Powder Technol. 71: F_d = -eta v, eta = alpha(e) sqrt(m_eff k_n), with
// alpha(e) the polynomial fit of the coefficient of restitution e used by LAMMPS' `damping
// tsuji`. The peer benchmark uses it (e = 0.5) so crushdem can run the same problem.
#pragma once

#include <cmath>

#include "crushdem/core/types.hpp"

namespace crushdem {

CD_HD inline double tsuji_alpha(double e) {
  // Valid for 0 < e <= 1; alpha(1) = 0 up to the fit's accuracy.
  return 1.2728 - 4.2783 * e + 11.087 * e * e - 22.348 * e * e * e + 27.467 * e * e * e * e -
         18.022 * e * e * e * e * e + 4.8218 * e * e * e * e * e * e;
}

struct ViscousDamping {
  double alpha_n = 0.0;  // 0 = no viscous damping
  double tangential_factor = 1.0;
};

CD_HD inline double viscous_coefficient(double alpha, double m_eff, double k_n) {
  return alpha * std::sqrt(m_eff * k_n);
}

}  // namespace crushdem

// Viscous contact damping (optional; off by default, docs/model.md 1.4 uses local damping).
//
// Tsuji et al. (1992), Powder Technol. 71: F_d = -eta v with eta = alpha sqrt(m* F_n / delta)
// (for Hertz F_n / delta = K sqrt(delta), Tsuji's form), alpha = sqrt(2) alpha_fit(e) where
// alpha_fit is the polynomial fit of the coefficient of restitution e (Marshall 2009, eq. 53) and
// sqrt(2) the effective-mass convention of Tsuji 1992, as in LAMMPS `damping tsuji`. The peer
// benchmark uses it (e = 0.5) so crushdem can run the same problem. Optional; off by default.
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

/// eta = alpha sqrt(m* F_n / delta); `stiffness` is F_n / delta (the secant stiffness).
CD_HD inline double viscous_coefficient(double alpha, double m_eff, double stiffness) {
  return alpha * std::sqrt(m_eff * stiffness);
}

}  // namespace crushdem

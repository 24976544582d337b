// Viscous contact damping (optional; off by default, docs/model.md 1.4 uses local damping).
//
// Tsuji et al. (1992), Powder Technol. 71: F_d = -eta v with eta = alpha sqrt(m* F_n / delta)
// (for Hertz F_n / delta = K sqrt(delta), Tsuji's form), alpha = sqrt(2) alpha_fit(e) where
// alpha_fit is the polynomial fit of the coefficient of restitution e (Marshall 2009, eq. 53) and
// sqrt(2) the effective-mass convention of Tsuji 1992, as in LAMMPS `damping tsuji`. The peer
// benchmark uses it (e = 0.5) so crushdem can run the same problem. Optional; off by default.
#pragma once

#include <cmath>

#include "crushdem/core/params.hpp"
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

/// The key of [contact] the viscous damping owns.
struct ViscousConfig {
  double restitution = 1.0;  // < 1 adds Tsuji viscous damping (off by default)
  static const ParamTable<ViscousConfig>& config_params() {
    using C = ViscousConfig;
    static const ParamTable<C> table = {
        {"restitution", &C::restitution, "-",
         "< 1 adds Tsuji viscous contact damping (as LAMMPS `damping tsuji`) for this coefficient "
         "of restitution; the fit is approximate (a head-on impact with 0.5 rebounds at 0.55); "
         "1 = none",
         [](double v) { return v > 0.0 && v <= 1.0; },
         "a coefficient of restitution in (0, 1] (1 = no viscous damping)"},
    };
    return table;
  }
  ViscousDamping derive() const {
    ViscousDamping d;
    if (restitution < 1.0) d.alpha_n = std::sqrt(2.0) * tsuji_alpha(restitution);
    return d;
  }
};

/// eta = alpha sqrt(m* F_n / delta); `stiffness` is F_n / delta (the secant stiffness).
CD_HD inline double viscous_coefficient(double alpha, double m_eff, double stiffness) {
  return alpha * std::sqrt(m_eff * stiffness);
}

}  // namespace crushdem

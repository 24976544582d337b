// The grains' material (docs/model.md 1, Table 1 of the reference study): what every contact law
// derives its stiffness from.
#pragma once

#include "crushdem/core/params.hpp"
#include "crushdem/core/types.hpp"

namespace crushdem {

/// E* for two grains of one material from the shear modulus G and Poisson's ratio nu.
CD_HD inline double effective_modulus(double G, double nu) {
  return G / (1.0 - nu);
}

struct MaterialConfig {
  double density = 2650.0;      // [kg/m^3] quartz (CHOICE)
  double shear_modulus = 32e9;  // G [Pa] (STUDY, Table 1)
  double poisson_ratio = 0.19;  // nu [-] (STUDY)
  double friction = 0.275;      // mu, grain-grain [-] (STUDY)
  double E_star() const { return effective_modulus(shear_modulus, poisson_ratio); }
};

/// The keys of [material] (core/params.hpp).
const ParamTable<MaterialConfig>& material_params();

}  // namespace crushdem

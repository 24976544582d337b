// Material and contact-law parameters (docs/model.md 1, Table 1 of the reference study).
#pragma once

#include <string>

#include "crushdem/contact/damping.hpp"
#include "crushdem/contact/hertz.hpp"
#include "crushdem/contact/rough_hertz.hpp"
#include "crushdem/contact/tangential.hpp"
#include "crushdem/core/params.hpp"

namespace crushdem {

struct MaterialConfig {
  double density = 2650.0;      // [kg/m^3] quartz (CHOICE)
  double shear_modulus = 32e9;  // G [Pa] (STUDY, Table 1)
  double poisson_ratio = 0.19;  // nu [-] (STUDY)
  double friction = 0.275;      // mu, grain-grain [-] (STUDY)
  void validate() const;        // throws ConfigError naming "material.<key>"
  double E_star() const { return effective_modulus(shear_modulus, poisson_ratio); }
};

enum class NormalLaw { Hertz, Rough };

/// How grains turn. Free: spins integrated from the contact moments (Table 1 as stated).
/// Rolling: free spins plus the rolling-resistance moment of contact/rolling.hpp (mu_r =
/// rolling_friction). Blocked: spins held at zero and contact moments ignored, the
/// "rotation prohibited" spheres of Arroyo et al. (2011, Geotechnique 61(6)); sliding friction
/// still acts on the translations. Not in Table 1 (CHOICE).
enum class Rotation { Free, Rolling, Blocked };

struct ContactConfig {
  NormalLaw law = NormalLaw::Rough;    // "hertz" | "rough"
  double roughness_Sq = 0.6e-6;        // S_q [m] (STUDY); used by the rough law
  double k1 = 0.05, k2 = 5.0;          // rough-law transition constants (CHOICE: Table 1 n1, n2)
  double wall_friction = 0.0;          // mu against walls (CHOICE)
  double restitution = 1.0;            // < 1 adds Tsuji viscous damping (off by default)
  double rolling_friction = 0.0;       // mu_r of grain-grain rolling resistance (CHOICE; 0 = off)
  Rotation rotation = Rotation::Free;  // "free" | "rolling" (needs mu_r > 0) | "blocked"
  void validate() const;               // throws ConfigError naming "contact.<key>"
};

const char* to_string(NormalLaw law);
NormalLaw parse_normal_law(const std::string& s, const std::string& key);
const char* to_string(Rotation r);
Rotation parse_rotation(const std::string& s, const std::string& key);

/// Everything a contact kernel needs, derived once from the configuration.
struct ContactParams {
  double E_star = 0.0;
  double tangential_ratio = 0.0;  // k_t / k_n
  double mu = 0.0, mu_wall = 0.0;
  double mu_r = 0.0;  // rolling friction, grain-grain (0 = no rolling resistance)
  // Multiplies every spin update: 1, or 0 with rotation blocked (0 * w + 0 * T keeps w = 0;
  // x * 1 is exact, so free rotation keeps its bits).
  double spin_scale = 1.0;
  ViscousDamping viscous;
  RoughHertzParams rough_pp, rough_pw;  // grain-grain (s = sqrt2 S_q) and grain-wall (s = S_q)
};

ContactParams make_contact_params(const MaterialConfig& m, const ContactConfig& c);

/// The keys of [material] and [contact] (core/params.hpp).
const ParamTable<MaterialConfig>& material_params();
const ParamTable<ContactConfig>& contact_params();

}  // namespace crushdem

#include "crushdem/contact/contact_config.hpp"

#include <cmath>
#include <sstream>

#include "crushdem/core/error.hpp"

namespace crushdem {
namespace {

void require(bool ok, const std::string& key, double v, const std::string& expected) {
  if (!ok || std::isnan(v)) throw ConfigError(bad_value(key, show_number(v), expected));
}

}  // namespace

void MaterialConfig::validate() const {
  require(density > 0.0 && std::isfinite(density), "material.density", density,
          "a positive density in kg/m^3");
  require(shear_modulus > 0.0 && std::isfinite(shear_modulus), "material.shear_modulus",
          shear_modulus, "a positive shear modulus in Pa");
  require(poisson_ratio > -1.0 && poisson_ratio < 0.5, "material.poisson_ratio", poisson_ratio,
          "a Poisson's ratio in (-1, 0.5)");
  require(friction >= 0.0 && std::isfinite(friction), "material.friction", friction,
          "a friction coefficient >= 0");
}

void ContactConfig::validate() const {
  require(roughness_Sq >= 0.0 && std::isfinite(roughness_Sq), "contact.roughness_Sq", roughness_Sq,
          "a roughness >= 0 in m");
  require(k1 > 0.0 && std::isfinite(k1), "contact.k1", k1, "a positive number");
  require(k2 > k1 && std::isfinite(k2), "contact.k2", k2, "a number larger than contact.k1");
  require(wall_friction >= 0.0 && std::isfinite(wall_friction), "contact.wall_friction",
          wall_friction, "a friction coefficient >= 0");
  require(restitution > 0.0 && restitution <= 1.0, "contact.restitution", restitution,
          "a coefficient of restitution in (0, 1] (1 = no viscous damping)");
  require(rolling_friction >= 0.0 && std::isfinite(rolling_friction), "contact.rolling_friction",
          rolling_friction, "a rolling friction coefficient >= 0 (0 = no rolling resistance)");
  if (rotation == Rotation::Rolling && !(rolling_friction > 0.0)) {
    throw ConfigError(bad_value("contact.rolling_friction", show_number(rolling_friction),
                                "mu_r > 0 with contact.rotation = \"rolling\""));
  }
  if (rotation != Rotation::Rolling && rolling_friction != 0.0) {
    throw ConfigError(bad_value("contact.rolling_friction", show_number(rolling_friction),
                                std::string("0 with contact.rotation = \"") + to_string(rotation) +
                                    "\" (rolling resistance needs rotation = \"rolling\")"));
  }
}

const char* to_string(NormalLaw law) {
  return law == NormalLaw::Hertz ? "hertz" : "rough";
}

NormalLaw parse_normal_law(const std::string& s, const std::string& key) {
  if (s == "hertz") return NormalLaw::Hertz;
  if (s == "rough") return NormalLaw::Rough;
  throw ConfigError(bad_value(key, "\"" + s + "\"", "\"hertz\" or \"rough\""));
}

const char* to_string(Rotation r) {
  switch (r) {
    case Rotation::Free: return "free";
    case Rotation::Rolling: return "rolling";
    case Rotation::Blocked: return "blocked";
  }
  return "free";
}

Rotation parse_rotation(const std::string& s, const std::string& key) {
  for (Rotation r : {Rotation::Free, Rotation::Rolling, Rotation::Blocked}) {
    if (s == to_string(r)) return r;
  }
  throw ConfigError(bad_value(key, "\"" + s + "\"", "\"free\", \"rolling\" or \"blocked\""));
}

ContactParams make_contact_params(const MaterialConfig& m, const ContactConfig& c) {
  ContactParams p;
  p.E_star = m.E_star();
  p.tangential_ratio = mindlin_stiffness_ratio(m.poisson_ratio);
  p.mu = m.friction;
  p.mu_wall = c.wall_friction;
  p.mu_r = c.rotation == Rotation::Rolling ? c.rolling_friction : 0.0;
  p.spin_scale = c.rotation == Rotation::Blocked ? 0.0 : 1.0;
  if (c.restitution < 1.0) p.viscous.alpha_n = std::sqrt(2.0) * tsuji_alpha(c.restitution);
  const double Sq = c.law == NormalLaw::Rough ? c.roughness_Sq : 0.0;
  p.rough_pp = make_rough_hertz(std::sqrt(2.0) * Sq, c.k1, c.k2);
  p.rough_pw = make_rough_hertz(Sq, c.k1, c.k2);
  return p;
}

}  // namespace crushdem

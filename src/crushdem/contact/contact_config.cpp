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
  validate_params(*this, material_params(), "material");
}

void ContactConfig::validate() const {
  validate_params(*this, contact_params(), "contact");
  require(k2 > k1 && std::isfinite(k2), "contact.k2", k2, "a number larger than contact.k1");
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

const ParamTable<MaterialConfig>& material_params() {
  using M = MaterialConfig;
  static const ParamTable<M> table = {
      {"density", &M::density, "kg/m^3", "grain density (quartz; CHOICE)",
       [](double v) { return v > 0.0; }, "a positive density in kg/m^3"},
      {"shear_modulus", &M::shear_modulus, "Pa", "G (Table 1)", [](double v) { return v > 0.0; },
       "a positive shear modulus in Pa"},
      {"poisson_ratio", &M::poisson_ratio, "-", "nu (Table 1); E* = G / (1 - nu)",
       [](double v) { return v > -1.0 && v < 0.5; }, "a Poisson's ratio in (-1, 0.5)"},
      {"friction", &M::friction, "-", "grain-grain friction coefficient mu (Table 1)",
       [](double v) { return v >= 0.0; }, "a friction coefficient >= 0"},
  };
  return table;
}

const ParamTable<ContactConfig>& contact_params() {
  using C = ContactConfig;
  static const ParamTable<C> table = {
      {"law",
       ParamChoice<C>{[](const C& c) { return std::string(to_string(c.law)); },
                      [](C& c, const std::string& v, const std::string& key) {
                        c.law = parse_normal_law(v, key);
                      },
                      "\"hertz\" or \"rough\""},
       "",
       "`\"rough\"`: rough-surface Hertz (Otsubo et al. 2017, docs/model.md 1.2); `\"hertz\"`: "
       "smooth Hertz"},
      {"roughness_Sq", &C::roughness_Sq, "m",
       "rms surface roughness S_q (Table 1); s = sqrt(2) S_q between grains, S_q against walls",
       [](double v) { return v >= 0.0; }, "a roughness >= 0 in m"},
      {"k1", &C::k1, "-", "transition-load constant (Table 1 n1; the original code used 1)",
       [](double v) { return v > 0.0; }, "a positive number"},
      {"k2", &C::k2, "-",
       "transition-load constant, > k1 (Table 1 n2; the original code used 100)"},
      {"wall_friction", &C::wall_friction, "-", "friction coefficient against walls (CHOICE)",
       [](double v) { return v >= 0.0; }, "a friction coefficient >= 0"},
      {"restitution", &C::restitution, "-",
       "< 1 adds Tsuji viscous contact damping (as LAMMPS `damping tsuji`) for this coefficient "
       "of restitution; the fit is approximate (a head-on impact with 0.5 rebounds at 0.55); "
       "1 = none",
       [](double v) { return v > 0.0 && v <= 1.0; },
       "a coefficient of restitution in (0, 1] (1 = no viscous damping)"},
      {"rolling_friction", &C::rolling_friction, "-",
       "mu_r of grain-grain rolling resistance (docs/model.md 1.5; PFC `rrlinear`): a moment "
       "spring k_r = k_t R*^2 on the relative bending rotation, capped at mu_r R* F_n "
       "(`contact/rolling.hpp`). Not in Table 1 (CHOICE); 0 = off; > 0 needs `rotation = "
       "\"rolling\"` (implied when `rotation` is not given). Grain-grain contacts only",
       [](double v) { return v >= 0.0; },
       "a rolling friction coefficient >= 0 (0 = no rolling resistance)"},
      {"rotation",
       ParamChoice<C>{[](const C& c) { return std::string(to_string(c.rotation)); },
                      [](C& c, const std::string& v, const std::string& key) {
                        c.rotation = parse_rotation(v, key);
                      },
                      "\"free\", \"rolling\" or \"blocked\""},
       "",
       "how grains turn (not in Table 1, CHOICE): `\"free\"` spins from the contact moments; "
       "`\"rolling\"` free spins plus the rolling resistance of `rolling_friction` (> 0); "
       "`\"blocked\"` spins held at zero and contact moments ignored (the rotation-prohibited "
       "spheres of Arroyo et al. 2011), sliding friction still acting. Grains and fragments "
       "alike. Without the key, `rolling_friction` > 0 means `\"rolling\"`; crushdem's study "
       "parameter set uses `\"blocked\"` (docs/model.md 1.5)"},
  };
  return table;
}

}  // namespace crushdem

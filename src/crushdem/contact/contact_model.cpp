#include "crushdem/contact/contact_model.hpp"

#include <cmath>

#include "crushdem/core/error.hpp"

namespace crushdem {
namespace {

/// Calls f.template operator()<T, I>() for each type T of the list, with its index I.
template <class... Ts, class F>
void for_each_model(TypeList<Ts...>, F&& f) {
  [&]<std::size_t... I>(std::index_sequence<I...>) {
    (f.template operator()<Ts, I>(), ...);
  }
  (std::index_sequence_for<Ts...>{});
}

/// "\"hertz\" or \"rough\"": the names of the normal sub-models, for messages and docs.
const std::string& law_choices() {
  static const std::string text = [] {
    std::vector<std::string> names;
    for_each_model(NormalModels{}, [&]<class N, std::size_t>() {
      names.push_back(std::string("\"") + N::kName + "\"");
    });
    std::string out;
    for (std::size_t k = 0; k < names.size(); ++k) {
      out += (k == 0 ? "" : (k + 1 == names.size() ? " or " : ", ")) + names[k];
    }
    return out;
  }();
  return text;
}

}  // namespace

const ParamTable<MaterialConfig>& material_params() {
  using M = MaterialConfig;
  static const ParamTable<M> table = {
      {"density",
       &M::density,
       "kg/m^3",
       "grain density (quartz; CHOICE)",
       [](double v) { return v > 0.0; },
       "a positive density in kg/m^3",
       {},
       {},
       [](double v) { return v >= 100.0 && v <= 25000.0; },
       "100 to 25,000 kg/m^3"},
      {"shear_modulus",
       &M::shear_modulus,
       "Pa",
       "G (Table 1)",
       [](double v) { return v > 0.0; },
       "a positive shear modulus in Pa",
       {},
       {},
       [](double v) { return v >= 1e5 && v <= 1e12; },
       "1e5 to 1e12 Pa"},
      {"poisson_ratio", &M::poisson_ratio, "-", "nu (Table 1); E* = G / (1 - nu)",
       [](double v) { return v > -1.0 && v < 0.5; }, "a Poisson's ratio in (-1, 0.5)"},
      {"friction", &M::friction, "-", "grain-grain friction coefficient mu (Table 1)",
       [](double v) { return v >= 0.0; }, "a friction coefficient >= 0"},
  };
  return table;
}

const char* to_string(NormalLaw law) {
  const char* name = "";
  for_each_model(NormalModels{}, [&]<class N, std::size_t I>() {
    if (static_cast<std::size_t>(law) == I) name = N::kName;
  });
  return name;
}

NormalLaw parse_normal_law(const std::string& s, const std::string& key) {
  int found = -1;
  for_each_model(NormalModels{}, [&]<class N, std::size_t I>() {
    if (s == N::kName) found = static_cast<int>(I);
  });
  if (found < 0) throw ConfigError(bad_value(key, "\"" + s + "\"", law_choices()));
  return static_cast<NormalLaw>(found);
}

const ParamTable<ContactConfig>& contact_params() {
  using C = ContactConfig;
  static const ParamTable<C> table = [] {
    std::string doc;
    for_each_model(NormalModels{}, [&]<class N, std::size_t>() {
      doc += std::string(doc.empty() ? "" : "; ") + "`\"" + N::kName + "\"`: " + N::kDoc;
    });
    static const std::string law_doc = doc;
    ParamTable<C> t = {
        {"law",
         ParamChoice<C>{[](const C& c) { return std::string(to_string(c.law)); },
                        [](C& c, const std::string& v, const std::string& key) {
                          c.law = parse_normal_law(v, key);
                        },
                        law_choices()},
         "", law_doc},
    };
    for_each_model(NormalModels{},
                   [&]<class N, std::size_t>() { append_rows(t, N::config_params()); });
    append_rows(t, TangentialConfig::config_params());
    append_rows(t, ViscousConfig::config_params());
    append_rows(t, RotationConfig::config_params());
    return t;
  }();
  return table;
}

void ContactConfig::validate() const {
  validate_params(*this, contact_params(), "contact");
  for_each_model(NormalModels{}, [&]<class N, std::size_t>() {
    N::check(static_cast<const typename N::Config&>(*this));
  });
  RotationConfig::check(*this);
}

ContactParams make_contact_params(const MaterialConfig& m, const ContactConfig& c) {
  ContactParams p;
  p.tangential_ratio = mindlin_stiffness_ratio(m.poisson_ratio);
  p.mu = m.friction;
  p.mu_wall = c.wall_friction;
  p.spin_scale = c.spin_scale();
  p.viscous = c.derive();
  return p;
}

ContactLaw::ContactLaw() : ContactLaw(MaterialConfig{}, ContactConfig{}) {}

ContactLaw::ContactLaw(const MaterialConfig& m, const ContactConfig& c)
    : cp_(make_contact_params(m, c)) {
  for_each_model(NormalModels{}, [&]<class N, std::size_t I>() {
    if (static_cast<std::size_t>(c.law) != I) return;
    const typename N::Params params = N::derive(m, static_cast<const typename N::Config&>(c));
    normal_ = Chosen<N>{params};
    if constexpr (N::kTables > 0) {
      static_assert(N::kTables <= kMaxLawTables, "raise kMaxLawTables");
      for (const TableBlock& b : N::tables(params)) tables_.push_back(b);
    }
  });
  for (std::size_t k = 0; k < tables_.size(); ++k) host_[k] = tables_[k].host;
  bool chosen = false;
  for_each_model(CoupleModels{}, [&]<class C, std::size_t>() {
    if (chosen || !C::selected(c)) return;
    couple_ = Chosen<C>{C::derive(c)};
    chosen = true;
  });
}

bool ContactLaw::has_couple() const {
  return std::visit([](const auto& c) { return std::decay_t<decltype(c)>::Model::kActive; },
                    couple_);
}

std::vector<HistoryField> ContactLaw::pair_history() const {
  return with_law(*this, [](const auto& model) {
    const auto fields = std::decay_t<decltype(model)>::pair_history();
    return std::vector<HistoryField>(fields.begin(), fields.end());
  });
}

}  // namespace crushdem

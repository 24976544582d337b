// The contact law as one unit, in the manner of LAMMPS `pair granular`: a normal sub-model
// (chosen by contact.law), the Mindlin tangential spring with its Coulomb cap, Tsuji viscous
// damping, and a couple sub-model on the relative rotation (rolling resistance, chosen by
// contact.rotation). Each sub-model owns its [contact] keys (a Config with its parameter
// table and its joint checks), its derived parameters (plain values, the same on the host and
// the device) and the per-contact history it keeps (declared as HistoryFields). This file is
// the registry: the lists below are the only place a sub-model is named, and every loop (the
// CPU pair and wall loops, the device step and its emulation), the contact history, the
// checkpoint and the device's fields follow from them through with_law().
//
// A normal sub-model N has:
//   kName, kDoc                   the value of contact.law and a line for the docs
//   Config, config_params(),      its keys (Config is a base of ContactConfig, so its fields
//   check(const Config&)          read as cfg.contact.<key>) and the checks joining them
//   Params, derive(material, c)   its derived parameters (plain values)
//   kTables, tables(params)       the host table blocks its evaluator reads (kTables may be 0)
//   Law, pair_law(params, placed), wall_law(params, placed)
//                                 the evaluators, with the table blocks where they run
// A couple sub-model C has: kActive, kHistory (history vectors per pair entry) and
// kHistoryFields, Params, selected(RotationConfig), derive(RotationConfig) and moment(...).
#pragma once

#include <array>
#include <string>
#include <type_traits>
#include <utility>
#include <variant>
#include <vector>

#include "crushdem/contact/damping.hpp"
#include "crushdem/contact/hertz.hpp"
#include "crushdem/contact/history_field.hpp"
#include "crushdem/contact/material.hpp"
#include "crushdem/contact/rolling.hpp"
#include "crushdem/contact/rough_hertz.hpp"
#include "crushdem/contact/tangential.hpp"
#include "crushdem/core/params.hpp"

namespace crushdem {

template <class... Ts>
struct TypeList {};

// --- the registry ------------------------------------------------------------------------------

/// The normal sub-models, in the order of NormalLaw.
using NormalModels = TypeList<HertzNormal, RoughNormal>;
enum class NormalLaw { Hertz, Rough };
/// The couple sub-models; exactly one is selected by the rotation keys.
using CoupleModels = TypeList<NoRolling, RollingResistance>;

// --- configuration -----------------------------------------------------------------------------

template <class List>
struct ConfigsOf;
template <class... Ts>
struct ConfigsOf<TypeList<Ts...>> : Ts::Config... {};

/// The keys of [contact]: the law's name and every sub-model's Config.
struct ContactConfig : ConfigsOf<NormalModels>, TangentialConfig, ViscousConfig, RotationConfig {
  NormalLaw law = NormalLaw::Rough;  // "hertz" | "rough"
  void validate() const;             // throws ConfigError naming "contact.<key>"
};

const char* to_string(NormalLaw law);
NormalLaw parse_normal_law(const std::string& s, const std::string& key);

/// The keys of [contact] (core/params.hpp): `law`, then each sub-model's rows.
const ParamTable<ContactConfig>& contact_params();

// --- derived parameters ------------------------------------------------------------------------

/// What every law shares, derived once from the configuration: plain values.
struct ContactParams {
  double tangential_ratio = 0.0;  // k_t / k_n (Mindlin)
  double mu = 0.0, mu_wall = 0.0;
  // Multiplies every spin update: 1, or 0 with rotation blocked (RotationConfig::spin_scale).
  double spin_scale = 1.0;
  ViscousDamping viscous;
};

ContactParams make_contact_params(const MaterialConfig& m, const ContactConfig& c);

/// One combination of sub-models with its evaluators bound to tables where it runs: what the
/// loops and kernels are instantiated on. Plain values and table pointers, passed by value.
template <class Normal, class Couple>
struct ContactModel {
  using NormalModel = Normal;
  using CoupleModel = Couple;
  using Law = typename Normal::Law;
  static constexpr bool kCouple = Couple::kActive;
  /// History vectors per grain-pair entry: the tangential spring, then the couple's.
  static constexpr int kPairHistory = 1 + Couple::kHistory;
  Law pair_law, wall_law;
  ContactParams cp;
  typename Couple::Params couple;
  /// The declared pair history, in the order of the entries' history vectors.
  static std::array<HistoryField, kPairHistory> pair_history() {
    std::array<HistoryField, kPairHistory> out{};
    out[0] = kTangentialHistory;
    if constexpr (Couple::kHistory > 0) {
      for (int k = 0; k < Couple::kHistory; ++k) out[1 + k] = Couple::kHistoryFields[k];
    }
    return out;
  }
};

/// The most table blocks any normal sub-model reads.
inline constexpr int kMaxLawTables = 2;

/// The configured law, derived once: which sub-models, their parameters (plain values) and the
/// host table blocks their evaluators read. Host state; with_law() hands a kernel the
/// ContactModel of the combination.
class ContactLaw {
 public:
  template <class N>
  struct Chosen {
    using Model = N;
    typename N::Params params;
  };
  template <class List>
  struct VariantOf;
  template <class... Ts>
  struct VariantOf<TypeList<Ts...>> {
    using type = std::variant<Chosen<Ts>...>;
  };
  using NormalChoice = typename VariantOf<NormalModels>::type;
  using CoupleChoice = typename VariantOf<CoupleModels>::type;

  ContactLaw();
  ContactLaw(const MaterialConfig& m, const ContactConfig& c);

  const ContactParams& params() const { return cp_; }
  /// The grain-grain friction (sample preparation lowers it, then restores the material's).
  void set_friction(double mu) { cp_.mu = mu; }
  const NormalChoice& normal() const { return normal_; }
  const CoupleChoice& couple() const { return couple_; }
  bool has_couple() const;
  /// The table blocks of the normal sub-model on the host (kMaxLawTables at most).
  const std::vector<TableBlock>& tables() const { return tables_; }
  /// The host pointers of tables(), in the form with_law() takes.
  const double* const* host_tables() const { return host_.data(); }
  /// The declared history vectors of a grain-pair entry, in order.
  std::vector<HistoryField> pair_history() const;
  /// The parameters and host evaluators of normal sub-model N, which must be the chosen one
  /// (std::bad_variant_access otherwise): for tests and reports.
  template <class N>
  const typename N::Params& normal_params() const {
    return std::get<Chosen<N>>(normal_).params;
  }
  template <class N>
  typename N::Law pair_law() const {
    return N::pair_law(normal_params<N>(), host_tables());
  }
  template <class N>
  typename N::Law wall_law() const {
    return N::wall_law(normal_params<N>(), host_tables());
  }

 private:
  NormalChoice normal_;
  CoupleChoice couple_;
  ContactParams cp_;
  std::vector<TableBlock> tables_;
  std::array<const double*, kMaxLawTables> host_{};
};

/// Calls f(ContactModel<N, C>{...}) for the configured combination, its evaluators reading the
/// table blocks at `placed` (the host's, or a device's copies in the order of law.tables()).
template <class F>
decltype(auto) with_law(const ContactLaw& law, const double* const* placed, F&& f) {
  return std::visit(
      [&](const auto& normal, const auto& couple) -> decltype(auto) {
        using N = typename std::decay_t<decltype(normal)>::Model;
        using C = typename std::decay_t<decltype(couple)>::Model;
        ContactModel<N, C> model{N::pair_law(normal.params, placed),
                                 N::wall_law(normal.params, placed), law.params(), couple.params};
        return f(model);
      },
      law.normal(), law.couple());
}

/// with_law() on the host's tables.
template <class F>
decltype(auto) with_law(const ContactLaw& law, F&& f) {
  return with_law(law, law.host_tables(), std::forward<F>(f));
}

}  // namespace crushdem

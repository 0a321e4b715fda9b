// Which material pairs collide as rough hard spheres in EDM, and with which tangential rule
// (contact/rough.hpp). Shared by the EDM engine and by `matep log verify --scene`.
//
// A pair is rough when its mixed friction is > 0 or either material sets `tangential`; every
// other pair keeps the smooth operator (no rotation). The mixing rule is the soft-sphere engine's
// (engine/soft_plan.cpp): the mean of the two materials' values, a value set on one side only
// used alone. Defaults: law "walton", mu = 0, beta0 = 0.4 (the seed report's sticking value after
// Maw's data; Lun & Bent; docs/references.md §S.3.1).
#pragma once

#include <fmt/format.h>

#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "contact/rough.hpp"
#include "engine/system.hpp"

namespace matep {

// Default sticking tangential restitution of a rough EDM pair (seed report,
// docs/references.md §S.3.1).
inline constexpr double kDefaultRoughBeta0 = 0.4;

inline std::optional<TangentialLaw> tangential_law_of(const std::string& name) {
  if (name == "walton") return TangentialLaw::Walton;
  if (name == "constant") return TangentialLaw::Constant;
  if (name == "fem_fit") return TangentialLaw::FemFit;
  return std::nullopt;
}

// The rule of the pair (a, b), or nullopt for a smooth pair. Throws std::invalid_argument
// ("material.NAME.tangential: ...") when the two materials set different laws.
inline std::optional<TangentialModel> rough_rule(const Material& a, const Material& b) {
  auto mix = [](const std::optional<double>& x, const std::optional<double>& y, double fallback) {
    if (x && y) return 0.5 * (*x + *y);
    if (x) return *x;
    if (y) return *y;
    return fallback;
  };
  const double mu = mix(a.friction, b.friction, 0.0);
  if (!(mu > 0.0) && a.tangential.empty() && b.tangential.empty()) return std::nullopt;
  if (!a.tangential.empty() && !b.tangential.empty() && a.tangential != b.tangential)
    throw std::invalid_argument(fmt::format(
        "material.{}.tangential: \"{}\" differs from material.{}.tangential = \"{}\"; two materials that "
        "collide need one tangential rule (set it on one of them, or the same on both)",
        a.name, a.tangential, b.name, b.tangential));
  const std::string& name = a.tangential.empty() ? b.tangential : a.tangential;
  TangentialModel m;
  m.law = name.empty() ? TangentialLaw::Walton : tangential_law_of(name).value_or(TangentialLaw::Walton);
  m.friction = mu;
  m.beta0 = mix(a.tangential_restitution, b.tangential_restitution, kDefaultRoughBeta0);
  return m;
}

// The rules of every pair of materials (particle-particle and particle-wall: walls name
// materials of the same list).
struct RoughRules {
  int materials = 0;
  std::vector<char> rough;              // [a * materials + b]: the pair is rough
  std::vector<TangentialModel> model;   // its rule (unused for smooth pairs)
  bool any = false;                     // some pair is rough: the engine carries spins

  bool is_rough(int a, int b) const { return rough[static_cast<std::size_t>(a) * materials + b] != 0; }
  const TangentialModel& rule(int a, int b) const { return model[static_cast<std::size_t>(a) * materials + b]; }
};

inline RoughRules make_rough_rules(const std::vector<Material>& materials) {
  RoughRules r;
  const int M = static_cast<int>(materials.size());
  r.materials = M;
  r.rough.assign(static_cast<std::size_t>(M) * M, 0);
  r.model.assign(static_cast<std::size_t>(M) * M, TangentialModel{});
  for (int a = 0; a < M; ++a)
    for (int b = 0; b < M; ++b)
      if (const auto m = rough_rule(materials[a], materials[b])) {
        r.rough[static_cast<std::size_t>(a) * M + b] = 1;
        r.model[static_cast<std::size_t>(a) * M + b] = *m;
        r.any = true;
      }
  return r;
}

}  // namespace matep

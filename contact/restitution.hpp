// Normal coefficient of restitution as a function of the normal impact speed u_n.
// Models follow the seed report, section 3.1, eqs. 3.3-3.6 (docs/references.md §S.3.1).
#pragma once

#include <algorithm>
#include <cmath>

namespace matep {

struct Restitution {
  enum class Model { Constant, Power, Schwager, Exponential };
  Model model = Model::Constant;
  double e = 1.0;   // Constant: e
  double B = 1.0;   // Power: e = B u^-b  (seed eq. 3.3)
  double b = 0.0;
  double e0 = 1.0;  // Schwager-Poschel: e = 1 - (1 - e0)(u/u0)^n  (seed eq. 3.6)
  double u0 = 1.0;
  double n = 0.2;
  double C = 1.0;   // Exponential: e = C exp(-a u)  (seed eq. 3.5)
  double a = 0.0;

  static Restitution constant(double e) {
    Restitution r;
    r.e = e;
    return r;
  }

  bool is_elastic() const { return model == Model::Constant && e == 1.0; }

  // Value at normal impact speed u >= 0, clamped to [0, 1].
  double operator()(double u) const {
    double v = 1.0;
    switch (model) {
      case Model::Constant: v = e; break;
      case Model::Power: v = (u > 0.0) ? B * std::pow(u, -b) : 1.0; break;  // capped at 1 below
      case Model::Schwager: v = 1.0 - (1.0 - e0) * std::pow(u / u0, n); break;
      case Model::Exponential: v = C * std::exp(-a * u); break;
    }
    if (!(v >= 0.0)) v = 0.0;  // also maps NaN to 0
    return std::min(v, 1.0);
  }
};

// Restitution of a contact between two materials: the mean of the two models at the same u
// (documented mixing rule; identical materials give the material's own value).
inline double mixed_restitution(const Restitution& a, const Restitution& b, double u) {
  if (&a == &b) return a(u);
  return 0.5 * (a(u) + b(u));
}

}  // namespace matep

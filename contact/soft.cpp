// Exact damping ratio of the clipped Hertz-Tsuji law; see soft.hpp.
#include "contact/soft.hpp"
#include "contact/roots.hpp"

#include <array>
#include <cmath>

namespace matep {

namespace {

// State (X, V) of X'' = -X^3/2 - c X^1/4 X' as functions of s = t^(1/4): dX/ds = 4 s^3 V,
// dV/ds = -4 s^3 (X^3/2 + c X^1/4 V). X ~ s^4 near s = 0, so X^1/4 and X^3/2 are smooth in s.
using Y = std::array<double, 2>;

Y rhs(double s, const Y& y, double c) {
  const double x = y[0] > 0.0 ? y[0] : 0.0;
  const double q = std::sqrt(std::sqrt(x));
  const double j = 4.0 * s * s * s;
  return {j * y[1], -j * (x * std::sqrt(x) + c * q * y[1])};
}

Y rk4(double s, const Y& y, double h, double c) {
  const Y k1 = rhs(s, y, c);
  const Y k2 = rhs(s + 0.5 * h, {y[0] + 0.5 * h * k1[0], y[1] + 0.5 * h * k1[1]}, c);
  const Y k3 = rhs(s + 0.5 * h, {y[0] + 0.5 * h * k2[0], y[1] + 0.5 * h * k2[1]}, c);
  const Y k4 = rhs(s + h, {y[0] + h * k3[0], y[1] + h * k3[1]}, c);
  return {y[0] + h / 6.0 * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0]),
          y[1] + h / 6.0 * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1])};
}

// Normal force of the scaled law, unclipped.
double force(const Y& y, double c) {
  const double x = y[0] > 0.0 ? y[0] : 0.0;
  return x * std::sqrt(x) + c * std::sqrt(std::sqrt(x)) * y[1];
}

}  // namespace

ClippedHertz hertz_clipped_collision(double zeta) {
  // Elastic: contact ends at X = 0 after 2.94328 X_max, X_max = (5/4)^(2/5)
  // (docs/references.md §1.2).
  if (zeta <= 0.0) return {1.0, 2.9432751843 * std::pow(1.25, 0.4)};
  const double c = 2.0 * zeta * std::sqrt(1.5);
  const double h = 1.0 / 2048.0;
  double s = 0.0;
  Y y = {0.0, 1.0};
  for (int k = 0; k < 1 << 16; ++k) {
    const Y z = rk4(s, y, h, c);
    if (z[1] < 0.0 && (force(z, c) <= 0.0 || z[0] <= 0.0)) {
      // The force vanishes (or the overlap closes) inside this step: bisect the step length.
      double a = 0.0, b = h;
      Y yb = z;
      for (int it = 0; it < 60; ++it) {
        const double m = 0.5 * (a + b);
        const Y ym = rk4(s, y, m, c);
        if (ym[1] < 0.0 && (force(ym, c) <= 0.0 || ym[0] <= 0.0)) {
          b = m;
          yb = ym;
        } else {
          a = m;
        }
      }
      const double t = s + b;
      return {-yb[1], t * t * t * t};
    }
    y = z;
    s += h;
  }
  return {0.0, s * s * s * s};  // not reached for zeta > 0
}

double hertz_clipped_damping_ratio(double e) {
  if (e >= 1.0) return 0.0;
  // e(zeta) decreases monotonically; bracket, then regula falsi (Illinois) on e(zeta) - e.
  double a = 0.0, fa = 1.0 - e, b = 0.5, fb = hertz_clipped_collision(b).e - e;
  while (fb > 0.0) {
    a = b;
    fa = fb;
    b *= 2.0;
    fb = hertz_clipped_collision(b).e - e;
  }
  return illinois_root([&](double x) { return hertz_clipped_collision(x).e - e; }, a, fa, b, fb,
                       1e-13 * b, 100, 1e-13);
}

}  // namespace matep

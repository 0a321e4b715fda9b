// Real polynomials of degree <= 8 in double and the earliest time one of them closes: the impact
// times of the curved wall shapes (contact/cylinder.hpp, cone.hpp, plane_patch.hpp) are the roots of
// such polynomials (squared distances along straight or parabolic flights).
// Root isolation by the derivative sequence (the classical "roots of p lie between consecutive
// roots of p'" argument, applied degree by degree from the linear derivative upwards: e.g.
// Press et al., Numerical Recipes 3rd ed., sec. 9.5, or Collins & Loos, "Real zeros of
// polynomials", 1982): p is monotone between consecutive sign changes of p', so each such
// interval holds at most one root, found by a safeguarded Illinois iteration (contact/roots.hpp).
// Nothing is skipped: double (tangent) roots are the minima of p between two monotone pieces and
// show up as a piece that ends at p <= 0.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace matep {

struct Poly {
  static constexpr int kMax = 8;
  std::array<double, kMax + 1> c{};  // p(t) = sum_k c[k] t^k
  int n = 0;                         // degree (c[n] may still be 0 until trim())

  Poly() = default;
  Poly(std::initializer_list<double> cs) {
    int k = 0;
    for (double v : cs) c[k++] = v;
    n = k - 1;
  }

  // Horner.
  double operator()(double t) const {
    double s = c[n];
    for (int k = n - 1; k >= 0; --k) s = s * t + c[k];
    return s;
  }
  Poly derivative() const {
    Poly d;
    d.n = n > 0 ? n - 1 : 0;
    for (int k = 1; k <= n; ++k) d.c[k - 1] = k * c[k];
    return d;
  }
  // Drops exactly-zero leading coefficients.
  void trim() {
    while (n > 0 && c[n] == 0.0) --n;
  }
  Poly operator+(const Poly& o) const {
    Poly r;
    r.n = std::max(n, o.n);
    for (int k = 0; k <= r.n; ++k) r.c[k] = (k <= n ? c[k] : 0.0) + (k <= o.n ? o.c[k] : 0.0);
    return r;
  }
  Poly operator-(const Poly& o) const {
    Poly r;
    r.n = std::max(n, o.n);
    for (int k = 0; k <= r.n; ++k) r.c[k] = (k <= n ? c[k] : 0.0) - (k <= o.n ? o.c[k] : 0.0);
    return r;
  }
  // Product; the degrees must add up to at most kMax.
  Poly operator*(const Poly& o) const {
    Poly r;
    r.n = n + o.n;
    for (int i = 0; i <= n; ++i)
      for (int j = 0; j <= o.n; ++j) r.c[i + j] += c[i] * o.c[j];
    return r;
  }
  Poly operator*(double s) const {
    Poly r = *this;
    for (int k = 0; k <= n; ++k) r.c[k] *= s;
    return r;
  }
};

// A bound on the moduli of the roots (Cauchy: 1 + max |c_k / c_n|), capped at kPolyHorizon: a
// polynomial whose leading coefficient is a round-off remnant would otherwise push the search to
// times where t^8 overflows. No flight of a simulation lasts 1e30 time units.
inline constexpr double kPolyHorizon = 1e30;
inline double root_bound(const Poly& p) {
  double m = 0.0;
  for (int k = 0; k < p.n; ++k) m = std::max(m, std::abs(p.c[k] / p.c[p.n]));
  return std::min(1.0 + m, kPolyHorizon);
}

// Root of f on [a, b] with f(a) > 0 >= f(b), returned on the f <= 0 side and as early as
// round-off allows: Illinois steps (Dowell & Jarratt 1971), with a bisection step whenever the
// bracket has not halved over the last three steps, until the bracket is one ulp wide (or f hits 0).
template <class F>
double safe_root(F&& f, double a, double fa, double b, double fb) {
  int side = 0;
  double width = b - a;
  for (int it = 0; it < 400; ++it) {
    double x;
    if (it % 3 == 2 && b - a > 0.5 * width) {
      x = 0.5 * (a + b);
    } else {
      x = (a * fb - b * fa) / (fb - fa);
    }
    if (it % 3 == 2) width = b - a;
    if (!(x > a && x < b)) {
      x = 0.5 * (a + b);
      if (!(x > a && x < b)) break;  // a and b adjacent doubles
    }
    const double fx = f(x);
    if (fx > 0.0) {
      a = x;
      fa = fx;
      if (side == 1) fb *= 0.5;
      side = 1;
    } else {
      b = x;
      fb = fx;
      if (fx == 0.0) break;
      if (side == -1) fa *= 0.5;
      side = -1;
    }
  }
  return b;
}

namespace poly_detail {

// Root of p on [a, b] where p changes sign (either way), on the side where it has changed.
inline double bracket_root(const Poly& p, double a, double fa, double b, double fb) {
  if (fa < 0.0) return safe_root([&](double t) { return -p(t); }, a, -fa, b, -fb);
  return safe_root(p, a, fa, b, fb);
}

// The sign changes of p in the open interval (lo, hi), in increasing order, into out (at most p.n);
// returns their number. The sign changes of p' split [lo, hi] into monotone pieces, each holding at
// most one sign change of p.
inline int sign_changes(Poly p, double lo, double hi, double* out) {
  p.trim();
  if (p.n == 0) return 0;
  if (p.n == 1) {
    const double t = -p.c[0] / p.c[1];
    if (t > lo && t < hi) {
      out[0] = t;
      return 1;
    }
    return 0;
  }
  double e[Poly::kMax + 2];
  e[0] = lo;
  const int m = sign_changes(p.derivative(), lo, hi, e + 1);
  e[m + 1] = hi;
  int k = 0;
  double fa = p(lo);
  for (int i = 0; i <= m; ++i) {
    const double a = e[i], b = e[i + 1];
    const double fb = p(b);
    if ((fa > 0.0 && fb < 0.0) || (fa < 0.0 && fb > 0.0)) {
      const double r = bracket_root(p, a, fa, b, fb);
      if (r > lo && r < hi) out[k++] = r;
    }
    fa = fb;
  }
  return k;
}

}  // namespace poly_detail

// The earliest t in [0, limit) at which p closes: the first time p reaches <= 0 from above while
// decreasing, or the start of a decreasing stretch on which p is already <= 0 (p(0) <= 0 while
// decreasing: t = 0; p <= 0 at a local maximum: the turning point). These are the round-off rules of
// gap_closing_time (contact/predict.hpp) for a gap whose sign is the sign of p. Candidates are
// offered in increasing order to accept(t) (e.g. a check that the contact point lies on the finite
// part of a surface); the first accepted one is returned, infinity if none.
// Method: the monotone pieces of p on [0, min(limit, root_bound)] come from the sign changes of p'
// (poly_detail::sign_changes); on a decreasing piece [a, b], p(a) <= 0 gives a and p(a) > 0 >= p(b)
// the root in between, refined to one ulp. A tangent root is the end b of a decreasing piece with
// p(b) <= 0 (in round-off: a touch that p evaluates at +1e-300 counts as a miss).
template <class Accept>
double earliest_closing(Poly p, double limit, Accept&& accept) {
  constexpr double inf = std::numeric_limits<double>::infinity();
  p.trim();
  if (p.n == 0) return inf;  // a constant never closes
  const double hi = std::min(limit, root_bound(p) * 1.0000001 + 1e-300);
  if (!(hi > 0.0)) {
    // limit == 0: only "now" can count
    return (p(0.0) <= 0.0 && p.derivative()(0.0) < 0.0 && accept(0.0)) ? 0.0 : inf;
  }
  double e[Poly::kMax + 2];
  e[0] = 0.0;
  const int m = poly_detail::sign_changes(p.derivative(), 0.0, hi, e + 1);
  e[m + 1] = hi;
  const Poly dp = p.derivative();
  double fa = p(0.0);
  for (int i = 0; i <= m; ++i) {
    const double a = e[i], b = e[i + 1];
    const double fb = p(b);
    // Decreasing piece? The sign of p' inside (p' keeps its sign between its sign changes).
    const double mid = 0.5 * (a + b);
    const double slope = dp(mid);
    const bool decreasing = slope < 0.0 || (slope == 0.0 && fb < fa);
    if (decreasing) {
      if (fa <= 0.0) {
        if (accept(a)) return a < limit ? a : inf;
      } else if (fb <= 0.0) {
        const double r = poly_detail::bracket_root(p, a, fa, b, fb);
        if (!(r < limit)) return inf;
        if (accept(r)) return r;
      }
    }
    fa = fb;
  }
  return inf;
}

inline double earliest_closing(const Poly& p, double limit = std::numeric_limits<double>::infinity()) {
  return earliest_closing(p, limit, [](double) { return true; });
}

}  // namespace matep

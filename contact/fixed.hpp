// Event-time prediction for a hard sphere (disk) against an immovable one, a fixed grain: the moving
// grain flies on a parabola under gravity while the fixed grain stays put, so gravity does not
// cancel in the relative motion as it does for two moving grains (contact/predict.hpp).
//
// The relative position p(t) = r + v t + g t^2/2 meets the contact distance sigma where
//   f(t) = |p(t)|^2 - sigma^2 = c4 t^4 + c3 t^3 + c2 t^2 + c1 t + c0 = 0,
//   c4 = g.g/4, c3 = v.g, c2 = v.v + r.g, c1 = 2 r.v, c0 = r.r - sigma^2   (DERIVED: expand |p|^2).
// The earliest closing root is found without skipping one: the roots of the quadratic f'' cut
// [0, T] into intervals on which f' is monotone, so that f has at most one turn on each; walking
// them in order, a decreasing stretch that starts with f <= 0 is an event at its start (the
// round-off rule of contact/predict.hpp: touching and closing is an event now, and a receding
// overlap is an event when the gap starts to close again), and one that starts with f > 0 and
// ends with f <= 0 holds exactly one root, refined by Illinois (contact/roots.hpp) with bisection
// steps where the secant stalls. A turn of f (a root of f') is located only when the answer needs
// it: a maximum always, a minimum unless f is clearly below zero at the end of its interval. T is
// the earlier of `limit` and the time after which the fall alone keeps the grain out of reach.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "contact/predict.hpp"

namespace matep {

namespace detail {

// Root of h on [a, b] with h(a) > 0 >= h(b): regula falsi with the Illinois modification
// (contact/roots.hpp), and a bisection step wherever the secant point rounds onto an end of the
// bracket (one end's value tiny against the other's, where plain Illinois stops with a wide
// bracket). Stops at a point where |h| <= htol (h's round-off level), or at adjacent doubles,
// returning the end on the h <= 0 side.
template <class H>
double closing_root(H&& h, double a, double ha, double b, double hb, double htol) {
  int side = 0;
  for (int it = 0; it < 400; ++it) {
    double x = (a * hb - b * ha) / (hb - ha);
    if (!(x > a && x < b)) {
      x = 0.5 * (a + b);
      if (!(x > a && x < b)) break;  // a and b are adjacent doubles
      side = 0;
    }
    const double hx = h(x);
    if (std::abs(hx) <= htol) return x;
    if (hx > 0.0) {
      a = x;
      ha = hx;
      if (side == 1) hb *= 0.5;
      side = 1;
    } else {
      b = x;
      hb = hx;
      if (side == -1) ha *= 0.5;
      side = -1;
    }
  }
  return b;
}

}  // namespace detail

// Time until a sphere at relative position r (from the fixed grain's centre, periodic image
// included) with velocity v and acceleration g reaches the contact distance sigma while closing,
// or kNever if that does not happen before `limit`.
template <class V>
inline double fixed_sphere_impact_time(const V& r, const V& v, const V& g, double sigma, double limit = kNever) {
  const double gg = g.squaredNorm();
  if (gg == 0.0) return pair_collision_time(r, v, sigma, limit);
  const double rr = r.squaredNorm(), vv = v.squaredNorm();
  const double vn = std::sqrt(vv), gn = std::sqrt(gg);
  // Rejection: |p(t)| >= |r| - |v| t - |g| t^2/2, so nothing happens before `limit` while
  // |r| > sigma + |v| limit + |g| limit^2/2.
  if (limit < kNever) {
    const double reach = sigma + limit * (vn + 0.5 * gn * limit);
    if (rr > reach * reach) return kNever;
  }
  const double rn = std::sqrt(rr);
  // Beyond t_hi, |g| t^2/2 - |v| t - |r| > sigma: no root.
  const double t_hi = (vn + std::sqrt(vv + 2.0 * gn * (rn + sigma))) / gn;
  const double T = std::min(limit, t_hi);
  const double c4 = 0.25 * gg, c3 = v.dot(g), c2 = vv + r.dot(g), c1 = 2.0 * r.dot(v);
  auto f = [&](double t) {
    const V p = r + t * (v + (0.5 * t) * g);
    return compensated_gap2(p, sigma);
  };
  auto df = [&](double t) { return ((4.0 * c4 * t + 3.0 * c3) * t + 2.0 * c2) * t + c1; };
  auto ndf = [&](double t) { return -df(t); };
  // Round-off levels: of f, from the rounding of p (|p| ~ sigma near a root), and of f'.
  constexpr double kEps = std::numeric_limits<double>::epsilon();
  const double ftol = 4.0 * kEps * sigma * (rn + T * (vn + gn * T));
  const double dtol = 8.0 * kEps * (((4.0 * c4 * T + 3.0 * std::abs(c3)) * T + 2.0 * std::abs(c2)) * T + std::abs(c1));
  auto root = [&](double a, double fa, double b, double fb) {  // f(a) > 0 >= f(b)
    const double t = detail::closing_root(f, a, fa, b, fb, ftol);
    return t < limit ? t : kNever;
  };
  // Roots of f'' = 12 c4 t^2 + 6 c3 t + 2 c2 in (0, T) (c4 > 0), cancellation-free, ascending.
  std::array<double, 4> cut{};
  int nc = 0;
  cut[nc++] = 0.0;
  {
    const double a = 12.0 * c4, b = 6.0 * c3, c = 2.0 * c2;
    const double disc = b * b - 4.0 * a * c;
    if (disc > 0.0) {
      const double q = -0.5 * (b + std::copysign(std::sqrt(disc), b));
      double x1 = q / a, x2 = q != 0.0 ? c / q : 0.0;
      if (x1 > x2) std::swap(x1, x2);
      for (const double x : {x1, x2})
        if (x > 0.0 && x < T) cut[nc++] = x;
    }
  }
  cut[nc++] = T;
  double c = 0.0, fc = f(0.0), dc = df(0.0);
  for (int k = 1; k < nc; ++k) {
    const double d = cut[k], fd = f(d), dd = df(d);
    if (dc < 0.0 && dd > 0.0) {  // f falls to a minimum, then rises
      if (fc <= 0.0) return c < limit ? c : kNever;
      // Clearly below zero at d: one crossing, before the minimum (f <= f(d) < -ftol from there
      // to d). Near zero at d, f may be rising through a second root there: find the minimum.
      if (fd < -ftol) return root(c, fc, d, fd);
      const double x = detail::closing_root(ndf, c, -dc, d, -dd, dtol);  // a dip below zero?
      const double fx = f(x);
      if (fx <= 0.0) return root(c, fc, x, fx);
    } else if (dc > 0.0 && dd < 0.0) {  // f rises to a maximum, then falls
      const double x = detail::closing_root(df, c, dc, d, dd, dtol);
      const double fx = f(x);
      if (fx <= 0.0) return x < limit ? x : kNever;  // still overlapping where it turns: closing now
      if (fd <= 0.0) return root(x, fx, d, fd);
    } else if (dc <= 0.0 && dd <= 0.0 && (dc < 0.0 || dd < 0.0)) {  // falling throughout
      if (fc <= 0.0) return c < limit ? c : kNever;
      if (fd <= 0.0) return root(c, fc, d, fd);
    }
    c = d;
    fc = fd;
    dc = dd;
  }
  return kNever;
}

}  // namespace matep

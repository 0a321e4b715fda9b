// Event-time prediction for a hard sphere (disk) against an immovable one, a fixed grain: the moving
// grain flies on a parabola under gravity while the fixed grain stays put, so gravity does not
// cancel in the relative motion as it does for two moving grains (contact/predict.hpp).
//
// The relative position p(t) = r + v t + g t^2/2 meets the contact distance sigma where
//   f(t) = |p(t)|^2 - sigma^2 = c4 t^4 + c3 t^3 + c2 t^2 + c1 t + c0 = 0,
//   c4 = g.g/4, c3 = v.g, c2 = v.v + r.g, c1 = 2 r.v, c0 = r.r - sigma^2   (DERIVED: expand |p|^2).
// The earliest closing root is found without skipping one: the roots of f' (a cubic, split into
// monotone pieces by the roots of the quadratic f'') cut [0, T] into intervals on which f is
// monotone; the first decreasing interval whose start has f <= 0 is an event at its start (the
// round-off rule of contact/predict.hpp: touching and closing is an event now, and a receding
// overlap is an event when the gap starts to close again), otherwise the first decreasing interval
// whose end has f <= 0 holds exactly one root, refined by Illinois (contact/roots.hpp) with
// bisection steps where the secant stalls, down to adjacent doubles.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>

#include "contact/predict.hpp"

namespace matep {

namespace detail {

// Root of h on [a, b] with h(a) > 0 >= h(b), to adjacent doubles: regula falsi with the Illinois
// modification (contact/roots.hpp), and a bisection step wherever the secant point rounds onto an
// end of the bracket (one end's value tiny against the other's, where plain Illinois stops with a
// wide bracket). Returns the end on the h <= 0 side.
template <class H>
double closing_root(H&& h, double a, double ha, double b, double hb) {
  int side = 0;
  for (int it = 0; it < 400; ++it) {
    double x = (a * hb - b * ha) / (hb - ha);
    if (!(x > a && x < b)) {
      x = 0.5 * (a + b);
      if (!(x > a && x < b)) break;  // a and b are adjacent doubles
      side = 0;
    }
    const double hx = h(x);
    if (hx > 0.0) {
      a = x;
      ha = hx;
      if (side == 1) hb *= 0.5;
      side = 1;
    } else {
      b = x;
      hb = hx;
      if (hx == 0.0) break;
      if (side == -1) ha *= 0.5;
      side = -1;
    }
  }
  return b;
}

// Root of a function h that changes sign on [a, b] (h(a), h(b) of opposite signs or zero).
template <class H>
double sign_change_root(H&& h, double a, double ha, double b, double hb) {
  if (ha == 0.0) return a;
  if (hb == 0.0) return b;
  if (ha > 0.0) return closing_root(h, a, ha, b, hb);
  auto neg = [&](double t) { return -h(t); };
  return closing_root(neg, a, -ha, b, -hb);
}

}  // namespace detail

// Time until a sphere at relative position r (from the fixed grain's centre, periodic image
// included) with velocity v and acceleration g reaches the contact distance sigma while closing,
// or kNever if that does not happen before `limit`.
template <class V>
inline double fixed_sphere_impact_time(const V& r, const V& v, const V& g, double sigma, double limit = kNever) {
  const double gg = g.squaredNorm();
  if (gg == 0.0) return pair_collision_time(r, v, sigma, limit);
  // Rejection: |p(t)| >= |r| - |v| t - |g| t^2/2, so no contact before that bound closes the gap.
  const double rn = r.norm(), vn = v.norm(), gn = std::sqrt(gg);
  if (rn > sigma && !(gap_closing_time(rn - sigma, -vn, -gn) < limit)) return kNever;
  // Beyond T_hi, |g| t^2/2 - |v| t - |r| > sigma: no root.
  const double t_hi = (vn + std::sqrt(vn * vn + 2.0 * gn * (rn + sigma))) / gn;
  const double T = std::min(limit, t_hi);
  const double c4 = 0.25 * gg, c3 = v.dot(g), c2 = v.squaredNorm() + r.dot(g), c1 = 2.0 * r.dot(v);
  auto f = [&](double t) {
    const V p = r + t * (v + (0.5 * t) * g);
    return compensated_gap2(p, sigma);
  };
  auto df = [&](double t) { return ((4.0 * c4 * t + 3.0 * c3) * t + 2.0 * c2) * t + c1; };
  auto d2f = [&](double t) { return (12.0 * c4 * t + 6.0 * c3) * t + 2.0 * c2; };
  // Roots of f'' = 12 c4 t^2 + 6 c3 t + 2 c2 in (0, T) (c4 > 0), cancellation-free.
  std::array<double, 5> cut{};
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
  // Roots of f' (monotone between the cuts): the ends of the intervals on which f is monotone.
  std::array<double, 5> ends{};
  int ne = 0;
  ends[ne++] = 0.0;
  for (int k = 0; k + 1 < nc; ++k) {
    const double a = cut[k], b = cut[k + 1];
    const double da = df(a), db = df(b);
    if ((da < 0.0 && db > 0.0) || (da > 0.0 && db < 0.0)) {
      const double x = detail::sign_change_root(df, a, da, b, db);
      if (x > ends[ne - 1] && x < T) ends[ne++] = x;
    }
  }
  ends[ne++] = T;
  double fa = f(0.0);
  for (int k = 0; k + 1 < ne; ++k) {
    const double a = ends[k], b = ends[k + 1];
    const double fb = f(b);
    // Decreasing on [a, b]: f' < 0 inside (f' at the middle; f'' decides at a double root of f').
    double slope = df(0.5 * (a + b));
    if (slope == 0.0) slope = -d2f(a);
    if (slope < 0.0) {
      if (fa <= 0.0) return a;  // touching (or overlapping by round-off) and closing: now
      if (fb <= 0.0) {
        const double t = detail::closing_root(f, a, fa, b, fb);
        return t < limit ? t : kNever;
      }
    }
    fa = fb;
  }
  return kNever;
}

}  // namespace matep

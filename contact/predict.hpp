// Event-time prediction for hard particles: pair collisions (Allen & Tildesley, "Computer
// Simulation of Liquids", sec. 3.7), plane walls and cell boundaries under uniform gravity.
// All functions use the round-off-stable rule of Bannerman et al., Comput. Part. Mech. 1, 191
// (2014): an event exists only if the particles approach; an approaching pair that already
// overlaps collides now (t = 0); a receding one is never an event.
#pragma once

#include <cmath>
#include <limits>

#include "contact/roots.hpp"

namespace matep {

inline constexpr double kNever = std::numeric_limits<double>::infinity();

// Time until |r + v t| = sigma for a pair with relative position r and relative velocity v
// (gravity cancels in relative motion). Roots of v.v t^2 + 2 (r.v) t + (r.r - sigma^2) = 0;
// the earlier root in the cancellation-free form t = c / (-b + sqrt(b^2 - v^2 c)).
// r.r - sigma^2 with error-free transformations (TwoSum and an FMA TwoProduct, as in Ogita, Rump
// & Oishi, SIAM J. Sci. Comput. 26, 1955 (2005), "Dot2"): near contact the plain difference loses
// most of its digits to cancellation, and the collision time is proportional to it.
template <class V>
inline double compensated_gap2(const V& r, double sigma) {
  double s = -sigma * sigma;
  double comp = std::fma(-sigma, sigma, -s);
  for (int k = 0; k < r.size(); ++k) {
    const double p = r[k] * r[k];
    const double ep = std::fma(r[k], r[k], -p);
    const double t = s + p;
    const double z = t - s;
    comp += ((s - (t - z)) + (p - z)) + ep;
    s = t;
  }
  return s + comp;
}

// |r x v|^2 (2D: the scalar cross product squared).
template <class V>
inline double cross_norm2(const V& r, const V& v) {
  if constexpr (V::RowsAtCompileTime == 2) {
    const double z = r[0] * v[1] - r[1] * v[0];
    return z * z;
  } else {
    const double x = r[1] * v[2] - r[2] * v[1];
    const double y = r[2] * v[0] - r[0] * v[2];
    const double z = r[0] * v[1] - r[1] * v[0];
    return x * x + y * y + z * z;
  }
}

template <class V>
[[gnu::always_inline]] inline double pair_collision_time(const V& r, const V& v, double sigma, double limit = kNever) {
  const double b = r.dot(v);
  if (b >= 0.0) return kNever;  // receding or tangent: never an event
  double c = r.squaredNorm() - sigma * sigma;
  // Cheap rejection against the caller's current best: the root is at least c / (-2b)
  // (sqrt(disc) <= -b when c >= 0), so a pair that cannot beat `limit` costs no sqrt.
  if (c > 0.0 && c >= limit * (-2.0 * b)) return kNever;
  // Discriminant b^2 - v^2 c written as v^2 sigma^2 - |r x v|^2 (Lagrange's identity): the
  // direct form cancels catastrophically when the pair starts far apart.
  const double disc = v.squaredNorm() * sigma * sigma - cross_norm2(r, v);
  if (disc <= 0.0) return kNever;  // miss
  if (std::abs(c) < 0.0625 * sigma * sigma) c = compensated_gap2(r, sigma);
  const double t = c / (-b + std::sqrt(disc));
  return t > 0.0 ? t : 0.0;  // overlapping and approaching: now
}

// Earliest t >= 0 at which f(t) = d + v t + a t^2 / 2 reaches zero while decreasing (f' <= 0).
// d is a gap (distance to a wall minus radius, or to a cell face), v its rate of change, a its
// constant acceleration. d < 0 (round-off overlap) with v < 0 gives t = 0; with v >= 0 the event
// is the moment the gap starts to close again, if it ever does.
inline double gap_closing_time(double d, double v, double a) {
  if (d <= 0.0 && v < 0.0) return 0.0;
  if (a == 0.0) {
    if (v >= 0.0) return kNever;
    return d / (-v);
  }
  if (a < 0.0) {  // f is concave: the gap always closes eventually
    const double A = -a;
    const double disc = v * v + 2.0 * A * d;
    if (disc < 0.0) return v > 0.0 ? v / A : 0.0;  // overlap never opens: closes after the turn
    const double s = std::sqrt(disc);
    if (v < 0.0) return 2.0 * d / (s - v);  // stable form of (v + s) / A
    return (v + s) / A;
  }
  // a > 0: convex; closes only if moving in fast enough to reach zero before turning back
  if (v >= 0.0) return kNever;
  const double disc = v * v - 2.0 * a * d;
  if (disc < 0.0) return kNever;
  const double t = 2.0 * d / (-v + std::sqrt(disc));  // stable form of (-v - sqrt) / a
  return t > 0.0 ? t : 0.0;
}

// Time for a sphere (centre x, velocity v, radius R, acceleration g) to reach a plane wall
// through `point` with unit `normal` (particles live on the normal's side).
template <class V>
inline double wall_collision_time(const V& x, const V& v, const V& g, double R, const V& point,
                                  const V& normal) {
  const double d = (x - point).dot(normal) - R;
  return gap_closing_time(d, v.dot(normal), g.dot(normal));
}

// Earliest t >= 0 at which the gap to an oscillating plane,
//   g(t) = d + v t + a t^2 / 2 - An sin(omega (t0 + t)),
// reaches zero while closing, or kNever if that does not happen before `limit`. d, v and a are the
// gap to the plane's mean position (minus the radius), its rate and its constant acceleration at
// the absolute time t0; An is the amplitude's normal component, omega = 2 pi f. The round-off
// rules of gap_closing_time apply: g(0) <= 0 while closing is an event now (t = 0); g(0) <= 0
// while opening is not, and the event is the next time the gap closes (after it has opened, or
// when it turns while still closed).
// Method (safe bracketing): |g''| <= M = |a| + |An| omega^2, so from a point with gap g > 0 and
// rate r, g(t + s) lies between g + r s - M s^2 / 2 and g + r s + M s^2 / 2.
// 1. Outside the wall's band, g >= S(t) - |An| with S(t) = d + v t + a t^2 / 2: jump in closed form
//    to the time this envelope closes (kNever if it never does: no root).
// 2. Step to the first zero of the lower bound: no root can lie before it (conservative
//    advancement; it converges on a root from the open side and steps over a miss).
// 3. When r < 0 and the upper bound reaches zero at s_hi before the rate can turn (r^2 > 2 M g,
//    i.e. s_hi < |r| / M), g is strictly decreasing on [t, t + s_hi]: exactly one root, bracketed
//    by the zeros of the two bounds, refined by Illinois (contact/roots.hpp) down to the round-off
//    level of g. So no root between samples is skipped and the earliest one is returned.
// Returns the time reached after 100000 steps (a pathological near-tangency) rather than
// running on; a caller treats an event whose gap is still open as a checkpoint.
inline double oscillating_gap_closing_time(double d, double v, double a, double An, double omega, double t0,
                                           double limit = kNever) {
  if (An == 0.0 || omega == 0.0) {
    const double t = gap_closing_time(d, v, a);
    return t < limit ? t : kNever;
  }
  const double B = std::abs(An);
  const double M = std::abs(a) + B * omega * omega;
  auto gap = [&](double t) { return d + t * (v + 0.5 * a * t) - An * std::sin(omega * (t0 + t)); };
  constexpr double kEps = std::numeric_limits<double>::epsilon();
  double t = 0.0;
  int opening = 0;
  for (int it = 0; it < 100000; ++it) {
    // Smallest useful step: a few ulps of the absolute time (a dip shorter than this is M tmin^2/8
    // deep at most: round-off).
    const double tmin = 4.0 * kEps * (std::abs(t0) + t + 1.0 / omega);
    const double S = d + t * (v + 0.5 * a * t), Sd = v + a * t;
    if (S - B > 0.0) {  // 1. clear of the band
      const double te = gap_closing_time(S - B, Sd, a);
      if (te == kNever || !(t + te < limit)) return kNever;
      if (te > tmin) {
        t += te;
        continue;
      }
    }
    if (!(t < limit)) return kNever;
    const double ph = omega * (t0 + t);
    const double g = S - An * std::sin(ph);
    const double r = Sd - An * omega * std::cos(ph);
    if (g <= 0.0) {
      if (r < 0.0) return t;  // touching and closing: now
      // Touching and opening (round-off overlap after a collision): step while the rate cannot
      // turn negative (r - M s >= 0); the gap opens, or it turns while still closed (an event).
      if (r == 0.0 && a + An * omega * omega * std::sin(ph) < 0.0) return t;
      if (++opening > 10000) return t;
      t += std::max(r / M, tmin);
      continue;
    }
    opening = 0;
    const double h2 = 2.0 * M * g;
    if (r < 0.0 && r * r > h2) {  // 3. one root in [t + s_lo, t + s_hi]
      double lo = t + 2.0 * g / (-r + std::sqrt(r * r + h2));
      double hi = t + 2.0 * g / (-r + std::sqrt(r * r - h2));
      if (!(lo < limit)) return kNever;
      double glo = gap(lo), ghi = gap(hi);
      if (glo <= 0.0) {  // round-off: the root lies in [t, lo]
        hi = lo;
        ghi = glo;
        lo = t;
        glo = g;
      }
      if (ghi > 0.0) {  // round-off: the root lies at or just past hi
        if (!(hi > t)) return t;
        t = hi;
        continue;
      }
      // Stop at the round-off level of g: its terms' size, and the phase's error times |An|.
      const double ftol =
          kEps * (std::abs(d) + hi * (std::abs(v) + std::abs(a) * hi) + B * (1.0 + omega * (std::abs(t0) + hi)));
      double root = illinois_root(gap, lo, glo, hi, ghi, 0.0, 200, ftol);
      // Regula falsi stops when its point rounds onto an end of the bracket (one end's value tiny
      // against the other's), answering that end: finish such a stop by bisection.
      double groot = gap(root);
      if (groot < -ftol) {
        double blo = lo, bhi = root;
        for (int k = 0; k < 200; ++k) {
          const double m = 0.5 * (blo + bhi);
          if (!(m > blo && m < bhi)) break;
          const double gm = gap(m);
          if (gm > 0.0) blo = m;
          else bhi = m;
          if (std::abs(gm) <= ftol) {
            bhi = m;
            break;
          }
        }
        root = bhi;
      }
      return root < limit ? root : kNever;
    }
    // 2. safe step to the first zero of the lower bound g + r s - M s^2 / 2
    const double q = std::sqrt(r * r + h2);
    const double s = r >= 0.0 ? (r + q) / M : 2.0 * g / (q - r);
    t += std::max(s, tmin);
  }
  return t;
}

// Time for a sphere (centre x, velocity v, radius R, acceleration g, all at the absolute time t0)
// to reach a plane wall with unit `normal` whose point oscillates as
// p(t) = point + amplitude sin(omega t); see oscillating_gap_closing_time.
template <class V>
inline double moving_wall_collision_time(const V& x, const V& v, const V& g, double R, const V& point,
                                         const V& normal, const V& amplitude, double omega, double t0,
                                         double limit = kNever) {
  const double d = (x - point).dot(normal) - R;
  return oscillating_gap_closing_time(d, v.dot(normal), g.dot(normal), amplitude.dot(normal), omega, t0, limit);
}

// Time for a coordinate x (velocity v, acceleration a) to leave the slab [lo, hi]; `up` tells
// which face is crossed first.
inline double slab_exit_time(double x, double v, double a, double lo, double hi, bool& up) {
  const double t_up = gap_closing_time(hi - x, -v, -a);
  const double t_dn = gap_closing_time(x - lo, v, a);
  up = t_up < t_dn;
  return up ? t_up : t_dn;
}

}  // namespace matep

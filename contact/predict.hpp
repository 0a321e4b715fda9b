// Event-time prediction for hard particles: pair collisions (Allen & Tildesley, "Computer
// Simulation of Liquids", sec. 3.7), plane walls and cell boundaries under uniform gravity.
// All functions use the round-off-stable rule of Bannerman et al., Comput. Part. Mech. 1, 191
// (2014): an event exists only if the particles approach; an approaching pair that already
// overlaps collides now (t = 0); a receding one is never an event.
#pragma once

#include <cmath>
#include <limits>

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
inline double pair_collision_time(const V& r, const V& v, double sigma, double limit = kNever) {
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

// Time for a coordinate x (velocity v, acceleration a) to leave the slab [lo, hi]; `up` tells
// which face is crossed first.
inline double slab_exit_time(double x, double v, double a, double lo, double hi, bool& up) {
  const double t_up = gap_closing_time(hi - x, -v, -a);
  const double t_dn = gap_closing_time(x - lo, v, a);
  up = t_up < t_dn;
  return up ? t_up : t_dn;
}

}  // namespace matep

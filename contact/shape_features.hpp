// Impact times of the curved and bounded wall shapes (contact/cylinder.hpp, cone.hpp,
// plane_patch.hpp), feature by feature. A shape's surface is cut into features (a face, a
// lateral surface of revolution, a straight edge, a corner, a circular rim); a sphere of radius R
// touches a feature when its centre reaches the feature's offset surface at distance R:
//   corner (point):        a sphere,           |r|^2 - R^2 = 0
//   edge (line):           a cylinder,         |r_perp|^2 - R^2 = 0
//   face (plane):          two planes,         r.n = +-R
//   lateral cone / tube:   two coaxial cones,  rho^2 - (c + k z)^2 = 0  (rho = c + k z, c = r1 +- R l/L)
//   rim (circle, radius A): a torus,           (|r|^2 + A^2 - R^2)^2 - 4 A^2 rho^2 = 0
// (ray-sphere, ray-cylinder, ray-cone and ray-torus intersections of ray tracing, e.g. Glassner
// ed., "An Introduction to Ray Tracing", 1989, ch. 2; the torus quartic is the classical implicit
// form of the torus). Along a flight r(t) = r0 + v t + g t^2 / 2 every coordinate is quadratic in
// t, so each offset equation is a polynomial of degree 2 (point, line, cone; straight flight), 4
// (the same under gravity; torus, straight) or 8 (torus under gravity), with the sign chosen so
// that it is > 0 while the sphere is clear of the feature: solved by earliest_closing
// (contact/poly.hpp) for points, lines, faces and infinite cylinders; for rims and finite lateral
// surfaces it only cuts time into monotone pieces and the feature's distance decides
// (closing_on_pieces below). A root counts only where the feature is real: the foot point on the
// finite part of a line or cone, the side of a thin sheet the particle is on. The shape's impact time is the earliest
// accepted root over its features: the first touch of the whole surface is a touch of one of its
// features at a point of that feature's valid region, so none is skipped.
// now_ok: whether a closing at t = 0 may count. The shapes decide "now" on their own gap (an
// approaching particle within round-off of the surface) and pass now_ok = whether the particle
// approaches the nearest surface point: a feature whose polynomial is <= 0 at t = 0 by round-off
// while the particle leaves the surface is no event (the engine would find no normal speed to
// reverse, and predict the same event again).
#pragma once

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>

#include "contact/poly.hpp"
#include "contact/predict.hpp"
#include "contact/vec.hpp"
#include "contact/wall.hpp"

namespace matep {

// A ballistic or parabolic flight relative to a reference point: r(t) = r0 + r1 t + r2 t^2,
// r1 = v, r2 = g / 2.
template <int D>
struct Flight {
  Vec<D> r0, r1, r2;
  Flight(const Vec<D>& x, const Vec<D>& v, const Vec<D>& g, const Vec<D>& origin)
      : r0(x - origin), r1(v), r2(0.5 * g) {}
  Vec<D> at(double t) const { return r0 + t * (r1 + t * r2); }
  bool straight() const { return r2.squaredNorm() == 0.0; }
  // Along unit e: the scalar quadratic r(t).e.
  Poly along(const Vec<D>& e) const {
    Poly p{r0.dot(e), r1.dot(e), r2.dot(e)};
    return p;
  }
  // The part perpendicular to unit e (e = 0: the whole vector).
  Flight perp(const Vec<D>& e) const {
    Flight f = *this;
    f.r0 -= r0.dot(e) * e;
    f.r1 -= r1.dot(e) * e;
    f.r2 -= r2.dot(e) * e;
    return f;
  }
  // |r(t)|^2, degree 4 (2 for a straight flight).
  Poly norm2() const {
    Poly p{r0.squaredNorm(), 2.0 * r0.dot(r1), r1.squaredNorm() + 2.0 * r0.dot(r2), 2.0 * r1.dot(r2),
           r2.squaredNorm()};
    p.trim();
    return p;
  }

 private:
  Flight() = default;
};

// Whether a particle at a contact with normal n closes on it now: normal speed < 0, or at rest
// normally with gravity pressing it in (gap_closing_time's d <= 0 rules).
template <int D>
bool closing_now(const Vec<D>& v, const Vec<D>& g, const Vec<D>& n) {
  const double vn = v.dot(n);
  return vn < 0.0 || (vn == 0.0 && g.dot(n) < 0.0);
}

// The earliest closing of a feature decided on its direct gap h(t) (distance minus R, computed from
// the position at t), with the polynomial p (same roots, same sign) used only to cut [0, limit] into
// pieces on which p is monotone (contact/poly.hpp), hence holds at most one root of h. Needed where
// p is a product whose second factor can vanish too: the rim torus (d_near^2 - R^2)(d_far^2 - R^2)
// for a path near the axis of a rim no wider than the particle, the lateral cone
// (rho - c - k z)(rho + c + k z) near the apex of its offset. There p's values near a touch are
// products of two small numbers, below p's round-off, while h resolves them; a root of p where h
// is clearly open (a spurious root of the rounded p) is not taken. On each piece [a, b]:
//  * h(a) <= 0 and p falls over the piece (the gap already closed and closing; t = 0 only with now_ok),
//  * h(a) > 0 >= h(b): the root, by safeguarded Illinois on h (safe_root),
//  * h(a), h(b) > 0 but b a local minimum of p within p's round-off of zero (a grazing dip that p
//    cannot resolve): a golden-section search for h's minimum over the two pieces around b, then
//    the root before it if it dips to <= 0.
// valid(t): the feature exists at the touch (foot point on the finite part).
template <class H, class Valid>
double closing_on_pieces(Poly p, H&& h, Valid&& valid, double limit, bool now_ok) {
  p.trim();
  if (p.n == 0) return kNever;
  const double hi = std::min(limit, root_bound(p) * 1.0000001 + 1e-300);
  if (!(hi > 0.0)) return kNever;
  double e[Poly::kMax + 2];
  e[0] = 0.0;
  const int m = poly_detail::sign_changes(p.derivative(), 0.0, hi, e + 1);
  e[m + 1] = hi;
  auto bisect = [&](double a, double b) {  // h(a) > 0 >= h(b): safeguarded Illinois (poly.hpp)
    return safe_root(h, a, h(a), b, h(b));
  };
  auto roundoff = [&](double t) {  // p's evaluation error bound at t, with a margin
    double s = 0.0, tk = 1.0;
    for (int k = 0; k <= p.n; ++k, tk *= std::abs(t)) s += std::abs(p.c[k]) * tk;
    return 1024.0 * std::numeric_limits<double>::epsilon() * s;
  };
  const Poly dp = p.derivative();
  double ha = h(0.0);
  for (int i = 0; i <= m; ++i) {
    const double a = e[i], b = e[i + 1];
    const double hb = h(b);
    if (ha <= 0.0) {
      // Closed at a: an event if the piece closes further (p' < 0 inside: the sign of the slope
      // from the polynomial, not from h's round-off noise around zero).
      if (dp(0.5 * (a + b)) < 0.0 && (a > 0.0 || now_ok) && valid(a)) return a;
    } else if (hb <= 0.0) {
      const double r = bisect(a, b);
      if (valid(r)) return r;
    } else if (i < m && dp(0.5 * (a + b)) < 0.0 && std::abs(p(b)) <= roundoff(b)) {
      // b is a local minimum of p within its round-off of zero: search the two pieces around it.
      double lo = a, up = e[i + 2];
      const double g = 0.6180339887498949;
      double c = up - g * (up - lo), d = lo + g * (up - lo), hc = h(c), hd = h(d);
      for (int k = 0; k < 120 && hc > 0.0 && hd > 0.0; ++k) {
        if (hc < hd) {
          up = d;
          d = c;
          hd = hc;
          c = up - g * (up - lo);
          hc = h(c);
        } else {
          lo = c;
          c = d;
          hc = hd;
          d = lo + g * (up - lo);
          hd = h(d);
        }
        if (!(c < d)) break;
      }
      const double tm = hc <= 0.0 ? c : (hd <= 0.0 ? d : kNever);
      if (tm < kNever) {
        const double r = bisect(a, tm);
        if (valid(r)) return r;
      }
    }
    ha = hb;
  }
  return kNever;
}

// Whether a particle whose gap is `gap` cannot reach the surface before `limit`: the gap of these
// shapes is a distance (minus R), so it changes no faster than the centre moves, and the centre
// moves at most |v| t + |g| t^2 / 2 in a time t. A cheap rejection before any root search.
template <int D>
bool out_of_reach(double gap, const Vec<D>& v, const Vec<D>& g, double limit) {
  if (!(limit < kNever)) return false;
  return gap > limit * (v.norm() + 0.5 * g.norm() * limit) * (1.0 + 1e-12);
}

// The times [t_in, t_out] of the first stay of the flight x + v t + g t^2 / 2 (t >= 0) in the box
// [lo - pad, hi + pad]; false if it never enters (t_out = kNever: it never leaves). A crossing so
// soon that the centre has moved less than 1e-9 pad counts as at t = 0 (a particle on the box's
// face): the intervals' midpoints decide whether it enters or leaves. Shapes whose impact search
// is local (contact/mesh.hpp, rotating.hpp) start at the entry and stop at the exit.
template <int D>
bool flight_box_window(const Vec<D>& x, const Vec<D>& v, const Vec<D>& g, const Vec<D>& lo, const Vec<D>& hi,
                       double pad, double& t_in, double& t_out) {
  double cand[4 * D + 1];
  int nc = 0;
  cand[nc++] = 0.0;
  const double sv = v.norm(), sg = g.norm();
  auto add = [&](double r) {
    if (r > 0.0 && r * (sv + 0.5 * sg * r) > 1e-9 * pad) cand[nc++] = r;
  };
  for (int k = 0; k < D; ++k)
    for (const double b : {lo[k] - pad, hi[k] + pad}) {
      // a t^2 + b1 t + c0 = 0, a = g / 2, b1 = v, c0 = x - b (the stable quadratic formula)
      const double a = 0.5 * g[k], b1 = v[k], c0 = x[k] - b;
      if (a == 0.0) {
        if (b1 != 0.0) add(-c0 / b1);
        continue;
      }
      const double disc = b1 * b1 - 4.0 * a * c0;
      if (disc < 0.0) continue;
      const double q = -0.5 * (b1 + std::copysign(std::sqrt(disc), b1));
      add(q / a);
      if (q != 0.0) add(c0 / q);
    }
  for (int i = 1; i < nc; ++i)  // insertion sort (a handful)
    for (int j = i; j > 0 && cand[j] < cand[j - 1]; --j) std::swap(cand[j], cand[j - 1]);
  auto in_box = [&](double t) {
    const Vec<D> p = x + t * v + (0.5 * t * t) * g;
    return ((p.array() >= lo.array() - pad) && (p.array() <= hi.array() + pad)).all();
  };
  bool found = false;
  for (int i = 0; i < nc; ++i) {
    const double a = cand[i], b = i + 1 < nc ? cand[i + 1] : kNever;
    const bool inside = in_box(b < kNever ? 0.5 * (a + b) : 2.0 * a + 1.0);
    if (inside && !found) {
      found = true;
      t_in = a;
    }
    if (!inside && found) {
      t_out = a;
      return true;
    }
  }
  if (found) t_out = kNever;
  return found;
}

namespace feature {

// The earliest closing time of a point feature (a corner, the apex of a cone, the end of a 2D
// segment) at the origin of f: |r|^2 - R^2.
template <int D>
double point(const Flight<D>& f, double R, double limit, bool now_ok) {
  return earliest_closing(f.norm2() - Poly{R * R}, limit, [&](double t) { return t > 0.0 || now_ok; });
}

// A straight edge along unit e through the origin of f, from s = lo to s = hi along e: the
// offset cylinder |r_perp|^2 - R^2, a root counting only if its foot point lies on the edge.
template <int D>
double edge(const Flight<D>& f, const Vec<D>& e, double lo, double hi, double R, double limit, bool now_ok) {
  const Flight<D> fp = f.perp(e);
  return earliest_closing(fp.norm2() - Poly{R * R}, limit, [&](double t) {
    if (t == 0.0 && !now_ok) return false;
    const double s = f.at(t).dot(e);
    return s >= lo && s <= hi;
  });
}

// A face through the origin of f with unit normal n, touched from the side `side` (+1: the side
// n points to; -1 the other): side r.n - R, a root counting only if in_region(r(t)) (the foot point
// on the finite part of the face) and the particle is on that side.
template <int D, class Region>
double face(const Flight<D>& f, const Vec<D>& n, int side, double R, double limit, bool now_ok,
            Region&& in_region) {
  const Poly p = f.along(n) * static_cast<double>(side) - Poly{R};
  return earliest_closing(p, limit, [&](double t) {
    if (t == 0.0 && !now_ok) return false;
    const Vec<D> r = f.at(t);
    return side * r.dot(n) >= 0.0 && in_region(r);
  });
}

// A circle of radius A around the origin of f in the plane perpendicular to unit n (in 2D: the two
// points +-A along the in-plane direction perpendicular to n): the offset torus
// (|r|^2 + A^2 - R^2)^2 - 4 A^2 rho^2, rho^2 = |r_perp|^2. It equals
// (d_near^2 - R^2)(d_far^2 - R^2) with d_near <= d_far the distances to the nearest and the
// farthest point of the circle in the particle's meridian plane: > 0 while the sphere is clear of
// the circle. It isolates; the distance to the circle decides (closing_on_pieces), since near the
// axis of a circle no wider than the sphere both factors are small.
template <int D>
double rim(const Flight<D>& f, const Vec<D>& n, double A, double R, double limit, bool now_ok) {
  const Poly r2 = f.norm2();
  const Poly rho2 = f.perp(n).norm2();
  const Poly q = r2 + Poly{A * A - R * R};
  auto h = [&](double t) {  // the distance to the circle minus R
    const Vec<D> r = f.at(t);
    const double z = r.dot(n);
    return std::hypot((r - z * n).norm() - A, z) - R;
  };
  return closing_on_pieces(q * q - rho2 * (4.0 * A * A), h, [](double) { return true; }, limit, now_ok);
}

// The lateral surface of a frustum: the surface of revolution about unit axis a (through the
// origin of f) of the segment from (z, rho) = (0, r1) to (L, r2) in the meridian half-plane.
// Its offsets at distance R are the cones rho = c + k z, k = (r2 - r1) / L, c = r1 + side R l / L
// (l = sqrt(L^2 + (r2 - r1)^2); side +1 outside, -1 inside). The polynomial side (rho^2 - (c + k z)^2)
// isolates, the signed distance sigma from the generator line decides (closing_on_pieces): a touch
// counts with the foot point on the segment (0 <= tau <= 1, which also keeps it off the other nappe)
// and the particle on that side (side sigma >= 0). L = infinity (k = 0): an infinite cylinder of
// radius r1 (no region). 2D: the two segments mirrored about the axis, rho = |the coordinate across
// the axis|.
// one_sided: an infinite cylinder with grains on one side only: every root counts (a particle on
// the wrong side overlaps, by the signed-gap convention).
template <int D>
double lateral(const Flight<D>& f, const Vec<D>& a, double r1, double r2, double L, int side, double R, double limit,
               bool now_ok, bool one_sided = false) {
  const bool infinite = !(L < std::numeric_limits<double>::infinity());
  const double dr = infinite ? 0.0 : r2 - r1;
  const double k = infinite ? 0.0 : dr / L;
  const double ell_over_L = infinite ? 1.0 : std::sqrt(L * L + dr * dr) / L;
  const double c = r1 + side * R * ell_over_L;
  if (side < 0 && infinite && c <= 0.0) return kNever;  // the particle does not fit inside
  const Poly z = f.along(a);
  const Poly rho2 = f.perp(a).norm2();
  const Poly cz = Poly{c} + z * k;
  const Poly p = (rho2 - cz * cz) * static_cast<double>(side);
  if (one_sided) return earliest_closing(p, limit, [&](double t) { return t > 0.0 || now_ok; });
  const double ell = std::sqrt(L * L + dr * dr);
  // Meridian coordinates at t: the foot parameter tau on the generator and the signed distance sigma
  // from the generator line (> 0 outside).
  auto meridian = [&](double t, double& tau, double& sigma) {
    const Vec<D> r = f.at(t);
    const double zt = r.dot(a);
    const double rho = (r - zt * a).norm();
    tau = (zt * L + (rho - r1) * dr) / (ell * ell);
    sigma = (L * (rho - r1) - dr * zt) / ell;
  };
  auto h = [&](double t) {  // distance from the offset line on this side (> 0: clear of it)
    double tau, sigma;
    meridian(t, tau, sigma);
    return side * sigma - R;
  };
  auto valid = [&](double t) {  // the foot point on the segment, the particle on this side
    double tau, sigma;
    meridian(t, tau, sigma);
    return tau >= 0.0 && tau <= 1.0 && side * sigma >= 0.0;
  };
  return closing_on_pieces(p, h, valid, limit, now_ok);
}

}  // namespace feature

// The meridian foot of x - p on the segment (0, r1)-(L, r2) of a surface of revolution (z along unit
// a, rho >= 0 across; revolved_segment_point below), in the precision T of r: the unit w across
// the axis in r's meridian half-plane, the foot's axial and radial coordinates zf, rf, and x's
// offsets dz, dp from it. Returns the distance hypot(dz, dp).
template <class T, int D>
T revolved_segment_foot(const Eigen::Matrix<T, D, 1>& r, const Vec<D>& a_d, double r1_d, double r2_d, double L_d,
                        Eigen::Matrix<T, D, 1>& w, T& zf, T& rf, T& dz, T& dp) {
  using VT = Eigen::Matrix<T, D, 1>;
  const VT a = a_d.template cast<T>();
  const T r1 = r1_d, r2 = r2_d, L = L_d;
  const T z = r.dot(a);
  w = r - z * a;
  const T rho = w.norm();
  if (rho > T(0)) {
    w /= rho;
  } else {  // on the axis: any direction across it
    VT e = VT::Zero();
    e[std::abs(a[0]) < T(0.9) ? 0 : 1] = T(1);
    w = (e - e.dot(a) * a).normalized();
  }
  const T dr = r2 - r1, ell2 = L * L + dr * dr;
  T tau = (z * L + (rho - r1) * dr) / ell2;
  tau = std::clamp(tau, T(0), T(1));
  zf = tau * L;
  rf = r1 + tau * dr;
  dz = z - zf;
  dp = rho - rf;
  return std::hypot(dz, dp);
}

// The nearest point of a surface of revolution generated by the segment (0, r1)-(L, r2) of the
// meridian half-plane (z along unit a from p, rho >= 0 across): a finite tube (r1 = r2) or a
// frustum (contact/cone.hpp). In the meridian half-plane of x the nearest point of the surface is
// the nearest point of the segment (the surface is symmetric about the axis). Returns the gap and
// normal for radius R and fills q, the contact point. On the axis any meridian plane will do.
template <int D>
WallPoint<D> revolved_segment_point(const Vec<D>& p, const Vec<D>& a, double r1, double r2, double L,
                                    const Vec<D>& x, double R, Vec<D>& q) {
  Vec<D> w;
  double zf, rf, dz, dp;
  const double dist = revolved_segment_foot<double, D>(Vec<D>(x - p), a, r1, r2, L, w, zf, rf, dz, dp);
  q = p + zf * a + rf * w;
  WallPoint<D> out;
  out.gap = dist - R;
  if (dist > 0.0) {
    out.normal = (dz / dist) * a + (dp / dist) * w;
  } else {  // the centre on the sheet: the outward meridian normal of the generator
    const double dr = r2 - r1, ell = std::sqrt(L * L + dr * dr);
    out.normal = (-dr / ell) * a + (L / ell) * w;
  }
  return out;
}

// Extended precision (long double: a 64-bit significand on x86-64) for the last step of an
// impact time on a curved wall. At a grazing touch the gap closes slowly (its rate is
// ~sqrt(2 kappa depth) for a path dipping `depth` past a surface of curvature kappa: 1e-5 to
// 1e-7 of the speed at 1e-9 R), so the double gap's round-off (~1e-16) would move the root by up
// to ~1e-9 relative; the same gap in long double moves it by ~1e-12. Position of the flight at s
// relative to `origin`, x + s v + s^2 g / 2 - origin, in long double.
template <int D>
using VecX = Eigen::Matrix<long double, D, 1>;
template <int D>
VecX<D> flight_point_x(const Vec<D>& x, const Vec<D>& v, const Vec<D>& g, double s, const Vec<D>& origin) {
  const long double S = s;
  return VecX<D>(x.template cast<long double>() - origin.template cast<long double>() +
                 S * (v.template cast<long double>() + (0.5L * S) * g.template cast<long double>()));
}

// revolved_segment_point's gap for the flight's position at s, in long double.
template <int D>
long double revolved_segment_gap_x(const Vec<D>& p, const Vec<D>& a, double r1, double r2, double L,
                                   const Vec<D>& x, const Vec<D>& v, const Vec<D>& g, double s, double R) {
  VecX<D> w;
  long double zf, rf, dz, dp;
  return revolved_segment_foot<long double, D>(flight_point_x<D>(x, v, g, s, p), a, r1, r2, L, w, zf, rf, dz, dp) -
         static_cast<long double>(R);
}

// Moves an impact time t found on a feature's polynomial onto the shape's own gap function
// gap(t) (the one the engines evaluate, from WallShape::at, or the same in long double: see
// flight_point_x) to round-off: a bracket
// [a, b] with gap(a) > 0 >= gap(b) is searched within a relative 1e-6 of t, by steps doubling
// from a few ulps, then narrowed to one ulp (safe_root). Where none is found (a start-of-interval
// event with the gap already closed, or a tangent touch that the direct gap sees as a round-off
// miss), t is kept.
template <class Gap>
double refine_on_gap(Gap&& gap, double t) {
  if (!(t > 0.0) || !std::isfinite(t)) return t;
  constexpr double eps = std::numeric_limits<double>::epsilon();
  const double span = 1e-6 * t;
  double a, b;
  const double gt = gap(t);
  if (gt > 0.0) {
    a = t;
    b = t;
    bool found = false;
    for (double d = 4.0 * eps * t; d <= span; d *= 2.0) {
      b = t + d;
      if (gap(b) <= 0.0) {
        found = true;
        break;
      }
      a = b;
    }
    if (!found) return t;
  } else {
    b = t;
    a = t;
    bool found = false;
    for (double d = 4.0 * eps * t; d <= span; d *= 2.0) {
      a = std::max(0.0, t - d);
      if (gap(a) > 0.0) {
        found = true;
        break;
      }
      b = a;
      if (a == 0.0) break;
    }
    if (!found) return t;
  }
  return safe_root(gap, a, gap(a), b, gap(b));
}

}  // namespace matep

// The cone wall (a hopper, a funnel, a conical drum): WallShape<D> (contact/wall.hpp).
//   ConeWall<D>(point, axis, r1, r2, length, omega = 0)
// A frustum: the axis passes through `point` along the unit vector `axis`; the surface has radius
// r1 at `point` and r2 at point + length axis, length > 0, r1, r2 >= 0 and not both 0 (r1 = r2 is
// an open tube; one radius 0 is a full cone whose apex is a point of the surface). A hopper with
// its outlet at `point`: r1 < r2 with axis up; or r1 > r2 with axis down. Always finite, a thin
// sheet touched from both sides: gap = the distance from the sphere's centre to the nearest point
// of the surface (lateral surface and end circles) minus R, normal from that point towards the
// centre. 2D: the axial section, two segments from point +- r1 w to point + length axis +- r2 w
// (w across the axis), mirror images about the axis, touched from both sides.
// omega: a rotation about the own axis (AxisRotation, right-handed about `axis`; 2D: about the
// plane's normal through `point`): the geometry does not change, the surface at the contact point
// q moves at omega axis x (q - point).
// Impact times (contact/shape_features.hpp): the lateral offsets are cones again,
// rho = r1 + k z +- R l / L (k = (r2 - r1) / L, l the generator's length): quadratic in t for a
// straight flight, quartic under gravity; the rims are offset tori (quartic / octic; a zero-radius
// end and the 2D segment ends are points: quadratic / quartic); roots are taken only where the
// foot point lies on the generator and on the right nappe, the earliest one refined on the gap
// of at() evaluated in long double.
// bracketed() is true: the engine passes its earliest event so far as the limit, and a flight that
// cannot reach the surface before it (gap > |v| limit + |g| limit^2 / 2) costs one at() call.
#pragma once

#include <fmt/format.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "contact/predict.hpp"
#include "contact/shape_features.hpp"
#include "contact/wall.hpp"

namespace matep {

template <int D>
class ConeWall final : public WallShape<D> {
 public:
  ConeWall(const Vec<D>& point, const Vec<D>& axis, double r1, double r2, double length, double omega = 0.0)
      : point_(point), r1_(r1), r2_(r2), length_(length) {
    if (!(length > 0.0) || !std::isfinite(length)) throw std::invalid_argument("cone: length must be finite and > 0");
    if (!(r1 >= 0.0) || !(r2 >= 0.0) || !(r1 + r2 > 0.0))
      throw std::invalid_argument("cone: radii must be >= 0 and not both 0");
    const double n = axis.norm();
    if (!(n > 0.0)) throw std::invalid_argument("cone: axis must be a nonzero vector");
    axis_ = axis / n;
    rot_.point = point_;
    rot_.axis = axis_;
    rot_.omega = omega;
  }

  const Vec<D>& point() const { return point_; }
  const Vec<D>& axis() const { return axis_; }
  double r1() const { return r1_; }
  double r2() const { return r2_; }
  double length() const { return length_; }
  double omega() const { return rot_.omega; }
  Vec<D> end() const { return point_ + length_ * axis_; }

  const char* kind() const override { return "cone"; }
  std::string describe() const override {
    std::string s = fmt::format("cone from ({}) radius {} to ({}) radius {} (touched from both sides)",
                                fmt::join(point_, ", "), r1_, fmt::join(end(), ", "), r2_);
    if (rot_.active()) s += fmt::format(", rotating at {} rad/s about its axis", rot_.omega);
    return s;
  }

  WallPoint<D> at(const Vec<D>& x, double R, double) const override {
    Vec<D> q;
    WallPoint<D> c = revolved_segment_point<D>(point_, axis_, r1_, r2_, length_, x, R, q);
    if (rot_.active()) c.velocity = rot_.velocity(q);
    return c;
  }

  double impact_time(const Vec<D>& x, const Vec<D>& v, const Vec<D>& g, double R, double,
                     double limit) const override {
    // Now: an approaching particle within round-off of the surface. (The rotation's surface velocity
    // is normal to every contact normal: both lie in / across the meridian plane.)
    const WallPoint<D> c0 = at(x, R, 0.0);
    const bool approaching = closing_now(v, g, c0.normal);
    if (c0.gap <= 0.0 && approaching) return 0.0;
    if (out_of_reach(c0.gap, v, g, limit)) return kNever;
    const Flight<D> f(x, v, g, point_);
    double t = std::min(feature::lateral(f, axis_, r1_, r2_, length_, -1, R, limit, approaching),
                        feature::lateral(f, axis_, r1_, r2_, length_, +1, R, limit, approaching));
    t = std::min(t, end_time(f, r1_, R, std::min(t, limit), approaching));
    const Flight<D> f1(x, v, g, end());
    t = std::min(t, end_time(f1, r2_, R, std::min(t, limit), approaching));
    if (!(t < limit)) return kNever;
    // The root on the gap in long double (flight_point_x: grazing touches of the curved surface).
    t = refine_on_gap(
        [&](double s) { return revolved_segment_gap_x<D>(point_, axis_, r1_, r2_, length_, x, v, g, s, R); }, t);
    return t < limit ? t : kNever;
  }

  double max_speed() const override { return std::abs(rot_.omega) * std::max(r1_, r2_); }
  Spin<D> spin() const override { return rot_.spin(); }
  bool moving() const override { return rot_.active(); }
  // The engine passes the earliest event found so far as `limit`: most flights are rejected by
  // out_of_reach without a root search.
  bool bracketed() const override { return true; }
  bool bounds(Vec<D>& lo, Vec<D>& hi) const override {
    const Vec<D> p1 = end();
    for (int k = 0; k < D; ++k) {
      const double s = std::sqrt(std::max(0.0, 1.0 - axis_[k] * axis_[k]));
      lo[k] = std::min(point_[k] - r1_ * s, p1[k] - r2_ * s);
      hi[k] = std::max(point_[k] + r1_ * s, p1[k] + r2_ * s);
    }
    return true;
  }
  // The rims (or the apex) give every direction.
  bool has_normal(const Vec<D>& n, double tol) const override { return std::abs(n.norm() - 1.0) <= tol; }

 Vec<D> anchor() const override { return point_; }
  void tessellate(double, const Vec<D>&, const Vec<D>&, SurfaceMesh& out) const override {
    revolve_band<D>(point_, axis_, r1_, r2_, 0.0, length_, out);
  }

 private:
  // The end circle of radius A around the origin of f (a torus; a point when A = 0; two points in 2D).
  double end_time(const Flight<D>& f, double A, double R, double limit, bool now_ok) const {
    if (A == 0.0) return feature::point(f, R, limit, now_ok);
    if constexpr (D == 2) {
      const Vec<D> w(-axis_[1], axis_[0]);
      Flight<D> fa = f, fb = f;
      fa.r0 -= A * w;
      fb.r0 += A * w;
      return std::min(feature::point(fa, R, limit, now_ok), feature::point(fb, R, limit, now_ok));
    } else {
      return feature::rim(f, axis_, A, R, limit, now_ok);
    }
  }

  Vec<D> point_, axis_;
  double r1_ = 0.0, r2_ = 0.0, length_ = 0.0;
  AxisRotation<D> rot_;
};

}  // namespace matep

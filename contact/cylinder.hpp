// The cylinder wall (a drum, a pipe, a tube): WallShape<D> (contact/wall.hpp).
//   CylinderWall<D>(point, axis, radius, length = 0, inside = true, omega = 0)
// 3D: the axis passes through `point` along the unit vector `axis`; `radius` > 0.
//  * length <= 0 or infinity: an infinite cylinder, one-sided: the grains live inside
//    (inside = true) or outside (false) and the gap is signed (a grain on the wrong side has a
//    negative gap, an overlap): inside, gap = radius - rho - R with rho the distance from the axis.
//  * length > 0: an open tube from `point` to point + length axis, a thin sheet touched from both
//    sides (`inside` is ignored): gap = the distance from the sphere's centre to the nearest point
//    of the finite surface (lateral surface and end circles) minus R, normal from that point
//    towards the centre.
// 2D: a circle of radius `radius` around `point` (axis and length unused: length must be <= 0),
//    one-sided, grains inside or outside.
// omega: a rotation about the cylinder's own axis (2D: about the centre) at omega rad/s,
// right-handed about `axis` (AxisRotation): the geometry does not change, the surface at the
// contact point q moves at omega axis x (q - point).
// Impact times (contact/shape_features.hpp): the lateral offset cylinder (rho = radius -+ R) is a
// quadratic in t for a straight flight and a quartic under gravity; the rims of a tube are offset
// tori (quartic, octic under gravity); roots are taken only where the foot point lies on the tube
// (0 <= z <= length), and the earliest one is refined on the gap of at() evaluated in long double.
// bracketed() is true: the engine passes its earliest event so far as the limit, and a flight that
// cannot reach the surface before it (gap > |v| limit + |g| limit^2 / 2) costs one at() call.
#pragma once

#include <fmt/format.h>

#include <Eigen/Geometry>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "contact/predict.hpp"
#include "contact/shape_features.hpp"
#include "contact/wall.hpp"

namespace matep {

template <int D>
class CylinderWall final : public WallShape<D> {
 public:
  CylinderWall(const Vec<D>& point, const Vec<D>& axis, double radius, double length = 0.0, bool inside = true,
               double omega = 0.0)
      : point_(point), radius_(radius), inside_(inside) {
    if (!(radius > 0.0)) throw std::invalid_argument("cylinder: radius must be > 0");
    finite_ = length > 0.0 && std::isfinite(length);
    length_ = finite_ ? length : std::numeric_limits<double>::infinity();
    if constexpr (D == 2) {
      if (finite_) throw std::invalid_argument("cylinder: a 2D cylinder is a full circle (length must be <= 0)");
      axis_ = Vec<D>::Zero();  // every coordinate lies across the "axis"
    } else {
      const double n = axis.norm();
      if (!(n > 0.0)) throw std::invalid_argument("cylinder: axis must be a nonzero vector");
      axis_ = axis / n;
    }
    rot_.point = point_;
    rot_.axis = axis_;
    rot_.omega = omega;
  }

  const Vec<D>& point() const { return point_; }
  const Vec<D>& axis() const { return axis_; }
  double radius() const { return radius_; }
  double length() const { return length_; }  // infinity when infinite
  bool finite() const { return finite_; }
  bool inside() const { return inside_; }
  double omega() const { return rot_.omega; }

  const char* kind() const override { return "cylinder"; }
  std::string describe() const override {
    std::string s;
    if constexpr (D == 2) {
      s = fmt::format("circle around ({}) of radius {}, grains {}", fmt::join(point_, ", "), radius_,
                      inside_ ? "inside" : "outside");
    } else if (finite_) {
      s = fmt::format("open tube from ({}) along ({}) of radius {} and length {} (touched from both sides)",
                      fmt::join(point_, ", "), fmt::join(axis_, ", "), radius_, length_);
    } else {
      s = fmt::format("infinite cylinder through ({}) along ({}) of radius {}, grains {}", fmt::join(point_, ", "),
                      fmt::join(axis_, ", "), radius_, inside_ ? "inside" : "outside");
    }
    if (rot_.active()) s += fmt::format(", rotating at {} rad/s about its axis", rot_.omega);
    return s;
  }

  WallPoint<D> at(const Vec<D>& x, double R, double) const override {
    Vec<D> q;
    WallPoint<D> c;
    if (finite_) {
      c = revolved_segment_point<D>(point_, axis_, radius_, radius_, length_, x, R, q);
    } else {
      const Vec<D> r = x - point_;
      const double z = r.dot(axis_);
      Vec<D> w = r - z * axis_;
      const double rho = w.norm();
      if (rho > 0.0) {
        w /= rho;
      } else {
        Vec<D> e = Vec<D>::Zero();
        e[D == 3 && std::abs(axis_[0]) >= 0.9 ? 1 : 0] = 1.0;
        w = (e - e.dot(axis_) * axis_).normalized();
      }
      q = point_ + z * axis_ + radius_ * w;
      c.gap = inside_ ? radius_ - rho - R : rho - radius_ - R;
      c.normal = inside_ ? Vec<D>(-w) : w;
    }
    if (rot_.active()) c.velocity = rot_.velocity(q);
    return c;
  }

  double impact_time(const Vec<D>& x, const Vec<D>& v, const Vec<D>& g, double R, double,
                     double limit) const override {
    // Now: an approaching particle that touches or overlaps (round-off after a collision).
    // (The rotation is about the axis: the surface velocity is normal to every contact normal.)
    const WallPoint<D> c0 = at(x, R, 0.0);
    const bool approaching = closing_now(v, g, c0.normal);
    if (c0.gap <= 0.0 && approaching) return 0.0;
    if (out_of_reach(c0.gap, v, g, limit)) return kNever;
    const Flight<D> f(x, v, g, point_);
    double t;
    if (!finite_) {
      t = feature::lateral(f, axis_, radius_, radius_, length_, inside_ ? -1 : 1, R, limit, approaching,
                           /*one_sided=*/true);
    } else {
      t = std::min(feature::lateral(f, axis_, radius_, radius_, length_, -1, R, limit, approaching),
                   feature::lateral(f, axis_, radius_, radius_, length_, +1, R, limit, approaching));
      t = std::min(t, feature::rim(f, axis_, radius_, R, std::min(t, limit), approaching));
      const Flight<D> f1(x, v, g, Vec<D>(point_ + length_ * axis_));
      t = std::min(t, feature::rim(f1, axis_, radius_, R, std::min(t, limit), approaching));
    }
    if (!(t < limit)) return kNever;
    // The root on the gap in long double (flight_point_x: grazing touches of the curved surface).
    t = refine_on_gap(
        [&](double s) {
          if (finite_) return revolved_segment_gap_x<D>(point_, axis_, radius_, radius_, length_, x, v, g, s, R);
          const VecX<D> r = flight_point_x<D>(x, v, g, s, point_), a = axis_.template cast<long double>();
          const long double rho = VecX<D>(r - r.dot(a) * a).norm(), Rc = radius_;
          return (inside_ ? Rc - rho : rho - Rc) - static_cast<long double>(R);
        },
        t);
    return t < limit ? t : kNever;
  }

  double max_speed() const override { return std::abs(rot_.omega) * radius_; }
  Spin<D> spin() const override { return rot_.spin(); }
  bool moving() const override { return rot_.active(); }
  // The engine passes the earliest event found so far as `limit`: most flights are rejected by
  // out_of_reach without a root search.
  bool bracketed() const override { return true; }
  bool bounds(Vec<D>& lo, Vec<D>& hi) const override {
    if (!finite_) return false;
    const Vec<D> p1 = point_ + length_ * axis_;
    for (int k = 0; k < D; ++k) {
      const double ext = radius_ * std::sqrt(std::max(0.0, 1.0 - axis_[k] * axis_[k]));
      lo[k] = std::min(point_[k], p1[k]) - ext;
      hi[k] = std::max(point_[k], p1[k]) + ext;
    }
    return true;
  }
  // Infinite 3D: the lateral normals, perpendicular to the axis. 2D circle: any direction. A tube:
  // its rims give every direction.
  bool has_normal(const Vec<D>& n, double tol) const override {
    if (std::abs(n.norm() - 1.0) > tol) return false;
    if constexpr (D == 3) {
      if (!finite_) return std::abs(n.dot(axis_)) <= tol;
    }
    return true;
  }

 Vec<D> anchor() const override { return point_; }
  // The tube (an infinite one over the axial range of the box), or the circle in 2D.
  void tessellate(double, const Vec<D>& lo, const Vec<D>& hi, SurfaceMesh& out) const override {
    if constexpr (D == 2) {
      const int n = 96;
      const auto base = static_cast<std::uint32_t>(out.points.size());
      std::vector<std::uint32_t> cell;
      for (int k = 0; k < n; ++k) {
        const double a = 2.0 * 3.14159265358979323846 * k / n;
        out.points.push_back({point_[0] + radius_ * std::cos(a), point_[1] + radius_ * std::sin(a), 0.0});
        cell.push_back(base + static_cast<std::uint32_t>(k));
      }
      cell.push_back(base);  // closed
      out.cells.push_back(std::move(cell));
    } else {
      auto [s0, s1] = finite_ ? std::pair<double, double>{0.0, length_} : axial_range<D>(point_, axis_, lo, hi);
      revolve_band<D>(point_, axis_, radius_, radius_, s0, s1, out);
    }
  }

 private:
  Vec<D> point_, axis_;
  double radius_ = 0.0, length_ = 0.0;
  bool inside_ = true, finite_ = false;
  AxisRotation<D> rot_;
};

}  // namespace matep

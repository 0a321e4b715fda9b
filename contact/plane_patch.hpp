// The bounded plane wall: a finite piece of a plane (a patch) or an infinite plane with a hole (a
// silo floor with an orifice): WallShape<D> (contact/wall.hpp). Static, or a disk patch turning
// about its normal (a turntable).
//   BoundedPlane<D>(centre, normal, radius, hole = false, omega = 0)    a disk (2D: a segment)
//   BoundedPlane<D>(centre, normal, u, a, b, hole = false)               a rectangle
// The plane passes through `centre` with unit `normal`. Disk: radius `radius` around `centre`.
// Rectangle: half-sizes a along the in-plane unit direction u (made perpendicular to the normal)
// and b along normal x u. hole = false: only that region is wall (a patch); hole = true: the plane
// minus that region (the hole's edge belongs to the wall). A thin sheet touched from both sides (a
// grain that fell through the hole lives below the floor): gap = the distance from the sphere's
// centre to the nearest point of the sheet minus R, normal from that point towards the centre
// (+-normal over the face, radial at an edge, rim or corner).
// 2D: the plane is a line, the region a segment of half-length `radius` (or a; b unused) along
// the line's direction (-normal_y, normal_x): a segment (patch) or a line with a gap (hole); the
// edges are the segment's end points.
// omega (3D disk patches only; a rectangle or the 2D segment would change shape, a holed plane
// would move without bound): rotation about the normal through the centre, right-handed about
// `normal` (AxisRotation); the surface at the contact point q moves at omega normal x (q - centre).
// Impact times (contact/shape_features.hpp): the face (two offset planes: linear in t, quadratic
// under gravity) where the foot point lies in (patch) or out of (hole) the region; a disk's rim
// (offset torus: quartic / octic); a rectangle's edges (offset cylinders around segments:
// quadratic / quartic) and corners (offset spheres: quadratic / quartic); 2D end points (circles).
// The earliest accepted root, refined on the gap of at().
// bracketed() is true: the engine passes its earliest event so far as the limit, and a flight that
// cannot reach the surface before it (gap > |v| limit + |g| limit^2 / 2) costs one at() call.
// kind(): "plane patch" or "plane with hole" ("plane" is the infinite plane of contact/plane.hpp).
#pragma once

#include <fmt/format.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "contact/plane.hpp"
#include "contact/predict.hpp"
#include "contact/shape_features.hpp"
#include "contact/wall.hpp"

namespace matep {

template <int D>
class BoundedPlane final : public WallShape<D> {
 public:
  // A disk of `radius` (2D: a segment of half-length `radius`).
  BoundedPlane(const Vec<D>& centre, const Vec<D>& normal, double radius, bool hole = false, double omega = 0.0)
      : centre_(centre), hole_(hole), disk_(true), a_(radius), b_(radius) {
    set_frame(normal, Vec<D>::Zero());
    if (!(radius > 0.0)) throw std::invalid_argument("bounded plane: radius must be > 0");
    if (omega != 0.0 && (D == 2 || hole))
      throw std::invalid_argument("bounded plane: only a 3D disk patch may rotate about its normal");
    rot_.point = centre_;
    rot_.axis = normal_;
    rot_.omega = omega;
  }
  // A rectangle with half-sizes a along u and b along normal x u (2D: a segment of half-length a).
  BoundedPlane(const Vec<D>& centre, const Vec<D>& normal, const Vec<D>& u, double a, double b, bool hole = false)
      : centre_(centre), hole_(hole), disk_(D == 2), a_(a), b_(D == 2 ? a : b) {
    set_frame(normal, u);
    if (!(a > 0.0) || !(b_ > 0.0)) throw std::invalid_argument("bounded plane: half-sizes must be > 0");
  }

  const Vec<D>& centre() const { return centre_; }
  const Vec<D>& normal() const { return normal_; }
  const Vec<D>& u() const { return u_; }
  const Vec<D>& v() const { return v_; }  // normal x u (2D: unused)
  double a() const { return a_; }         // radius of a disk, half-size along u
  double b() const { return b_; }         // half-size along v
  bool hole() const { return hole_; }
  bool disk() const { return disk_; }
  double omega() const { return rot_.omega; }

  const char* kind() const override { return hole_ ? "plane with hole" : "plane patch"; }
  std::string describe() const override {
    std::string region;
    if (D == 2)
      region = fmt::format("a segment of half-length {} along ({})", a_, fmt::join(u_, ", "));
    else if (disk_)
      region = fmt::format("a disk of radius {}", a_);
    else
      region = fmt::format("a rectangle {} x {} (half-sizes) along ({}) and ({})", a_, b_, fmt::join(u_, ", "),
                           fmt::join(v_, ", "));
    std::string s = fmt::format("{} through ({}) normal ({}): {} {}, touched from both sides", kind(),
                                fmt::join(centre_, ", "), fmt::join(normal_, ", "), hole_ ? "without" : "only",
                                region);
    if (rot_.active()) s += fmt::format(", turning at {} rad/s about its normal", rot_.omega);
    return s;
  }

  WallPoint<D> at(const Vec<D>& x, double R, double) const override {
    const Vec<D> r = x - centre_;
    const double h = r.dot(normal_);
    const Vec<D> s = r - h * normal_;
    const Vec<D> q = nearest_in_plane(s);
    const Vec<D> d = r - q;
    const double dist = d.norm();
    WallPoint<D> c;
    c.gap = dist - R;
    c.normal = dist > 0.0 ? Vec<D>(d / dist) : normal_;
    if (rot_.active()) c.velocity = rot_.velocity(Vec<D>(centre_ + q));
    return c;
  }

  double impact_time(const Vec<D>& x, const Vec<D>& v, const Vec<D>& g, double R, double,
                     double limit) const override {
    // Now: an approaching particle within round-off of the sheet (the turntable's surface velocity
    // is in the plane and normal to a rim's radial normal: it does not change the normal speed).
    const WallPoint<D> c0 = at(x, R, 0.0);
    const bool approaching = closing_now(v, g, c0.normal);
    if (c0.gap <= 0.0 && approaching) return 0.0;
    if (out_of_reach(c0.gap, v, g, limit)) return kNever;
    const Flight<D> f(x, v, g, centre_);
    auto on_face = [&](const Vec<D>& r) { return in_region(Vec<D>(r - r.dot(normal_) * normal_)) != hole_; };
    double t = std::min(feature::face(f, normal_, +1, R, limit, approaching, on_face),
                        feature::face(f, normal_, -1, R, limit, approaching, on_face));
    if constexpr (D == 2) {
      for (int sgn = -1; sgn <= 1; sgn += 2) {
        Flight<D> fe = f;
        fe.r0 -= (sgn * a_) * u_;
        t = std::min(t, feature::point(fe, R, std::min(t, limit), approaching));
      }
    } else if (disk_) {
      t = std::min(t, feature::rim(f, normal_, a_, R, std::min(t, limit), approaching));
    } else {
      for (int sgn = -1; sgn <= 1; sgn += 2) {
        Flight<D> fu = f, fv = f;  // edges along v at +-a u, along u at +-b v
        fu.r0 -= (sgn * a_) * u_;
        fv.r0 -= (sgn * b_) * v_;
        t = std::min(t, feature::edge(fu, v_, -b_, b_, R, std::min(t, limit), approaching));
        t = std::min(t, feature::edge(fv, u_, -a_, a_, R, std::min(t, limit), approaching));
        for (int sg2 = -1; sg2 <= 1; sg2 += 2) {
          Flight<D> fc = f;
          fc.r0 -= (sgn * a_) * u_ + (sg2 * b_) * v_;
          t = std::min(t, feature::point(fc, R, std::min(t, limit), approaching));
        }
      }
    }
    if (!(t < limit)) return kNever;
    t = refine_on_gap([&](double s) { return at(Vec<D>(f.at(s) + centre_), R, 0.0).gap; }, t);
    return t < limit ? t : kNever;
  }

  double max_speed() const override { return std::abs(rot_.omega) * a_; }
  bool moving() const override { return rot_.active(); }
  // The engine passes the earliest event found so far as `limit`: most flights are rejected by
  // out_of_reach without a root search.
  bool bracketed() const override { return true; }
  bool bounds(Vec<D>& lo, Vec<D>& hi) const override {
    if (hole_) return false;
    for (int k = 0; k < D; ++k) {
      double ext;
      if (disk_) ext = a_ * std::sqrt(std::max(0.0, 1.0 - normal_[k] * normal_[k]));
      else ext = a_ * std::abs(u_[k]) + b_ * std::abs(v_[k]);
      lo[k] = centre_[k] - ext;
      hi[k] = centre_[k] + ext;
    }
    return true;
  }
  // The face gives +-normal, the edges, rims and corners every other direction.
  bool has_normal(const Vec<D>& n, double tol) const override { return std::abs(n.norm() - 1.0) <= tol; }
  Vec<D> anchor() const override { return centre_; }

  // The patch (a 48-gon or the rectangle; 2D: the segment), or the plane cut by the box minus the
  // hole (3D: quads between the hole's edge and the box's cut along rays from the centre; 2D: the
  // line's two pieces).
  void tessellate(double, const Vec<D>& lo, const Vec<D>& hi, SurfaceMesh& out) const override {
    auto push = [&](const Vec<D>& x) {
      out.points.push_back({x[0], x[1], D == 3 ? x[D - 1] : 0.0});
      return static_cast<std::uint32_t>(out.points.size() - 1);
    };
    if constexpr (D == 2) {
      if (!hole_) {
        out.cells.push_back({push(centre_ - a_ * u_), push(centre_ + a_ * u_)});
        return;
      }
      const auto [s0, s1] = axial_range<D>(centre_, u_, lo, hi);
      if (s0 < -a_) out.cells.push_back({push(centre_ + s0 * u_), push(centre_ - a_ * u_)});
      if (s1 > a_) out.cells.push_back({push(centre_ + a_ * u_), push(centre_ + s1 * u_)});
    } else {
      // The hole's (or patch's) edge along the in-plane direction e, from the centre.
      auto edge = [&](const Vec<D>& e) {
        if (disk_) return Vec<D>(centre_ + a_ * e);
        const double eu = std::abs(e.dot(u_)), ev = std::abs(e.dot(v_));
        const double t = std::min(eu > 0.0 ? a_ / eu : 1e300, ev > 0.0 ? b_ / ev : 1e300);
        return Vec<D>(centre_ + t * e);
      };
      std::vector<double> angles;
      for (int k = 0; k < 64; ++k) angles.push_back(2.0 * 3.14159265358979323846 * k / 64);
      if (!disk_)
        for (const double su : {-1.0, 1.0})
          for (const double sv : {-1.0, 1.0}) {
            double a = std::atan2(sv * b_, su * a_);
            if (a < 0.0) a += 2.0 * 3.14159265358979323846;
            angles.push_back(a);
          }
      std::sort(angles.begin(), angles.end());
      auto dir = [&](double a) { return Vec<D>(std::cos(a) * u_ + std::sin(a) * v_); };
      if (!hole_) {
        std::vector<std::uint32_t> cell;
        for (const double a : angles) cell.push_back(push(edge(dir(a))));
        out.cells.push_back(std::move(cell));
        return;
      }
      // The plane's cut by the box (convex, around the centre when the hole lies in the domain).
      SurfaceMesh cut;
      PlaneWall<D>(centre_, normal_).tessellate(0.0, lo, hi, cut);
      if (cut.cells.empty()) return;
      std::vector<std::array<double, 2>> poly;  // in-plane coordinates about the centre
      for (const auto k : cut.cells[0]) {
        const Vec<D> q(cut.points[k][0], cut.points[k][1], cut.points[k][2]);
        poly.push_back({(q - centre_).dot(u_), (q - centre_).dot(v_)});
      }
      auto outer = [&](double a) {  // where the ray at angle a leaves the polygon
        const double ex = std::cos(a), ey = std::sin(a);
        double best = 0.0;
        for (std::size_t k = 0; k < poly.size(); ++k) {
          const auto& A = poly[k];
          const auto& B = poly[(k + 1) % poly.size()];
          const double dx = B[0] - A[0], dy = B[1] - A[1];
          const double det = ex * (-dy) - ey * (-dx);
          if (det == 0.0) continue;
          const double t = (A[0] * (-dy) - A[1] * (-dx)) / det;
          const double s = (ex * A[1] - ey * A[0]) / det;
          if (t > 0.0 && s >= 0.0 && s <= 1.0) best = std::max(best, t);
        }
        return Vec<D>(centre_ + best * dir(a));
      };
      const auto n = angles.size();
      std::vector<std::uint32_t> in, ou;
      for (const double a : angles) {
        in.push_back(push(edge(dir(a))));
        ou.push_back(push(outer(a)));
      }
      for (std::size_t k = 0; k < n; ++k) {
        const std::size_t k1 = (k + 1) % n;
        out.cells.push_back({in[k], ou[k], ou[k1], in[k1]});
      }
    }
  }

 private:
  void set_frame(const Vec<D>& normal, const Vec<D>& u) {
    const double nn = normal.norm();
    if (!(nn > 0.0)) throw std::invalid_argument("bounded plane: normal must be a nonzero vector");
    normal_ = normal / nn;
    if constexpr (D == 2) {
      u_ = Vec<D>(-normal_[1], normal_[0]);
      v_ = Vec<D>::Zero();
    } else {
      Vec<D> w = u;
      if (w.squaredNorm() == 0.0) {  // a disk: any in-plane direction
        w = Vec<D>::Zero();
        w[std::abs(normal_[0]) < 0.9 ? 0 : 1] = 1.0;
      }
      w -= w.dot(normal_) * normal_;
      if (!(w.norm() > 1e-12)) throw std::invalid_argument("bounded plane: u must not be parallel to the normal");
      u_ = w.normalized();
      v_ = normal_.cross(u_);
    }
  }
  // Whether the in-plane offset s from the centre lies in the disk / rectangle (boundary included).
  bool in_region(const Vec<D>& s) const {
    if (disk_) return s.norm() <= a_;
    return std::abs(s.dot(u_)) <= a_ && std::abs(s.dot(v_)) <= b_;
  }
  // The nearest point of the sheet's in-plane part to the in-plane offset s.
  Vec<D> nearest_in_plane(const Vec<D>& s) const {
    if (disk_) {
      const double l = s.norm();
      if (!hole_) return l <= a_ ? s : Vec<D>(s * (a_ / l));
      if (l >= a_) return s;
      return l > 0.0 ? Vec<D>(s * (a_ / l)) : Vec<D>(a_ * u_);
    }
    double s1 = s.dot(u_), s2 = s.dot(v_);
    if (!hole_) return std::clamp(s1, -a_, a_) * u_ + std::clamp(s2, -b_, b_) * v_;
    if (std::abs(s1) > a_ || std::abs(s2) > b_) return s;
    if (a_ - std::abs(s1) <= b_ - std::abs(s2)) s1 = s1 < 0.0 ? -a_ : a_;  // out through the nearer edge
    else s2 = s2 < 0.0 ? -b_ : b_;
    return s1 * u_ + s2 * v_;
  }

  Vec<D> centre_, normal_, u_, v_;
  bool hole_ = false, disk_ = true;
  double a_ = 0.0, b_ = 0.0;
  AxisRotation<D> rot_;
};

}  // namespace matep

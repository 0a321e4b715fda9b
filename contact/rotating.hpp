// Any bounded wall turning about a fixed axis at a constant angular velocity: a paddle, a mixer
// blade, a drum with lifters, a mesh from CAD (WallShape<D>, contact/wall.hpp). A decorator over a
// wall at rest (`body`, given in its position at t = 0): at time t the surface is the body's turned
// by the angle omega t about the axis through `point` (right-handed about `axis`; in 2D about the
// point). Shapes of revolution turning about their own axis (a drum, a turntable) keep their
// geometry and have the closed forms of their own files; this is for the others.
//   gap, normal:       the body's, at the particle's position turned back by -omega t (the gap is
//                      a distance: a rotation keeps it), the normal turned forward;
//   surface velocity:  omega axis x (c - point) at the contact point c (AxisRotation);
//   features:          the body's (a mesh's facets), looked up in the body's frame.
// Impact times: in the body's frame the flight is no longer a polynomial, so the time is found by
// conservative advancement (the gap g(t) changes no faster than the centre moves relative to the
// surface, |v + g t| + |omega| r_max, r_max the body's farthest point from the axis
// (WallShape::reach_from_axis: a mesh's farthest vertex, else its box's farthest corner): stepping by
// g / that bound never passes the first touch; e.g. Mirtich, "Impulse-based dynamic simulation of
// rigid body systems", PhD thesis, Berkeley 1996, ch. 4). Once the gap is below 1e-6 R and
// closing, a trial step past the linear estimate of the touch that finds the gap closed gives a
// bracket, narrowed to round-off on the gap itself (safe_root, contact/poly.hpp). The search
// starts where the flight enters the box of every position the body takes (padded by R) and ends
// at its exit, at the engine's limit, or after a bounded number of steps: then the time reached is
// returned as a checkpoint (the gap still open) for the engine to predict again from, so a
// prediction's cost stays bounded. Just after a bounce (touching, leaving) the steps are at least
// 1e-9 R / bound long.
// The soft engines' neighbour lists: sweep_speed() = |omega| r_max, the fastest any surface point
// moves, counts towards the list's skin (engine/tdm, engine/hybrid rebuild when the grains' and
// the surface's motions together could close the skin).
#pragma once

#include <fmt/format.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <memory>
#include <stdexcept>
#include <string>

#include "contact/predict.hpp"
#include "contact/shape_features.hpp"
#include "contact/wall.hpp"

namespace matep {

template <int D>
class RotatingWall final : public WallShape<D> {
 public:
  RotatingWall(std::shared_ptr<const WallShape<D>> body, const Vec<D>& point, const Vec<D>& axis, double omega)
      : body_(std::move(body)) {
    if (!body_) throw std::invalid_argument("rotating wall: no shape");
    if (body_->moving()) throw std::invalid_argument("rotation: the shape already moves (one motion per wall)");
    Vec<D> lo, hi;
    if (!body_->bounds(lo, hi))
      throw std::invalid_argument(fmt::format("rotation: an unbounded {} cannot turn about an axis", body_->kind()));
    if (!std::isfinite(omega)) throw std::invalid_argument("rotation: angular_velocity must be finite");
    rot_.point = point;
    rot_.omega = omega;
    if constexpr (D == 3) {
      if (!(axis.norm() > 0.0)) throw std::invalid_argument("rotation: axis must be a nonzero vector");
      rot_.axis = axis.normalized();
    }
    // The body's farthest point from the axis.
    rmax_ = body_->reach_from_axis(point, rot_.axis);
    blo_ = lo;
    bhi_ = hi;
  }

  const WallShape<D>& body() const { return *body_; }
  const AxisRotation<D>& rotation() const { return rot_; }

  const char* kind() const override { return body_->kind(); }
  std::string describe() const override {
    if constexpr (D == 3)
      return fmt::format("{}, turning at {} rad/s about the axis through ({}) along ({})", body_->describe(),
                         rot_.omega, fmt::join(rot_.point, ", "), fmt::join(rot_.axis, ", "));
    else
      return fmt::format("{}, turning at {} rad/s about ({})", body_->describe(), rot_.omega,
                         fmt::join(rot_.point, ", "));
  }

  WallPoint<D> at(const Vec<D>& x, double R, double t) const override { return to_world(body_->at(to_body(x, t), R, 0.0), x, R, t); }
  bool multi_contact() const override { return body_->multi_contact(); }
  void features_near(const Vec<D>& x, double R, double reach, double t, std::vector<std::uint32_t>& out) const override {
    body_->features_near(to_body(x, t), R, reach, 0.0, out);
  }
  WallPoint<D> at_feature(const Vec<D>& x, double R, double t, std::uint32_t f) const override {
    return to_world(body_->at_feature(to_body(x, t), R, 0.0, f), x, R, t);
  }
  Vec<D> feature_velocity(const Vec<D>& x, double R, double t, std::uint32_t f) const override {
    return at_feature(x, R, t, f).velocity;
  }
  WallPoint<D> at_impact(const Vec<D>& x, const Vec<D>& v, double R, double t) const override {
    // The velocity relative to the body's frame, turned into it.
    const Vec<D> xb = to_body(x, t);
    const Vec<D> vrel = v - rot_.velocity(x);
    return to_world(body_->at_impact(xb, turn(vrel, -angle(t)), R, 0.0), x, R, t);
  }

  double impact_time(const Vec<D>& x, const Vec<D>& v, const Vec<D>& g, double R, double t0,
                     double limit_in) const override {
    double limit = limit_in;
    auto pos = [&](double s) { return Vec<D>(x + s * v + (0.5 * s * s) * g); };
    auto vel = [&](double s) { return Vec<D>(v + s * g); };
    const WallPoint<D> c0 = at(x, R, t0);
    const double tol = 1e-13 * R, floor = 1e-9 * R;
    auto closing = [&](const WallPoint<D>& c, double s) {
      const double un = (vel(s) - c.velocity).dot(c.normal);
      return un < 0.0 || (un == 0.0 && g.dot(c.normal) < 0.0);
    };
    if (c0.gap <= tol && closing(c0, 0.0)) return 0.0;
    // Only within the box every position of the body lies in (padded by R) can it be touched: the
    // search starts at the entry (a checkpoint there) and stops at the exit (a checkpoint).
    Vec<D> lo, hi;
    bounds(lo, hi);
    double t_in = 0.0, t_out = kNever;
    if (!flight_box_window<D>(x, v, g, lo, hi, R * (1.0 + 1e-6) + 1e-9 * (hi - lo).norm(), t_in, t_out)) return kNever;
    if (t_in > 0.0) return t_in < limit ? t_in : kNever;
    limit = std::min(limit, t_out);
    const double w = std::abs(rot_.omega) * rmax_, sv = v.norm(), sg = g.norm();
    double s = 0.0, gap = c0.gap;
    for (int k = 0; k < kSteps; ++k) {
      // Touching while leaving (just bounced): step at least floor / bound, the time in which no
      // surface point can come back by more than floor.
      const double step_gap = gap <= tol ? floor : gap;
      // The speed bound over the step: |v| + |g| (s + ds) + w, ds first from the bound at s, then
      // once more from the bound at its end (never longer than the first).
      double bound = sv + sg * s + w;
      if (!(bound > 0.0)) return kNever;
      double ds = step_gap / bound;
      bound = sv + sg * (s + ds) + w;
      ds = step_gap / bound;
      s += ds;
      if (!(s < limit)) return limit < limit_in ? limit : kNever;  // at the exit: a checkpoint
      const WallPoint<D> c = at(pos(s), R, t0 + s);
      gap = c.gap;
      if (gap <= tol && closing(c, s)) return s;
      // Near and closing: try past the linear estimate of the touch; a bracket found there is
      // narrowed to round-off (contact/poly.hpp safe_root) on the gap itself.
      const double un = (vel(s) - c.velocity).dot(c.normal);
      if (gap <= 1e-6 * R && un < 0.0) {
        const double b = s + 2.0 * gap / -un;
        auto h = [&](double q) { return at(pos(q), R, t0 + q).gap; };
        const double hb = b < limit ? h(b) : 1.0;
        if (hb <= 0.0) {
          const double r = safe_root(h, s, gap, b, hb);
          return r < limit ? r : kNever;
        }
      }
    }
    return s;  // a checkpoint: the gap is still open (s < limit)
  }
  bool bracketed() const override { return true; }

  double max_speed() const override { return std::abs(rot_.omega) * rmax_; }
  double sweep_speed() const override { return std::abs(rot_.omega) * rmax_; }
  Spin<D> spin() const override { return rot_.spin(); }
  bool moving() const override { return rot_.active(); }
  Vec<D> anchor() const override { return rot_.point; }
  // Every position the body takes: the box around the axis of radius rmax (3D: along the axis,
  // the body's extent).
  bool bounds(Vec<D>& lo, Vec<D>& hi) const override {
    if constexpr (D == 2) {
      lo = rot_.point - Vec<D>::Constant(rmax_);
      hi = rot_.point + Vec<D>::Constant(rmax_);
    } else {
      double s0 = kNever, s1 = -kNever;
      for (int m = 0; m < 8; ++m) {
        Vec<D> c;
        for (int k = 0; k < 3; ++k) c[k] = ((m >> k) & 1) ? bhi_[k] : blo_[k];
        const double s = (c - rot_.point).dot(rot_.axis);
        s0 = std::min(s0, s);
        s1 = std::max(s1, s);
      }
      for (int k = 0; k < 3; ++k) {
        const double ext = rmax_ * std::sqrt(std::max(0.0, 1.0 - rot_.axis[k] * rot_.axis[k]));
        const double a = rot_.point[k] + s0 * rot_.axis[k], b = rot_.point[k] + s1 * rot_.axis[k];
        lo[k] = std::min(a, b) - ext;
        hi[k] = std::max(a, b) + ext;
      }
    }
    return true;
  }
  bool has_normal(const Vec<D>& n, double tol) const override { return std::abs(n.norm() - 1.0) <= tol; }
  void tessellate(double t, const Vec<D>& lo, const Vec<D>& hi, SurfaceMesh& out) const override {
    const std::size_t first = out.points.size();
    body_->tessellate(0.0, lo, hi, out);
    for (std::size_t k = first; k < out.points.size(); ++k) {
      Vec<D> p;
      for (int j = 0; j < D; ++j) p[j] = out.points[k][static_cast<std::size_t>(j)];
      const Vec<D> q = rot_.point + turn(Vec<D>(p - rot_.point), angle(t));
      for (int j = 0; j < D; ++j) out.points[k][static_cast<std::size_t>(j)] = q[j];
    }
  }

 private:
  static constexpr int kSteps = 64;

  double angle(double t) const { return rot_.omega * t; }
  Vec<D> turn(const Vec<D>& r, double a) const {
    if constexpr (D == 2) {
      const double c = std::cos(a), s = std::sin(a);
      return Vec<D>(c * r[0] - s * r[1], s * r[0] + c * r[1]);
    } else {
      return Eigen::AngleAxisd(a, rot_.axis) * r;
    }
  }
  Vec<D> to_body(const Vec<D>& x, double t) const { return rot_.point + turn(Vec<D>(x - rot_.point), -angle(t)); }
  WallPoint<D> to_world(WallPoint<D> c, const Vec<D>& x, double R, double t) const {
    if (!(c.gap < kNever)) return c;
    c.normal = turn(c.normal, angle(t));
    c.velocity = rot_.velocity(Vec<D>(x - (R + c.gap) * c.normal));
    return c;
  }

  std::shared_ptr<const WallShape<D>> body_;
  AxisRotation<D> rot_;
  double rmax_ = 0.0;
  Vec<D> blo_, bhi_;
};

}  // namespace matep

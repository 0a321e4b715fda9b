// A wall shape that exists only in the tests: a spherical container (a circle in 2D) of radius Rc
// around `centre`, with the particles inside. It proves that a shape added in one file, through
// contact/wall.hpp alone, works in all three engines without a line in engine/.
// Impact times in closed form for straight flights (no gravity): |d + v t| = Rc - R, the larger root
// of v.v t^2 + 2 (d.v) t + (d.d - s^2) = 0, s = Rc - R (the particle is inside, so the gap closes
// when it moves outward through that root).
#pragma once

#include <fmt/format.h>

#include <cmath>
#include <stdexcept>
#include <string>

#include "contact/predict.hpp"
#include "contact/wall.hpp"

namespace matep::test {

template <int D>
class SphereContainer final : public WallShape<D> {
 public:
  SphereContainer(const Vec<D>& centre, double radius) : centre_(centre), radius_(radius) {}

  const char* kind() const override { return "sphere container (test)"; }
  std::string describe() const override {
    return fmt::format("sphere container around ({}) of radius {}", fmt::join(centre_, ", "), radius_);
  }
  WallPoint<D> at(const Vec<D>& x, double R, double) const override {
    const Vec<D> d = x - centre_;
    const double r = d.norm();
    WallPoint<D> p;
    p.gap = radius_ - r - R;
    if (r > 0.0) {
      p.normal = -d / r;  // from the wall towards the particle: inwards
    } else {
      p.normal = Vec<D>::Zero();
      p.normal[0] = -1.0;
    }
    return p;
  }
  double impact_time(const Vec<D>& x, const Vec<D>& v, const Vec<D>& g, double R, double,
                     double limit) const override {
    if (g.squaredNorm() > 0.0) throw std::invalid_argument("the test sphere container has no gravity closed form");
    const Vec<D> d = x - centre_;
    const double s = radius_ - R;
    const double a = v.squaredNorm(), b = d.dot(v), c = d.squaredNorm() - s * s;
    if (a == 0.0) return kNever;
    if (c >= 0.0 && b > 0.0) return 0.0;  // on or past the surface by round-off, moving out: now
    const double disc = std::max(0.0, b * b - a * c);
    // Larger root, cancellation-free for b > 0.
    const double t = b > 0.0 ? -c / (b + std::sqrt(disc)) : (-b + std::sqrt(disc)) / a;
    const double dt = t > 0.0 ? t : 0.0;
    return dt < limit ? dt : kNever;
  }
  bool has_normal(const Vec<D>& n, double tol) const override { return std::abs(n.norm() - 1.0) <= tol; }

  const Vec<D>& centre() const { return centre_; }
  double radius() const { return radius_; }

 private:
  Vec<D> centre_;
  double radius_;
};

}  // namespace matep::test

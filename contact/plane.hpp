// The plane wall: an infinite plane through `point` with unit `normal` (particles live on the side
// the normal points to), static or oscillating sinusoidally along a fixed vector (the normal stays
// fixed): p(t) = point + amplitude sin(2 pi frequency t). The first WallShape (contact/wall.hpp).
// Impact times: contact/predict.hpp (closed form for a static plane; safe bracketing for an
// oscillating one).
#pragma once

#include <fmt/format.h>

#include <cmath>
#include <memory>
#include <numbers>
#include <string>

#include "contact/predict.hpp"
#include "contact/wall.hpp"

namespace matep {

// A plane as the soft path sees it during one force evaluation at time t of a step h: its gap and
// velocity at t and its velocity at t - h/2 (the only two times wall_contact asks about), computed
// once per evaluation instead of once per contact. Valid only for that evaluation.
template <int D>
struct PlaneInstant {
  Vec<D> p, n, u, uh;  // position and velocity at t, velocity at t - h/2
  WallPoint<D> at(const Vec<D>& x, double R, double) const { return {(x - p).dot(n) - R, n, u}; }
  Vec<D> surface_velocity(const Vec<D>&, double, double) const { return uh; }
};

template <int D>
class PlaneWall final : public WallShape<D> {
 public:
  Vec<D> point = Vec<D>::Zero();
  Vec<D> normal = Vec<D>::Zero();  // unit
  Vec<D> amplitude = Vec<D>::Zero();
  double frequency = 0.0;

  PlaneWall() = default;
  PlaneWall(const Vec<D>& p, const Vec<D>& n, const Vec<D>& amp = Vec<D>::Zero(), double f = 0.0)
      : point(p), normal(n), amplitude(amp), frequency(f) {}

  bool oscillating() const { return frequency > 0.0 && (amplitude.array() != 0.0).any(); }
  double angular_frequency() const { return 2.0 * std::numbers::pi * frequency; }
  // p(t) and its velocity u(t) = 2 pi f amplitude cos(2 pi f t).
  Vec<D> position(double t) const {
    if (!oscillating()) return point;
    return point + std::sin(angular_frequency() * t) * amplitude;
  }
  Vec<D> velocity(double t) const {
    if (!oscillating()) return Vec<D>::Zero();
    const double w = angular_frequency();
    return (w * std::cos(w * t)) * amplitude;
  }
  // The plane during a soft force evaluation at time t with half step hdt (PlaneInstant above).
  PlaneInstant<D> instant(double t, double hdt) const { return {position(t), normal, velocity(t), velocity(t - hdt)}; }

  const char* kind() const override { return "plane"; }
  std::string describe() const override {
    std::string s = fmt::format("plane through ({}) normal ({})", fmt::join(point, ", "), fmt::join(normal, ", "));
    if (oscillating())
      s += fmt::format(", oscillating: amplitude ({}) at frequency {} (peak speed {:.4g})", fmt::join(amplitude, ", "),
                       frequency, max_speed());
    return s;
  }
  WallPoint<D> at(const Vec<D>& x, double R, double t) const override {
    if (!oscillating()) return {(x - point).dot(normal) - R, normal, Vec<D>::Zero()};
    const double w = angular_frequency();
    return {(x - Vec<D>(point + std::sin(w * t) * amplitude)).dot(normal) - R, normal, (w * std::cos(w * t)) * amplitude};
  }
  Vec<D> surface_velocity(const Vec<D>&, double, double t) const override { return velocity(t); }
  double impact_time(const Vec<D>& x, const Vec<D>& v, const Vec<D>& g, double R, double t0,
                     double limit) const override {
    if (!oscillating()) return wall_collision_time(x, v, g, R, point, normal);
    return moving_wall_collision_time(x, v, g, R, point, normal, amplitude, angular_frequency(), t0, limit);
  }
  bool bracketed() const override { return oscillating(); }
  double stroke() const override { return oscillating() ? std::abs(amplitude.dot(normal)) : 0.0; }
  double max_speed() const override { return angular_frequency() * amplitude.norm(); }
  bool moving() const override { return oscillating(); }
  bool has_normal(const Vec<D>& n, double tol) const override { return (n - normal).norm() <= tol; }
  Vec<D> anchor() const override { return point; }
};

// The plane shape of a wall, or null when the wall has another shape.
template <int D>
const PlaneWall<D>* as_plane(const WallShape<D>* s) {
  return dynamic_cast<const PlaneWall<D>*>(s);
}

}  // namespace matep

// The plane wall: an infinite plane through `point` with unit `normal` (particles live on the side
// the normal points to), static or oscillating sinusoidally along a fixed vector (the normal stays
// fixed): p(t) = point + amplitude sin(2 pi frequency t). The first WallShape (contact/wall.hpp).
// Impact times: contact/predict.hpp (closed form for a static plane; safe bracketing for an
// oscillating one).
#pragma once

#include <fmt/format.h>

#include <algorithm>
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
  Spin<D> spin() const { return Spin<D>::Zero(); }
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
  // The plane at p(t) cut by the box: in 3D the convex polygon where it crosses the box's edges
  // (ordered by angle about their centroid), in 2D the segment where the line crosses the box.
  void tessellate(double t, const Vec<D>& lo, const Vec<D>& hi, SurfaceMesh& out) const override {
    const Vec<D> p = position(t);
    std::vector<Vec<D>> hits;
    // Each box edge: the corners that differ along axis k only.
    for (int k = 0; k < D; ++k)
      for (int m = 0; m < (1 << (D - 1)); ++m) {
        Vec<D> a, b;
        for (int q = 0, bit = 0; q < D; ++q) {
          if (q == k) {
            a[q] = lo[q];
            b[q] = hi[q];
          } else {
            a[q] = b[q] = ((m >> bit++) & 1) ? hi[q] : lo[q];
          }
        }
        const double fa = (a - p).dot(normal), fb = (b - p).dot(normal);
        if ((fa > 0.0 && fb > 0.0) || (fa < 0.0 && fb < 0.0)) continue;  // the edge does not reach it
        const double s = fa == fb ? 0.0 : fa / (fa - fb);
        hits.push_back(a + s * (b - a));
      }
    // A plane through a corner crosses several edges there: one point each.
    const double tol = 1e-12 * (hi - lo).norm();
    std::vector<Vec<D>> uniq;
    for (const auto& h : hits) {
      bool seen = false;
      for (const auto& q : uniq) seen = seen || (q - h).norm() <= tol;
      if (!seen) uniq.push_back(h);
    }
    hits = std::move(uniq);
    if (hits.size() < 2) return;
    Vec<D> c = Vec<D>::Zero();
    for (const auto& h : hits) c += h;
    c /= static_cast<double>(hits.size());
    std::vector<std::pair<double, Vec<D>>> ordered;
    if constexpr (D == 3) {
      const Vec<D> u = (std::abs(normal[0]) < 0.9 ? Vec<D>(1, 0, 0) : Vec<D>(0, 1, 0)).cross(normal).normalized();
      const Vec<D> w = normal.cross(u);
      for (const auto& h : hits) ordered.emplace_back(std::atan2((h - c).dot(w), (h - c).dot(u)), h);
    } else {
      const Vec<D> u(-normal[1], normal[0]);
      for (const auto& h : hits) ordered.emplace_back((h - c).dot(u), h);
    }
    std::sort(ordered.begin(), ordered.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
    std::vector<std::uint32_t> cell;
    if constexpr (D == 2) {  // the two extreme crossings
      ordered = {ordered.front(), ordered.back()};
    }
    for (const auto& [key, h] : ordered) {
      (void)key;
      cell.push_back(static_cast<std::uint32_t>(out.points.size()));
      out.points.push_back({h[0], h[1], D == 3 ? h[D - 1] : 0.0});
    }
    out.cells.push_back(std::move(cell));
  }
};

// The plane shape of a wall, or null when the wall has another shape.
template <int D>
const PlaneWall<D>* as_plane(const WallShape<D>* s) {
  return dynamic_cast<const PlaneWall<D>*>(s);
}

}  // namespace matep

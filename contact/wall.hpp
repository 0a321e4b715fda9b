// Walls as shapes: the one interface through which every engine meets a rigid wall. A shape tells,
// for a particle (sphere or disk) of radius R whose centre is at x at time t, the gap between the
// two, the contact normal and the surface's velocity at the contact point; for the event-driven
// engine it also gives the first contact time along a ballistic or parabolic flight. The engines
// (EDM collisions, the soft-contact loop of TDM and the hybrid), the scene reader and
// `matep log verify` know walls only through this class.
//
// Adding a shape: one file in contact/ with a class derived from WallShape<D> (contact/plane.hpp is
// the model), its scene keys in io/scene.cpp and its tests. Nothing in engine/ changes.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Geometry>

#include "contact/vec.hpp"

namespace matep {

// What a particle at x with radius R sees of a wall at time t.
template <int D>
struct WallPoint {
  double gap = 0.0;                  // distance from the surface minus R; < 0: overlap delta = -gap
  Vec<D> normal = Vec<D>::Zero();    // unit, from the wall towards the particle (n of contact/soft.hpp)
  Vec<D> velocity = Vec<D>::Zero();  // the surface's velocity at the contact point
};

// A rigid rotation of a wall about a fixed axis at a constant angular velocity omega (rad/s,
// right-handed about `axis`): the surface point c moves at omega axis x (c - point). In 2D the axis
// is the one out of the plane and `axis` is unused: the velocity is omega (-(c - point)_y, (c - point)_x).
// A shape that is symmetric about the axis (a drum about its own axis, a disk about its normal)
// keeps its geometry while its surface moves.
template <int D>
struct AxisRotation {
  Vec<D> point = Vec<D>::Zero();
  Vec<D> axis = Vec<D>::Zero();  // unit (3D)
  double omega = 0.0;

  bool active() const { return omega != 0.0; }
  // The angular velocity (2D: its z component).
  Spin<D> spin() const {
    if constexpr (D == 2) {
      Spin<D> s;
      s[0] = omega;
      return s;
    } else {
      return omega * axis;
    }
  }
  Vec<D> velocity(const Vec<D>& c) const {
    const Vec<D> r = c - point;
    if constexpr (D == 2) {
      return Vec<D>(-omega * r[1], omega * r[0]);
    } else {
      return omega * axis.cross(r);
    }
  }
};

// A picture of a wall surface for the snapshots: points (x, y, z; z = 0 in 2D) and cells, each a
// list of point indices: polygons in 3D, polylines in 2D.
struct SurfaceMesh {
  std::vector<std::array<double, 3>> points;
  std::vector<std::vector<std::uint32_t>> cells;
};

// Pictures of surfaces of revolution for tessellate(): the band between the circles of radius r0
// at point + s0 axis and r1 at point + s1 axis, as `segments` quads (3D); in 2D the two lines of the
// axial section (-r, +r about the axis).
template <int D>
void revolve_band(const Vec<D>& point, const Vec<D>& axis, double r0, double r1, double s0, double s1, SurfaceMesh& out,
                  int segments = 48) {
  auto push = [&](const Vec<D>& x) {
    out.points.push_back({x[0], x[1], D == 3 ? x[D - 1] : 0.0});
    return static_cast<std::uint32_t>(out.points.size() - 1);
  };
  if constexpr (D == 2) {
    const Vec<D> w(-axis[1], axis[0]);
    for (const double side : {-1.0, 1.0})
      out.cells.push_back({push(point + s0 * axis + side * r0 * w), push(point + s1 * axis + side * r1 * w)});
  } else {
    const Vec<D> u = (std::abs(axis[0]) < 0.9 ? Vec<D>(1, 0, 0) : Vec<D>(0, 1, 0)).cross(axis).normalized();
    const Vec<D> v = axis.cross(u);
    const auto base = static_cast<std::uint32_t>(out.points.size());
    for (int k = 0; k < segments; ++k) {
      const double a = 2.0 * 3.14159265358979323846 * k / segments;
      const Vec<D> e = std::cos(a) * u + std::sin(a) * v;
      push(point + s0 * axis + r0 * e);
      push(point + s1 * axis + r1 * e);
    }
    for (int k = 0; k < segments; ++k) {
      const auto k1 = static_cast<std::uint32_t>((k + 1) % segments);
      const auto kk = static_cast<std::uint32_t>(k);
      out.cells.push_back({base + 2 * kk, base + 2 * kk + 1, base + 2 * k1 + 1, base + 2 * k1});
    }
  }
}

// The range [s0, s1] of the axial coordinate (point + s axis) over the box [lo, hi]: an infinite
// shape along the axis is drawn over it.
template <int D>
std::pair<double, double> axial_range(const Vec<D>& point, const Vec<D>& axis, const Vec<D>& lo, const Vec<D>& hi) {
  double s0 = std::numeric_limits<double>::infinity(), s1 = -s0;
  for (int m = 0; m < (1 << D); ++m) {
    Vec<D> c;
    for (int k = 0; k < D; ++k) c[k] = ((m >> k) & 1) ? hi[k] : lo[k];
    const double s = (c - point).dot(axis);
    s0 = std::min(s0, s);
    s1 = std::max(s1, s);
  }
  return {s0, s1};
}

template <int D>
class WallShape;

// One feature of a multi-contact shape seen as a shape of its own (at, surface_velocity): what the
// soft path's wall_contact (engine/soft/forces.hpp) takes.
template <int D>
struct FeatureView {
  const WallShape<D>& shape;
  std::uint32_t feature;
  WallPoint<D> at(const Vec<D>& x, double R, double t) const { return shape.at_feature(x, R, t, feature); }
  Vec<D> surface_velocity(const Vec<D>& x, double R, double t) const {
    return shape.feature_velocity(x, R, t, feature);
  }
  Spin<D> spin() const { return shape.spin(); }
};

// A wall-list entry's wall and feature in one 32-bit slot (the soft engines' springs are keyed by
// particle and slot): at most kMaxWalls walls, 2^22 features per wall.
inline constexpr std::uint32_t kWallBits = 10, kMaxWalls = 1u << kWallBits, kMaxFeatures = 1u << (32 - kWallBits);
inline std::uint32_t wall_slot(std::uint32_t wall, std::uint32_t feature) { return wall | (feature << kWallBits); }
inline std::uint32_t slot_wall(std::uint32_t slot) { return slot & (kMaxWalls - 1); }
inline std::uint32_t slot_feature(std::uint32_t slot) { return slot >> kWallBits; }

template <int D>
class WallShape {
 public:
  virtual ~WallShape() = default;

  // "plane", ... (the scene's [wall.NAME] type).
  virtual const char* kind() const = 0;
  // One line for `matep check`.
  virtual std::string describe() const = 0;

  // Gap, normal and surface velocity for a particle at x with radius R at time t.
  virtual WallPoint<D> at(const Vec<D>& x, double R, double t) const = 0;
  // The surface's velocity at the contact point of a particle at x (radius R) at time t (the soft
  // path asks it at the half step as well). Zero for a wall at rest.
  virtual Vec<D> surface_velocity(const Vec<D>& x, double R, double t) const { return at(x, R, t).velocity; }
  // The wall's angular velocity as a rigid body (a turning drum, cone or RotatingWall; 2D: the z
  // component): the rolling resistance of the soft contacts acts on the grain's spin relative to it.
  virtual Spin<D> spin() const { return Spin<D>::Zero(); }

  // EDM: the earliest dt >= 0 at which a particle with centre x, velocity v, constant acceleration g
  // and radius R, all at the absolute time t0, reaches the surface while the gap closes (an
  // approaching particle overlapping by round-off: dt = 0; a receding one is never an event), or
  // kNever (infinity) if that does not happen before `limit`. Closed form where the motion allows;
  // otherwise a bracketing that never skips the earliest root (see bracketed()).
  virtual double impact_time(const Vec<D>& x, const Vec<D>& v, const Vec<D>& g, double R, double t0,
                             double limit) const = 0;
  // Whether impact_time is a search that profits from a limit (the engine calls it after the pair
  // tests, limited by the earliest event found, and treats an event whose gap is still open as a
  // checkpoint to re-predict from).
  virtual bool bracketed() const { return false; }

  // How far the surface moves from its rest position (neighbour lists reach this much further).
  virtual double stroke() const { return 0.0; }
  // The largest speed of any surface point (the soft plan's expected impact speed).
  virtual double max_speed() const { return 0.0; }
  // How fast the geometry itself sweeps through space (a turning paddle: |omega| r_max): the soft
  // engines rebuild their lists before the sweep since the last build could close the skin. Zero
  // for shapes at rest, shapes of revolution turning about their own axis (the surface moves, the
  // geometry stays) and oscillating planes (their stroke widens the list instead).
  virtual double sweep_speed() const { return 0.0; }
  // The largest distance of a surface point from the axis through p along unit a (2D: from p); by
  // default from the corners of bounds() (a bounded shape's box), tighter where a shape knows its
  // points (a mesh's vertices). contact/rotating.hpp's speed bound and swept box.
  virtual double reach_from_axis(const Vec<D>& p, const Vec<D>& a) const {
    Vec<D> lo, hi;
    if (!bounds(lo, hi)) return std::numeric_limits<double>::infinity();
    double r = 0.0;
    for (int m = 0; m < (1 << D); ++m) {
      Vec<D> c;
      for (int k = 0; k < D; ++k) c[k] = ((m >> k) & 1) ? hi[k] : lo[k];
      Vec<D> d = c - p;
      if constexpr (D == 3) d -= d.dot(a) * a;
      r = std::max(r, d.norm());
    }
    return r;
  }
  // Whether the surface moves at all (a moving wall keeps the grains touching it awake).
  virtual bool moving() const { return false; }

  // The point about which the wall's torque is reported (engine/wall_loads.hpp): a plane's point, a
  // rotating shape's axis point.
  virtual Vec<D> anchor() const { return Vec<D>::Zero(); }

  // The surface's axis-aligned bounding box (false: the shape is unbounded, an infinite plane or
  // cylinder). The scene reader checks that a bounded shape fits in the domain.
  virtual bool bounds(Vec<D>& lo, Vec<D>& hi) const {
    (void)lo;
    (void)hi;
    return false;
  }

  // The surface at time t as a SurfaceMesh, an unbounded one clipped to the box [lo, hi] (the
  // domain); appended to out. A shape without a picture leaves out empty.
  virtual void tessellate(double t, const Vec<D>& lo, const Vec<D>& hi, SurfaceMesh& out) const {
    (void)t;
    (void)lo;
    (void)hi;
    (void)out;
  }

  // Shapes made of several parts that a grain may touch at once (a triangle mesh's facets,
  // contact/mesh.hpp): multi_contact() is true and the soft engines keep one contact per part
  // (feature) within their list reach, each with its own spring. features_near appends the
  // features whose gap may be below `reach`; at_feature gives one feature's contact (gap = kNever
  // where that feature does not own the contact at x); feature_velocity its surface velocity.
  // A shape with one contact per grain keeps the defaults (one feature, number 0).
  virtual bool multi_contact() const { return false; }
  virtual void features_near(const Vec<D>& x, double R, double reach, double t, std::vector<std::uint32_t>& out) const {
    if (at(x, R, t).gap < reach) out.push_back(0);
  }
  virtual WallPoint<D> at_feature(const Vec<D>& x, double R, double t, std::uint32_t feature) const {
    (void)feature;
    return at(x, R, t);
  }
  virtual Vec<D> feature_velocity(const Vec<D>& x, double R, double t, std::uint32_t feature) const {
    (void)feature;
    return surface_velocity(x, R, t);
  }
  // EDM: the contact of a collision predicted by impact_time (x, v: the particle at the impact).
  // A shape that can be touched at several points at once (a mesh's concave corner) returns the
  // one the particle approaches fastest; the others at() (the nearest surface point).
  virtual WallPoint<D> at_impact(const Vec<D>& x, const Vec<D>& v, double R, double t) const {
    (void)v;
    return at(x, R, t);
  }

  // Whether n is the wall's normal at some point of its surface (within tol): `matep log verify`
  // checks a wall record's normal with it (the records carry no positions).
  virtual bool has_normal(const Vec<D>& n, double tol) const = 0;
};

}  // namespace matep

// PipeWall (contact/pipe.hpp): the U-tube.
// Impact times against the extended-precision reference (tests/support/impact_reference.hpp) on a
// long-double gap written here from the U-tube's geometry in its own frame (two straight legs of
// height H at x = 0 and x = 2 Rb joined by the half circle of radius Rb around (Rb, H) above them;
// the caps beyond the leg ends are the distances to the end points), not from the shape's code; the
// pipe is placed at a random point and orientation, 3D and 2D, straight and parabolic flights from
// random points inside, and grazing flights that dip in or pass clear by 1e-9 R (built on the
// convex inner side of the bend, or found among random flights); also a pipe bent in two planes
// (3D) and an S-channel (2D) whose pieces' centres are worked out by hand. Each case runs kQuick
// flights by default and kLong (10 000) in the *Long* tests.
// Engine-level physics: an elastic EDM gas under gravity in a U-tube closed by one plane across both
// legs keeps its energy and stays inside (3D and 2D); a grain at rest on the bottom of a horizontal
// straight leg has the static Hertz overlap of a flat wall (TDM 3D and 2D, hybrid 3D).
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>
#include <utility>
#include <vector>

#include "contact/pipe.hpp"
#include "engine/edm.hpp"
#include "engine/hybrid.hpp"
#include "engine/tdm.hpp"
#include "tests/support/shape_check.hpp"
#include "tests/support/shape_physics.hpp"

namespace matep {
namespace {

using test::FlightCase;
using test::ImpactStats;
using test::VecL;

constexpr int kQuick = 2000;
constexpr int kLong = 10000;
constexpr double kTmax = 3.0;
constexpr double kTol = 1e-10;
constexpr double kPi = 3.14159265358979323846;

enum class Gravity { None, On };

// A U-tube placed at `start` rising along unit `up`; `side` the unit direction (across `up`) towards
// the second leg. Its own frame: ex = side, ez = up (3D: ey = ez x ex); 2D: ex = side, ey = up.
template <int D>
struct UTube {
  Vec<D> start, up, side;
  double radius = 0.5, Rb = 1.0, H = 2.0;

  PipeWall<D> shape() const {
    std::vector<PipePiece<D>> pcs;
    pcs.push_back(PipePiece<D>::straight(H));
    if constexpr (D == 3) {
      // Turning towards axis x up = side: axis = up x side.
      pcs.push_back(PipePiece<D>::arc(Rb, kPi, Vec<D>(up.cross(side))));
    } else {
      // Left of up is (-up_y, up_x); side is to the left (angle > 0) or to the right (< 0).
      const double left = side.dot(Vec<D>(-up[1], up[0]));
      pcs.push_back(PipePiece<D>::arc(Rb, left > 0.0 ? kPi : -kPi));
    }
    pcs.push_back(PipePiece<D>::straight(H));
    return PipeWall<D>(start, up, radius, pcs);
  }

  // The U-tube's own orthonormal frame in long double, from the doubles the shape is given (up and
  // side are unit and perpendicular only to round-off, and a grazing root moves by ~1e-9 relative
  // per 1e-16 of shift of the wall): ez = up normalized; ex towards the second leg, 3D: the given
  // arc axis a = up x side made perpendicular to ez and unit, ex = a x ez; 2D: ez turned a quarter
  // towards side; ey = ez x ex (3D).
  void frame(VecL<D>& ex, VecL<D>& ey, VecL<D>& ez) const {
    ez = test::to_ld<D>(up).normalized();
    ey = VecL<D>::Zero();
    if constexpr (D == 3) {
      VecL<D> a = test::to_ld<D>(Vec<D>(up.cross(side)));
      a = (a - a.dot(ez) * ez).normalized();
      ex = a.cross(ez);
      ey = ez.cross(ex);
    } else {
      const long double left = side.dot(Vec<D>(-up[1], up[0]));
      ex = VecL<D>(-ez[1], ez[0]) * (left > 0.0 ? 1.0L : -1.0L);
    }
  }
  // The local coordinates (u along ex, w along ey, z along ez) of x, long double.
  void local(const VecL<D>& x, long double& u, long double& w, long double& z) const {
    VecL<D> ex, ey, ez;
    frame(ex, ey, ez);
    const VecL<D> r = x - test::to_ld<D>(start);
    u = r.dot(ex);
    z = r.dot(ez);
    w = r.dot(ey);
  }
  Vec<D> point(double u, double w, double z) const {
    Vec<D> x = start + u * side + z * up;
    if constexpr (D == 3) x += w * up.cross(side);
    (void)w;
    return x;
  }

  // Distance from the centreline: the legs (clamped to 0 <= z <= H) and the half circle (z >= H:
  // the circle's point in x's direction; below, the nearer end point).
  long double distance(const VecL<D>& x) const {
    long double u, w, z;
    local(x, u, w, z);
    const long double Hl = H, R = Rb;
    const long double z1 = std::clamp(z, 0.0L, Hl);
    const long double leg1 = std::sqrt(u * u + w * w + (z - z1) * (z - z1));
    // The second leg as the shape is given it: after a bend through kPi, the double nearest pi,
    // which is short of pi by 1.2e-16: it starts at (Rb - Rb cos phi, H + Rb sin phi) heading
    // (sin phi, -cos phi) (u, z) for H; at the bottom that is 2.4e-16 off the vertical leg, enough
    // to move a grazing root by 1e-10.
    const long double phi = kPi;
    const long double pu = R - R * std::cos(phi), pz = Hl + R * std::sin(phi), du = std::sin(phi), dz = std::cos(phi);
    const long double s2 = std::clamp((u - pu) * du + (z - pz) * dz, 0.0L, Hl);
    const long double leg2 = std::sqrt((u - pu - s2 * du) * (u - pu - s2 * du) + w * w +
                                       (z - pz - s2 * dz) * (z - pz - s2 * dz));
    long double bend;
    if (z >= Hl) {
      bend = std::hypot(std::hypot(u - R, z - Hl) - R, w);
    } else {
      bend = std::min(std::sqrt(u * u + w * w + (z - Hl) * (z - Hl)),
                      std::sqrt((u - 2 * R) * (u - 2 * R) + w * w + (z - Hl) * (z - Hl)));
    }
    return std::min({leg1, leg2, bend});
  }
  long double gap(const VecL<D>& x, long double R) const { return radius - R - distance(x); }
};

template <int D>
UTube<D> random_utube(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  UTube<D> t;
  for (int k = 0; k < D; ++k) t.start[k] = u(rng);
  t.up = test::random_unit<D>(rng);
  if constexpr (D == 3) {
    Vec<D> s = test::random_unit<D>(rng);
    while ((s - s.dot(t.up) * t.up).norm() < 1e-3) s = test::random_unit<D>(rng);
    t.side = (s - s.dot(t.up) * t.up).normalized();
  } else {
    t.side = Vec<D>(-t.up[1], t.up[0]) * (u(rng) > 0.0 ? 1.0 : -1.0);
  }
  return t;
}

// A random flight from a random point inside: radius 0.02..0.3, speed 0.3..2, gravity 0.5..5 in a
// random direction when on.
template <int D>
FlightCase<D> random_flight(std::mt19937_64& rng, const UTube<D>& p, Gravity grav) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  FlightCase<D> f;
  for (;;) {
    f.R = 0.02 + 0.28 * u(rng);
    const double a = -p.radius + (2.0 * p.Rb + 2.0 * p.radius) * u(rng);
    const double w = D == 3 ? p.radius * (2.0 * u(rng) - 1.0) : 0.0;
    const double z = -p.radius + (p.H + p.Rb + 2.0 * p.radius) * u(rng);
    f.x = p.point(a, w, z);
    f.v = (0.3 + 1.7 * u(rng)) * test::random_unit<D>(rng);
    f.g = grav == Gravity::On ? Vec<D>((0.5 + 4.5 * u(rng)) * test::random_unit<D>(rng)) : Vec<D>::Zero();
    if (p.gap(test::to_ld<D>(f.x), f.R) > 1e-9L) return f;
  }
}

// impact_time with a finite limit (the shape is bracketed()): the same time before the limit, to the
// accuracy asked of the times (kTol relative, absolute below the reference comparison's floor of
// 1e-3: a different limit cuts the polynomials' monotone pieces elsewhere, and a root near tangency,
// where the gap is flat, may then be refined to another double within that accuracy; seen: 2e-12),
// kNever when not.
template <int D>
void expect_limit_consistent(const PipeWall<D>& shape, const Vec<D>& x, const Vec<D>& v, const Vec<D>& g, double R,
                             double t) {
  if (t < kNever && t > 0.0) {
    EXPECT_NEAR(shape.impact_time(x, v, g, R, 0.0, t * (1.0 + 1e-6)), t, kTol * std::max(t, 1e-3));
    EXPECT_EQ(shape.impact_time(x, v, g, R, 0.0, t * (1.0 - 1e-6)), kNever);
  }
}

// n flights, a fresh random placement every 50.
template <int D>
void expect_case(const char* name, Gravity grav, int n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  ImpactStats total;
  for (int block = 0; block < n / 50; ++block) {
    const UTube<D> p = random_utube<D>(rng);
    const PipeWall<D> c = p.shape();
    test::merge_keep_first(total, test::check_impacts<D>(
                     [&](const Vec<D>& x, const Vec<D>& v, const Vec<D>& g, double R) {
                       const double t = c.impact_time(x, v, g, R, 0.0, kNever);
                       expect_limit_consistent<D>(c, x, v, g, R, t);
                       return t;
                     },
                     [&](const VecL<D>& x, long double R) { return p.gap(x, R); },
                     [&](std::mt19937_64& r) { return random_flight<D>(r, p, grav); }, 50, kTmax, kTol, rng()));
  }
  total.print(name);
  EXPECT_EQ(total.missed, 0) << name << " " << total.worst_case;
  EXPECT_EQ(total.early, 0) << name << " " << total.worst_case;
  EXPECT_LE(total.worst, kTol) << name << " " << total.worst_case;
  EXPECT_GT(total.hits, total.cases / 2) << name;
}

// A pipe bent in two planes (3D) or an S-shaped channel (2D), with the pieces' centres and frames
// worked out by hand from the header's convention (below) for the reference, fixed placement.
// 3D, radius 0.5, from 0 along z: straight 1 to (0, 0, 1); arc Rb 1, pi / 2 about y (towards
// y x z = x): centre (1, 0, 1), from (-1, 0, 0) towards (0, 0, 1), ends at (1, 0, 2) heading x; arc
// Rb 0.8, 2 pi / 3 about z (towards z x x = y): centre (1, 0.8, 2), from (0, -1, 0) towards
// (1, 0, 0), ends at (1 + 0.4 sqrt 3, 1.2, 2) heading (-1/2, sqrt 3 / 2, 0); straight 1.
// 2D, radius 0.3, from 0 along x: straight 1; arc Rb 0.6, +pi / 2 (left): centre (1, 0.6), from
// (0, -1) towards (1, 0), ends at (1.6, 0.6) heading y; arc Rb 0.5, -pi (right): centre (2.1, 0.6),
// from (-1, 0) towards (0, 1), ends at (2.6, 0.6) heading -y; straight 0.8 to (2.6, -0.2).
template <int D>
struct Chain {
  struct Piece {
    bool arc = false;
    VecL<D> p0 = VecL<D>::Zero(), p1 = VecL<D>::Zero(), c = VecL<D>::Zero(), e0 = VecL<D>::Zero(),
            e1 = VecL<D>::Zero();
    long double Rb = 0, phi = 0;
  };
  std::vector<Piece> pieces;
  double radius = 0.0;
  Vec<D> lo, hi;  // a box around it, for starting points

  static VecL<D> v(long double a, long double b, long double c = 0) {
    VecL<D> r;
    r[0] = a;
    r[1] = b;
    if constexpr (D == 3) r[2] = c;
    (void)c;
    return r;
  }
  static Piece seg(const VecL<D>& a, const VecL<D>& b) {
    Piece p;
    p.p0 = a;
    p.p1 = b;
    return p;
  }
  static Piece bend(const VecL<D>& c, const VecL<D>& e0, const VecL<D>& e1, long double Rb, long double phi) {
    Piece p;
    p.arc = true;
    p.c = c;
    p.e0 = e0;
    p.e1 = e1;
    p.Rb = Rb;
    p.phi = phi;
    p.p0 = c + Rb * e0;
    p.p1 = c + Rb * (std::cos(phi) * e0 + std::sin(phi) * e1);
    return p;
  }

  long double distance(const VecL<D>& x) const {
    long double best = std::numeric_limits<long double>::infinity();
    for (const Piece& p : pieces) {
      long double d;
      if (!p.arc) {
        const VecL<D> ab = p.p1 - p.p0;
        const long double s = std::clamp((x - p.p0).dot(ab) / ab.squaredNorm(), 0.0L, 1.0L);
        d = (x - p.p0 - s * ab).norm();
      } else {
        const VecL<D> r = x - p.c;
        const long double a = r.dot(p.e0), b = r.dot(p.e1);
        const long double off = (r - a * p.e0 - b * p.e1).norm();  // out of the bend's plane
        long double th = std::atan2(b, a);
        if (th < 0) th += 2 * 3.14159265358979323846264338L;
        if (th <= p.phi) d = std::hypot(std::hypot(a, b) - p.Rb, off);
        else d = std::min((x - p.p0).norm(), (x - p.p1).norm());
      }
      best = std::min(best, d);
    }
    return best;
  }
  long double gap(const VecL<D>& x, long double R) const { return radius - R - distance(x); }
};

template <int D>
std::pair<PipeWall<D>, Chain<D>> bent_pipe() {
  using P = PipePiece<D>;
  using C = Chain<D>;
  C ch;
  const long double s3 = std::sqrt(3.0L);
  if constexpr (D == 3) {
    ch.radius = 0.5;
    ch.pieces = {C::seg(C::v(0, 0, 0), C::v(0, 0, 1)), C::bend(C::v(1, 0, 1), C::v(-1, 0, 0), C::v(0, 0, 1), 1, kPi / 2),
                 C::bend(C::v(1, 0.8L, 2), C::v(0, -1, 0), C::v(1, 0, 0), 0.8L, 2 * kPi / 3),
                 C::seg(C::v(1 + 0.4L * s3, 1.2L, 2), C::v(1 + 0.4L * s3 - 0.5L, 1.2L + s3 / 2, 2))};
    ch.lo = Vec<D>(-0.5, -0.5, -0.5);
    ch.hi = Vec<D>(2.5, 2.5, 2.5);
    return {PipeWall<D>(Vec<D>::Zero(), Vec<D>(0, 0, 1), 0.5,
                        {P::straight(1), P::arc(1, kPi / 2, Vec<D>(0, 1, 0)), P::arc(0.8, 2 * kPi / 3, Vec<D>(0, 0, 1)),
                         P::straight(1)}),
            ch};
  } else {
    ch.radius = 0.3;
    ch.pieces = {C::seg(C::v(0, 0), C::v(1, 0)), C::bend(C::v(1, 0.6L), C::v(0, -1), C::v(1, 0), 0.6L, kPi / 2),
                 C::bend(C::v(2.1L, 0.6L), C::v(-1, 0), C::v(0, 1), 0.5L, kPi),
                 C::seg(C::v(2.6L, 0.6L), C::v(2.6L, -0.2L))};
    ch.lo = Vec<D>(-0.3, -0.5);
    ch.hi = Vec<D>(2.9, 1.4);
    return {PipeWall<D>(Vec<D>::Zero(), Vec<D>(1, 0), 0.3,
                        {P::straight(1), P::arc(0.6, kPi / 2), P::arc(0.5, -kPi), P::straight(0.8)}),
            ch};
  }
}

template <int D>
void expect_bent_case(const char* name, Gravity grav, int n, std::uint64_t seed) {
  const auto [c, ch] = bent_pipe<D>();
  // The shape's own end point against the hand-worked one.
  EXPECT_LT((test::to_ld<D>(c.end_point()) - ch.pieces.back().p1).norm(), 1e-14L) << name;
  const ImpactStats s = test::check_impacts<D>(
      [&](const Vec<D>& x, const Vec<D>& v, const Vec<D>& g, double R) {
        const double t = c.impact_time(x, v, g, R, 0.0, kNever);
        expect_limit_consistent<D>(c, x, v, g, R, t);
        return t;
      },
      [&](const VecL<D>& x, long double R) { return ch.gap(x, R); },
      [&](std::mt19937_64& rng) {
        std::uniform_real_distribution<double> u(0.0, 1.0);
        FlightCase<D> f;
        for (;;) {
          f.R = 0.02 + 0.18 * u(rng);
          for (int k = 0; k < D; ++k) f.x[k] = ch.lo[k] + (ch.hi[k] - ch.lo[k]) * u(rng);
          f.v = (0.3 + 1.7 * u(rng)) * test::random_unit<D>(rng);
          f.g = grav == Gravity::On ? Vec<D>((0.5 + 4.5 * u(rng)) * test::random_unit<D>(rng)) : Vec<D>::Zero();
          if (ch.gap(test::to_ld<D>(f.x), f.R) > 1e-9L) return f;
        }
      },
      n, kTmax, kTol, seed);
  s.print(name);
  EXPECT_EQ(s.missed, 0) << name << " " << s.worst_case;
  EXPECT_EQ(s.early, 0) << name << " " << s.worst_case;
  EXPECT_LE(s.worst, kTol) << name << " " << s.worst_case;
  EXPECT_GT(s.hits, s.cases / 2) << name;
}

void all_cases(int n) {
  expect_case<3>("3D U-tube, straight", Gravity::None, n, 1);
  expect_case<3>("3D U-tube, gravity", Gravity::On, n, 2);
  expect_case<2>("2D U-channel, straight", Gravity::None, n, 3);
  expect_case<2>("2D U-channel, gravity", Gravity::On, n, 4);
  expect_bent_case<3>("3D pipe bent in two planes, straight", Gravity::None, n, 5);
  expect_bent_case<3>("3D pipe bent in two planes, gravity", Gravity::On, n, 6);
  expect_bent_case<2>("2D S-channel, straight", Gravity::None, n, 7);
  expect_bent_case<2>("2D S-channel, gravity", Gravity::On, n, 8);
}

TEST(PipeImpact, MatchesTheReference) { all_cases(kQuick); }
TEST(PipeImpact, MatchesTheReferenceLong) { all_cases(kLong); }

// A flight that grazes the inner wall of the bend from within: at time T it passes the point P of
// the offset torus's inner equator (distance Rb - A from the bend's centre, in the bend's plane, at
// an angle th well inside the arc) along the bend's tangent there, with gravity (if on) along the
// normal u there (away from the wall). Its distance from the centre, sqrt((Rb - A + G s^2 / 2)^2 +
// (v s)^2) at s = t - T, is least at s = 0, so the gap, A - (Rb - that distance), has a local
// minimum there: the inner side of a bend is the only convex part of the pipe seen from inside.
// Sets T.
template <int D>
FlightCase<D> inner_bend_flight(std::mt19937_64& rng, const UTube<D>& p, Gravity grav, double& T) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  FlightCase<D> f;
  f.R = 0.02 + 0.28 * u(rng);
  const double A = p.radius - f.R;
  const double th = 0.7 + (kPi - 1.4) * u(rng);  // from the first leg's end, over the top
  // The bend's frame in local coordinates: centre (Rb, 0, H), th = 0 towards -side, pi / 2 up.
  const Vec<D> c = p.point(p.Rb, 0.0, p.H);
  const Vec<D> ur = -std::cos(th) * p.side + std::sin(th) * p.up;  // from the centre outwards
  const Vec<D> tg = std::sin(th) * p.side + std::cos(th) * p.up;   // the tangent, along the pipe
  const Vec<D> P = c + (p.Rb - A) * ur;
  const double s = (0.3 + 0.7 * u(rng)) * (u(rng) < 0.5 ? 1.0 : -1.0);
  const double G = grav == Gravity::On ? 0.5 + 4.5 * u(rng) : 0.0;
  T = 0.1 + 0.2 * u(rng);
  f.g = G * ur;
  const Vec<D> vT = s * tg;
  f.x = P - T * vT + 0.5 * T * T * f.g;
  f.v = vT - T * f.g;
  return f;
}

// Grazing flights that dip in or pass clear by 1e-9 R (test::make_graze shifts the path along the
// normal at its closest approach); the reference decides hit or miss. bend: flights built by
// inner_bend_flight; else random flights inside whose gap has an interior minimum before they hit
// (a parabola curving more than the wall, or the bend). A grazing root is ill-conditioned (see
// test_shape_cylinder.cpp): tolerance kTol = 1e-10, as for the random flights.
template <int D>
void graze_cases(Gravity grav, bool bend, int n, std::uint64_t seed, const char* name) {
  std::mt19937_64 rng(seed);
  ImpactStats total;
  int made = 0;
  for (int k = 0; k < 40 * n && made < n; ++k) {
    const UTube<D> p = random_utube<D>(rng);
    const PipeWall<D> c = p.shape();
    auto gld = [&](const VecL<D>& x, long double R) { return p.gap(x, R); };
    FlightCase<D> f;
    double window;
    if (bend) {
      double T;
      f = inner_bend_flight<D>(rng, p, grav, T);
      window = 2.0 * T;
    } else {
      f = random_flight<D>(rng, p, grav);
      const VecL<D> x = test::to_ld<D>(f.x), v = test::to_ld<D>(f.v), g = test::to_ld<D>(f.g);
      const long double hit = test::earliest_closing_root(
          [&](long double t) { return gld(VecL<D>(x + t * v + 0.5L * t * t * g), (long double)f.R); }, kTmax, 2000);
      if (!(hit <= kTmax)) continue;
      window = 0.98 * static_cast<double>(hit);
    }
    const double miss = (made % 2 ? 1e-9 : -1e-9);
    if (!test::make_graze<D>(f, gld, [&](const Vec<D>& y, double R) { return c.at(y, R, 0.0).normal; }, window,
                             miss * f.R))
      continue;
    ++made;
    const ImpactStats s = test::check_impacts<D>(
        [&](const Vec<D>& y, const Vec<D>& u, const Vec<D>& gg, double R) {
          return c.impact_time(y, u, gg, R, 0.0, kNever);
        },
        gld, [&](std::mt19937_64&) { return f; }, 1, kTmax, kTol, 0);
    if (s.missed + s.early > 0) std::printf("  %s: %s\n", name, s.worst_case.c_str());
    test::merge_keep_first(total, s);
  }
  total.print(name);
  std::printf("  %s: %d of %d flights made\n", name, made, n);
  EXPECT_GE(made, bend ? n / 2 : n / 4) << name;
  EXPECT_EQ(total.missed, 0) << name << " " << total.worst_case;
  EXPECT_EQ(total.early, 0) << name << " " << total.worst_case;
  EXPECT_LE(total.worst, kTol) << name << " " << total.worst_case;
}

TEST(PipeImpact, GrazingFlightsTouchOrMissAsTheReferenceSays) {
  graze_cases<3>(Gravity::None, true, 200, 21, "graze 3D inner bend, straight");
  graze_cases<3>(Gravity::On, true, 200, 22, "graze 3D inner bend, gravity");
  graze_cases<2>(Gravity::None, true, 200, 23, "graze 2D inner bend, straight");
  graze_cases<2>(Gravity::On, true, 200, 24, "graze 2D inner bend, gravity");
  graze_cases<3>(Gravity::On, false, 40, 25, "graze 3D U-tube, random, gravity");
  graze_cases<2>(Gravity::On, false, 100, 26, "graze 2D U-channel, random, gravity");
}

// Hand-made flights with closed-form times in the U-tube (start 0, up z, side x; radius 0.5, Rb 1,
// H 2; A = radius - R).
TEST(PipeImpact, ClosedFormFlights) {
  const UTube<3> u{Vec<3>::Zero(), Vec<3>(0, 0, 1), Vec<3>(1, 0, 0)};
  const PipeWall<3> c = u.shape();
  const double R = 0.1, A = 0.4;
  // Across the first leg along x from its axis: the wall at x = A.
  EXPECT_NEAR(c.impact_time(Vec<3>(0, 0, 1), Vec<3>(2, 0, 0), Vec<3>::Zero(), R, 0.0, kNever), A / 2.0, 1e-15);
  // Up the first leg's axis into the bend: the distance to the bend's circle (centre (1, 0, 2)) is
  // sqrt(1 + s^2) - 1 at z = 2 + s (below the leg's end point's s): the wall at sqrt(1 + s^2) = 1 + A.
  EXPECT_NEAR(c.impact_time(Vec<3>(0, 0, 1), Vec<3>(0, 0, 1), Vec<3>::Zero(), R, 0.0, kNever),
              1.0 + std::sqrt(2.0 * A + A * A), 1e-14);
  // Down the first leg's axis: into the cap below z = 0, |x| = A at z = -A.
  EXPECT_NEAR(c.impact_time(Vec<3>(0, 0, 1), Vec<3>(0, 0, -1), Vec<3>::Zero(), R, 0.0, kNever), 1.0 + A, 1e-14);
  // Up and down through the top of the bend (x = 1, 0.2 from the circle at z = 3): the outer wall
  // at z = 3 + A, the inner one at z = 3 - A.
  EXPECT_NEAR(c.impact_time(Vec<3>(1, 0, 2.8), Vec<3>(0, 0, 1), Vec<3>::Zero(), R, 0.0, kNever), 0.2 + A, 1e-14);
  EXPECT_NEAR(c.impact_time(Vec<3>(1, 0, 3.2), Vec<3>(0, 0, -1), Vec<3>::Zero(), R, 0.0, kNever), 0.2 + A, 1e-14);
  // Within the cross-section z = 2 where the first leg joins the bend (both pieces' nearest points
  // on their common end circle): outwards, sideways and towards the bend's centre, the wall at A.
  for (const Vec<3>& d : {Vec<3>(-1, 0, 0), Vec<3>(0, 1, 0), Vec<3>(0.6, -0.8, 0), Vec<3>(1, 0, 0)})
    EXPECT_NEAR(c.impact_time(Vec<3>(0, 0, 2), d, Vec<3>::Zero(), R, 0.0, kNever), A, 1e-15) << d.transpose();
  // Overlapping by round-off and approaching: now; receding: crosses the leg.
  const Vec<3> x(A + 1e-16, 0, 1);
  EXPECT_EQ(c.impact_time(x, Vec<3>(1, 0.2, 0), Vec<3>::Zero(), R, 0.0, kNever), 0.0);
  EXPECT_NEAR(c.impact_time(x, Vec<3>(-1, 0, 0), Vec<3>::Zero(), R, 0.0, kNever), 2.0 * A, 1e-14);
}

// The rest of the interface on hand-made points: gaps and normals, bounds, pictures, invalid input.
TEST(PipeShape, GeometryBoundsAndInvalidInput) {
  const UTube<3> u{Vec<3>::Zero(), Vec<3>(0, 0, 1), Vec<3>(1, 0, 0)};
  const PipeWall<3> c = u.shape();
  const double R = 0.1;
  EXPECT_LT((c.end_point() - Vec<3>(2, 0, 0)).norm(), 1e-14);
  EXPECT_LT((c.end_direction() - Vec<3>(0, 0, -1)).norm(), 1e-14);
  EXPECT_NEAR(c.length(), 4.0 + kPi, 1e-14);
  WallPoint<3> p = c.at(Vec<3>(0.2, 0, 1), R, 0.0);  // first leg
  EXPECT_NEAR(p.gap, 0.5 - R - 0.2, 1e-15);
  EXPECT_LT((p.normal - Vec<3>(-1, 0, 0)).norm(), 1e-15);
  p = c.at(Vec<3>(1, 0.3, 3.0), R, 0.0);  // top of the bend, off its plane
  EXPECT_NEAR(p.gap, 0.5 - R - 0.3, 1e-15);
  EXPECT_LT((p.normal - Vec<3>(0, -1, 0)).norm(), 1e-15);
  p = c.at(Vec<3>(1, 0, 2.0), R, 0.0);  // the bend's centre, between the legs: 1 from everything
  EXPECT_NEAR(p.gap, 0.5 - R - 1.0, 1e-15);
  p = c.at(Vec<3>(2, 0, -0.3), R, 0.0);  // below the second leg: its cap
  EXPECT_NEAR(p.gap, 0.5 - R - 0.3, 1e-15);
  EXPECT_LT((p.normal - Vec<3>(0, 0, 1)).norm(), 1e-14);
  Vec<3> lo, hi;
  ASSERT_TRUE(c.bounds(lo, hi));
  EXPECT_LT((lo - Vec<3>(-0.5, -0.5, 0.0)).norm(), 1e-14);
  EXPECT_LT((hi - Vec<3>(2.5, 0.5, 3.5)).norm(), 1e-14);
  EXPECT_TRUE(c.anchor() == Vec<3>::Zero());
  EXPECT_TRUE(c.has_normal(Vec<3>(0.6, 0, 0.8), 1e-12));
  EXPECT_STREQ(c.kind(), "pipe");
  SurfaceMesh m;
  c.tessellate(0.0, lo, hi, m);
  EXPECT_GT(m.cells.size(), 24u * 24u);
  for (const auto& q : m.points) {  // every drawn point on the wall: distance radius from the centreline
    EXPECT_NEAR(c.at(Vec<3>(q[0], q[1], q[2]), 0.0, 0.0).gap, 0.0, 1e-12);
  }
  const UTube<2> u2{Vec<2>::Zero(), Vec<2>(0, 1), Vec<2>(1, 0)};
  const PipeWall<2> c2 = u2.shape();
  EXPECT_LT((c2.end_point() - Vec<2>(2, 0)).norm(), 1e-14);
  Vec<2> lo2, hi2;
  ASSERT_TRUE(c2.bounds(lo2, hi2));
  EXPECT_LT((lo2 - Vec<2>(-0.5, 0.0)).norm(), 1e-14);
  EXPECT_LT((hi2 - Vec<2>(2.5, 3.5)).norm(), 1e-14);
  SurfaceMesh m2;
  c2.tessellate(0.0, lo2, hi2, m2);
  ASSERT_EQ(m2.cells.size(), 2u);
  for (const auto& q : m2.points) EXPECT_NEAR(c2.at(Vec<2>(q[0], q[1]), 0.0, 0.0).gap, 0.0, 1e-12);

  using P3 = PipePiece<3>;
  const Vec<3> z(0, 0, 1);
  EXPECT_THROW(PipeWall<3>(Vec<3>::Zero(), z, 0.0, {P3::straight(1)}), std::invalid_argument);
  EXPECT_THROW(PipeWall<3>(Vec<3>::Zero(), Vec<3>::Zero(), 1.0, {P3::straight(1)}), std::invalid_argument);
  EXPECT_THROW(PipeWall<3>(Vec<3>::Zero(), z, 1.0, {}), std::invalid_argument);
  EXPECT_THROW(PipeWall<3>(Vec<3>::Zero(), z, 1.0, {P3::straight(0)}), std::invalid_argument);
  EXPECT_THROW(PipeWall<3>(Vec<3>::Zero(), z, 1.0, {P3::arc(1.0, 1.0, Vec<3>(1, 0, 0))}), std::invalid_argument);
  EXPECT_THROW(PipeWall<3>(Vec<3>::Zero(), z, 1.0, {P3::arc(2.0, 0.0, Vec<3>(1, 0, 0))}), std::invalid_argument);
  EXPECT_THROW(PipeWall<3>(Vec<3>::Zero(), z, 1.0, {P3::arc(2.0, 1.0, Vec<3>(1, 0, 1))}), std::invalid_argument);
  EXPECT_THROW(PipeWall<3>(Vec<3>::Zero(), z, 1.0, {P3::arc(2.0, 7.0, Vec<3>(1, 0, 0))}), std::invalid_argument);
}

// ---- engines ---------------------------------------------------------------------------------

// An elastic EDM gas under gravity (g = 1 down) in a U-tube standing on the plane z = 0 (2D: a
// U-channel on y = 0), which closes both legs: kinetic plus potential energy is conserved to 1e-10
// and no grain leaves the tube (every 0.1 s and at the end).
template <int D>
void check_edm_gas_in_utube(int n, double R) {
  const Vec<D> up = test::up_axis<D>(), side = test::axis_x<D>();
  const UTube<D> u{Vec<D>::Zero(), up, side};
  auto shape = std::make_shared<PipeWall<D>>(u.shape());
  Vec<D> lo = Vec<D>::Constant(-0.7), hi = Vec<D>::Constant(0.7);
  lo[D - 1] = -0.2;
  hi[0] = 2.7;
  hi[D - 1] = 3.7;
  System<D> s = test::hard_material_system<D>(lo, hi);
  s.gravity = -1.0 * up;
  s.walls.push_back(Wall<D>{"pipe", 0, shape});
  s.walls.push_back(plane_wall<D>("floor", Vec<D>::Zero(), up));
  test::fill_gas<D>(s, n, R, [&](const Vec<D>& x) { return x[D - 1] > 1.5 * R && shape->at(x, R, 0.0).gap > 0.5 * R; },
                    5);
  struct Snap final : Observer<D> {
    const WallShape<D>* shape = nullptr;
    double R = 0.0, worst = 0.0;
    bool wants_snapshots() const override { return true; }
    void on_snapshot(const Snapshot<D>& sn) override {
      for (const auto& x : sn.x) worst = std::max({worst, -shape->at(x, R, sn.time).gap, R - x[D - 1]});
    }
  } snap;
  snap.shape = shape.get();
  snap.R = R;
  EdmSettings es;
  es.end_time = 20.0;
  es.snapshot_interval = 0.1;
  const RunResult<D> r = run_edm<D>(s, es, QueueKind::Calendar, {&snap});
  ASSERT_EQ(r.status, "ok") << r.message;
  auto energy = [&](const std::vector<Vec<D>>& x, const std::vector<Vec<D>>& v) {
    double e = 0.0;
    for (std::size_t i = 0; i < x.size(); ++i) e += 0.5 * v[i].squaredNorm() - s.gravity.dot(x[i]);
    return e;
  };
  const double ratio = energy(r.x, r.v) / energy(s.x, s.v);
  double worst = snap.worst;
  for (const auto& x : r.x) worst = std::max({worst, -shape->at(x, R, r.time).gap, R - x[D - 1]});
  std::printf("EDM gas in a closed U-tube (%dD): %zu grains, %llu wall collisions, energy ratio - 1 = %.3g, worst "
              "overlap %.3g\n",
              D, s.size(), static_cast<unsigned long long>(r.counts.wall), ratio - 1.0, worst);
  EXPECT_EQ(static_cast<int>(s.size()), n);
  EXPECT_NEAR(ratio, 1.0, 1e-10);
  EXPECT_LT(worst, 1e-12);
  EXPECT_LT(r.max_overlap, 1e-12);
  EXPECT_GT(r.counts.wall, 1000u);
}
TEST(PipeEngines, ElasticEdmGasInAClosedUTubeKeepsItsEnergyAndStaysInside3D) { check_edm_gas_in_utube<3>(80, 0.04); }
TEST(PipeEngines, ElasticEdmGasInAClosedUChannelKeepsItsEnergyAndStaysInside2D) { check_edm_gas_in_utube<2>(40, 0.04); }

// A grain at rest on the bottom of a horizontal straight leg (a U lying flat: legs along x, the bend
// turning about z; 2D: a channel along x bending up): the static Hertz overlap of a flat wall,
// m g = (4/3) E* sqrt(R*) delta^(3/2) with R* = R, since the engines' wall contacts take R* = R for
// every shape (engine/soft_plan.cpp wall_contact; see test_shape_cylinder.cpp).
void check_static_overlap_3d(bool hybrid) {
  const double rp = 0.2;
  auto shape = std::make_shared<PipeWall<3>>(
      Vec<3>::Zero(), Vec<3>(1, 0, 0), rp,
      std::vector<PipePiece<3>>{PipePiece<3>::straight(1.0), PipePiece<3>::arc(0.4, kPi, Vec<3>(0, 0, 1)),
                                PipePiece<3>::straight(1.0)});
  test::expect_static_hertz_overlap<3>(shape, Vec<3>(0.5, 0, -(rp - test::kGrainR)), Vec<3>(0, 0, 1),
                                       Vec<3>(0, 0, -test::kG), hybrid);
}
TEST(PipeEngines, GrainAtRestInAStraightLegHasTheStaticHertzOverlapTdm3D) { check_static_overlap_3d(false); }
TEST(PipeEngines, GrainAtRestInAStraightLegHasTheStaticHertzOverlapHybrid3D) { check_static_overlap_3d(true); }
TEST(PipeEngines, GrainAtRestInAStraightLegHasTheStaticHertzOverlapTdm2D) {
  const double rp = 0.2;
  auto shape = std::make_shared<PipeWall<2>>(
      Vec<2>::Zero(), Vec<2>(1, 0), rp,
      std::vector<PipePiece<2>>{PipePiece<2>::straight(1.0), PipePiece<2>::arc(0.4, kPi / 2),
                                PipePiece<2>::straight(0.5)});
  test::expect_static_hertz_overlap<2>(shape, Vec<2>(0.5, -(rp - test::kGrainR)), Vec<2>(0, 1),
                                       Vec<2>(0, -test::kG), false);
}

}  // namespace
}  // namespace matep

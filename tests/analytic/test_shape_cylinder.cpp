// CylinderWall (contact/cylinder.hpp).
// Impact times against the extended-precision reference (tests/support/impact_reference.hpp on a
// long-double gap written here from the geometry, not from the shape's code): infinite cylinders
// with the grains inside and outside, open tubes (lateral surface and rims), 2D circles; straight
// flights and parabolic ones; a rotating drum (the same geometry, so the same times); grazing flights
// that dip in or pass clear by 1e-9 R. Each case runs kQuick flights by default and kLong (10 000)
// in the *Long* tests (run them with --gtest_filter=*Long*; they take ~10x longer).
// Engine-level physics: an elastic EDM gas in a closed tube keeps its energy and stays inside; a
// grain at rest on the bottom of a horizontal drum has the static Hertz overlap (TDM and hybrid); a
// sphere rolling without slip at the bottom of a drum oscillates with the closed-form period.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>

#include "contact/cylinder.hpp"
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
using test::expect_limit_consistent;

constexpr int kQuick = 2000;
constexpr int kLong = 10000;
constexpr double kTmax = 3.0;
constexpr double kTol = 1e-10;

enum class Gravity { None, On };

template <int D>
Vec<D> random_perp(std::mt19937_64& rng, const Vec<D>& a) {
  for (;;) {
    Vec<D> u = test::random_unit<D>(rng);
    u -= u.dot(a) * a;
    if (u.norm() > 1e-3) return u.normalized();
  }
}

// A random cylinder (unit radius, random point and axis; 2D: axis unused).
template <int D>
CylinderWall<D> random_cylinder(std::mt19937_64& rng, double length, bool inside, double omega = 0.0) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Vec<D> p;
  for (int k = 0; k < D; ++k) p[k] = u(rng);
  return CylinderWall<D>(p, test::random_unit<D>(rng), 1.0, length, inside, omega);
}

// Long-double gap of a particle at x for the cylinder c (the definitions in cylinder.hpp's header).
template <int D>
long double gap_ld(const CylinderWall<D>& c, const VecL<D>& x, long double R) {
  const VecL<D> p = test::to_ld<D>(c.point()), a = test::to_ld<D>(c.axis());
  long double z, rho;
  test::meridian<D>(x, p, a, z, rho);
  const long double Rc = c.radius();
  if (c.finite()) return test::segment_distance(z, rho, Rc, Rc, c.length()) - R;
  return c.inside() ? Rc - rho - R : rho - Rc - R;
}

// A random flight for cylinder c: start clear of the surface (inside / outside / anywhere near a
// tube), speed 0.3..2, gravity 0.5..5 in a random direction when on.
template <int D>
FlightCase<D> random_flight(std::mt19937_64& rng, const CylinderWall<D>& c, Gravity grav) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  FlightCase<D> f;
  for (;;) {
    f.R = 0.02 + 0.28 * u(rng);
    const Vec<D> a = c.axis();
    const Vec<D> w = D == 2 ? test::random_unit<D>(rng) : random_perp<D>(rng, a);
    double rho, z = 0.0;
    if (c.finite()) {
      rho = 2.5 * u(rng);
      z = -1.0 + (c.length() + 2.0) * u(rng);
    } else if (c.inside()) {
      rho = (c.radius() - f.R) * std::sqrt(u(rng));
      z = 2.0 * u(rng) - 1.0;
    } else {
      rho = c.radius() + f.R + 2.0 * u(rng);
      z = 2.0 * u(rng) - 1.0;
    }
    f.x = c.point() + z * a + rho * w;
    f.v = (0.3 + 1.7 * u(rng)) * test::random_unit<D>(rng);
    f.g = grav == Gravity::On ? Vec<D>((0.5 + 4.5 * u(rng)) * test::random_unit<D>(rng)) : Vec<D>::Zero();
    if (gap_ld<D>(c, test::to_ld<D>(f.x), f.R) > 1e-9L) return f;
  }
}

// n flights for a fresh random cylinder of the given kind every 50 flights.
template <int D>
ImpactStats run_case(double length, bool inside, Gravity grav, int n, std::uint64_t seed, double omega = 0.0) {
  std::mt19937_64 rng(seed);
  ImpactStats total;
  for (int block = 0; block < n / 50; ++block) {
    const CylinderWall<D> c = random_cylinder<D>(rng, length, inside, omega);
    const ImpactStats s = test::check_impacts<D>(
        [&](const Vec<D>& x, const Vec<D>& v, const Vec<D>& g, double R) {
          const double t = c.impact_time(x, v, g, R, 0.0, kNever);
          expect_limit_consistent<decltype(c), D>(c, x, v, g, R, t);
          if (omega != 0.0) {  // the rotating drum: the static one's time (its axis renormalized: ulps)
            const CylinderWall<D> still(c.point(), c.axis(), c.radius(), length, inside, 0.0);
            const double ts = still.impact_time(x, v, g, R, 0.0, kNever);
            if (std::isinf(t) || std::isinf(ts)) EXPECT_EQ(t, ts);
            else EXPECT_NEAR(t, ts, 1e-12 * std::max(1.0, t));
          }
          return t;
        },
        [&](const VecL<D>& x, long double R) { return gap_ld<D>(c, x, R); },
        [&](std::mt19937_64& r) { return random_flight<D>(r, c, grav); }, 50, kTmax, kTol, rng());
    test::merge_keep_first(total, s);
  }
  return total;
}

template <int D>
void expect_case(const char* name, double length, bool inside, Gravity grav, int n, std::uint64_t seed,
                 double omega = 0.0) {
  const ImpactStats s = run_case<D>(length, inside, grav, n, seed, omega);
  s.print(name);
  EXPECT_EQ(s.missed, 0) << name << " " << s.worst_case;
  EXPECT_EQ(s.early, 0) << name << " " << s.worst_case;
  EXPECT_LE(s.worst, kTol) << name << " " << s.worst_case;
  EXPECT_GT(s.hits, s.cases / 8) << name;
}

void all_cases(int n) {
  expect_case<3>("3D inside, straight", 0.0, true, Gravity::None, n, 1);
  expect_case<3>("3D inside, gravity", 0.0, true, Gravity::On, n, 2);
  expect_case<3>("3D outside, straight", 0.0, false, Gravity::None, n, 3);
  expect_case<3>("3D outside, gravity", 0.0, false, Gravity::On, n, 4);
  expect_case<3>("3D tube, straight", 2.0, true, Gravity::None, n, 5);
  expect_case<3>("3D tube, gravity", 2.0, true, Gravity::On, n, 6);
  expect_case<3>("3D rotating drum, gravity", 0.0, true, Gravity::On, n, 7, 3.0);
  expect_case<3>("3D rotating tube, gravity", 2.0, true, Gravity::On, n, 8, -2.0);
  expect_case<2>("2D inside, straight", 0.0, true, Gravity::None, n, 9);
  expect_case<2>("2D inside, gravity", 0.0, true, Gravity::On, n, 10);
  expect_case<2>("2D outside, gravity", 0.0, false, Gravity::On, n, 11);
}

TEST(CylinderImpact, MatchesTheReference) { all_cases(kQuick); }
TEST(CylinderImpact, MatchesTheReferenceLong) { all_cases(kLong); }

// A flight that grazes the inside of a drum from within: at time T it passes a point of the inner
// offset surface (rho = Rc - R) tangentially, with gravity G along the inward normal there and
// G > s^2 sin^2(theta) / (Rc - R) (the parabola curves more than the surface: a local minimum of the
// gap, the only way to graze a concave surface). Sets T.
template <int D>
FlightCase<D> inside_graze_flight(std::mt19937_64& rng, const CylinderWall<D>& c, double& T) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (;;) {
    FlightCase<D> f;
    f.R = 0.02 + 0.28 * u(rng);
    const double s_in = c.radius() - f.R;
    const Vec<D> a = c.axis();
    const Vec<D> w = D == 2 ? test::random_unit<D>(rng) : random_perp<D>(rng, a);
    Vec<D> e;  // circumferential
    if constexpr (D == 2) e = Vec<D>(-w[1], w[0]);
    else e = a.cross(w);
    const double G = 2.0 + 3.0 * u(rng), s = 0.1 + 0.9 * u(rng);
    const double th = D == 2 ? 1.5707963267948966 : 3.141592653589793 * u(rng);
    if (!(G > 1.2 * s * s * std::sin(th) * std::sin(th) / s_in)) continue;
    const Vec<D> vT = s * (std::cos(th) * a + std::sin(th) * e);
    f.g = -G * w;
    T = 0.1 + 0.4 * u(rng);
    const Vec<D> cp = c.point() + (2.0 * u(rng) - 1.0) * a + s_in * w;
    f.x = cp - T * vT + 0.5 * T * T * f.g;
    f.v = vT - T * f.g;
    if (gap_ld<D>(c, test::to_ld<D>(f.x), f.R) > 1e-6L) return f;
  }
}

// Grazing flights: random flights shifted so that their closest approach dips in or passes clear
// by 1e-9 R (test::make_graze; from inside a drum: inside_graze_flight); the reference decides hit
// or miss, and the time must match within kTol = 1e-10 relative. A grazing root is ill-conditioned:
// the gap's rate there is ~sqrt(2 kappa 1e-9 R) ~ 1e-5 of the speed, so a round-off of 1e-16 in the
// gap would move it by ~1e-11 absolute (up to 1e-9 relative on a curved wall): the shapes refine the
// root on the gap in long double (contact/shape_features.hpp, flight_point_x).
template <int D>
void graze_cases(double length, bool inside, Gravity grav, int n, std::uint64_t seed, const char* name) {
  std::mt19937_64 rng(seed);
  ImpactStats total;
  int made = 0;
  for (int k = 0; k < n; ++k) {
    const CylinderWall<D> c = random_cylinder<D>(rng, length, inside);
    const double miss = (k % 2 ? 1e-9 : -1e-9);
    double window = kTmax, T = 0.0;
    const bool concave = inside && length <= 0.0;
    FlightCase<D> f = concave ? inside_graze_flight<D>(rng, c, T) : random_flight<D>(rng, c, grav);
    if (concave) window = 2.0 * T;
    auto gld = [&](const VecL<D>& x, long double R) { return gap_ld<D>(c, x, R); };
    if (!test::make_graze<D>(f, gld, [&](const Vec<D>& x, double R) { return c.at(x, R, 0.0).normal; }, window,
                             miss * f.R))
      continue;
    ++made;
    const ImpactStats s = test::check_impacts<D>(
        [&](const Vec<D>& x, const Vec<D>& v, const Vec<D>& g, double R) {
          return c.impact_time(x, v, g, R, 0.0, kNever);
        },
        gld, [&](std::mt19937_64&) { return f; }, 1, kTmax, kTol, 0);
    if (s.missed + s.early > 0) std::printf("  %s: %s\n", name, s.worst_case.c_str());
    test::merge(total, s);
  }
  total.print(name);
  EXPECT_GT(made, n / 4) << name;
  EXPECT_EQ(total.missed, 0) << name << " " << total.worst_case;
  EXPECT_EQ(total.early, 0) << name << " " << total.worst_case;
  EXPECT_LE(total.worst, kTol) << name << " " << total.worst_case;
}

TEST(CylinderImpact, GrazingFlightsTouchOrMissAsTheReferenceSays) {
  graze_cases<3>(0.0, false, Gravity::None, 300, 21, "graze 3D outside, straight");
  graze_cases<3>(0.0, true, Gravity::On, 300, 22, "graze 3D inside, gravity");
  graze_cases<3>(0.0, false, Gravity::On, 300, 23, "graze 3D outside, gravity");
  graze_cases<3>(2.0, true, Gravity::None, 300, 24, "graze 3D tube, straight");
  graze_cases<3>(2.0, true, Gravity::On, 300, 25, "graze 3D tube, gravity");
  graze_cases<2>(0.0, true, Gravity::On, 300, 26, "graze 2D inside, gravity");
}

// The round-off rules at t = 0 (contact/predict.hpp): overlapping and approaching -> now;
// overlapping and receding -> the next closing, not now.
TEST(CylinderImpact, RoundOffRulesAtContact) {
  const CylinderWall<3> c(Vec<3>::Zero(), Vec<3>(0, 0, 1), 1.0);
  const double R = 0.1;
  const Vec<3> x(1.0 - R + 1e-16, 0.0, 0.0);  // overlapping by round-off
  EXPECT_EQ(c.impact_time(x, Vec<3>(1.0, 0.3, 0.0), Vec<3>::Zero(), R, 0.0, kNever), 0.0);
  // Receding along -x: crosses the drum and hits the far side at 2 (1 - R) (chord through the axis).
  const double t = c.impact_time(x, Vec<3>(-1.0, 0.0, 0.0), Vec<3>::Zero(), R, 0.0, kNever);
  EXPECT_NEAR(t, 2.0 * (1.0 - R), 1e-14);
  // Overlapping by round-off at the bottom of a horizontal drum, leaving at 1e-9 while gravity 10
  // pulls it back: it turns at t = 1e-10 while still overlapping (the gap rises by v^2 / 2g =
  // 5e-20 only): the event is the turn (gap_closing_time's rule for a gap that closes again).
  const CylinderWall<3> drum(Vec<3>::Zero(), Vec<3>(1, 0, 0), 1.0);
  const Vec<3> xb(0.0, 0.0, -(1.0 - R) - 1e-15);
  EXPECT_NEAR(drum.impact_time(xb, Vec<3>(0, 0, 1e-9), Vec<3>(0, 0, -10.0), R, 0.0, kNever), 1e-10, 1e-16);
  // ... and leaving at 1e-3 it opens the gap (by 5e-8) and falls back onto the wall: the root of
  // -1e-15 + 1e-3 t - 5 t^2 = 0 after the turn, t = 2e-4. (The overlap 1e-15 is held to an ulp of
  // 0.9, 1e-16, which moves t by 1e-16 / v = 1e-13.)
  EXPECT_NEAR(drum.impact_time(xb, Vec<3>(0, 0, 1e-3), Vec<3>(0, 0, -10.0), R, 0.0, kNever),
              (1e-3 + std::sqrt(1e-6 - 20.0 * 1e-15)) / 10.0, 2e-13);
  // A tube: a particle leaving through the open end is never stopped.
  const CylinderWall<3> tube(Vec<3>::Zero(), Vec<3>(0, 0, 1), 1.0, 1.0);
  EXPECT_EQ(tube.impact_time(Vec<3>(0, 0, 0.5), Vec<3>(0, 0, 1), Vec<3>::Zero(), R, 0.0, kNever), kNever);
  // ... and one entering along the axis neither.
  EXPECT_EQ(tube.impact_time(Vec<3>(0, 0, -2), Vec<3>(0, 0, 1), Vec<3>::Zero(), R, 0.0, kNever), kNever);
  // One flying at the rim along z at rho = 1: hits the rim torus when |(rho - 1, z)| = R, at z = -R.
  EXPECT_NEAR(tube.impact_time(Vec<3>(1, 0, -2), Vec<3>(0, 0, 1), Vec<3>::Zero(), R, 0.0, kNever), 2.0 - R, 1e-14);
}

// Paths along (or within eps of) the axis of a tube no wider than the particle: the rim torus's
// quartic is then a product of two small factors, below its own round-off near the touch
// (closing_on_pieces decides on the distance itself). Closed forms:
//  * R = 0.25 > A = 0.2, falling from z = 3 at v = -1 with g = -0.3 onto the top rim (z = 1): on the
//    axis the rim is at distance sqrt(A^2 + (z - 1)^2) = R at z = 1.15: 0.15 t^2 + t = 1.85 (within
//    eps, the touch moves by O(eps));
//  * R = A = 0.2 rising along the axis at speed 1 from z = -3 towards the bottom rim (z = 0), eps off
//    the axis: it passes within A - eps of the circle, touching when (A - eps)^2 + z^2 = A^2,
//    z = -sqrt(2 A eps - eps^2) (a grazing touch: tolerance from its conditioning, 1e-9).
TEST(CylinderImpact, PathsAlongTheAxisOfANarrowTubeTouchItsRim) {
  const CylinderWall<3> tube(Vec<3>::Zero(), Vec<3>(0, 0, 1), 0.2, 1.0);
  const Vec<3> d = Vec<3>(0.3, 0.7, 0.0).normalized();
  const double t_fall = (-1.0 + std::sqrt(1.0 + 4.0 * 0.15 * 1.85)) / 0.3;
  for (double eps : {0.0, 1e-15, 1e-12, 1e-9, 1e-6}) {
    const double t = tube.impact_time(Vec<3>(eps * d + Vec<3>(0, 0, 3)), Vec<3>(0, 0, -1), Vec<3>(0, 0, -0.3), 0.25,
                                      0.0, kNever);
    EXPECT_NEAR(t, t_fall, 1e-13 + 10.0 * eps) << eps;
  }
  for (double eps : {1e-13, 1e-11, 1e-9, 1e-7, 1e-5}) {
    const double t =
        tube.impact_time(Vec<3>(eps * d + Vec<3>(0, 0, -3)), Vec<3>(0, 0, 1), Vec<3>::Zero(), 0.2, 0.0, kNever);
    EXPECT_NEAR(t, 3.0 - std::sqrt(2.0 * 0.2 * eps - eps * eps), 1e-9) << eps;
  }
}

// The rest of the interface on hand-made points: gaps and normals, surface velocity of a turning
// drum (omega axis x (q - point) at the contact point q), bounds, speeds, normals, invalid input.
TEST(CylinderShape, GeometryVelocityBoundsAndNormals) {
  const double R = 0.1;
  const CylinderWall<3> drum(Vec<3>::Zero(), Vec<3>(0, 0, 2), 1.0, 0.0, true, 2.0);  // axis normalized
  WallPoint<3> c = drum.at(Vec<3>(0.5, 0, 3), R, 0.0);
  EXPECT_NEAR(c.gap, 1.0 - 0.5 - R, 1e-15);
  EXPECT_LT((c.normal - Vec<3>(-1, 0, 0)).norm(), 1e-15);
  EXPECT_LT((c.velocity - Vec<3>(0, 2, 0)).norm(), 1e-15);  // q = (1, 0, 3): 2 z x (1, 0, 0)
  EXPECT_LT((drum.surface_velocity(Vec<3>(0.5, 0, 3), R, 0.0) - Vec<3>(0, 2, 0)).norm(), 1e-15);
  EXPECT_DOUBLE_EQ(drum.max_speed(), 2.0);
  EXPECT_TRUE(drum.moving());
  EXPECT_STREQ(drum.kind(), "cylinder");
  EXPECT_NE(drum.describe().find("infinite cylinder"), std::string::npos);
  Vec<3> lo, hi;
  EXPECT_FALSE(drum.bounds(lo, hi));
  EXPECT_TRUE(drum.has_normal(Vec<3>(0.6, 0.8, 0), 1e-12));
  EXPECT_FALSE(drum.has_normal(Vec<3>(0, 0, 1), 1e-12));
  const CylinderWall<3> pipe(Vec<3>::Zero(), Vec<3>(0, 0, 1), 1.0, 0.0, false);
  c = pipe.at(Vec<3>(0, 2, 0), R, 0.0);
  EXPECT_NEAR(c.gap, 2.0 - 1.0 - R, 1e-15);
  EXPECT_LT((c.normal - Vec<3>(0, 1, 0)).norm(), 1e-15);
  EXPECT_NEAR(pipe.at(Vec<3>(0, 0.5, 0), R, 0.0).gap, 0.5 - 1.0 - R, 1e-15);  // wrong side: overlap
  EXPECT_FALSE(pipe.moving());
  // A tube: below its bottom end on the axis the nearest points are the rim, sqrt(1 + 1) away.
  const CylinderWall<3> tube(Vec<3>::Zero(), Vec<3>(1, 0, 0), 1.0, 2.0);
  c = tube.at(Vec<3>(-1, 0, 0), R, 0.0);
  EXPECT_NEAR(c.gap, std::sqrt(2.0) - R, 1e-15);
  EXPECT_NEAR(c.normal[0], -1.0 / std::sqrt(2.0), 1e-15);
  // ... and from outside and inside of the wall the same distance: a sheet.
  EXPECT_NEAR(tube.at(Vec<3>(1, 0, 1.3), R, 0.0).gap, 0.3 - R, 1e-15);
  EXPECT_NEAR(tube.at(Vec<3>(1, 0, 0.7), R, 0.0).gap, 0.3 - R, 1e-15);
  EXPECT_TRUE(tube.bounds(lo, hi));
  EXPECT_LT((lo - Vec<3>(0, -1, -1)).norm(), 1e-15);
  EXPECT_LT((hi - Vec<3>(2, 1, 1)).norm(), 1e-15);
  EXPECT_TRUE(tube.has_normal(Vec<3>(1, 0, 0), 1e-12));  // at a rim
  EXPECT_NE(tube.describe().find("open tube"), std::string::npos);
  // 2D: a circle turning about its centre.
  const CylinderWall<2> circle(Vec<2>(1, 1), Vec<2>::Zero(), 0.5, 0.0, true, -3.0);
  const WallPoint<2> c2 = circle.at(Vec<2>(1, 1.2), R, 0.0);
  EXPECT_NEAR(c2.gap, 0.5 - 0.2 - R, 1e-15);
  EXPECT_LT((c2.normal - Vec<2>(0, -1)).norm(), 1e-15);
  EXPECT_LT((c2.velocity - Vec<2>(1.5, 0)).norm(), 1e-15);  // q - centre = (0, 0.5): -3 (-0.5, 0)
  EXPECT_THROW(CylinderWall<3>(Vec<3>::Zero(), Vec<3>(0, 0, 1), 0.0), std::invalid_argument);
  EXPECT_THROW(CylinderWall<2>(Vec<2>::Zero(), Vec<2>::Zero(), 1.0, 2.0), std::invalid_argument);
}

// ---- engines ---------------------------------------------------------------------------------

// An elastic EDM gas in a closed tube: an open tube (length 2, radius 1, touched from both sides)
// with two infinite planes as caps. Kinetic energy is conserved to round-off and every grain stays
// inside (gap to the tube >= 0 and inside its radius).
TEST(CylinderEngines, ElasticEdmGasInAClosedTubeKeepsItsEnergyAndStaysInside) {
  const double R = 0.05, L = 2.0;
  System<3> s = test::hard_material_system<3>(Vec<3>(-1.2, -1.2, -0.2), Vec<3>(1.2, 1.2, L + 0.2));
  s.walls.push_back(Wall<3>{"tube", 0, std::make_shared<CylinderWall<3>>(Vec<3>::Zero(), Vec<3>(0, 0, 1), 1.0, L)});
  s.walls.push_back(plane_wall<3>("bottom", Vec<3>::Zero(), Vec<3>(0, 0, 1)));
  s.walls.push_back(plane_wall<3>("top", Vec<3>(0, 0, L), Vec<3>(0, 0, -1)));
  test::fill_gas<3>(s, 80, R, [&](const Vec<3>& x) {
    return std::hypot(x[0], x[1]) < 1.0 - 1.5 * R && x[2] > 1.5 * R && x[2] < L - 1.5 * R;
  }, 5);
  EdmSettings es;
  es.end_time = 10.0;
  const RunResult<3> r = run_edm<3>(s, es, QueueKind::Calendar);
  ASSERT_EQ(r.status, "ok") << r.message;
  const double ke0 = test::kinetic<3>(s.v), ke1 = test::kinetic<3>(r.v);
  EXPECT_NEAR(ke1 / ke0, 1.0, 1e-10);
  double worst = 0.0;
  for (const auto& x : r.x) {
    worst = std::max(worst, -s.walls[0].geometry().at(x, R, r.time).gap);
    worst = std::max(worst, std::hypot(x[0], x[1]) + R - 1.0);
  }
  EXPECT_LT(worst, 1e-12);
  EXPECT_LT(r.max_overlap, 1e-12);
  EXPECT_GT(r.counts.wall, 500u);
  std::printf("EDM gas in a closed tube: %llu wall collisions, energy ratio - 1 = %.3g, worst overlap %.3g\n",
              static_cast<unsigned long long>(r.counts.wall), ke1 / ke0 - 1.0, worst);
}

// Grains on both sides of a tilted open tube in a closed box under gravity (rims, both faces).
TEST(CylinderEngines, ElasticEdmGasAroundATiltedOpenTubeKeepsItsEnergy) {
  const Vec<3> a = Vec<3>(0.3, -0.2, 1.0).normalized();
  auto tube = std::make_shared<CylinderWall<3>>(Vec<3>(-0.45 * a), a, 0.25, 0.9);
  test::expect_edm_gas_around<3>(tube, 80, 0.03, 11, "tilted tube");
}

// The same in 2D: a circle with gravity; kinetic plus potential energy is conserved.
TEST(CylinderEngines, ElasticEdmGasInACircleUnderGravityKeepsItsEnergy) {
  const double R = 0.04;
  System<2> s = test::hard_material_system<2>(Vec<2>(-1.2, -1.2), Vec<2>(1.2, 1.2));
  s.gravity = Vec<2>(0.0, -1.0);
  s.walls.push_back(Wall<2>{"drum", 0, std::make_shared<CylinderWall<2>>(Vec<2>::Zero(), Vec<2>::Zero(), 1.0)});
  test::fill_gas<2>(s, 60, R, [&](const Vec<2>& x) { return x.norm() < 1.0 - 1.5 * R; }, 6);
  EdmSettings es;
  es.end_time = 10.0;
  const RunResult<2> r = run_edm<2>(s, es, QueueKind::Calendar);
  ASSERT_EQ(r.status, "ok") << r.message;
  auto energy = [&](const std::vector<Vec<2>>& x, const std::vector<Vec<2>>& v) {
    double e = 0.0;
    for (std::size_t i = 0; i < x.size(); ++i) e += 0.5 * v[i].squaredNorm() - s.gravity.dot(x[i]);
    return e;
  };
  EXPECT_NEAR(energy(r.x, r.v) / energy(s.x, s.v), 1.0, 1e-10);
  for (const auto& x : r.x) EXPECT_LT(x.norm() + R - 1.0, 1e-12);
  EXPECT_GT(r.counts.wall, 200u);
}

// A grain at rest on the bottom of a horizontal drum (axis x, radius 0.5): the static Hertz overlap
// m g = (4/3) E* sqrt(R*) delta^(3/2). The engines' wall contacts take R* = R for every shape
// (engine/soft_plan.cpp wall_contact: a wall is flat for the contact law), so
// delta = (3 m g / (4 E* sqrt(R)))^(2/3), E* = 1/((1 - nu^2)/E + (1 - nu^2)/E) (the wall of the
// grain's material). (The exact Hertz contact of a sphere in a cylinder is elliptic, with principal
// relative curvatures 1/R along the axis and 1/R - 1/Rc around it; see the final report.)
template <int D>
void check_static_overlap(bool hybrid) {
  const double Rc = 0.5;
  auto shape = std::make_shared<CylinderWall<D>>(Vec<D>::Zero(), test::axis_x<D>(), Rc);
  const Vec<D> dn = test::down<D>();
  test::expect_static_hertz_overlap<D>(shape, Vec<D>((Rc - test::kGrainR) * dn), Vec<D>(-dn), Vec<D>(test::kG * dn),
                                       hybrid);
}
TEST(CylinderEngines, GrainAtRestInADrumHasTheStaticHertzOverlapTdm3D) { check_static_overlap<3>(false); }
TEST(CylinderEngines, GrainAtRestInADrumHasTheStaticHertzOverlapTdm2D) { check_static_overlap<2>(false); }
TEST(CylinderEngines, GrainAtRestInADrumHasTheStaticHertzOverlapHybrid3D) { check_static_overlap<3>(true); }

// A sphere rolling without slip at the bottom of a horizontal drum (radius Rc, grain r): for small
// amplitude the centre swings on a circle of radius a = Rc - r with period
// 2 pi sqrt(7 (Rc - r) / (5 g)) (energy m v^2 / 2 + I w^2 / 2, I = 2/5 m r^2, rolling v = w r:
// effective mass 7/5 m; the classical ball-in-a-bowl result); 2D disks (I = 1/2 m r^2):
// 2 pi sqrt(3 (Rc - r) / (2 g)). A soft grain touches the wall at l = r - delta from its centre
// (delta the static Hertz overlap), so the lever is l and a = Rc - l:
// T = 2 pi sqrt((1 + q r^2 / l^2) a / g) (1 + theta0^2 / 16) with q = I / (m r^2) and the
// amplitude theta0 = 0.05 (the pendulum's finite-amplitude factor). The corrections are 0.3 % in
// 3D and 2 % in 2D (a 2D Hertz grain sinks in 5 % of its radius).
template <int D>
void check_rolling(bool hybrid) {
  const double Rc = 0.5, r = test::kGrainR;
  auto shape = std::make_shared<CylinderWall<D>>(Vec<D>::Zero(), test::axis_x<D>(), Rc);
  const double q = D == 3 ? 0.4 : 0.5;  // I / (m r^2)
  const double delta = test::hertz_overlap(test::grain_mass<D>(r) * test::kG, r);
  const double l = r - delta, a = Rc - l;
  const double T = 2.0 * 3.141592653589793 * std::sqrt((1.0 + q * r * r / (l * l)) * a / test::kG) *
                   (1.0 + 0.05 * 0.05 / 16.0);
  const double rigid = 2.0 * 3.141592653589793 * std::sqrt((1.0 + q) * (Rc - r) / test::kG);
  const double got = test::rolling_period<D>(shape, Rc - r, hybrid);
  std::printf("rolling in a drum (%s, %dD): period %.6f, closed form %.6f (rigid %.6f), ratio - 1 = %.3g\n",
              hybrid ? "hybrid" : "TDM", D, got, T, rigid, got / T - 1.0);
  EXPECT_NEAR(got / T, 1.0, 5e-3);
}
TEST(CylinderEngines, SphereRollingInADrumHasTheClosedFormPeriodTdm) { check_rolling<3>(false); }
TEST(CylinderEngines, SphereRollingInADrumHasTheClosedFormPeriodHybrid) { check_rolling<3>(true); }
TEST(CylinderEngines, DiskRollingInACircleHasTheClosedFormPeriodTdm) { check_rolling<2>(false); }

}  // namespace
}  // namespace matep

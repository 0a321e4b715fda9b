// ConeWall (contact/cone.hpp).
// Impact times against the extended-precision reference (tests/support/impact_reference.hpp on a
// long-double gap written here: the distance in the meridian half-plane to the generator segment):
// hoppers (r1 > r2 > 0), full cones (an apex at either end), a flat wide frustum, the 2D axial
// section; straight and parabolic flights from anywhere around the sheet (it is touched from both
// sides); a rotating cone (same geometry, same times); grazing flights that dip in or pass clear by
// 1e-9 R. kQuick flights per case by default, kLong (10 000) in the *Long* test.
// Engine-level physics: an elastic EDM gas in a closed hopper keeps its energy and stays inside, and
// so does one draining through an open hopper (3D, 2D) or around a full cone under gravity; a grain
// at rest inside a cone lying on its side has the static Hertz overlap (TDM and hybrid); a
// frictionless sphere slides down the inside of a cone with the closed-form acceleration
// g cos(beta) along the generator (TDM and hybrid).
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>

#include "contact/cone.hpp"
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

struct Shape {
  double r1, r2, L;
};
constexpr Shape kHopper{0.8, 0.2, 1.0}, kApexTop{0.7, 0.0, 1.2}, kApexBottom{0.0, 0.6, 0.8}, kFlat{1.0, 0.3, 0.3};

template <int D>
ConeWall<D> random_cone(std::mt19937_64& rng, const Shape& sh, double omega = 0.0) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Vec<D> p;
  for (int k = 0; k < D; ++k) p[k] = u(rng);
  return ConeWall<D>(p, test::random_unit<D>(rng), sh.r1, sh.r2, sh.L, omega);
}

template <int D>
long double gap_ld(const ConeWall<D>& c, const VecL<D>& x, long double R) {
  long double z, rho;
  test::meridian<D>(x, test::to_ld<D>(c.point()), test::to_ld<D>(c.axis()), z, rho);
  return test::segment_distance(z, rho, c.r1(), c.r2(), c.length()) - R;
}

// Starts anywhere in the cylinder around the cone (z in [-0.7, L + 0.7], rho up to max r + 0.7),
// clear of the sheet; speed 0.3..2; gravity 0.5..5 in a random direction when on.
template <int D>
FlightCase<D> random_flight(std::mt19937_64& rng, const ConeWall<D>& c, bool gravity) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  FlightCase<D> f;
  for (;;) {
    f.R = 0.02 + 0.18 * u(rng);
    const Vec<D> a = c.axis();
    Vec<D> w = test::random_unit<D>(rng);
    w -= w.dot(a) * a;
    if (w.norm() < 1e-3) continue;
    w.normalize();
    const double rho = (std::max(c.r1(), c.r2()) + 0.7) * std::sqrt(u(rng));
    const double z = -0.7 + (c.length() + 1.4) * u(rng);
    f.x = c.point() + z * a + rho * w;
    f.v = (0.3 + 1.7 * u(rng)) * test::random_unit<D>(rng);
    f.g = gravity ? Vec<D>((0.5 + 4.5 * u(rng)) * test::random_unit<D>(rng)) : Vec<D>::Zero();
    if (gap_ld<D>(c, test::to_ld<D>(f.x), f.R) > 1e-9L) return f;
  }
}

template <int D>
void expect_case(const char* name, const Shape& sh, bool gravity, int n, std::uint64_t seed, double omega = 0.0) {
  std::mt19937_64 rng(seed);
  ImpactStats total;
  for (int block = 0; block < n / 50; ++block) {
    const ConeWall<D> c = random_cone<D>(rng, sh, omega);
    const ImpactStats s = test::check_impacts<D>(
        [&](const Vec<D>& x, const Vec<D>& v, const Vec<D>& g, double R) {
          const double t = c.impact_time(x, v, g, R, 0.0, kNever);
          expect_limit_consistent<decltype(c), D>(c, x, v, g, R, t);
          if (omega != 0.0) {  // the static cone's time (its axis renormalized: ulps)
            const ConeWall<D> still(c.point(), c.axis(), sh.r1, sh.r2, sh.L);
            const double ts = still.impact_time(x, v, g, R, 0.0, kNever);
            if (std::isinf(t) || std::isinf(ts)) EXPECT_EQ(t, ts);
            else EXPECT_NEAR(t, ts, 1e-12 * std::max(1.0, t));
          }
          return t;
        },
        [&](const VecL<D>& x, long double R) { return gap_ld<D>(c, x, R); },
        [&](std::mt19937_64& r) { return random_flight<D>(r, c, gravity); }, 50, kTmax, kTol, rng());
    test::merge(total, s);
  }
  total.print(name);
  EXPECT_EQ(total.missed, 0) << name << " " << total.worst_case;
  EXPECT_EQ(total.early, 0) << name << " " << total.worst_case;
  EXPECT_LE(total.worst, kTol) << name << " " << total.worst_case;
  EXPECT_GT(total.hits, total.cases / 10) << name;
}

void all_cases(int n) {
  expect_case<3>("3D hopper, straight", kHopper, false, n, 1);
  expect_case<3>("3D hopper, gravity", kHopper, true, n, 2);
  expect_case<3>("3D apex at the far end, gravity", kApexTop, true, n, 3);
  expect_case<3>("3D apex at the point, straight", kApexBottom, false, n, 4);
  expect_case<3>("3D flat frustum, gravity", kFlat, true, n, 5);
  expect_case<3>("3D rotating hopper, gravity", kHopper, true, n, 6, 2.5);
  expect_case<2>("2D hopper, straight", kHopper, false, n, 7);
  expect_case<2>("2D hopper, gravity", kHopper, true, n, 8);
  expect_case<2>("2D V (apex), gravity", kApexBottom, true, n, 9);
}

TEST(ConeImpact, MatchesTheReference) { all_cases(kQuick); }
TEST(ConeImpact, MatchesTheReferenceLong) { all_cases(kLong); }

// Grazing flights (test::make_graze): random flights shifted along the normal at their closest
// approach until they dip in or pass clear by 1e-9 R. Tolerance kTol = 1e-10 relative, as for the
// random flights (a grazing root's conditioning: see test_shape_cylinder.cpp).
template <int D>
void graze_cases(const Shape& sh, bool gravity, int n, std::uint64_t seed, const char* name) {
  std::mt19937_64 rng(seed);
  ImpactStats total;
  int made = 0;
  for (int k = 0; k < n; ++k) {
    const ConeWall<D> c = random_cone<D>(rng, sh);
    const double miss = (k % 2 ? 1e-9 : -1e-9);
    FlightCase<D> f = random_flight<D>(rng, c, gravity);
    auto gld = [&](const VecL<D>& x, long double R) { return gap_ld<D>(c, x, R); };
    if (!test::make_graze<D>(f, gld, [&](const Vec<D>& x, double R) { return c.at(x, R, 0.0).normal; }, kTmax,
                             miss * f.R))
      continue;
    ++made;
    const ImpactStats s = test::check_impacts<D>(
        [&](const Vec<D>& x, const Vec<D>& v, const Vec<D>& g, double R) {
          return c.impact_time(x, v, g, R, 0.0, kNever);
        },
        gld, [&](std::mt19937_64&) { return f; }, 1, kTmax, kTol, 0);
    test::merge(total, s);
  }
  total.print(name);
  EXPECT_GT(made, n / 5) << name;
  EXPECT_EQ(total.missed, 0) << name << " " << total.worst_case;
  EXPECT_EQ(total.early, 0) << name << " " << total.worst_case;
  EXPECT_LE(total.worst, kTol) << name << " " << total.worst_case;
}

TEST(ConeImpact, GrazingFlightsTouchOrMissAsTheReferenceSays) {
  graze_cases<3>(kHopper, false, 300, 21, "graze 3D hopper, straight");
  graze_cases<3>(kHopper, true, 300, 22, "graze 3D hopper, gravity");
  graze_cases<3>(kApexTop, true, 300, 23, "graze 3D apex, gravity");
  graze_cases<2>(kHopper, true, 300, 24, "graze 2D hopper, gravity");
}

// Hand-made flights with known answers.
TEST(ConeImpact, ClosedFormFlights) {
  // A 45-degree cone, apex at the origin, opening upwards (r = z): a particle falling along the
  // axis from z = 2 inside it meets the inner offset cone where its centre is R sqrt(2) above the
  // apex (the offset of rho = z by R: rho = z - R sqrt 2); it touches the apex point first? No: on
  // the axis the distance to the surface is z / sqrt 2, reached R at z = R sqrt 2.
  const ConeWall<3> cone(Vec<3>::Zero(), Vec<3>(0, 0, 1), 0.0, 1.0, 1.0);
  const double R = 0.1;
  const double t = cone.impact_time(Vec<3>(0, 0, 2), Vec<3>(0, 0, -1), Vec<3>::Zero(), R, 0.0, kNever);
  EXPECT_NEAR(t, 2.0 - R * std::sqrt(2.0), 1e-14);
  // Under gravity g = 1 from rest: 1/2 t^2 = 2 - R sqrt 2.
  const double tg = cone.impact_time(Vec<3>(0, 0, 2), Vec<3>::Zero(), Vec<3>(0, 0, -1), R, 0.0, kNever);
  EXPECT_NEAR(tg, std::sqrt(2.0 * (2.0 - R * std::sqrt(2.0))), 1e-14);
  // Approaching the apex from below along the axis: the apex point at distance R, t = 1 - R.
  EXPECT_NEAR(cone.impact_time(Vec<3>(0, 0, -1), Vec<3>(0, 0, 1), Vec<3>::Zero(), R, 0.0, kNever), 1.0 - R, 1e-14);
  // A hopper's outlet (r2 = 0.2 at z = 1, axis up from r1 = 0.8 at z = 0, falling down the axis from
  // z = 3): it passes through the outlet unless R >= 0.2 ... with R = 0.1 it flies through both
  // openings: never.
  const ConeWall<3> hopper(Vec<3>::Zero(), Vec<3>(0, 0, 1), 0.8, 0.2, 1.0);
  EXPECT_EQ(hopper.impact_time(Vec<3>(0, 0, 3), Vec<3>(0, 0, -1), Vec<3>::Zero(), R, 0.0, kNever), kNever);
  // R = 0.25 does not fit through the outlet: it hits the rim torus (circle radius 0.2 at z = 1)
  // where sqrt(0.2^2 + (z - 1)^2) = 0.25: z = 1.15, t = 1.85.
  EXPECT_NEAR(hopper.impact_time(Vec<3>(0, 0, 3), Vec<3>(0, 0, -1), Vec<3>::Zero(), 0.25, 0.0, kNever), 1.85, 1e-13);
  // The same two paths eps off the axis (the torus and the offset cone are then products of two
  // small factors near the touch; closing_on_pieces decides on the distance): the touch moves by
  // O(eps) (first order: the apex case reaches rho = c + k z = eps, so 1 eps earlier in z).
  const Vec<3> d = Vec<3>(0.3, 0.7, 0.0).normalized();
  for (double eps : {1e-15, 1e-12, 1e-9, 1e-6}) {
    EXPECT_NEAR(cone.impact_time(Vec<3>(eps * d + Vec<3>(0, 0, 2)), Vec<3>(0, 0, -1), Vec<3>::Zero(), R, 0.0, kNever),
                2.0 - R * std::sqrt(2.0) - eps, 1e-13 + 1e-3 * eps)
        << eps;
    EXPECT_NEAR(
        hopper.impact_time(Vec<3>(eps * d + Vec<3>(0, 0, 3)), Vec<3>(0, 0, -1), Vec<3>::Zero(), 0.25, 0.0, kNever),
        1.85, 1e-13 + 10.0 * eps)
        << eps;
  }
}

// The rest of the interface on hand-made points.
TEST(ConeShape, GeometryVelocityBoundsAndNormals) {
  const double R = 0.1;
  // 45 degrees: rho = 0.2 + z for z in [0, 0.5]; turning at 2 rad/s about +z.
  const ConeWall<3> cone(Vec<3>::Zero(), Vec<3>(0, 0, 1), 0.2, 0.7, 0.5, 2.0);
  // A point at rho = 0.2 + 0.25 - d sqrt 2 / ... : take the foot (0.45, 0, 0.25) and go d = 0.05
  // along the inward normal (-1, 0, 1)/sqrt 2.
  const Vec<3> n(-1.0 / std::sqrt(2.0), 0, 1.0 / std::sqrt(2.0));
  const Vec<3> foot(0.45, 0, 0.25);
  WallPoint<3> c = cone.at(Vec<3>(foot + 0.05 * n), R, 0.0);
  EXPECT_NEAR(c.gap, 0.05 - R, 1e-15);
  EXPECT_LT((c.normal - n).norm(), 1e-14);
  EXPECT_LT((c.velocity - Vec<3>(0, 2.0 * 0.45, 0)).norm(), 1e-14);  // 2 z x (0.45, 0, 0.25)
  c = cone.at(Vec<3>(foot - 0.05 * n), R, 0.0);  // the outside: the same distance
  EXPECT_NEAR(c.gap, 0.05 - R, 1e-15);
  EXPECT_LT((c.normal + n).norm(), 1e-14);
  // Above the wide end, on the axis at z = 1: in the meridian plane the nearest point of the
  // generator (0, 0.2)-(0.5, 0.7) is its foot at tau = (1 * 0.5 - 0.2 * 0.5) / 0.5 = 0.8, (z, rho) =
  // (0.4, 0.6), sqrt(0.6^2 + 0.6^2) away (nearer than the rim, sqrt(0.7^2 + 0.5^2)).
  EXPECT_NEAR(cone.at(Vec<3>(0, 0, 1.0), R, 0.0).gap, std::hypot(0.6, 0.6) - R, 1e-15);
  // Below the narrow end on the axis at z = -1: tau < 0, the rim (0, 0.2) is nearest.
  EXPECT_NEAR(cone.at(Vec<3>(0, 0, -1.0), R, 0.0).gap, std::hypot(1.0, 0.2) - R, 1e-15);
  Vec<3> lo, hi;
  EXPECT_TRUE(cone.bounds(lo, hi));
  EXPECT_LT((lo - Vec<3>(-0.7, -0.7, 0)).norm(), 1e-15);
  EXPECT_LT((hi - Vec<3>(0.7, 0.7, 0.5)).norm(), 1e-15);
  EXPECT_DOUBLE_EQ(cone.max_speed(), 1.4);
  EXPECT_TRUE(cone.moving());
  EXPECT_TRUE(cone.has_normal(Vec<3>(0, 0, 1), 1e-12));
  EXPECT_STREQ(cone.kind(), "cone");
  EXPECT_NE(cone.describe().find("rotating"), std::string::npos);
  // 2D: the two mirrored segments.
  const ConeWall<2> v(Vec<2>::Zero(), Vec<2>(0, 1), 0.2, 0.7, 0.5);
  EXPECT_NEAR(v.at(Vec<2>(-0.45, 0.25) + 0.05 * Vec<2>(1, 1) / std::sqrt(2.0), R, 0.0).gap, 0.05 - R, 1e-15);
  EXPECT_NEAR(v.at(Vec<2>(0.45, 0.25) + 0.05 * Vec<2>(-1, 1) / std::sqrt(2.0), R, 0.0).gap, 0.05 - R, 1e-15);
  EXPECT_THROW(ConeWall<3>(Vec<3>::Zero(), Vec<3>(0, 0, 1), 0.0, 0.0, 1.0), std::invalid_argument);
  EXPECT_THROW(ConeWall<3>(Vec<3>::Zero(), Vec<3>(0, 0, 1), 0.2, 0.3, 0.0), std::invalid_argument);
}

// ---- engines ---------------------------------------------------------------------------------

// A hopper (45 degrees: r = 0.3 at z = 0 up to 0.8 at z = 0.5) closed by two planes: an elastic
// EDM gas keeps its energy and every grain stays inside the cone.
TEST(ConeEngines, ElasticEdmGasInAClosedHopperKeepsItsEnergyAndStaysInside) {
  const double R = 0.04, r1 = 0.3, r2 = 0.8, L = 0.5;
  System<3> s = test::hard_material_system<3>(Vec<3>(-1, -1, -0.2), Vec<3>(1, 1, L + 0.2));
  s.walls.push_back(Wall<3>{"hopper", 0, std::make_shared<ConeWall<3>>(Vec<3>::Zero(), Vec<3>(0, 0, 1), r1, r2, L)});
  s.walls.push_back(plane_wall<3>("bottom", Vec<3>::Zero(), Vec<3>(0, 0, 1)));
  s.walls.push_back(plane_wall<3>("top", Vec<3>(0, 0, L), Vec<3>(0, 0, -1)));
  const double k = (r2 - r1) / L, c = std::sqrt(1.0 + k * k);  // inner offset: rho = r1 + k z - R c
  test::fill_gas<3>(s, 60, R, [&](const Vec<3>& x) {
    return x[2] > 1.5 * R && x[2] < L - 1.5 * R && std::hypot(x[0], x[1]) < r1 + k * x[2] - 1.5 * R * c;
  }, 5);
  EdmSettings es;
  es.end_time = 10.0;
  const RunResult<3> r = run_edm<3>(s, es, QueueKind::Calendar);
  ASSERT_EQ(r.status, "ok") << r.message;
  EXPECT_NEAR(test::kinetic<3>(r.v) / test::kinetic<3>(s.v), 1.0, 1e-10);
  double worst = 0.0;
  for (const auto& x : r.x) {
    worst = std::max(worst, -s.walls[0].geometry().at(x, R, r.time).gap);
    worst = std::max(worst, std::hypot(x[0], x[1]) - (r1 + k * x[2]));  // centre inside the cone
  }
  EXPECT_LT(worst, 1e-12);
  EXPECT_LT(r.max_overlap, 1e-12);
  EXPECT_GT(r.counts.wall, 500u);
  std::printf("EDM gas in a closed hopper: %llu wall collisions, energy ratio - 1 = %.3g\n",
              static_cast<unsigned long long>(r.counts.wall), test::kinetic<3>(r.v) / test::kinetic<3>(s.v) - 1.0);
}

// Grains draining through an open hopper (outlet wider than a grain) onto the box's floor and
// bouncing back onto its outside: rims, both faces, under gravity; 3D and 2D; and a full cone
// with its apex down (an apex point).
TEST(ConeEngines, ElasticEdmGasThroughAnOpenHopperKeepsItsEnergy) {
  auto hopper = std::make_shared<ConeWall<3>>(Vec<3>(0, 0, -0.2), Vec<3>(0, 0, 1), 0.1, 0.45, 0.5);
  test::expect_edm_gas_around<3>(hopper, 80, 0.03, 12, "hopper 3D");
  auto hopper2 = std::make_shared<ConeWall<2>>(Vec<2>(0, -0.2), Vec<2>(0, 1), 0.1, 0.45, 0.5);
  test::expect_edm_gas_around<2>(hopper2, 40, 0.03, 13, "hopper 2D");
  auto funnel = std::make_shared<ConeWall<3>>(Vec<3>(0.05, 0, -0.3), Vec<3>(0.1, 0.2, 1.0), 0.0, 0.4, 0.6);
  test::expect_edm_gas_around<3>(funnel, 80, 0.03, 14, "full cone, apex down");
}

// A grain at rest inside a cone lying on its side: the axis is tilted up by the half-angle alpha
// (tan alpha = (r2 - r1) / L) so that the lowest generator is horizontal; the grain sits on it, in
// the transverse trough (a sphere on a slope would roll: friction cannot hold it). The contact
// normal is vertical, the normal load m g: the static Hertz overlap (R* = R, as in the drum test).
template <int D>
void check_static(bool hybrid) {
  const double r1 = 0.2, r2 = 0.5, L = 0.6, R = test::kGrainR;
  const double al = std::atan((r2 - r1) / L), ell = std::hypot(L, r2 - r1);
  Vec<D> a = Vec<D>::Zero(), w = Vec<D>::Zero();
  a[0] = std::cos(al);
  a[D - 1] = std::sin(al);
  w[0] = std::sin(al);
  w[D - 1] = -std::cos(al);
  auto cone = std::make_shared<ConeWall<D>>(Vec<D>::Zero(), a, r1, r2, L);
  const Vec<D> n = -((-(r2 - r1) / ell) * a + (L / ell) * w);  // inward normal of the lowest generator
  ASSERT_LT((n - test::up_axis<D>()).norm(), 1e-14);
  const Vec<D> surf = 0.5 * L * a + 0.5 * (r1 + r2) * w;
  test::expect_static_hertz_overlap<D>(cone, Vec<D>(surf + R * n), n, Vec<D>(test::kG * test::down<D>()), hybrid);
}
TEST(ConeEngines, GrainAtRestInAConeOnItsSideHasTheStaticHertzOverlapTdm3D) { check_static<3>(false); }
TEST(ConeEngines, GrainAtRestInAConeOnItsSideHasTheStaticHertzOverlapTdm2D) { check_static<2>(false); }
TEST(ConeEngines, GrainAtRestInAConeOnItsSideHasTheStaticHertzOverlapHybrid3D) { check_static<3>(true); }

// A frictionless grain slides down the inside of a cone along a generator (no azimuthal motion):
// the forces are gravity and the normal force, so along the generator (unit e, pointing down the
// slope) its acceleration is g.e = g cos(beta), beta the angle between the generator and the
// vertical; here a cone with rho = r1 + z tan(beta) with beta = 30 degrees from the axis (60 from
// horizontal): g cos(30). Released at the static overlap, the centre's height falls as
// z(t) = z0 - 1/2 g cos^2(beta) t^2 (the vertical part of the slide), checked at t = 0.2 s.
template <int D>
void check_slide(bool hybrid) {
  const double beta = 3.141592653589793 / 6.0, r1 = 0.1, L = 1.0, r2 = r1 + L * std::tan(beta), R = test::kGrainR;
  auto cone = std::make_shared<ConeWall<D>>(Vec<D>::Zero(), test::up_axis<D>(), r1, r2, L);
  const double ell = std::hypot(L, r2 - r1);
  Vec<D> n = Vec<D>::Zero();  // inward normal of the slope in the x-z plane: (-L, r2 - r1) / ell
  n[0] = -L / ell;
  n[D - 1] = (r2 - r1) / ell;
  const double m = test::grain_mass<D>(R);
  const double delta = test::hertz_overlap(m * test::kG * std::abs(n[D - 1]), R);
  const double z0 = 0.8;
  Vec<D> x = Vec<D>::Zero();
  x[0] = r1 + z0 * std::tan(beta);
  x[D - 1] = z0;
  x += (R - delta) * n;
  System<D> s = test::hertz_system<D>(Vec<D>::Constant(-1.0), Vec<D>::Constant(1.2), 0.5, 0.0);
  s.gravity = test::kG * test::down<D>();
  s.walls.push_back(Wall<D>{"cone", 0, cone});
  test::add_grain<D>(s, x, Vec<D>::Zero(), R);
  const double T = 0.2;
  const RunResult<D> r = test::run_soft<D>(s, hybrid, T, 0.0, nullptr);
  ASSERT_EQ(r.status, "ok") << r.message;
  const double drop = x[D - 1] - r.x[0][D - 1];
  const double expected = 0.5 * test::kG * std::cos(beta) * std::cos(beta) * T * T;
  std::printf("slide down a cone (%s, %dD): drop %.6f, closed form %.6f, ratio - 1 = %.3g\n", hybrid ? "hybrid" : "TDM",
              D, drop, expected, drop / expected - 1.0);
  EXPECT_NEAR(drop / expected, 1.0, 5e-3);
  if constexpr (D == 3) {
    EXPECT_NEAR(r.x[0][1], 0.0, 1e-9);  // no azimuthal drift
  }
}
TEST(ConeEngines, FrictionlessGrainSlidesDownTheInsideAsTheClosedFormSaysTdm3D) { check_slide<3>(false); }
TEST(ConeEngines, FrictionlessGrainSlidesDownTheInsideAsTheClosedFormSaysTdm2D) { check_slide<2>(false); }
TEST(ConeEngines, FrictionlessGrainSlidesDownTheInsideAsTheClosedFormSaysHybrid3D) { check_slide<3>(true); }

}  // namespace
}  // namespace matep

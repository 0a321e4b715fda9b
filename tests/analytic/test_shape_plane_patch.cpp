// BoundedPlane (contact/plane_patch.hpp): disk and rectangle patches, planes with a disk or a
// rectangular hole, 2D segments and lines with a gap.
// Impact times against the extended-precision reference (tests/support/impact_reference.hpp on a
// long-double gap written here: height over the plane and the in-plane distance to the region),
// straight and parabolic flights from both sides, a turntable (a rotating disk: same geometry, same
// times), grazing flights that dip in or pass clear by 1e-9 R. kQuick flights per case by default,
// kLong (10 000) in the *Long* test.
// Engine-level physics: an elastic EDM gas under gravity above a silo floor with an orifice (a
// plane with a disk hole, 3D; a line with a gap, 2D) keeps its energy, grains fall through the
// hole and none ever overlaps the floor; a grain at rest on a patch has the static Hertz overlap
// (TDM, hybrid); a sphere rolling on a turntable circles at (2/7) of the table's angular speed
// (TDM, hybrid).
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>

#include "contact/plane_patch.hpp"
#include "tests/support/shape_check.hpp"
#include "tests/support/shape_physics.hpp"

namespace matep {
namespace {

using test::FlightCase;
using test::ImpactStats;
using test::merge;
using test::VecL;
using test::expect_limit_consistent;

constexpr int kQuick = 2000;
constexpr int kLong = 10000;
constexpr double kTmax = 3.0;
constexpr double kTol = 1e-10;

enum class Outline { Disk, Rectangle };

template <int D>
BoundedPlane<D> random_plane(std::mt19937_64& rng, Outline o, bool hole, double omega = 0.0) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Vec<D> c;
  for (int k = 0; k < D; ++k) c[k] = u(rng);
  const Vec<D> n = test::random_unit<D>(rng);
  if (o == Outline::Disk) return BoundedPlane<D>(c, n, 0.6, hole, omega);
  Vec<D> w;
  do w = test::random_unit<D>(rng);
  while (std::abs(w.dot(n)) > 0.95);
  return BoundedPlane<D>(c, n, w, 0.7, 0.4, hole);
}

// Long-double gap: height h over the plane, in-plane offset s; the distance to the region's part
// of the plane is sqrt(h^2 + e^2) with e the in-plane distance from s to the sheet.
template <int D>
long double gap_ld(const BoundedPlane<D>& p, const VecL<D>& x, long double R) {
  const VecL<D> r = x - test::to_ld<D>(p.centre()), n = test::to_ld<D>(p.normal());
  const long double h = r.dot(n);
  const VecL<D> s = r - h * n;
  long double e;
  if (p.disk()) {
    const long double l = s.norm(), A = p.a();
    e = p.hole() ? std::max(0.0L, A - l) : std::max(0.0L, l - A);
  } else {
    const long double s1 = std::abs(s.dot(test::to_ld<D>(p.u()))), s2 = std::abs(s.dot(test::to_ld<D>(p.v())));
    const long double a = p.a(), b = p.b();
    if (!p.hole()) {
      e = std::hypot(std::max(0.0L, s1 - a), std::max(0.0L, s2 - b));
    } else {
      e = (s1 <= a && s2 <= b) ? std::min(a - s1, b - s2) : 0.0L;
    }
  }
  return std::hypot(h, e) - R;
}

// Starts within 1 of the plane on either side, in-plane within 1.3 of the centre.
template <int D>
FlightCase<D> random_flight(std::mt19937_64& rng, const BoundedPlane<D>& p, bool gravity) {
  std::uniform_real_distribution<double> u(-1.0, 1.0), u01(0.0, 1.0);
  FlightCase<D> f;
  for (;;) {
    f.R = 0.02 + 0.18 * u01(rng);
    Vec<D> s = 1.3 * test::random_unit<D>(rng) * std::sqrt(u01(rng));
    s -= s.dot(p.normal()) * p.normal();
    f.x = p.centre() + s + u(rng) * p.normal();
    f.v = (0.3 + 1.7 * u01(rng)) * test::random_unit<D>(rng);
    f.g = gravity ? Vec<D>((0.5 + 4.5 * u01(rng)) * test::random_unit<D>(rng)) : Vec<D>::Zero();
    if (gap_ld<D>(p, test::to_ld<D>(f.x), f.R) > 1e-9L) return f;
  }
}

template <int D>
void expect_case(const char* name, Outline o, bool hole, bool gravity, int n, std::uint64_t seed, double omega = 0.0) {
  std::mt19937_64 rng(seed);
  ImpactStats total;
  for (int block = 0; block < n / 50; ++block) {
    const BoundedPlane<D> p = random_plane<D>(rng, o, hole, omega);
    merge(total, test::check_impacts<D>(
                     [&](const Vec<D>& x, const Vec<D>& v, const Vec<D>& g, double R) {
                       const double t = p.impact_time(x, v, g, R, 0.0, kNever);
                       expect_limit_consistent<decltype(p), D>(p, x, v, g, R, t);
                       if (omega != 0.0) {  // the still disk's time (its normal renormalized: ulps)
                         const BoundedPlane<D> still(p.centre(), p.normal(), p.a(), hole);
                         const double ts = still.impact_time(x, v, g, R, 0.0, kNever);
                         if (std::isinf(t) || std::isinf(ts)) EXPECT_EQ(t, ts);
                         else EXPECT_NEAR(t, ts, 1e-12 * std::max(1.0, t));
                       }
                       return t;
                     },
                     [&](const VecL<D>& x, long double R) { return gap_ld<D>(p, x, R); },
                     [&](std::mt19937_64& r) { return random_flight<D>(r, p, gravity); }, 50, kTmax, kTol, rng()));
  }
  total.print(name);
  EXPECT_EQ(total.missed, 0) << name << " " << total.worst_case;
  EXPECT_EQ(total.early, 0) << name << " " << total.worst_case;
  EXPECT_LE(total.worst, kTol) << name << " " << total.worst_case;
  EXPECT_GT(total.hits, total.cases / 10) << name;
}

void all_cases(int n) {
  expect_case<3>("3D disk patch, straight", Outline::Disk, false, false, n, 1);
  expect_case<3>("3D disk patch, gravity", Outline::Disk, false, true, n, 2);
  expect_case<3>("3D rectangle patch, straight", Outline::Rectangle, false, false, n, 3);
  expect_case<3>("3D rectangle patch, gravity", Outline::Rectangle, false, true, n, 4);
  expect_case<3>("3D disk hole, straight", Outline::Disk, true, false, n, 5);
  expect_case<3>("3D disk hole, gravity", Outline::Disk, true, true, n, 6);
  expect_case<3>("3D rectangular hole, gravity", Outline::Rectangle, true, true, n, 7);
  expect_case<3>("3D turntable, gravity", Outline::Disk, false, true, n, 8, 4.0);
  expect_case<2>("2D segment, gravity", Outline::Disk, false, true, n, 9);
  expect_case<2>("2D line with a gap, straight", Outline::Disk, true, false, n, 10);
  expect_case<2>("2D line with a gap, gravity", Outline::Rectangle, true, true, n, 11);
}

TEST(BoundedPlaneImpact, MatchesTheReference) { all_cases(kQuick); }
TEST(BoundedPlaneImpact, MatchesTheReferenceLong) { all_cases(kLong); }

// Grazing flights (test::make_graze), tolerance kTol = 1e-10 relative (a grazing root's
// conditioning: see test_shape_cylinder.cpp). Over a flat face a straight flight cannot graze (no interior minimum):
// these graze edges, rims and corners, and the face under gravity.
template <int D>
void graze_cases(Outline o, bool hole, bool gravity, int n, std::uint64_t seed, const char* name) {
  std::mt19937_64 rng(seed);
  ImpactStats total;
  int made = 0;
  for (int k = 0; k < n; ++k) {
    const BoundedPlane<D> p = random_plane<D>(rng, o, hole);
    const double miss = (k % 2 ? 1e-9 : -1e-9);
    FlightCase<D> f = random_flight<D>(rng, p, gravity);
    auto gld = [&](const VecL<D>& x, long double R) { return gap_ld<D>(p, x, R); };
    if (!test::make_graze<D>(f, gld, [&](const Vec<D>& x, double R) { return p.at(x, R, 0.0).normal; }, kTmax,
                             miss * f.R))
      continue;
    ++made;
    merge(total, test::check_impacts<D>(
                     [&](const Vec<D>& x, const Vec<D>& v, const Vec<D>& g, double R) {
                       return p.impact_time(x, v, g, R, 0.0, kNever);
                     },
                     gld, [&](std::mt19937_64&) { return f; }, 1, kTmax, kTol, 0));
  }
  total.print(name);
  EXPECT_GT(made, n / 8) << name;
  EXPECT_EQ(total.missed, 0) << name << " " << total.worst_case;
  EXPECT_EQ(total.early, 0) << name << " " << total.worst_case;
  EXPECT_LE(total.worst, kTol) << name << " " << total.worst_case;
}

TEST(BoundedPlaneImpact, GrazingFlightsTouchOrMissAsTheReferenceSays) {
  graze_cases<3>(Outline::Disk, false, false, 300, 21, "graze 3D disk patch, straight");
  graze_cases<3>(Outline::Rectangle, false, true, 300, 22, "graze 3D rectangle patch, gravity");
  graze_cases<3>(Outline::Disk, true, true, 300, 23, "graze 3D disk hole, gravity");
  graze_cases<3>(Outline::Rectangle, true, false, 300, 24, "graze 3D rectangular hole, straight");
  graze_cases<2>(Outline::Disk, true, true, 300, 25, "graze 2D line with a gap, gravity");
}

// Hand-made flights with known answers on a horizontal floor z = 0 with a hole of radius 0.3.
TEST(BoundedPlaneImpact, ClosedFormFlights) {
  const BoundedPlane<3> floor(Vec<3>::Zero(), Vec<3>(0, 0, 1), 0.3, /*hole=*/true);
  const double R = 0.1;
  // Falling through the middle of the hole: never touched.
  EXPECT_EQ(floor.impact_time(Vec<3>(0, 0, 1), Vec<3>(0, 0, -1), Vec<3>::Zero(), R, 0.0, kNever), kNever);
  // Falling onto the floor at rho = 0.5: the face at z = R, t = 1 - R.
  EXPECT_NEAR(floor.impact_time(Vec<3>(0.5, 0, 1), Vec<3>(0, 0, -1), Vec<3>::Zero(), R, 0.0, kNever), 1.0 - R, 1e-15);
  // ... from below (it fell through earlier): the face's other side.
  EXPECT_NEAR(floor.impact_time(Vec<3>(0.5, 0, -1), Vec<3>(0, 0, 1), Vec<3>::Zero(), R, 0.0, kNever), 1.0 - R, 1e-15);
  // Falling at rho = 0.25 (the edge 0.05 away): the rim at distance R when (z^2 + 0.05^2) = R^2.
  const double z = std::sqrt(R * R - 0.05 * 0.05);
  EXPECT_NEAR(floor.impact_time(Vec<3>(0.25, 0, 1), Vec<3>(0, 0, -1), Vec<3>::Zero(), R, 0.0, kNever), 1.0 - z, 1e-14);
  // The same under gravity g = 2 from rest: 1/2 2 t^2 = 1 - z.
  EXPECT_NEAR(floor.impact_time(Vec<3>(0.25, 0, 1), Vec<3>::Zero(), Vec<3>(0, 0, -2), R, 0.0, kNever),
              std::sqrt(1.0 - z), 1e-14);
  // A rectangle patch: a flight along x at height R/2 over the plane hits the edge x = -a (a line
  // along y) where (x + a)^2 + (R/2)^2 = R^2.
  const BoundedPlane<3> rect(Vec<3>::Zero(), Vec<3>(0, 0, 1), Vec<3>(1, 0, 0), 0.7, 0.4);
  const double dx = std::sqrt(R * R - 0.25 * R * R);
  EXPECT_NEAR(rect.impact_time(Vec<3>(-2, 0.1, 0.5 * R), Vec<3>(1, 0, 0), Vec<3>::Zero(), R, 0.0, kNever),
              2.0 - 0.7 - dx, 1e-14);
  // ... and a flight along the diagonal direction past the corner (0.7, 0.4) at height 0 hits the
  // corner point at distance R.
  const Vec<3> dir = Vec<3>(0.7, 0.4, 0.0).normalized();
  EXPECT_NEAR(rect.impact_time(Vec<3>(2.0 * dir), -dir, Vec<3>::Zero(), R, 0.0, kNever),
              2.0 - Vec<3>(0.7, 0.4, 0.0).norm() - R, 1e-14);
}

// The rest of the interface on hand-made points.
TEST(BoundedPlaneShape, GeometryVelocityBoundsAndNormals) {
  const double R = 0.1;
  const Vec<3> z(0, 0, 1);
  const BoundedPlane<3> table(Vec<3>(0, 0, 1), z, 0.5, false, 3.0);  // a turntable at height 1
  WallPoint<3> c = table.at(Vec<3>(0.2, 0, 1.3), R, 0.0);  // over the face
  EXPECT_NEAR(c.gap, 0.3 - R, 1e-15);
  EXPECT_LT((c.normal - z).norm(), 1e-15);
  EXPECT_LT((c.velocity - Vec<3>(0, 0.6, 0)).norm(), 1e-15);  // 3 z x (0.2, 0, 0)
  EXPECT_LT((table.at(Vec<3>(0.2, 0, 0.7), R, 0.0).normal + z).norm(), 1e-15);  // from below
  c = table.at(Vec<3>(0.8, 0, 1.4), R, 0.0);  // beyond the rim: (0.3, 0, 0.4) from (0.5, 0, 1)
  EXPECT_NEAR(c.gap, 0.5 - R, 1e-15);
  EXPECT_LT((c.normal - Vec<3>(0.6, 0, 0.8)).norm(), 1e-15);
  Vec<3> lo, hi;
  EXPECT_TRUE(table.bounds(lo, hi));
  EXPECT_LT((lo - Vec<3>(-0.5, -0.5, 1)).norm(), 1e-15);
  EXPECT_LT((hi - Vec<3>(0.5, 0.5, 1)).norm(), 1e-15);
  EXPECT_DOUBLE_EQ(table.max_speed(), 1.5);
  EXPECT_STREQ(table.kind(), "plane patch");
  // A rectangle 2 x 1 (half-sizes 1, 0.5) along x: a corner and an edge.
  const BoundedPlane<3> rect(Vec<3>::Zero(), z, Vec<3>(1, 0, 0.3), 1.0, 0.5);
  EXPECT_NEAR(rect.at(Vec<3>(1.3, 0.9, 0), R, 0.0).gap, 0.5 - R, 1e-15);   // corner (1, 0.5, 0)
  EXPECT_NEAR(rect.at(Vec<3>(0.2, -0.8, 0.4), R, 0.0).gap, 0.5 - R, 1e-15);  // edge y = -0.5
  EXPECT_TRUE(rect.bounds(lo, hi));
  EXPECT_LT((hi - Vec<3>(1, 0.5, 0)).norm(), 1e-15);
  EXPECT_FALSE(rect.moving());
  // A floor with a hole of radius 0.3 at the origin: in the hole the nearest point is on the rim.
  const BoundedPlane<3> floor(Vec<3>::Zero(), z, 0.3, true);
  EXPECT_NEAR(floor.at(Vec<3>(0.1, 0, 0), R, 0.0).gap, 0.2 - R, 1e-15);
  EXPECT_NEAR(floor.at(Vec<3>(2, 0, -0.4), R, 0.0).gap, 0.4 - R, 1e-15);  // under the floor
  EXPECT_FALSE(floor.bounds(lo, hi));
  EXPECT_STREQ(floor.kind(), "plane with hole");
  // A rectangular hole: from inside, out through the nearer edge.
  const BoundedPlane<3> slot(Vec<3>::Zero(), z, Vec<3>(1, 0, 0), 1.0, 0.2, true);
  EXPECT_NEAR(slot.at(Vec<3>(0.5, 0.1, 0), R, 0.0).gap, 0.1 - R, 1e-15);
  EXPECT_TRUE(slot.has_normal(Vec<3>(0.6, 0.8, 0), 1e-12));
  // 2D: a segment of half-length 0.5 on the line y = 0.
  const BoundedPlane<2> seg(Vec<2>::Zero(), Vec<2>(0, 1), 0.5);
  EXPECT_NEAR(seg.at(Vec<2>(0.8, 0.4), R, 0.0).gap, 0.5 - R, 1e-15);
  EXPECT_NEAR(seg.at(Vec<2>(0.2, -0.4), R, 0.0).gap, 0.4 - R, 1e-15);
  EXPECT_THROW(BoundedPlane<3>(Vec<3>::Zero(), z, 0.3, true, 1.0), std::invalid_argument);  // a turning hole
  EXPECT_THROW(BoundedPlane<2>(Vec<2>::Zero(), Vec<2>(0, 1), 0.3, false, 1.0), std::invalid_argument);
  EXPECT_THROW(BoundedPlane<3>(Vec<3>::Zero(), z, Vec<3>(0, 0, 2), 1.0, 1.0), std::invalid_argument);
}

// ---- engines ---------------------------------------------------------------------------------

// A silo: a box (side planes) whose floor at height 0.4 is a plane with a hole (3D: a disk of
// radius 0.15; 2D: a gap of half-width 0.15), a bottom plane at 0, elastic grains under gravity.
// Kinetic + potential energy is conserved, some grains fall through the hole (and bounce back up
// through it), no grain overlaps the holed floor in any snapshot (every 0.25 s) nor at the end.
template <int D>
void check_silo() {
  const double R = 0.03, zf = 0.4;
  Vec<D> lo = Vec<D>::Constant(-0.5), hi = Vec<D>::Constant(0.5);
  lo[D - 1] = 0.0;
  hi[D - 1] = 1.2;
  System<D> s = test::hard_material_system<D>(lo, hi);
  s.gravity = -1.0 * test::up_axis<D>();
  for (int k = 0; k < D; ++k) {
    Vec<D> e = Vec<D>::Zero();
    e[k] = 1.0;
    s.walls.push_back(plane_wall<D>("lo", Vec<D>(lo), Vec<D>(e)));
    s.walls.push_back(plane_wall<D>("hi", Vec<D>(hi), Vec<D>(-e)));
  }
  Vec<D> c = Vec<D>::Zero();
  c[D - 1] = zf;
  auto floor = std::make_shared<BoundedPlane<D>>(c, test::up_axis<D>(), 0.15, /*hole=*/true);
  s.walls.push_back(Wall<D>{"floor", 0, floor});
  test::fill_gas<D>(s, D == 3 ? 80 : 40, R, [&](const Vec<D>& x) {
    bool in = x[D - 1] > zf + 1.5 * R && x[D - 1] < 1.2 - 1.5 * R;
    for (int k = 0; k < D - 1; ++k) in = in && std::abs(x[k]) < 0.5 - 1.5 * R;
    return in;
  }, 7);
  EdmSettings es;
  es.end_time = 20.0;
  es.snapshot_interval = 0.25;
  struct Snap final : Observer<D> {
    const WallShape<D>* shape = nullptr;
    double R = 0.0, worst = 0.0;
    int below_max = 0;
    double zf = 0.0;
    bool wants_snapshots() const override { return true; }
    void on_snapshot(const Snapshot<D>& sn) override {
      int below = 0;
      for (const auto& x : sn.x) {
        worst = std::max(worst, -shape->at(x, R, sn.time).gap);
        if (x[D - 1] < zf) ++below;
      }
      below_max = std::max(below_max, below);
    }
  } snap;
  snap.shape = floor.get();
  snap.R = R;
  snap.zf = zf;
  const RunResult<D> r = run_edm<D>(s, es, QueueKind::Calendar, {&snap});
  ASSERT_EQ(r.status, "ok") << r.message;
  auto energy = [&](const std::vector<Vec<D>>& x, const std::vector<Vec<D>>& v) {
    double e = 0.0;
    for (std::size_t i = 0; i < x.size(); ++i) e += 0.5 * v[i].squaredNorm() - s.gravity.dot(x[i]);
    return e;
  };
  const double ratio = energy(r.x, r.v) / energy(s.x, s.v);
  EXPECT_NEAR(ratio, 1.0, 1e-10);
  EXPECT_LT(snap.worst, 1e-12);
  EXPECT_LT(r.max_overlap, 1e-12);
  EXPECT_GT(snap.below_max, 0);
  std::printf("EDM silo (%dD): %llu wall collisions, energy ratio - 1 = %.3g, up to %d grains below the floor, "
              "worst floor overlap %.3g\n",
              D, static_cast<unsigned long long>(r.counts.wall), ratio - 1.0, snap.below_max, snap.worst);
}
TEST(BoundedPlaneEngines, ElasticEdmGasOverASiloFloorWithAHoleKeepsItsEnergy3D) { check_silo<3>(); }
TEST(BoundedPlaneEngines, ElasticEdmGasOverAFloorWithAGapKeepsItsEnergy2D) { check_silo<2>(); }

// Grains around a tilted rectangle patch, a tilted disk patch and a plane with a rectangular hole,
// under gravity in a closed box (faces from both sides, edges, corners, rims).
TEST(BoundedPlaneEngines, ElasticEdmGasAroundPatchesAndHolesKeepsItsEnergy) {
  const Vec<3> n = Vec<3>(0.2, 0.1, 1.0).normalized();
  test::expect_edm_gas_around<3>(std::make_shared<BoundedPlane<3>>(Vec<3>(0, 0, -0.1), n, Vec<3>(1, 0.3, 0), 0.3, 0.2),
                                 80, 0.03, 15, "rectangle patch");
  test::expect_edm_gas_around<3>(std::make_shared<BoundedPlane<3>>(Vec<3>(0.1, 0, 0), n, 0.3), 80, 0.03, 16,
                                 "disk patch");
  test::expect_edm_gas_around<3>(
      std::make_shared<BoundedPlane<3>>(Vec<3>(0, 0, -0.1), n, Vec<3>(1, 0.3, 0), 0.15, 0.1, true), 80, 0.03, 17,
      "plane with a rectangular hole");
  test::expect_edm_gas_around<2>(std::make_shared<BoundedPlane<2>>(Vec<2>(0.05, 0), Vec<2>(0.2, 1.0), 0.3), 40, 0.03,
                                 18, "2D segment");
}

// A grain at rest in the middle of a horizontal patch (a flat wall: R* = R): the static Hertz
// overlap delta = (3 m g / (4 E* sqrt R))^(2/3).
template <int D>
void check_static(bool hybrid, Outline o) {
  const Vec<D> n = test::up_axis<D>();
  std::shared_ptr<const WallShape<D>> patch;
  if (o == Outline::Disk) {
    patch = std::make_shared<BoundedPlane<D>>(Vec<D>::Zero(), n, 0.3);
  } else {
    patch = std::make_shared<BoundedPlane<D>>(Vec<D>::Zero(), n, test::axis_x<D>(), 0.3, 0.2);
  }
  test::expect_static_hertz_overlap<D>(patch, Vec<D>(test::kGrainR * n), n, Vec<D>(test::kG * test::down<D>()),
                                       hybrid);
}
TEST(BoundedPlaneEngines, GrainAtRestOnADiskHasTheStaticHertzOverlapTdm3D) { check_static<3>(false, Outline::Disk); }
TEST(BoundedPlaneEngines, GrainAtRestOnARectangleHasTheStaticHertzOverlapHybrid3D) {
  check_static<3>(true, Outline::Rectangle);
}
TEST(BoundedPlaneEngines, GrainAtRestOnASegmentHasTheStaticHertzOverlapTdm2D) { check_static<2>(false, Outline::Disk); }

// A sphere on a turntable (a disk patch turning at Omega about its vertical normal), placed at rest
// at radius 0.2 with friction 0.5: after a short slip it rolls, and its velocity turns at a constant
// rate omega_c. Rolling at the contact point c = x - l n (lever l from the centre to the surface):
// v + w x (-l n) = Omega n x (x - centre); with m v' = F and I w' = (-l n) x F this gives
// v' (1 + m l^2 / I) = Omega n x v, so omega_c = Omega q' / (1 + q'), q' = I / (m l^2) = q r^2 / l^2:
// the classical (2/7) Omega for a rigid solid sphere (q = 2/5, l = r). A soft grain's lever is
// l = r - delta (delta its static Hertz overlap): a 0.9 % correction, included.
void check_turntable(bool hybrid) {
  const double Omega = 5.0, r = test::kGrainR;
  const Vec<3> n(0, 0, 1);
  auto table = std::make_shared<BoundedPlane<3>>(Vec<3>::Zero(), n, 1.0, false, Omega);
  const double delta = test::hertz_overlap(test::grain_mass<3>(r) * test::kG, r);
  System<3> s = test::hertz_system<3>(Vec<3>(-1.1, -1.1, -0.2), Vec<3>(1.1, 1.1, 0.5), 0.5, 0.5);
  s.gravity = Vec<3>(0, 0, -test::kG);
  s.walls.push_back(Wall<3>{"table", 0, table});
  test::add_grain<3>(s, Vec<3>(0.2, 0.0, r - delta), Vec<3>::Zero(), r);
  test::Tracker<3> tr;
  const double T = 3.0;
  const RunResult<3> res = test::run_soft<3>(s, hybrid, T, 1e-3, &tr);
  ASSERT_EQ(res.status, "ok") << res.message;
  // Least-squares slope of the unwrapped direction angle of v over [0.5, T].
  int m = 0;
  const double slope = test::velocity_turning_rate(tr.track, 0.5, m);
  ASSERT_GT(m, 100);
  const double q = 0.4, l = r - delta, qq = q * r * r / (l * l);
  const double expected = Omega * qq / (1.0 + qq);
  std::printf("turntable (%s): velocity turns at %.6f rad/s, closed form %.6f (rigid 2/7 Omega = %.6f), "
              "ratio - 1 = %.3g\n",
              hybrid ? "hybrid" : "TDM", slope, expected, 2.0 / 7.0 * Omega, slope / expected - 1.0);
  EXPECT_NEAR(slope / expected, 1.0, 5e-3);
}
TEST(BoundedPlaneEngines, SphereOnATurntableCirclesAtTwoSeventhsOfItsSpeedTdm) { check_turntable(false); }
TEST(BoundedPlaneEngines, SphereOnATurntableCirclesAtTwoSeventhsOfItsSpeedHybrid) { check_turntable(true); }

}  // namespace
}  // namespace matep

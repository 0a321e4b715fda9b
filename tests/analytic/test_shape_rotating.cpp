// RotatingWall (contact/rotating.hpp): any bounded shape turning about a given axis.
// Geometry on hand-made points: a paddle (a rectangle patch) a quarter turn later has the gap,
// normal and surface velocity of the turned paddle. Impact times against the extended-precision
// reference (the long-double distance to the octahedron turned back by the long-double angle,
// tests/support/impact_reference.hpp): turning octahedra (random axes, |omega| up to 4 rad/s),
// straight and parabolic flights. Engines: a sphere on the lid of a turning box (a mesh) circles
// at (2/7) of the lid's angular speed (TDM, hybrid); an elastic EDM gas stirred by a turning
// paddle never overlaps it and gains energy from it.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>

#include "contact/plane_patch.hpp"
#include "contact/rotating.hpp"
#include "tests/support/mesh_shapes.hpp"
#include "tests/support/shape_check.hpp"
#include "tests/support/shape_physics.hpp"

namespace matep {
namespace {

using test::FlightCase;
using test::ImpactStats;
using test::VecL;

constexpr double kPi = 3.14159265358979323846;

TEST(RotatingShape, APaddleAQuarterTurnLaterIsTheTurnedPaddle) {
  // A paddle in the plane y = 0 (normal y), 0.4 x 0.2 (half-sizes 0.2 along x, 0.1 along z),
  // centred at (0.3, 0, 0), turning about z through the origin at pi/2 rad/s: at t = 1 it lies in
  // the plane x = 0, centred at (0, 0.3, 0), its normal -x.
  auto paddle = std::make_shared<BoundedPlane<3>>(Vec<3>(0.3, 0, 0), Vec<3>(0, 1, 0), Vec<3>(1, 0, 0), 0.2, 0.1);
  const RotatingWall<3> w(paddle, Vec<3>::Zero(), Vec<3>(0, 0, 1), 0.5 * kPi);
  const double R = 0.05;
  WallPoint<3> c = w.at(Vec<3>(0.0, 0.3, 0.0) + Vec<3>(-0.15, 0, 0), R, 1.0);  // 0.15 from the face
  EXPECT_NEAR(c.gap, 0.15 - R, 1e-14);
  EXPECT_LT((c.normal - Vec<3>(-1, 0, 0)).norm(), 1e-14);
  // The contact point (0, 0.3, 0) moves at omega z x (0, 0.3, 0) = (-0.3 omega, 0, 0).
  EXPECT_LT((c.velocity - Vec<3>(-0.3 * 0.5 * kPi, 0, 0)).norm(), 1e-14);
  // At t = 0 the same point is 0.15 beyond the paddle's end x = 0.1 ... along -x: the edge.
  c = w.at(Vec<3>(-0.15, 0.3, 0.0), R, 0.0);
  EXPECT_NEAR(c.gap, std::hypot(0.25, 0.3) - R, 1e-14);
  EXPECT_TRUE(w.moving());
  EXPECT_NEAR(w.sweep_speed(), 0.5 * kPi * std::hypot(0.5, 0.0), 1e-14);  // the far corner: (0.5, 0, +-0.1)
  Vec<3> lo, hi;
  ASSERT_TRUE(w.bounds(lo, hi));
  EXPECT_NEAR(hi[0], 0.5, 1e-14);
  EXPECT_NEAR(lo[1], -0.5, 1e-14);
  EXPECT_NEAR(hi[2], 0.1, 1e-14);
  // An unbounded shape, a moving shape and a zero axis cannot turn.
  EXPECT_THROW(RotatingWall<3>(std::make_shared<BoundedPlane<3>>(Vec<3>::Zero(), Vec<3>(0, 0, 1), 0.1, true),
                               Vec<3>::Zero(), Vec<3>(0, 0, 1), 1.0),
               std::invalid_argument);
  EXPECT_THROW(RotatingWall<3>(std::make_shared<BoundedPlane<3>>(Vec<3>::Zero(), Vec<3>(0, 0, 1), 0.1, false, 2.0),
                               Vec<3>::Zero(), Vec<3>(0, 0, 1), 1.0),
               std::invalid_argument);
  EXPECT_THROW(RotatingWall<3>(paddle, Vec<3>::Zero(), Vec<3>::Zero(), 1.0), std::invalid_argument);
}

// Long-double rotation of r by angle a about unit k (Rodrigues).
VecL<3> turn_ld(const VecL<3>& r, const VecL<3>& k, long double a) {
  return r * std::cos(a) + k.cross(r) * std::sin(a) + k * k.dot(r) * (1.0L - std::cos(a));
}

void expect_turning_octahedra(bool gravity, int n, std::uint64_t seed, const char* name) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0), u01(0.0, 1.0);
  ImpactStats total;
  for (int block = 0; block < n / 25; ++block) {
    const auto body = test::octahedron(Vec<3>(0.2 * u(rng), 0.2 * u(rng), 0.2 * u(rng)), 0.6, rng());
    const Vec<3> p(0.2 * u(rng), 0.2 * u(rng), 0.2 * u(rng));
    const Vec<3> axis = test::random_unit<3>(rng);
    const double omega = 4.0 * u(rng);
    const RotatingWall<3> w(body, p, axis, omega);
    const VecL<3> pl = test::to_ld<3>(p), kl = test::to_ld<3>(axis);
    auto gap_at = [&](const VecL<3>& x, long double R, long double t) {
      return test::mesh_gap_ld(*body, VecL<3>(pl + turn_ld(VecL<3>(x - pl), kl, -static_cast<long double>(omega) * t)), R);
    };
    for (int k = 0; k < 25; ++k) {
      FlightCase<3> f;
      do {
        f.R = 0.02 + 0.13 * u01(rng);
        for (int j = 0; j < 3; ++j) f.x[j] = 0.9 * u(rng);
        f.v = (0.3 + 1.7 * u01(rng)) * test::random_unit<3>(rng);
        f.g = gravity ? Vec<3>((0.5 + 4.5 * u01(rng)) * test::random_unit<3>(rng)) : Vec<3>::Zero();
      } while (!(gap_at(test::to_ld<3>(f.x), f.R, 0.0L) > 1e-9L));
      const VecL<3> x = test::to_ld<3>(f.x), v = test::to_ld<3>(f.v), g = test::to_ld<3>(f.g);
      const double tmax = 3.0;
      const long double ref = test::earliest_closing_root(
          [&](long double t) { return gap_at(VecL<3>(x + t * v + 0.5L * t * t * g), f.R, t); }, tmax, 6000);
      const double got = test::impact_following_checkpoints<3>(w, f.x, f.v, f.g, f.R, kNever);
      ++total.cases;
      const bool hit = ref <= tmax;
      total.hits += hit;
      const double tol = 1e-10 * std::max(hit ? static_cast<double>(ref) : tmax, 1e-3);
      if (hit) {
        const double err = std::abs(got - static_cast<double>(ref)) / std::max(static_cast<double>(ref), 1e-3);
        if (!(got <= static_cast<double>(ref) + tol)) ++total.missed;
        else if (got < static_cast<double>(ref) - tol) ++total.early;
        if (!(err <= total.worst)) {
          total.worst = std::isfinite(err) ? err : 1e300;
          total.worst_case = fmt::format("ref {} got {}", static_cast<double>(ref), got);
        }
      } else if (got < tmax - tol) {
        ++total.early;
        total.worst_case = fmt::format("no reference root, got {}", got);
      }
    }
  }
  total.print(name);
  EXPECT_EQ(total.missed, 0) << name << " " << total.worst_case;
  EXPECT_EQ(total.early, 0) << name << " " << total.worst_case;
  EXPECT_LE(total.worst, 1e-10) << name << " " << total.worst_case;
  EXPECT_GT(total.hits, total.cases / 10) << name;
}

TEST(RotatingImpact, TurningOctahedraMatchTheReference) {
  expect_turning_octahedra(false, 1000, 1, "turning octahedron, straight");
  expect_turning_octahedra(true, 1000, 2, "turning octahedron, gravity");
}
TEST(RotatingImpact, TurningOctahedraMatchTheReferenceLong) {
  expect_turning_octahedra(false, 4000, 3, "turning octahedron, straight (long)");
  expect_turning_octahedra(true, 4000, 4, "turning octahedron, gravity (long)");
}

// ---- engines ---------------------------------------------------------------------------------

// A sphere rolling on the lid of a closed box mesh (2 x 2 x 0.2) turning about the vertical axis
// through its centre at Omega = 5 rad/s: placed at rest, it is set rolling by the lid and its
// velocity turns at (2/7) Omega (the classical result for a rigid sphere on a turntable; with the
// soft grain's lever arm r - delta as in test_shape_plane_patch.cpp's turntable, where a disk
// patch turning about its own normal gives the same closed form). The lid's geometry turns with
// it (the box is no shape of revolution), so this checks the decorator's surface velocity and its
// feature lookup in the turning frame.
void check_turning_lid(bool hybrid) {
  const double Omega = 5.0, r = test::kGrainR;
  auto box = test::box_mesh(Vec<3>(-1.0, -1.0, -0.2), Vec<3>(1.0, 1.0, 0.0), true);
  const double delta = test::hertz_overlap(test::grain_mass<3>(r) * test::kG, r);
  System<3> s = test::hertz_system<3>(Vec<3>(-1.5, -1.5, -0.3), Vec<3>(1.5, 1.5, 0.5), 0.5, 0.5);
  s.gravity = Vec<3>(0, 0, -test::kG);
  s.walls.push_back(
      Wall<3>{"lid", 0, std::make_shared<RotatingWall<3>>(box, Vec<3>::Zero(), Vec<3>(0, 0, 1), Omega)});
  test::add_grain<3>(s, Vec<3>(0.2, 0.0, r - delta), Vec<3>::Zero(), r);
  test::Tracker<3> tr;
  const double T = 3.0;
  const RunResult<3> res = test::run_soft<3>(s, hybrid, T, 1e-3, &tr);
  ASSERT_EQ(res.status, "ok") << res.message;
  int m = 0;
  const double slope = test::velocity_turning_rate(tr.track, 0.5, m);
  ASSERT_GT(m, 100);
  const double q = 0.4, l = r - delta, qq = q * r * r / (l * l);
  const double expected = Omega * qq / (1.0 + qq);
  std::printf("turning box lid (%s): velocity turns at %.6f rad/s, closed form %.6f, ratio - 1 = %.3g\n",
              hybrid ? "hybrid" : "TDM", slope, expected, slope / expected - 1.0);
  EXPECT_NEAR(slope / expected, 1.0, 5e-3);
  EXPECT_LT(std::abs(res.x[0][2] - (r - delta)), 1e-3 * r);  // still on the lid
}
TEST(RotatingEngines, ASphereOnATurningBoxLidCirclesAtTwoSeventhsOfItsSpeedTdm) { check_turning_lid(false); }
TEST(RotatingEngines, ASphereOnATurningBoxLidCirclesAtTwoSeventhsOfItsSpeedHybrid) { check_turning_lid(true); }

// 150 elastic hard grains in a closed box of planes with a paddle (a rectangle patch) turning
// about the box's vertical axis: no grain ever overlaps the paddle, and the paddle's work goes into
// the gas (its energy grows).
TEST(RotatingEngines, ElasticEdmGasStirredByAPaddleNeverOverlapsIt) {
  System<3> s = test::hard_material_system<3>(Vec<3>::Constant(-0.6), Vec<3>::Constant(0.6));
  for (int k = 0; k < 3; ++k) {
    Vec<3> e = Vec<3>::Zero();
    e[k] = 1.0;
    s.walls.push_back(plane_wall<3>("lo", Vec<3>(-0.6 * e), e));
    s.walls.push_back(plane_wall<3>("hi", Vec<3>(0.6 * e), Vec<3>(-e)));
  }
  auto paddle = std::make_shared<BoundedPlane<3>>(Vec<3>(0.2, 0, 0), Vec<3>(0, 1, 0), Vec<3>(1, 0, 0), 0.2, 0.3);
  auto turning = std::make_shared<RotatingWall<3>>(paddle, Vec<3>::Zero(), Vec<3>(0, 0, 1), 6.0);
  s.walls.push_back(Wall<3>{"paddle", 0, turning});
  test::fill_gas<3>(s, 150, 0.03, [&](const Vec<3>& x) {
    return (x.array().abs() < 0.55).all() && std::hypot(x[0], x[1]) > 0.5;  // outside the paddle's sweep
  }, 5);
  for (auto& v : s.v) v *= 0.3;
  struct Snap final : Observer<3> {
    const WallShape<3>* shape = nullptr;
    double worst = 0.0;
    bool wants_snapshots() const override { return true; }
    void on_snapshot(const Snapshot<3>& sn) override {
      for (const auto& x : sn.x) worst = std::max(worst, -shape->at(x, 0.03, sn.time).gap);
    }
  } snap;
  snap.shape = turning.get();
  EdmSettings es;
  es.end_time = 3.0;
  es.snapshot_interval = 0.01;
  const RunResult<3> r = run_edm<3>(s, es, QueueKind::Calendar, {&snap});
  ASSERT_EQ(r.status, "ok") << r.message;
  const double e0 = test::kinetic<3>(s.v), e1 = test::kinetic<3>(r.v);
  std::printf("gas stirred by a paddle: %llu wall collisions, worst overlap %.3g R, energy x %.3f\n",
              static_cast<unsigned long long>(r.counts.wall), snap.worst / 0.03, e1 / e0);
  EXPECT_LT(snap.worst, 1e-8 * 0.03);
  EXPECT_LT(r.max_overlap, 1e-8 * 0.03);
  EXPECT_GT(e1, 1.5 * e0);  // stirred: the paddle's edge moves at up to 2.4 m/s, the gas at ~0.5
}

}  // namespace
}  // namespace matep

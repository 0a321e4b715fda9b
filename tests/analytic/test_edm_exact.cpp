// Event-driven engine against exact trajectories and conservation laws.
#include <gtest/gtest.h>

#include <cmath>

#include "engine/edm.hpp"
#include "tests/support/systems.hpp"

using namespace matep;
using matep::test::Recorder;

namespace {

// A ball of radius R dropped from rest with its lowest point h above a floor at y = 0.
template <int D>
System<D> bouncing_ball(double h, double e, double R = 0.05) {
  System<D> s;
  s.lower = Vec<D>::Constant(-1.0);
  s.upper = Vec<D>::Constant(1.0);
  s.upper[1] = 3.0;
  s.lower[1] = -0.5;
  s.periodic.fill(true);
  s.periodic[1] = false;
  s.gravity = Vec<D>::Zero();
  s.gravity[1] = -9.81;
  Material m;
  m.name = "ball";
  m.density = 1000.0;
  m.restitution = Restitution::constant(e);
  s.materials.push_back(m);
  Vec<D> up = Vec<D>::Zero(), top = Vec<D>::Zero();
  up[1] = 1.0;
  top[1] = 2.9;
  s.walls.push_back(plane_wall<D>("floor", Vec<D>::Zero(), up));
  s.walls.push_back(plane_wall<D>("roof", top, -up));
  Vec<D> x = Vec<D>::Zero();
  x[1] = h + R;
  s.x.push_back(x);
  s.v.push_back(Vec<D>::Zero());
  s.radius.push_back(R);
  s.material.push_back(0);
  return s;
}

template <int D>
void check_bouncing_ball_impacts() {
  const double h = 1.0, e = 0.8, g = 9.81;
  const System<D> sys = bouncing_ball<D>(h, e);
  EdmSettings set;
  set.end_time = 4.05;  // the Zeno time is 4.0637 s: stop before the accumulation point
  Recorder<D> rec;
  const RunResult<D> res = run_edm<D>(sys, set, QueueKind::Calendar, {&rec});
  ASSERT_EQ(res.status, "ok");
  ASSERT_GE(rec.records.size(), 20u);
  // k-th impact: t_k = t1 (1 + 2 sum_{j=1}^{k-1} e^j), t1 = sqrt(2h/g) (docs/references.md §3.2).
  const double t1 = std::sqrt(2.0 * h / g);
  double sum = 0.0, ej = 1.0;
  for (int k = 1; k <= 20; ++k) {
    const double tk = t1 * (1.0 + 2.0 * sum);
    EXPECT_EQ(rec.records[k - 1].kind, EventKind::WallCollision);
    EXPECT_NEAR(rec.records[k - 1].time, tk, 1e-10 * tk) << "impact " << k;
    // impact speed e^(k-1) sqrt(2 g h)
    const double speed = -rec.records[k - 1].vi_before[1];
    EXPECT_NEAR(speed, std::pow(e, k - 1) * std::sqrt(2 * g * h), 1e-9) << "impact " << k;
    ej *= e;
    sum += ej;
  }
}

}  // namespace

TEST(EdmExact, BouncingBallImpactTimes2D) { check_bouncing_ball_impacts<2>(); }
TEST(EdmExact, BouncingBallImpactTimes3D) { check_bouncing_ball_impacts<3>(); }

TEST(EdmExact, BouncingBallCollapseStopsWithStatusNotAHang) {
  const System<3> sys = bouncing_ball<3>(1.0, 0.8);
  EdmSettings set;
  set.end_time = 10.0;
  const RunResult<3> res = run_edm<3>(sys, set, QueueKind::Calendar);
  EXPECT_EQ(res.status, "collapse");
  EXPECT_NE(res.message.find("particle 0"), std::string::npos) << res.message;
  // It collapses at the Zeno time T = t_drop (1 + e)/(1 - e) = 4.0637 s. The collapse watch sees
  // it coming when the bounces are 4.4 decades shorter than the first (0.90 s): T - t is then
  // about 2 t_drop e^k / (1 - e) = 1.6e-4 s.
  const double zeno = std::sqrt(2.0 / 9.81) * 1.8 / 0.2;
  EXPECT_LT(res.time, zeno);
  EXPECT_GT(res.time, zeno - 1e-3);
}

TEST(EdmExact, TcModelKeepsTheBallBouncing) {
  const System<3> sys = bouncing_ball<3>(1.0, 0.8);
  EdmSettings set;
  set.end_time = 6.0;
  set.tc = 1e-3;
  const RunResult<3> res = run_edm<3>(sys, set, QueueKind::Calendar);
  EXPECT_EQ(res.status, "ok");
  // Once bounces are shorter than tc they are elastic: the ball keeps a small hop.
  EXPECT_GT(res.v[0].norm() + (res.x[0][1] - 0.05), 0.0);
  EXPECT_GT(res.x[0][1], 0.05 - 1e-12);
}

TEST(EdmExact, HeadOnPairCollisionTimeAndOutcome) {
  System<3> s;
  s.lower = Vec<3>::Constant(-10);
  s.upper = Vec<3>::Constant(10);
  s.periodic = {true, true, true};
  Material m;
  m.name = "m";
  m.density = 1.0;
  m.restitution = Restitution::constant(0.5);
  s.materials.push_back(m);
  s.x = {Vec<3>(-2, 0, 0), Vec<3>(2, 0, 0)};
  s.v = {Vec<3>(1, 0, 0), Vec<3>(-1, 0, 0)};
  s.radius = {0.5, 0.5};
  s.material = {0, 0};
  EdmSettings set;
  set.end_time = 5.0;
  Recorder<3> rec;
  const auto res = run_edm<3>(s, set, QueueKind::Heap, {&rec});
  ASSERT_EQ(rec.records.size(), 1u);
  EXPECT_DOUBLE_EQ(rec.records[0].time, 1.5);  // gap 3 closed at relative speed 2
  EXPECT_DOUBLE_EQ(res.v[0][0], -0.5);
  EXPECT_DOUBLE_EQ(res.v[1][0], 0.5);
  EXPECT_DOUBLE_EQ(res.x[0][0], -0.5 - 0.5 * 3.5);  // contact at x = -0.5, then 3.5 s at -0.5
}

TEST(EdmExact, ElasticGasMillionEventsConservesEnergyWithoutOverlap) {
  const System<3> sys = test::lattice_gas<3>(10, 0.3, 1.0, 1.0, 11);
  EdmSettings set;
  set.end_time = 120.0;
  set.thermo_interval = 120.0;
  Recorder<3> rec;
  rec.collisions = false;
  const auto res = run_edm<3>(sys, set, QueueKind::Calendar, {&rec});
  ASSERT_EQ(res.status, "ok");
  EXPECT_GE(res.counts.total(), 1000000u);
  const double E0 = rec.samples.front().kinetic_energy;
  double E1 = 0;
  for (const auto& v : res.v) E1 += 0.5 * sys.mass(0) * v.squaredNorm();
  EXPECT_LT(std::abs(E1 - E0) / E0, 1e-10);
  EXPECT_LT(res.max_overlap_relative, 1e-9);
  Vec<3> p = Vec<3>::Zero();
  for (const auto& v : res.v) p += v;
  EXPECT_LT(p.norm(), 1e-10);
}

TEST(EdmExact, EveryLoggedCollisionConservesMomentumAndLosesExactEnergy) {
  const System<2> sys = test::lattice_gas<2>(20, 0.3, 1.0, 0.7, 5);
  EdmSettings set;
  set.end_time = 5.0;
  Recorder<2> rec;
  const auto res = run_edm<2>(sys, set, QueueKind::Calendar, {&rec});
  ASSERT_EQ(res.status, "ok");
  ASSERT_GT(rec.records.size(), 1000u);
  for (const auto& r : rec.records) {
    const Vec<2> p0 = r.mi * r.vi_before + r.mj * r.vj_before;
    const Vec<2> p1 = r.mi * r.vi_after + r.mj * r.vj_after;
    EXPECT_LT((p1 - p0).norm(), 1e-13 * (r.mi * r.vi_before.norm() + r.mj * r.vj_before.norm()));
    const double u = (r.vi_before - r.vj_before).dot(r.normal);
    const double mstar = r.mi * r.mj / (r.mi + r.mj);
    const double E0 = 0.5 * r.mi * r.vi_before.squaredNorm() + 0.5 * r.mj * r.vj_before.squaredNorm();
    const double E1 = 0.5 * r.mi * r.vi_after.squaredNorm() + 0.5 * r.mj * r.vj_after.squaredNorm();
    EXPECT_NEAR(E0 - E1, (1 - r.e * r.e) * 0.5 * mstar * u * u, 1e-12 * E0);
    EXPECT_DOUBLE_EQ(r.e, 0.7);
    EXPECT_LT(u, 0.0);
  }
}

TEST(EdmExact, CalendarAndHeapQueuesGiveTheIdenticalEventSequence) {
  const System<3> sys = test::lattice_gas<3>(8, 0.35, 1.0, 0.9, 3);
  EdmSettings set;
  set.end_time = 3.0;
  Recorder<3> a, b;
  const auto ra = run_edm<3>(sys, set, QueueKind::Calendar, {&a});
  const auto rb = run_edm<3>(sys, set, QueueKind::Heap, {&b});
  ASSERT_EQ(a.records.size(), b.records.size());
  ASSERT_GT(a.records.size(), 5000u);
  for (std::size_t k = 0; k < a.records.size(); ++k) {
    ASSERT_EQ(a.records[k].time, b.records[k].time) << k;
    ASSERT_EQ(a.records[k].i, b.records[k].i) << k;
    ASSERT_EQ(a.records[k].j, b.records[k].j) << k;
  }
  EXPECT_EQ(ra.counts.cell, rb.counts.cell);
  EXPECT_EQ(ra.counts.stale, rb.counts.stale);
  for (std::size_t i = 0; i < ra.x.size(); ++i) EXPECT_EQ(ra.x[i], rb.x[i]);
}

TEST(EdmExact, DenseInelasticColumnCollapsesWithinBoundedTime) {
  // A 2D column of disks resting on a floor under gravity, e = 0.5: hard-sphere dynamics heads
  // into inelastic collapse; the engine must stop with status "collapse", never hang.
  System<2> s;
  s.lower = Vec<2>(0.0, 0.0);
  s.upper = Vec<2>(10.0, 60.0);
  s.periodic = {true, false};
  s.gravity = Vec<2>(0.0, -1.0);
  Material m;
  m.name = "m";
  m.density = 1.0;
  m.restitution = Restitution::constant(0.5);
  s.materials.push_back(m);
  s.walls.push_back(plane_wall<2>("floor", Vec<2>(0, 0), Vec<2>(0, 1)));
  std::mt19937_64 rng(1);
  std::normal_distribution<double> G(0.0, 0.3);
  for (int row = 0; row < 30; ++row)
    for (int col = 0; col < 9; ++col) {
      s.x.push_back(Vec<2>(0.6 + col * 1.1, 0.6 + row * 1.5));
      s.v.push_back(Vec<2>(G(rng), G(rng)));
      s.radius.push_back(0.5);
      s.material.push_back(0);
    }
  s.upper[1] = 60.0;
  EdmSettings set;
  set.end_time = 200.0;
  const auto res = run_edm<2>(s, set, QueueKind::Calendar);
  EXPECT_EQ(res.status, "collapse");
  EXPECT_LT(res.time, 200.0);
  std::printf("dense column: collapse at t = %.6g after %llu collisions\n", res.time,
              (unsigned long long)res.counts.collisions());
  EXPECT_NE(res.message.find("inelastic collapse"), std::string::npos);
}

TEST(EdmExact, ElasticBallUnderGravityConservesKineticPlusPotentialEnergy) {
  const System<2> sys = bouncing_ball<2>(1.0, 1.0);
  EdmSettings set;
  set.end_time = 10.0;
  set.thermo_interval = 0.01;
  Recorder<2> rec;
  const auto res = run_edm<2>(sys, set, QueueKind::Calendar, {&rec});
  ASSERT_EQ(res.status, "ok");
  ASSERT_GT(rec.samples.size(), 900u);
  // E = KE - sum m g.x; at t = 0 the ball is at rest at height h + R = 1.05 m.
  const double m = sys.mass(0), E0 = m * 9.81 * 1.05;
  for (const auto& s : rec.samples) {
    EXPECT_NEAR(s.kinetic_energy + s.potential_energy, E0, 1e-12 * E0) << "t = " << s.time;
    EXPECT_DOUBLE_EQ(s.temperature, 2.0 * s.kinetic_energy / 2.0);  // T = m v^2 / d, N = 1, d = 2
  }
  EXPECT_GT(rec.samples.back().collisions, 8u);  // about 11 bounces in 10 s
}

TEST(EdmExact, RotationalEnergyOfSpinningParticlesIsCarriedThrough) {
  // Smooth collisions do not change spins; the rotational energy is sum q m R^2 w^2 / 2 with
  // q = 2/5 for spheres (1/2 for disks) and stays constant.
  System<3> sys = test::lattice_gas<3>(6, 0.2, 1.0, 0.8, 2);
  sys.w.resize(sys.size());
  double expected = 0.0;
  for (std::size_t i = 0; i < sys.size(); ++i) {
    sys.w[i] = Vec<3>(0.1 * i, -0.2, 0.3);
    expected += 0.5 * 0.4 * sys.mass(i) * 0.25 * sys.w[i].squaredNorm();
  }
  EdmSettings set;
  set.end_time = 2.0;
  set.thermo_interval = 1.0;
  Recorder<3> rec;
  const auto res = run_edm<3>(sys, set, QueueKind::Calendar, {&rec});
  ASSERT_EQ(rec.samples.size(), 3u);
  for (const auto& s : rec.samples) EXPECT_NEAR(s.rotational_energy, expected, 1e-12 * expected);
  ASSERT_EQ(res.w.size(), sys.size());
  EXPECT_EQ(res.w[7], sys.w[7]);
}

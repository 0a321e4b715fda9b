// A wall shape added in a test-only file (tests/support/sphere_wall.hpp: a spherical container)
// works in all three engines through contact/wall.hpp alone:
//  * EDM: a particle bouncing inside follows the exact piecewise-straight path (impact times from
//    the chord, reflection about the radius at the contact point, restitution on the normal part);
//    an elastic gas inside keeps its energy and stays inside;
//  * TDM: a particle pressed into the wall by delta0 leaves along the inward normal at
//    delta0 sqrt(k/m) (linear spring, no damping: k delta0^2/2 = m v^2/2); a radial impact returns
//    at e times the impact speed (the clipped linear law's e);
//  * hybrid: the same pressed particle starts soft, is pushed off by the soft wall contact, turns
//    hard and bounces off the far side as an EDM wall collision.
// Expected values are closed forms computed here, never this code's output.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>

#include "engine/edm.hpp"
#include "engine/hybrid.hpp"
#include "engine/tdm.hpp"
#include "tests/support/sphere_wall.hpp"

namespace matep {
namespace {

using test::SphereContainer;

constexpr double kRc = 1.0;   // container radius
constexpr double kR = 0.05;   // particle radius
constexpr double kRho = 1000.0;

template <int D>
Vec<D> unit_dir() {
  Vec<D> u = Vec<D>::Zero();
  u[0] = 0.6;
  u[1] = 0.8;
  return u;
}

// A container of radius kRc at the origin in a box just enclosing it; one material.
template <int D>
System<D> container(double e, double stiffness = 0.0) {
  System<D> s;
  s.lower = Vec<D>::Constant(-1.2 * kRc);
  s.upper = Vec<D>::Constant(1.2 * kRc);
  Material m;
  m.name = "grain";
  m.density = kRho;
  m.restitution = Restitution::constant(e);
  if (stiffness > 0.0) {
    m.contact = "linear";
    m.stiffness = stiffness;
  }
  s.materials.push_back(m);
  s.walls.push_back(Wall<D>{"container", 0, std::make_shared<SphereContainer<D>>(Vec<D>::Zero(), kRc)});
  return s;
}

template <int D>
void add(System<D>& s, const Vec<D>& x, const Vec<D>& v, double R = kR) {
  s.x.push_back(x);
  s.v.push_back(v);
  s.radius.push_back(R);
  s.material.push_back(0);
}

template <int D>
struct Recorder final : Observer<D> {
  std::vector<CollisionRecord<D>> walls;
  bool wants_collisions() const override { return true; }
  void on_collision(const CollisionRecord<D>& r) override {
    if (r.kind == EventKind::WallCollision) walls.push_back(r);
  }
};

// ---- EDM -----------------------------------------------------------------------------------

template <int D>
void check_edm_bounces(double e) {
  System<D> s = container<D>(e);
  Vec<D> x0 = Vec<D>::Zero(), v0 = Vec<D>::Zero();
  x0[0] = 0.1;
  x0[1] = 0.05;
  v0[0] = 1.0;
  v0[1] = 0.3;
  if constexpr (D == 3) v0[2] = -0.2;
  add(s, x0, v0);
  const double T = 12.0;
  // The exact path: straight flights; at |x| = Rc - R the normal part of v is reversed times e.
  std::vector<double> times;
  std::vector<Vec<D>> normals;
  Vec<D> x = x0, v = v0;
  double t = 0.0;
  const double sr = kRc - kR;
  for (;;) {
    const double a = v.squaredNorm(), b = x.dot(v), c = x.squaredNorm() - sr * sr;
    const double dt = (-b + std::sqrt(b * b - a * c)) / a;
    if (t + dt > T) {
      x += v * (T - t);
      break;
    }
    t += dt;
    x += v * dt;
    const Vec<D> n = -x / x.norm();
    v -= (1.0 + e) * v.dot(n) * n;
    times.push_back(t);
    normals.push_back(n);
  }
  ASSERT_GE(times.size(), 3u);
  EdmSettings es;
  es.end_time = T;
  Recorder<D> rec;
  const RunResult<D> r = run_edm<D>(s, es, QueueKind::Calendar, {&rec});
  ASSERT_EQ(r.status, "ok") << r.message;
  ASSERT_EQ(rec.walls.size(), times.size());
  for (std::size_t k = 0; k < times.size(); ++k) {
    EXPECT_NEAR(rec.walls[k].time, times[k], 1e-12) << "impact " << k;
    EXPECT_LT((rec.walls[k].normal - normals[k]).norm(), 1e-12) << "impact " << k;
    EXPECT_NEAR(rec.walls[k].e, e, 0.0);
  }
  EXPECT_LT((r.x[0] - x).norm(), 1e-11);
  EXPECT_LT((r.v[0] - v).norm(), 1e-12);
}

TEST(WallShapeEdm, BouncesInsideASphereFollowTheExactPath3D) { check_edm_bounces<3>(1.0); }
TEST(WallShapeEdm, InelasticBouncesInsideACircleFollowTheExactPath2D) { check_edm_bounces<2>(0.7); }

TEST(WallShapeEdm, ElasticGasInASphereKeepsItsEnergyAndStaysInside) {
  System<3> s = container<3>(1.0);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::normal_distribution<double> g(0.0, 1.0);
  while (s.size() < 60) {
    const Vec<3> x(0.8 * u(rng), 0.8 * u(rng), 0.8 * u(rng));
    if (x.norm() > 0.8) continue;
    bool free = true;
    for (const auto& y : s.x) free = free && (x - y).norm() > 2.0 * kR * 1.01;
    if (free) add<3>(s, x, Vec<3>(g(rng), g(rng), g(rng)));
  }
  double ke0 = 0.0;
  for (const auto& v : s.v) ke0 += v.squaredNorm();
  EdmSettings es;
  es.end_time = 10.0;
  const RunResult<3> r = run_edm<3>(s, es, QueueKind::Calendar);
  ASSERT_EQ(r.status, "ok") << r.message;
  double ke1 = 0.0, out = -kNever;
  for (std::size_t i = 0; i < r.v.size(); ++i) {
    ke1 += r.v[i].squaredNorm();
    out = std::max(out, r.x[i].norm() + kR - kRc);
  }
  EXPECT_NEAR(ke1 / ke0, 1.0, 1e-12);
  EXPECT_LT(out, 1e-12);
  EXPECT_GT(r.counts.wall, 200u);
  EXPECT_GT(r.counts.pair, 100u);
}

// ---- TDM -----------------------------------------------------------------------------------

constexpr double kK = 1e5;        // linear stiffness [N/m]
constexpr double kDelta0 = 0.002; // initial overlap with the wall

template <int D>
double mass() {
  return kRho * ball_volume<D>(kR);
}

template <int D>
System<D> pressed_into_wall() {
  System<D> s = container<D>(1.0, kK);
  add<D>(s, (kRc - kR + kDelta0) * unit_dir<D>(), Vec<D>::Zero());
  return s;
}

template <int D>
void check_tdm_push() {
  TdmSettings ts;
  ts.end_time = 0.05;
  ts.threads = 1;
  const RunResult<D> r = run_tdm<D>(pressed_into_wall<D>(), ts);
  ASSERT_EQ(r.status, "ok") << r.message;
  // k delta0^2 / 2 = m v^2 / 2, along the inward normal -u.
  const Vec<D> expected = -kDelta0 * std::sqrt(kK / mass<D>()) * unit_dir<D>();
  EXPECT_LT((r.v[0] - expected).norm(), 1e-3 * expected.norm()) << r.v[0].transpose();
  EXPECT_LT(r.x[0].norm() + kR, kRc);
}

TEST(WallShapeTdm, PressedParticleLeavesAlongTheNormalWithTheSpringEnergy3D) { check_tdm_push<3>(); }
TEST(WallShapeTdm, PressedParticleLeavesAlongTheNormalWithTheSpringEnergy2D) { check_tdm_push<2>(); }

TEST(WallShapeTdm, RadialImpactReturnsAtTheRestitution) {
  const double e = 0.5;
  System<3> s = container<3>(e, kK);
  add<3>(s, Vec<3>::Zero(), unit_dir<3>());
  TdmSettings ts;
  ts.end_time = 1.5;  // impact at 0.95 s
  ts.threads = 1;
  const RunResult<3> r = run_tdm<3>(s, ts);
  ASSERT_EQ(r.status, "ok") << r.message;
  EXPECT_LT((r.v[0] + e * unit_dir<3>()).norm(), 2e-3 * e);
}

// ---- hybrid --------------------------------------------------------------------------------

template <int D>
void check_hybrid_push_and_bounce() {
  const double speed = kDelta0 * std::sqrt(kK / mass<D>());
  EdmSettings es;
  es.end_time = 1.3 * 2.0 * (kRc - kR) / speed;  // pushed off within ms; then crosses 2 (Rc - R)
  Recorder<D> rec;
  const RunResult<D> r = run_hybrid<D>(pressed_into_wall<D>(), es, HybridSettings{}, {&rec});
  ASSERT_EQ(r.status, "ok") << r.message;
  EXPECT_EQ(r.hybrid.by_overlap, 1u);
  EXPECT_EQ(r.hybrid.to_hard, 1u);
  ASSERT_EQ(rec.walls.size(), 1u);  // the far side, as a hard collision
  // The hard collision: at the far side of the chord through the centre, elastic.
  EXPECT_LT((rec.walls[0].normal - unit_dir<D>()).norm(), 1e-3);
  EXPECT_NEAR(rec.walls[0].vi_before.norm(), speed, 1e-3 * speed);
  EXPECT_NEAR(rec.walls[0].vi_after.norm(), speed, 1e-3 * speed);
  const Vec<D> expected = speed * unit_dir<D>();  // back towards where it started
  EXPECT_LT((r.v[0] - expected).norm(), 1e-3 * speed);
  EXPECT_LT(r.x[0].norm() + kR, kRc);
}

TEST(WallShapeHybrid, PressedParticleIsPushedOffSoftAndBouncesHard3D) { check_hybrid_push_and_bounce<3>(); }
TEST(WallShapeHybrid, PressedParticleIsPushedOffSoftAndBouncesHard2D) { check_hybrid_push_and_bounce<2>(); }

}  // namespace
}  // namespace matep

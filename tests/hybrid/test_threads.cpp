// The hybrid's soft set on several threads (engine/hybrid/hybrid.cpp threads_for): the same
// trajectory as one thread up to round-off, bit-identical between runs with the same count, and
// conservation. Three systems large enough to be split (2 x 2048 awake soft grains): a compressed
// dense soft gas of spheres and one of disks (periodic, frictionless) and a frictional bed on a floor and between side walls
// whose grains fall asleep (rest rule; the soft set split down to 256 awake grains), which exercises the walls' owners, the sleepers' forces and
// the rows that the wakes append.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "engine/hybrid.hpp"
#include "tests/support/systems.hpp"

namespace matep {
namespace {

// 16^3 unit spheres (64^2 disks) on a simple cubic (square) lattice of spacing 0.99 d (every
// grain overlaps its neighbours by 0.01 d, so all start soft) at T = 1, linear spring-dashpot
// k = 9e4, e = 0.9.
template <int D>
System<D> dense_soft_gas() {
  const double phi = ball_volume<D>(0.5) / std::pow(0.99, D);
  System<D> s = test::lattice_gas<D>(D == 3 ? 16 : 64, phi, 1.0, 0.9, 11);
  s.materials[0].contact = "linear";
  s.materials[0].stiffness = 9.0e4;
  return s;
}

// 12 x 12 x 12 grains (d = 1 mm, 2500 kg/m^3, Hertz-Mindlin, E = 5e6 Pa, mu = 0.5, e = 0.5)
// stacked at a spacing of 0.995 d on a floor between side walls (x and y), released under gravity.
System<3> frictional_bed() {
  System<3> s;
  const double d = 1e-3, a = 0.995 * d;
  const int n = 12;
  s.lower = Vec<3>(0.0, 0.0, 0.0);
  s.upper = Vec<3>(n * a + 0.01 * d, n * a + 0.01 * d, 3.0 * n * d);
  s.periodic = {false, false, false};
  s.gravity = Vec<3>(0.0, 0.0, -9.81);
  Material m;
  m.name = "glass";
  m.density = 2500.0;
  m.restitution = Restitution::constant(0.5);
  m.contact = "hertz";
  m.young = 5e6;
  m.poisson = 0.3;
  m.friction = 0.5;
  s.materials.push_back(m);
  s.walls.push_back(plane_wall<3>("floor", Vec<3>::Zero(), Vec<3>(0.0, 0.0, 1.0)));
  s.walls.push_back(plane_wall<3>("x0", Vec<3>::Zero(), Vec<3>(1.0, 0.0, 0.0)));
  s.walls.push_back(plane_wall<3>("x1", s.upper, Vec<3>(-1.0, 0.0, 0.0)));
  s.walls.push_back(plane_wall<3>("y0", Vec<3>::Zero(), Vec<3>(0.0, 1.0, 0.0)));
  s.walls.push_back(plane_wall<3>("y1", s.upper, Vec<3>(0.0, -1.0, 0.0)));
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        s.x.push_back(Vec<3>((i + 0.5) * a + 0.005 * d, (j + 0.5) * a + 0.005 * d, 0.4975 * d + k * a));
        s.v.push_back(Vec<3>::Zero());
        s.radius.push_back(0.5 * d);
        s.material.push_back(0);
      }
  return s;
}

template <int D>
double max_position_difference(const RunResult<D>& a, const RunResult<D>& b) {
  double dx = 0.0;
  for (std::size_t i = 0; i < a.x.size(); ++i) dx = std::max(dx, (a.x[i] - b.x[i]).norm());
  return dx;
}
template <int D>
double max_velocity_difference(const RunResult<D>& a, const RunResult<D>& b) {
  double dv = 0.0;
  for (std::size_t i = 0; i < a.v.size(); ++i) dv = std::max(dv, (a.v[i] - b.v[i]).norm());
  return dv;
}
template <int D>
bool identical(const RunResult<D>& a, const RunResult<D>& b) {
  for (std::size_t i = 0; i < a.x.size(); ++i)
    if (a.x[i] != b.x[i] || a.v[i] != b.v[i]) return false;
  return true;
}

template <int D>
void dense_gas_on_two_threads() {
  const System<D> sys = dense_soft_gas<D>();
  HybridSettings hs;
  hs.cost_ratio = 1e9;  // releases off: the whole gas stays soft
  hs.hysteresis = 1e9;
  const SoftPlan plan = hybrid_preflight<D>(sys, hs);
  EdmSettings es;
  es.end_time = 400 * plan.default_dt;
  hs.threads = 1;
  const RunResult<D> one = run_hybrid<D>(sys, es, hs);
  hs.threads = 2;
  const RunResult<D> two = run_hybrid<D>(sys, es, hs);
  const RunResult<D> again = run_hybrid<D>(sys, es, hs);
  ASSERT_EQ(one.status, "ok");
  ASSERT_EQ(two.status, "ok");
  EXPECT_EQ(one.soft.threads, 1);
  EXPECT_EQ(two.soft.threads, 2);  // the soft set was split
  EXPECT_EQ(two.hybrid.soft_particle_steps, 4096 * (two.hybrid.substeps - 1));  // all soft from the 2nd
  EXPECT_GT(two.soft.rebuilds, 1u);  // list builds on two threads too
  // The same contacts, the same trajectory to round-off (the force sums differ in order only).
  EXPECT_EQ(one.soft.contacts, two.soft.contacts);
  EXPECT_LT(max_position_difference(one, two), 1e-10);
  EXPECT_LT(max_velocity_difference(one, two), 1e-9);  // speeds ~ 1
  EXPECT_TRUE(identical(two, again));  // deterministic for a given thread count
  // Momentum: zero at the start, conserved by the pair forces (spilled or not) to round-off.
  Vec<D> p = Vec<D>::Zero();
  double vmax = 0.0;
  for (const auto& v : two.v) {
    p += v;
    vmax = std::max(vmax, v.norm());
  }
  EXPECT_LT(p.norm(), 1e-9 * vmax * 4096);
}

TEST(HybridThreads, DenseSoftGasSameTrajectoryOnTwoThreads) { dense_gas_on_two_threads<3>(); }
TEST(HybridThreads, DenseSoftDiskGasSameTrajectoryOnTwoThreads) { dense_gas_on_two_threads<2>(); }

TEST(HybridThreads, FrictionalBedWithWallsAndSleepers) {
  const System<3> sys = frictional_bed();
  HybridSettings hs;
  hs.rest_speed = 2e-3;  // m/s: the bed settles and its grains fall asleep within the run
  hs.min_per_thread = 128;  // split the soft set down to 256 awake grains (the default: 4096)
  const SoftPlan plan = hybrid_preflight<3>(sys, hs);
  hs.rest_time = 50 * plan.default_dt;
  EdmSettings es;
  es.end_time = 600 * plan.default_dt;
  hs.threads = 1;
  const RunResult<3> one = run_hybrid<3>(sys, es, hs);
  hs.threads = 2;
  const RunResult<3> two = run_hybrid<3>(sys, es, hs);
  const RunResult<3> again = run_hybrid<3>(sys, es, hs);
  ASSERT_EQ(one.status, "ok") << one.message;
  ASSERT_EQ(two.status, "ok") << two.message;
  EXPECT_EQ(two.soft.threads, 2);
  EXPECT_GT(two.hybrid.slept, 100u);  // the rest rule took part
  EXPECT_GT(two.hybrid.woken, 0u);
  EXPECT_TRUE(identical(two, again));
  // One and two threads: the same sleepers and contacts, positions within 1e-6 d.
  EXPECT_EQ(one.hybrid.slept, two.hybrid.slept);
  EXPECT_EQ(one.hybrid.woken, two.hybrid.woken);
  EXPECT_EQ(one.soft.contacts, two.soft.contacts);
  EXPECT_LT(max_position_difference(one, two), 1e-9);
}

}  // namespace
}  // namespace matep

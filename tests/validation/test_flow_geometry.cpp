// Flow geometry at length: an elastic hard-sphere gas in a closed tube (a finite cylinder, touched
// from both sides, capped by two planes) keeps its kinetic energy over more than 10^6 collisions,
// a quarter of them with the curved wall, and no grain is ever found beyond the walls: every
// impact time on the tube (offset cylinder and rim tori, contact/shape_features.hpp) is exact.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>

#include "contact/cylinder.hpp"
#include "engine/edm.hpp"

namespace matep {
namespace {

TEST(FlowGeometryValidation, ElasticGasInAClosedTubeKeepsItsEnergyOverAMillionCollisions) {
  System<3> s;
  const double Rc = 0.05, L = 0.2, R = 0.002;
  s.lower = Vec<3>(-0.06, -0.06, -0.01);
  s.upper = Vec<3>(0.06, 0.06, 0.21);
  Material m;
  m.name = "g";
  m.density = 2500.0;
  m.restitution = Restitution::constant(1.0);
  s.materials.push_back(m);
  s.walls.push_back(Wall<3>{"tube", 0, std::make_shared<CylinderWall<3>>(Vec<3>::Zero(), Vec<3>(0, 0, 1), Rc, L)});
  s.walls.push_back(plane_wall<3>("bottom", Vec<3>::Zero(), Vec<3>(0, 0, 1)));
  s.walls.push_back(plane_wall<3>("top", Vec<3>(0, 0, L), Vec<3>(0, 0, -1)));
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::normal_distribution<double> g;
  while (s.x.size() < 2000) {
    const Vec<3> x(0.045 * u(rng), 0.045 * u(rng), 0.1 + 0.097 * u(rng));
    if (std::hypot(x[0], x[1]) > Rc - 1.01 * R) continue;
    bool ok = true;
    for (const auto& y : s.x) ok = ok && (x - y).norm() > 2.02 * R;
    if (!ok) continue;
    s.x.push_back(x);
    s.v.push_back(Vec<3>(g(rng), g(rng), g(rng)));
    s.radius.push_back(R);
    s.material.push_back(0);
  }
  double ke0 = 0.0;
  for (const auto& v : s.v) ke0 += 0.5 * s.mass(0) * v.squaredNorm();
  EdmSettings set;
  set.end_time = 5.0;
  const RunResult<3> r = run_edm<3>(s, set, QueueKind::Calendar);
  ASSERT_EQ(r.status, "ok");
  EXPECT_GT(r.counts.pair + r.counts.wall, 1000000u);
  EXPECT_GT(r.counts.wall, 200000u);
  double ke = 0.0, worst = 0.0;
  for (std::size_t i = 0; i < r.x.size(); ++i) {
    ke += 0.5 * s.mass(i) * r.v[i].squaredNorm();
    const Vec<3>& x = r.x[i];
    worst = std::max({worst, std::hypot(x[0], x[1]) + R - Rc, R - x[2], x[2] + R - L});
  }
  EXPECT_NEAR(ke / ke0, 1.0, 1e-10);
  EXPECT_LT(worst, 1e-12);
}

}  // namespace
}  // namespace matep

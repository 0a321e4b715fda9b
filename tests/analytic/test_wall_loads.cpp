// The grains' load on the walls (engine/wall_loads.hpp, thermo.csv's NAME_f*/NAME_t* columns):
// the mean force over each thermo interval and its torque about the wall's anchor, in all three
// engines, against momentum balance:
//  * EDM: an elastic ball bouncing on a floor under gravity, period T = 2 sqrt(2 h / g); each
//    interval of length T holds one bounce, whose impulse 2 m v = m g T makes the mean force exactly
//    m g; the torque about the floor's point p is (c - p) x F with c the contact point;
//  * TDM and the hybrid: a ball at rest on a floor presses it with m g; a bed's weight is carried by
//    the floor and (through friction) the side walls: the walls' vertical forces sum to the weight.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <vector>

#include "engine/edm.hpp"
#include "engine/hybrid.hpp"
#include "engine/tdm.hpp"
#include "tests/support/systems.hpp"

namespace matep {
namespace {

constexpr double kG = 9.81;

struct Samples final : Observer<2>, Observer<3> {
  std::vector<ThermoSample> rows;
  void on_sample(const ThermoSample& s) override { rows.push_back(s); }
};

// A ball of radius R at (a, b, R + h) above a floor z = 0 through p = (0.1, -0.2, 0) (3D), or at
// (a, R + h) above y = 0 through p = (0.1, 0) (2D), under gravity; one material.
template <int D>
System<D> ball_on_floor(const Material& m, double R, double h, double a, double b) {
  System<D> s;
  s.lower = Vec<D>::Constant(-1.0);
  s.upper = Vec<D>::Constant(1.0);
  s.gravity = Vec<D>::Zero();
  s.gravity[D - 1] = -kG;
  s.materials.push_back(m);
  Vec<D> p = Vec<D>::Zero(), n = Vec<D>::Zero(), x = Vec<D>::Zero();
  p[0] = 0.1;
  if constexpr (D == 3) p[1] = -0.2;
  p[D - 1] = -0.5;
  n[D - 1] = 1.0;
  s.walls.push_back(plane_wall<D>("floor", p, n));
  x[0] = a;
  if constexpr (D == 3) x[1] = b;
  x[D - 1] = -0.5 + R + h;
  s.x.push_back(x);
  s.v.push_back(Vec<D>::Zero());
  s.radius.push_back(R);
  s.material.push_back(0);
  return s;
}

// The torque about p of the force F (only along the last axis) applied at c, as the six numbers'
// torque part: 3D (c - p) x F; 2D its z component.
template <int D>
std::array<double, 3> torque_of(const Vec<D>& r, double Fz) {
  if constexpr (D == 3) return {r[1] * Fz, -r[0] * Fz, 0.0};
  else return {0.0, 0.0, r[0] * Fz};
}

template <int D>
void check_edm_bounce() {
  Material m;
  m.name = "ball";
  m.density = 1000.0;
  m.restitution = Restitution::constant(1.0);
  const double R = 0.05, h = 0.2, a = 0.3, b = 0.25;
  System<D> s = ball_on_floor<D>(m, R, h, a, b);
  const double mass = m.density * ball_volume<D>(R);
  const double T = 2.0 * std::sqrt(2.0 * h / kG);  // bounce period; impacts at T/2 + k T
  Samples obs;
  EdmSettings set;
  set.end_time = 8.0 * T;
  set.thermo_interval = T;
  const auto res = run_edm<D>(s, set, QueueKind::Calendar, {static_cast<Observer<D>*>(&obs)});
  ASSERT_EQ(res.status, "ok");
  ASSERT_GE(obs.rows.size(), 8u);
  EXPECT_TRUE(obs.rows.front().wall_loads.empty());  // no interval before t = 0
  Vec<D> r = Vec<D>::Zero();  // contact point minus the floor's point
  r[0] = a - 0.1;
  if constexpr (D == 3) r[1] = b + 0.2;
  const auto tq = torque_of<D>(r, -mass * kG);
  for (std::size_t k = 1; k < obs.rows.size(); ++k) {
    const auto& L = obs.rows[k].wall_loads;
    ASSERT_EQ(L.size(), 6u);
    EXPECT_NEAR(L[D - 1], -mass * kG, 1e-9 * mass * kG) << "interval " << k;
    EXPECT_NEAR(L[0], 0.0, 1e-12);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(L[3 + c], tq[c], 1e-9 * mass * kG) << "interval " << k;
  }
}

TEST(WallLoads, EdmBouncingBallPressesTheFloorWithItsWeight2D) { check_edm_bounce<2>(); }
TEST(WallLoads, EdmBouncingBallPressesTheFloorWithItsWeight3D) { check_edm_bounce<3>(); }

// A ball dropped from a small height settles on the floor (linear spring-dashpot, e = 0.3); over
// the last interval it is at rest and the floor carries m g at the contact point below the ball.
template <int D>
void check_soft_rest(bool hybrid) {
  const Material m = test::linear_material("ball", 1000.0, 1e4, 0.3);
  const double R = 0.05, a = -0.3, b = 0.4;
  System<D> s = ball_on_floor<D>(m, R, 0.01, a, b);
  const double mass = m.density * ball_volume<D>(R);
  Samples obs;
  std::vector<Observer<D>*> o{static_cast<Observer<D>*>(&obs)};
  RunResult<D> res;
  if (hybrid) {
    EdmSettings e;
    e.end_time = 2.0;
    e.thermo_interval = 0.5;
    res = run_hybrid<D>(s, e, HybridSettings{}, o);
  } else {
    TdmSettings t;
    t.end_time = 2.0;
    t.thermo_interval = 0.5;
    res = run_tdm<D>(s, t, o);
  }
  ASSERT_EQ(res.status, "ok");
  const auto& L = obs.rows.back().wall_loads;
  ASSERT_EQ(L.size(), 6u);
  EXPECT_NEAR(L[D - 1], -mass * kG, 1e-4 * mass * kG);
  EXPECT_NEAR(L[0], 0.0, 1e-6 * mass * kG);
  Vec<D> r = Vec<D>::Zero();
  r[0] = a - 0.1;
  if constexpr (D == 3) r[1] = b + 0.2;
  const auto tq = torque_of<D>(r, -mass * kG);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(L[3 + c], tq[c], 1e-4 * mass * kG);
}

TEST(WallLoads, TdmBallAtRestPressesTheFloorWithItsWeight2D) { check_soft_rest<2>(false); }
TEST(WallLoads, TdmBallAtRestPressesTheFloorWithItsWeight3D) { check_soft_rest<3>(false); }
TEST(WallLoads, HybridBallAtRestPressesTheFloorWithItsWeight3D) { check_soft_rest<3>(true); }

}  // namespace
}  // namespace matep

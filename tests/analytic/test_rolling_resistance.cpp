// Rolling resistance of the soft contacts (contact/soft.hpp rolling_torque; Ai, Chen, Rotter & Ooi,
// Powder Technol. 206, 269 (2011)) against closed forms, TDM and the hybrid's soft set.
//
// A ball (radius R, I = q m R^2) rolling without slip on a floor with a rolling torque M = mu_r R F_n
// against its spin: the friction force F_t acts at the lever l = R - delta (the contact point the
// soft path uses, wall_lever_arm), so with a = alpha l,
//   m a = m g sin(theta) - F_t,   q m R^2 alpha = F_t l - mu_r R m g cos(theta)
// give a = g (sin(theta) - mu_r cos(theta) R / l) / (1 + q R^2 / l^2): on a level floor the
// deceleration mu_r g R l / (q R^2 + l^2) (5/7 mu_r g for a sphere with l = R), on an incline
// rolling starts where tan(theta) = mu_r R / l (tan(theta) = mu_r with l = R).
//  * constant directional torque (model A): a ball set rolling on a level floor decelerates at that
//    rate (3D TDM and hybrid, 2D TDM);
//  * elastic-plastic spring-dashpot (model C, "epsd"): a ball at rest on an incline with
//    tan(theta) = 0.9 mu_r stays (the spring holds it), at 1.1 mu_r it rolls down with the
//    acceleration above (the spring saturates at M_m; the dashpot is off then);
//  * the rolling torque of a pair is equal and opposite: two balls in contact spinning the same
//    way keep their total angular momentum.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "contact/cylinder.hpp"
#include "contact/plane.hpp"
#include "engine/soft/forces.hpp"
#include "engine/hybrid.hpp"
#include "engine/tdm.hpp"
#include "tests/support/shape_physics.hpp"
#include "tests/support/systems.hpp"

namespace matep {
namespace {

using test::kG;
using test::kGrainR;

// Hertz grain on a floor at z = 0 (2D: y = 0) with friction mu and rolling resistance mu_r of the
// given model; gravity g at angle theta from the floor's normal, tilted along +x.
template <int D>
System<D> ball_on_floor(double mu, double mu_r, const char* model, double theta, const Vec<D>& v0, double w0) {
  Vec<D> lo = Vec<D>::Constant(-1.0), hi = Vec<D>::Constant(1.0);
  lo[0] = -50.0;
  hi[0] = 50.0;
  lo[D - 1] = -0.2;
  System<D> s = test::hertz_system<D>(lo, hi, 0.3, mu);
  s.materials[0].rolling_friction = mu_r;
  s.materials[0].rolling = model;
  s.gravity = Vec<D>::Zero();
  s.gravity[0] = kG * std::sin(theta);
  s.gravity[D - 1] = -kG * std::cos(theta);
  s.walls.push_back(plane_wall<D>("floor", Vec<D>::Zero(), test::up_axis<D>()));
  // Resting at its static Hertz overlap for the normal load.
  const double m = test::grain_mass<D>(kGrainR);
  const double delta = test::hertz_overlap(m * kG * std::cos(theta), kGrainR);
  Vec<D> x = Vec<D>::Zero();
  x[D - 1] = kGrainR - delta;
  test::add_grain<D>(s, x, v0, kGrainR);
  s.w.assign(1, Spin<D>::Zero());
  if constexpr (D == 3) s.w[0][1] = w0;  // about +y: rolls towards +x
  else s.w[0][0] = -w0;                  // about +z: clockwise rolls towards +x
  return s;
}

// The closed-form acceleration along +x of a ball rolling without slip (header).
template <int D>
double rolling_acceleration(double mu_r, double theta, double delta) {
  const double q = inertia_factor<D>(), R = kGrainR, l = R - delta;
  return kG * (std::sin(theta) - mu_r * std::cos(theta) * R / l) / (1.0 + q * R * R / (l * l));
}

// Least-squares slope of the grain's x velocity over the snapshots with t in [t0, t1].
double velocity_slope(const test::Track& tr, double t0, double t1, int& m) {
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  m = 0;
  for (std::size_t k = 0; k < tr.t.size(); ++k) {
    const double t = tr.t[k];
    if (t < t0 || t > t1) continue;
    sx += t;
    sy += tr.v[k][0];
    sxx += t * t;
    sxy += t * tr.v[k][0];
    ++m;
  }
  return (m * sxy - sx * sy) / (m * sxx - sx * sx);
}

// Constant torque, level floor: set rolling at 0.5 m/s, it decelerates at mu_r g R l/(q R^2 + l^2).
template <int D>
void check_constant_torque_deceleration(bool hybrid) {
  const double mu_r = 0.05, v0 = 0.5;
  Vec<D> v = Vec<D>::Zero();
  v[0] = v0;
  const System<D> s = ball_on_floor<D>(0.5, mu_r, "constant", 0.0, v, v0 / kGrainR);
  test::Tracker<D> tr;
  // It stops after v0 / (5/7 mu_r g) = 1.43 s: fit over [0.2, 1.0] s, where it still rolls.
  const RunResult<D> r = test::run_soft<D>(s, hybrid, 1.0, 0.01, &tr);
  ASSERT_EQ(r.status, "ok") << r.message;
  int m = 0;
  const double a = velocity_slope(tr.track, 0.2, 1.0, m);
  const double delta = test::hertz_overlap(test::grain_mass<D>(kGrainR) * kG, kGrainR);
  const double expect = rolling_acceleration<D>(mu_r, 0.0, delta);
  std::printf("constant rolling torque, %dD %s: deceleration %.6g, closed form %.6g (5/7 mu_r g = %.6g), ratio %.5f\n",
              D, hybrid ? "hybrid" : "TDM", -a, -expect, 5.0 / 7.0 * mu_r * kG, a / expect);
  EXPECT_GT(m, 50);
  EXPECT_NEAR(a / expect, 1.0, 0.01);
}

TEST(RollingResistance, ConstantTorqueDeceleratesARollingSphereAtFiveSeventhsMuRgTdm) {
  check_constant_torque_deceleration<3>(false);
}
TEST(RollingResistance, ConstantTorqueDeceleratesARollingSphereAtFiveSeventhsMuRgHybrid) {
  check_constant_torque_deceleration<3>(true);
}
TEST(RollingResistance, ConstantTorqueDeceleratesARollingDiskTdm2D) { check_constant_torque_deceleration<2>(false); }

// EPSD on an incline from rest: below tan(theta) = mu_r it stays, above it rolls down at the
// closed-form acceleration.
template <int D>
void check_epsd_incline(bool hybrid) {
  const double mu_r = 0.2;
  for (const double f : {0.9, 1.1}) {
    const double theta = std::atan(f * mu_r);
    const System<D> s = ball_on_floor<D>(1.0, mu_r, "epsd", theta, Vec<D>::Zero(), 0.0);
    test::Tracker<D> tr;
    const double T = 1.5;
    const RunResult<D> r = test::run_soft<D>(s, hybrid, T, 0.01, &tr);
    ASSERT_EQ(r.status, "ok") << r.message;
    const double x_end = r.x[0][0];
    const double delta = test::hertz_overlap(test::grain_mass<D>(kGrainR) * kG * std::cos(theta), kGrainR);
    if (f < 1.0) {
      // Held: the spring carries the torque m g sin(theta) R at a turn M / k_r, k_r = 2.25 mu_r^2 R^2
      // F_n / delta, a creep R M / k_r = tan(theta) delta / (2.25 mu_r^2) (a load applied at once
      // overshoots to twice that); the dashpot stops it. Rolling, it would cover a T^2 / 2 (a: the
      // closed form at 1.1 mu_r, about 0.1 m/s^2) and reach a T.
      const double creep = std::tan(theta) * delta / (2.25 * mu_r * mu_r);
      const double a11 = rolling_acceleration<D>(mu_r, std::atan(1.1 * mu_r), delta);
      std::printf("EPSD, %dD %s, tan(theta) = 0.9 mu_r: moved %.3g m (static creep %.3g m), final speed %.3g m/s\n", D,
                  hybrid ? "hybrid" : "TDM", x_end, creep, r.v[0].norm());
      EXPECT_LT(std::abs(x_end), 3.0 * creep);
      EXPECT_LT(r.v[0].norm(), 1e-3 * a11 * T);
    } else {
      int m = 0;
      const double a = velocity_slope(tr.track, 0.3, T, m);
      const double expect = rolling_acceleration<D>(mu_r, theta, delta);
      std::printf("EPSD, %dD %s, tan(theta) = 1.1 mu_r: acceleration %.6g, closed form %.6g, ratio %.5f\n", D,
                  hybrid ? "hybrid" : "TDM", a, expect, a / expect);
      EXPECT_GT(m, 50);
      EXPECT_NEAR(a / expect, 1.0, 0.01);
    }
  }
}

TEST(RollingResistance, EpsdSphereOnAnInclineStartsRollingAtTanThetaEqualsMuRTdm) { check_epsd_incline<3>(false); }
TEST(RollingResistance, EpsdSphereOnAnInclineStartsRollingAtTanThetaEqualsMuRHybrid) { check_epsd_incline<3>(true); }
TEST(RollingResistance, EpsdDiskOnAnInclineStartsRollingAtTanThetaEqualsMuRTdm2D) { check_epsd_incline<2>(false); }

// The rolling torques of a pair are equal and opposite: two touching balls without gravity or walls,
// spun about the same axis at different rates, keep their total angular momentum (frictionless, so
// only the rolling torque acts on the spins) while their relative spin decays.
template <int D>
void check_pair_torques_cancel(const char* model) {
  System<D> s = test::hertz_system<D>(Vec<D>::Constant(-1.0), Vec<D>::Constant(1.0), 0.9, 0.0);
  s.materials[0].rolling_friction = 0.3;
  s.materials[0].rolling = model;
  Vec<D> x = Vec<D>::Zero();
  x[0] = -kGrainR + 1e-4;
  Vec<D> v = Vec<D>::Zero();
  v[0] = 0.05;  // pressed together for a while (a slow collision)
  test::add_grain<D>(s, x, v, kGrainR);
  test::add_grain<D>(s, Vec<D>(-x), Vec<D>(-v), kGrainR);
  s.w.assign(2, Spin<D>::Zero());
  s.w[0][D == 3 ? 2 : 0] = 20.0;
  s.w[1][D == 3 ? 2 : 0] = -10.0;
  TdmSettings ts;
  ts.end_time = 0.004;
  ts.threads = 1;
  const RunResult<D> r = run_tdm<D>(s, ts, {});
  ASSERT_EQ(r.status, "ok") << r.message;
  const int k = D == 3 ? 2 : 0;
  const double sum0 = s.w[0][k] + s.w[1][k], sum1 = r.w[0][k] + r.w[1][k];
  const double rel0 = s.w[0][k] - s.w[1][k], rel1 = r.w[0][k] - r.w[1][k];
  std::printf("pair rolling torque (%s, %dD): spin sum %.17g -> %.17g, relative spin %.6g -> %.6g\n", model, D, sum0,
              sum1, rel0, rel1);
  EXPECT_NEAR(sum1, sum0, 1e-12 * std::abs(rel0));
  EXPECT_LT(std::abs(rel1), 0.999 * std::abs(rel0));  // the torque acted
}

TEST(RollingResistance, PairTorquesAreEqualAndOppositeConstant3D) { check_pair_torques_cancel<3>("constant"); }
TEST(RollingResistance, PairTorquesAreEqualAndOppositeEpsd3D) { check_pair_torques_cancel<3>("epsd"); }
TEST(RollingResistance, PairTorquesAreEqualAndOppositeEpsd2D) { check_pair_torques_cancel<2>("epsd"); }

// A turning wall's own spin is what the rolling torque resists (WallShape::spin): a frictionless
// ball pressed against a drum turning at Omega about z feels no rolling torque when it spins with
// the drum, and the full M_m = mu_r R F_n against the drum's turn when it does not spin (constant
// torque model, one force evaluation of soft::wall_contact).
TEST(RollingResistance, ATurningDrumsOwnSpinIsWhatTheTorqueResists) {
  const double Rc = 0.5, R = kGrainR, Omega = 3.0, mu_r = 0.1, delta = 1e-4;
  const CylinderWall<3> drum(Vec<3>::Zero(), Vec<3>(0, 0, 1), Rc, 0.0, true, Omega);
  EXPECT_NEAR((drum.spin() - Spin<3>(0, 0, Omega)).norm(), 0.0, 1e-15);
  SoftLaw law;
  law.normal = NormalLaw::Hertz;
  law.damping = HertzDamping::Tsuji;
  law.restitution = 0.9;
  law.rolling = RollingModel::Constant;
  law.rolling_friction = mu_r;
  law = law.resolved();
  PairParams p;
  p.Estar = test::estar_same();
  p.Gstar = 1e6;
  p.Rstar = R;
  p.mstar = test::grain_mass<3>(R);
  p.Ir = 1.4 * p.mstar * R * R;
  const SoftContact c = soft_contact(law, p);
  // The grain at the drum's wall on +x, overlapping by delta, moving with the wall's surface.
  const Vec<3> x(Rc - R + delta, 0.0, 0.0);
  const Vec<3> vwall = drum.surface_velocity(x, R, 0.0);
  for (const double spin : {Omega, 0.0}) {
    std::uint8_t touch = 1;
    Vec<3> xi = Vec<3>::Zero(), f = Vec<3>::Zero();
    Spin<3> tq = Spin<3>::Zero();
    bool began = false;
    const Spin<3> w(0.0, 0.0, spin);
    const soft::WallContact<3> wc = soft::wall_contact<3, NormalLaw::Hertz, true, true>(
        drum, 0.0, 1e-6, true, x, R, vwall, Vec<3>::Zero(), w, Spin<3>::Zero(), c, touch, xi, began, f, tq);
    ASSERT_NEAR(wc.delta, delta, 1e-15);
    const double Fn = wc.force.norm();  // frictionless: the normal force only
    std::printf("drum turning at %g rad/s, grain spin %g: rolling torque %.6g (M_m = %.6g)\n", Omega, spin, tq[2],
                mu_r * R * Fn);
    if (spin == Omega) EXPECT_NEAR(tq.norm(), 0.0, 1e-15);
    else EXPECT_NEAR(tq[2], mu_r * R * Fn, 1e-12 * mu_r * R * Fn);  // against the relative spin -Omega
  }
}

// The Epsd spring torque is a contact's history: it survives neighbour-list rebuilds (a skin so
// small that the lists are rebuilt almost every step gives the same run as one so large that they
// are built once), on a wall (the ball held on the incline) and in a pair whose owner in the half
// list changes (two balls pressed together, spinning, and sliding past each other across a cell
// boundary while in contact).
template <int D>
RunResult<D> held_on_incline(double skin) {
  const double mu_r = 0.2;
  System<D> s = ball_on_floor<D>(1.0, mu_r, "epsd", std::atan(0.9 * mu_r), Vec<D>::Zero(), 0.0);
  TdmSettings ts;
  ts.end_time = 0.3;
  ts.threads = 1;
  ts.skin = skin;
  return run_tdm<D>(s, ts, {});
}
RunResult<3> spinning_pair(double skin) {
  const double R = 0.5, gap = 1e-4;
  System<3> s = test::hertz_system<3>(Vec<3>::Zero(), Vec<3>::Constant(10.0), 0.7, 0.3);
  s.materials[0].rolling_friction = 0.3;
  s.materials[0].rolling = "epsd";
  s.materials[0].density = 1.0 / ball_volume<3>(R);
  // Cells 10/9 wide with the tiny skin: a boundary at y = 50/9 that both cross during the contact.
  const double yb = 50.0 / 9.0;
  test::add_grain<3>(s, Vec<3>(5.0 + R - 0.5 * gap, yb - 0.08, 5.0), Vec<3>(-0.05, 0.6, 0.0), R);
  test::add_grain<3>(s, Vec<3>(5.0 - R + 0.5 * gap, yb + 0.08, 5.0), Vec<3>(0.05, -0.6, 0.0), R);
  s.w = {Spin<3>(0.0, 0.0, 3.0), Spin<3>(1.0, 0.0, -2.0)};
  TdmSettings ts;
  ts.end_time = 0.3;
  ts.threads = 1;
  ts.skin = skin;
  return run_tdm<3>(s, ts, {});
}
TEST(RollingResistance, EpsdSpringTorqueSurvivesListRebuilds) {
  const RunResult<3> tiny = held_on_incline<3>(1e-7), big = held_on_incline<3>(0.5);
  ASSERT_EQ(tiny.status, "ok") << tiny.message;
  ASSERT_EQ(big.status, "ok") << big.message;
  EXPECT_GT(tiny.soft.rebuilds, 1000u);
  EXPECT_LE(big.soft.rebuilds, 2u);
  EXPECT_LT(test::relative_state_difference(tiny, big), 1e-12);
  const RunResult<3> ptiny = spinning_pair(1e-6), pbig = spinning_pair(4.0);
  ASSERT_EQ(ptiny.status, "ok") << ptiny.message;
  ASSERT_EQ(pbig.status, "ok") << pbig.message;
  EXPECT_EQ(ptiny.counts.pair, 1u);
  EXPECT_GT(ptiny.soft.rebuilds, 500u);
  EXPECT_LE(pbig.soft.rebuilds, 2u);
  EXPECT_GT(ptiny.x[0][1], 50.0 / 9.0);  // both crossed the cell boundary
  EXPECT_LT(ptiny.x[1][1], 50.0 / 9.0);
  std::printf("EPSD history through rebuilds: incline %.3g (%llu rebuilds), pair %.3g (%llu rebuilds)\n",
              test::relative_state_difference(tiny, big), static_cast<unsigned long long>(tiny.soft.rebuilds),
              test::relative_state_difference(ptiny, pbig), static_cast<unsigned long long>(ptiny.soft.rebuilds));
  EXPECT_LT(test::relative_state_difference(ptiny, pbig), 1e-12);
}

}  // namespace
}  // namespace matep

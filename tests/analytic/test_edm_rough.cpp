// Rough hard spheres through the event-driven engine (run_edm): single oblique wall impacts in
// the five Lun & Savage regimes against closed forms, Chung & Ooi (2011) tests 6-8, angular
// momentum about the contact point in every pair collision of a gas, energy that never rises, the
// event log's spins, the material mixing rule, and the smooth fast path left untouched.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "contact/rough.hpp"
#include "engine/edm.hpp"
#include "engine/rough_rules.hpp"
#include "tests/support/systems.hpp"

using namespace matep;
using matep::test::Recorder;

namespace {

constexpr double kTol = 1e-12;

template <int D>
Vec<D> axis(int k, double s = 1.0) {
  Vec<D> v = Vec<D>::Zero();
  v[k] = s;
  return v;
}

// The spin about the axis that a tangential velocity along x and a normal along y define: z in 3D,
// the disk's only component in 2D.
template <int D>
double spin_z(const Spin<D>& w) {
  if constexpr (D == 3) return w[2];
  else return w[0];
}

// One ball of radius R (density 1000) above a floor y = 0, flying at (vt, -vn): it hits the floor
// once, at t = h/vn. Periodic along the other axes, a high non-periodic box along y.
template <int D>
System<D> ball_on_floor(const Material& mat, double vt, double vn, double R = 0.05, double h = 0.1) {
  System<D> s;
  s.lower = Vec<D>::Constant(-1.0);
  s.upper = Vec<D>::Constant(1.0);
  s.lower[1] = -0.1;
  s.upper[1] = 5.0;
  s.periodic.fill(true);
  s.periodic[1] = false;
  Material m = mat;
  m.name = "ball";
  m.density = 1000.0;
  s.materials.push_back(m);
  s.walls.push_back(plane_wall<D>("floor", Vec<D>::Zero(), axis<D>(1), 0));
  s.x.push_back(axis<D>(1, R + h));
  s.v.push_back(vt * axis<D>(0) - vn * axis<D>(1));
  s.w.push_back(Spin<D>::Zero());
  s.radius.push_back(R);
  s.material.push_back(0);
  return s;
}

template <int D>
struct WallImpact {
  CollisionRecord<D> rec;
  RunResult<D> res;
};

template <int D>
WallImpact<D> impact(const Material& mat, double vt, double vn, double R = 0.05) {
  const double h = 0.1;
  EdmSettings set;
  set.end_time = 1.5 * h / vn;  // one impact, then up: v_y = e vn > 0 reaches y < 5 at 1.5 h/vn
  Recorder<D> rec;
  WallImpact<D> out;
  out.res = run_edm<D>(ball_on_floor<D>(mat, vt, vn, R, h), set, QueueKind::Calendar, {&rec});
  EXPECT_EQ(out.res.status, "ok");
  EXPECT_EQ(rec.records.size(), 1u);
  if (!rec.records.empty()) out.rec = rec.records.front();
  return out;
}

Material rough_material(double e, std::optional<double> mu, std::string law, std::optional<double> beta0) {
  Material m;
  m.restitution = Restitution::constant(e);
  m.friction = mu;
  m.tangential = std::move(law);
  m.tangential_restitution = beta0;
  return m;
}

// The five regimes on a floor (Lun & Savage 1987 via the seed report, docs/references.md §S.3.1).
// For a wall and no initial spin, J_t = -(1 + beta) m_t v_t with m_t = m q/(1 + q)
// (contact/rough.hpp), so
//   v_t' = v_t (1 - (1 + beta) q/(1 + q)),  omega_z' = -(1 + beta) v_t/((1 + q) R)
// (the spin of a ball whose contact point the friction holds back; omega_z < 0 rolls it along +x),
// and in gross sliding |J_t| = mu J_n = mu (1 + e) m v_n, so omega_z' = -mu (1 + e) v_n/(q R):
// -(5/2) mu (1 + e) v_n/R for spheres, -2 mu (1 + e) v_n/R for disks (the issue's closed form).
template <int D>
void check_wall_regimes() {
  const double e = 0.8, R = 0.05, vn = 1.0, vt = 3.0, q = D == 3 ? 0.4 : 0.5;
  auto tangential_after = [&](double beta) { return vt * (1.0 - (1.0 + beta) * q / (1.0 + q)); };
  auto spin_after = [&](double beta) { return -(1.0 + beta) * vt / ((1.0 + q) * R); };
  auto common = [&](const WallImpact<D>& w, const char* what) {
    ASSERT_EQ(w.res.v.size(), 1u) << what;
    ASSERT_EQ(w.res.w.size(), 1u) << what;
    // Normal rebound v_n' = e v_n (the normal contact velocity is the centre's).
    EXPECT_NEAR(w.res.v[0][1], e * vn, kTol) << what;
    // The log carries the spins before (zero) and after (the final spin: no later event).
    EXPECT_EQ(spin_z<D>(w.rec.wi_before), 0.0) << what;
    EXPECT_EQ(w.rec.wi_after, w.res.w[0]) << what;
    EXPECT_EQ(w.rec.vi_after, w.res.v[0]) << what;
  };

  // Perfectly smooth, beta = -1: Walton's rule with mu = 0 (the rough path, since `tangential`
  // is set) leaves v_t and the spin alone.
  {
    const auto w = impact<D>(rough_material(e, 0.0, "walton", std::nullopt), vt, vn, R);
    common(w, "smooth");
    EXPECT_NEAR(w.res.v[0][0], vt, kTol);
    EXPECT_EQ(spin_z<D>(w.res.w[0]), 0.0);
  }
  // Sliding, -1 < beta < 0: mu = 0.1, x = (1 + 1/q) mu (1 + e) v_n/v_t < 1.
  {
    const double mu = 0.1;
    const auto w = impact<D>(rough_material(e, mu, "", std::nullopt), vt, vn, R);
    common(w, "sliding");
    const double beta = -1.0 + (1.0 + 1.0 / q) * mu * (1.0 + e) * vn / vt;  // Walton 1993
    ASSERT_TRUE(lun_savage_regime(beta) == RoughRegime::Sliding);
    EXPECT_NEAR(spin_z<D>(w.res.w[0]), -mu * (1.0 + e) * vn / (q * R), 1e-10);
    if constexpr (D == 3) {
      EXPECT_NEAR(w.res.w[0][2], -2.5 * mu * (1.0 + e) * vn / R, 1e-10);
    }
    EXPECT_NEAR(w.res.v[0][0], vt - mu * (1.0 + e) * vn, kTol);  // |J_t| = mu J_n
    EXPECT_NEAR(w.res.v[0][0], tangential_after(beta), kTol);
  }
  // Rolling, beta = 0: Walton at the sliding limit x = 1 (v_t chosen so), and constant beta = 0.
  // The contact point ends at rest: v_t' = v_t/(1 + q) (5/7 for spheres), omega' = -v_t'/R.
  for (const bool walton : {true, false}) {
    const double mu = 0.1;
    const double vt_roll = walton ? (1.0 + 1.0 / q) * mu * (1.0 + e) * vn : vt;
    const auto w = impact<D>(walton ? rough_material(e, mu, "walton", std::nullopt)
                                    : rough_material(e, std::nullopt, "constant", 0.0),
                             vt_roll, vn, R);
    common(w, "rolling");
    EXPECT_NEAR(w.res.v[0][0], vt_roll / (1.0 + q), kTol);
    EXPECT_NEAR(spin_z<D>(w.res.w[0]), -vt_roll / ((1.0 + q) * R), 1e-10);
    EXPECT_NEAR(w.res.v[0][0] + R * spin_z<D>(w.res.w[0]), 0.0, 1e-12);  // v_c = v + R omega_z (n = y)
  }
  // Sticking, 0 < beta = beta0 < 1: Walton with mu = 1 (x > 1 + beta0), beta0 = 0.4.
  {
    const double beta0 = 0.4;
    const auto w = impact<D>(rough_material(e, 1.0, "walton", beta0), vt, vn, R);
    common(w, "sticking");
    ASSERT_GT((1.0 + 1.0 / q) * 1.0 * (1.0 + e) * vn / vt, 1.0 + beta0);
    EXPECT_NEAR(w.res.v[0][0], tangential_after(beta0), kTol);
    EXPECT_NEAR(spin_z<D>(w.res.w[0]), spin_after(beta0), 1e-10);
    EXPECT_NEAR(w.res.v[0][0] + R * spin_z<D>(w.res.w[0]), -beta0 * vt, 1e-12);
  }
  // Perfectly rough, beta = +1, e = 1: the kinetic energy (translation + rotation) is kept.
  {
    const auto w = impact<D>(rough_material(1.0, std::nullopt, "constant", 1.0), vt, vn, R);
    EXPECT_NEAR(w.res.v[0][0], tangential_after(1.0), kTol);
    EXPECT_NEAR(spin_z<D>(w.res.w[0]), spin_after(1.0), 1e-10);
    const double m = 1000.0 * ball_volume<D>(R);
    const double K0 = 0.5 * m * (vt * vt + vn * vn);
    const double K1 = 0.5 * m * w.res.v[0].squaredNorm() + 0.5 * q * m * R * R * w.res.w[0].squaredNorm();
    EXPECT_NEAR(K1, K0, 1e-14 * K0);
  }
}

}  // namespace

TEST(EdmRough, WallImpactFiveRegimesSpheres) { check_wall_regimes<3>(); }
TEST(EdmRough, WallImpactFiveRegimesDisks) { check_wall_regimes<2>(); }

// The seed's FEM fit (eq. 3.30, docs/references.md §S.3.3.3, as read in contact/rough.hpp) at a
// steep impact, where it is below the Coulomb cap: (1 + beta)/(1 + e) = 0.12 a^2.98 + 0.92 with
// a = arctan(v_n/v_t).
TEST(EdmRough, WallImpactFemFit) {
  const double e = 0.8, R = 0.05, vn = 2.0, vt = 1.0, q = 0.4;
  const auto w = impact<3>(rough_material(e, 1.0, "fem_fit", std::nullopt), vt, vn, R);
  const double a = std::atan(vn / vt);
  const double beta = (1.0 + e) * (0.12 * std::pow(a, 2.98) + 0.92) - 1.0;
  ASSERT_LT(beta, 1.0);
  ASSERT_LT(1.0 + beta, (1.0 + 1.0 / q) * 1.0 * (1.0 + e) * vn / vt);  // not capped
  EXPECT_NEAR(w.res.v[0][0] + R * w.res.w[0][2], -beta * vt, 1e-12);
}

// A wall oscillating along its own plane: the rough rule acts on the velocity relative to the
// wall (Galilean shift), so a ball with the wall's tangential velocity and no spin is untouched
// tangentially; the record carries the wall's velocity as vj.
TEST(EdmRough, MovingWallActsOnRelativeVelocity) {
  const double e = 0.8, R = 0.05, vn = 1.0, h = 0.1;
  System<3> s = ball_on_floor<3>(rough_material(e, 0.5, "walton", 0.4), 0.0, vn, R, h);
  // Wall velocity u(t) = 2 pi f A cos(2 pi f t) along x; impact at t* = h/vn.
  const double f = 1.0 / (4.0 * h / vn) / 2.0;  // t* = 1/(8 f): u = 2 pi f A cos(pi/4)
  s.walls[0] = plane_wall<3>("floor", Vec<3>::Zero(), axis<3>(1), 0, Vec<3>(0.01, 0.0, 0.0), f);
  const double ux = 2.0 * std::numbers::pi * f * 0.01 * std::cos(2.0 * std::numbers::pi * f * h / vn);
  s.v[0][0] = ux;
  EdmSettings set;
  set.end_time = 1.5 * h / vn;
  Recorder<3> rec;
  const RunResult<3> res = run_edm<3>(s, set, QueueKind::Calendar, {&rec});
  ASSERT_EQ(res.status, "ok");
  ASSERT_EQ(rec.records.size(), 1u);
  EXPECT_NEAR(rec.records[0].vj_before[0], ux, 1e-12);
  EXPECT_NEAR(res.v[0][0], ux, 1e-12);
  EXPECT_NEAR(res.w[0].norm(), 0.0, 1e-9);
  EXPECT_NEAR(res.v[0][1], e * vn, 1e-12);
}

// ---------------------------------------------------------------------------------------------
// Chung & Ooi (2011) tests 6-8 (docs/references.md §1.4) through the engine: bodies with spin and
// no tangential velocity of the centres (R = 0.1 m, v_n = 0.2 m/s per body, mu = 0.4, e = 0.5,
// aluminium alloy density 2700), on a wall (tests 6/8) and head-on pairs with equal spins (test 7).
// The digitised beta follows the sliding line beta = -1 + x, x = (1 + 1/q) mu (1 + e) v_n/v_t
// (3.5 mu (1 + e) v_n/v_t for spheres) for x <= 1; Walton's rule with beta0 = 1 must give it
// within 1 %.
namespace {

template <int D>
void check_chung_ooi(bool pair) {
  const double R = 0.1, v = 0.2, mu = 0.4, e = 0.5, q = D == 3 ? 0.4 : 0.5;
  const double vn = pair ? 2.0 * v : v;  // normal contact speed
  for (double x_target : {0.187, 0.358, 0.551, 0.765, 0.979}) {
    const double ut = (1.0 + 1.0 / q) * mu * (1.0 + e) * vn / x_target;  // tangential contact speed
    const double w = ut / (pair ? 2.0 * R : R);
    System<D> s;
    s.lower = Vec<D>::Constant(-1.0);
    s.upper = Vec<D>::Constant(1.0);
    s.periodic.fill(false);
    Material m = rough_material(e, mu, "walton", 1.0);
    m.name = "al";
    m.density = 2700.0;
    s.materials.push_back(m);
    // Spin about x: with n = +y on the upper body, its contact point (-R n) moves along z (3D);
    // 2D disks spin about z.
    Spin<D> spin = Spin<D>::Zero();
    spin[0] = w;
    const double gap = 0.01;
    if (pair) {
      s.x = {axis<D>(1, R + 0.5 * gap), axis<D>(1, -R - 0.5 * gap)};
      s.v = {axis<D>(1, -v), axis<D>(1, v)};
      s.w = {spin, spin};
      s.radius = {R, R};
      s.material = {0, 0};
    } else {
      s.lower[1] = 0.0;
      s.walls.push_back(plane_wall<D>("floor", Vec<D>::Zero(), axis<D>(1)));
      s.x = {axis<D>(1, R + gap)};
      s.v = {axis<D>(1, -v)};
      s.w = {spin};
      s.radius = {R};
      s.material = {0};
    }
    EdmSettings set;
    set.end_time = (pair ? 0.5 * gap / v : gap / v) * 1.5;
    Recorder<D> rec;
    const RunResult<D> res = run_edm<D>(s, set, QueueKind::Calendar, {&rec});
    ASSERT_EQ(res.status, "ok");
    ASSERT_EQ(rec.records.size(), 1u);
    const CollisionRecord<D>& r = rec.records[0];
    const Vec<D> n = r.normal;
    auto contact = [&](const Vec<D>& vi, const Spin<D>& wi, const Vec<D>& vj, const Spin<D>& wj) {
      const Vec<D> c = pair ? contact_velocity<D>(vi, wi, R, vj, wj, R, n)
                            : Vec<D>(vi - spin_cross<D>(R * wi, n));
      return Vec<D>(c - c.dot(n) * n);
    };
    const Vec<D> u0 = contact(r.vi_before, r.wi_before, r.vj_before, r.wj_before);
    const Vec<D> u1 = contact(r.vi_after, r.wi_after, r.vj_after, r.wj_after);
    const double beta = -u1.dot(u0) / u0.squaredNorm();
    const double x = (1.0 + 1.0 / q) * mu * (1.0 + e) * vn / u0.norm();
    EXPECT_NEAR(x, x_target, 1e-9);
    EXPECT_NEAR(beta, -1.0 + x, 0.01 * std::abs(-1.0 + x)) << "x = " << x;
  }
}

}  // namespace

TEST(EdmRoughChungOoi, Tests6to8SphereOnWall) { check_chung_ooi<3>(false); }
TEST(EdmRoughChungOoi, Tests6to8TwoSpheres) { check_chung_ooi<3>(true); }
TEST(EdmRoughChungOoi, Tests6to8DiskOnWall) { check_chung_ooi<2>(false); }
TEST(EdmRoughChungOoi, Tests6to8TwoDisks) { check_chung_ooi<2>(true); }

// ---------------------------------------------------------------------------------------------
// A rough gas in a box with rough walls (polydisperse, so that unequal lever arms and masses are
// exercised): every pair collision conserves linear momentum and each body's angular momentum
// about the contact point, m (x - c) x v + I omega (the impulse acts at c; contact/rough.hpp);
// the kinetic energy, translation plus rotation, never rises from one record or sample to the next.
namespace {

template <int D>
System<D> rough_box_gas(int n_side, double phi, double e, const Material& rough, std::uint64_t seed) {
  System<D> s = test::lattice_gas<D>(n_side, phi, 1.0, e, seed);
  Material m = rough;
  m.name = s.materials[0].name;
  m.density = s.materials[0].density;
  m.restitution = Restitution::constant(e);
  s.materials[0] = m;
  // Radii 0.35 ... 0.5 (the lattice spacing keeps them apart), random initial spins.
  std::mt19937_64 rng(seed + 100);
  std::uniform_real_distribution<double> u(0.35, 0.5), w(-1.0, 1.0);
  for (std::size_t i = 0; i < s.size(); ++i) {
    s.radius[i] = u(rng);
    Spin<D> sp;
    for (int k = 0; k < sp.size(); ++k) sp[k] = w(rng);
    s.w.push_back(sp);
  }
  // Rough walls on the first axis.
  s.periodic[0] = false;
  Material wm;
  wm.name = "wall";
  wm.friction = 0.5;
  s.materials.push_back(wm);
  s.walls = {plane_wall<D>("lo", s.lower, axis<D>(0), 1), plane_wall<D>("hi", s.upper, axis<D>(0, -1.0), 1)};
  return s;
}

template <int D>
void check_gas_conservation(const Material& rough, double e, std::uint64_t seed) {
  const System<D> s = rough_box_gas<D>(D == 3 ? 6 : 14, 0.15, e, rough, seed);
  const double q = D == 3 ? 0.4 : 0.5;
  EdmSettings set;
  set.end_time = 30.0;
  set.thermo_interval = 1.0;
  Recorder<D> rec;
  const RunResult<D> res = run_edm<D>(s, set, QueueKind::Calendar, {&rec});
  ASSERT_EQ(res.status, "ok");
  std::size_t pairs = 0, walls = 0, sliding = 0;
  auto cross = [](const Vec<D>& a, const Vec<D>& b) -> Spin<D> { return lever_moment<D>(a, b); };
  for (const auto& r : rec.records) {
    const double Ri = s.radius[r.i], mi = r.mi, Ii = q * mi * Ri * Ri;
    const double scale_i = mi * Ri * (r.vi_before.norm() + Ri * r.wi_before.norm()) + 1e-300;
    // Body i about the contact point x_i - R_i n: L = m (R_i n) x v + I omega.
    const Spin<D> Li0 = mi * cross(Ri * r.normal, r.vi_before) + Ii * r.wi_before;
    const Spin<D> Li1 = mi * cross(Ri * r.normal, r.vi_after) + Ii * r.wi_after;
    EXPECT_LT((Li1 - Li0).norm(), 1e-12 * scale_i);
    double K0 = 0.5 * mi * r.vi_before.squaredNorm() + 0.5 * Ii * r.wi_before.squaredNorm();
    double K1 = 0.5 * mi * r.vi_after.squaredNorm() + 0.5 * Ii * r.wi_after.squaredNorm();
    if (r.kind == EventKind::PairCollision) {
      ++pairs;
      const double Rj = s.radius[r.j], mj = r.mj, Ij = q * mj * Rj * Rj;
      const Spin<D> Lj0 = mj * cross(-Rj * r.normal, r.vj_before) + Ij * r.wj_before;
      const Spin<D> Lj1 = mj * cross(-Rj * r.normal, r.vj_after) + Ij * r.wj_after;
      EXPECT_LT((Lj1 - Lj0).norm(), 1e-12 * (mj * Rj * (r.vj_before.norm() + Rj * r.wj_before.norm()) + 1e-300));
      const Vec<D> dp = mi * (r.vi_after - r.vi_before) + mj * (r.vj_after - r.vj_before);
      EXPECT_LT(dp.norm(), 1e-13 * (mi * r.vi_before.norm() + mj * r.vj_before.norm()));
      K0 += 0.5 * mj * r.vj_before.squaredNorm() + 0.5 * Ij * r.wj_before.squaredNorm();
      K1 += 0.5 * mj * r.vj_after.squaredNorm() + 0.5 * Ij * r.wj_after.squaredNorm();
      // Is this collision sliding (the tangential impulse mu J_n)?
      const double dvn = (r.vi_after - r.vi_before).dot(r.normal);
      const Vec<D> dvt = (r.vi_after - r.vi_before) - dvn * r.normal;
      if (rough.friction && std::abs(dvt.norm() - *rough.friction * dvn) < 1e-9 * dvn) ++sliding;
    } else {
      ++walls;
    }
    EXPECT_LE(K1, K0 * (1.0 + 1e-13));
  }
  EXPECT_GT(pairs, 1000u);
  EXPECT_GT(walls, 20u);
  if (rough.tangential != "constant") {
    EXPECT_GT(sliding, 100u);
  }
  // Thermo rows: kinetic + rotational energy never rises.
  ASSERT_GE(rec.samples.size(), 20u);
  for (std::size_t k = 1; k < rec.samples.size(); ++k) {
    const double E0 = rec.samples[k - 1].kinetic_energy + rec.samples[k - 1].rotational_energy;
    const double E1 = rec.samples[k].kinetic_energy + rec.samples[k].rotational_energy;
    EXPECT_LE(E1, E0 * (1.0 + 1e-13));
  }
  EXPECT_GT(rec.samples.back().rotational_energy, 0.0);
}

Material walton(double mu, double beta0) {
  Material m;
  m.friction = mu;
  m.tangential_restitution = beta0;
  return m;
}

}  // namespace

TEST(EdmRoughGas, ConservationWalton3D) { check_gas_conservation<3>(walton(0.3, 0.4), 0.9, 1); }
TEST(EdmRoughGas, ConservationWalton2D) { check_gas_conservation<2>(walton(0.3, 0.4), 0.9, 2); }
TEST(EdmRoughGas, ConservationFemFit3D) {
  Material m = walton(0.3, 0.4);
  m.tangential = "fem_fit";
  check_gas_conservation<3>(m, 0.8, 3);
}

// Elastic, perfectly rough spheres (e = 1, beta = 1) conserve translational plus rotational
// energy exactly (contact/rough.hpp: loss (1 - e^2) m* v_n^2/2 + (1 - beta^2) m_t v_t^2/2 = 0),
// and their rotational temperature moves towards equipartition.
TEST(EdmRoughGas, PerfectlyRoughElasticGasConservesEnergy) {
  System<3> s = test::lattice_gas<3>(6, 0.2, 1.0, 1.0, 9);
  s.materials[0].tangential = "constant";
  s.materials[0].tangential_restitution = 1.0;
  EdmSettings set;
  set.end_time = 5.0;
  set.thermo_interval = 0.5;
  Recorder<3> rec;
  rec.collisions = false;
  const RunResult<3> res = run_edm<3>(s, set, QueueKind::Calendar, {&rec});
  ASSERT_EQ(res.status, "ok");
  const double E0 = rec.samples.front().kinetic_energy + rec.samples.front().rotational_energy;
  for (const auto& x : rec.samples) EXPECT_NEAR(x.kinetic_energy + x.rotational_energy, E0, 1e-11 * E0);
  EXPECT_GT(rec.samples.back().rotational_energy, 0.2 * E0);
}

// The material mixing rule (the soft-sphere engine's, engine/soft_plan.cpp): mean friction and
// mean beta0, a value set on one side used alone; smooth where neither side has friction or a
// rule; two different laws are refused with a message naming the key.
TEST(EdmRough, MixingRule) {
  Material a, b, c;
  a.name = "a";
  b.name = "b";
  c.name = "c";
  a.friction = 0.2;
  b.friction = 0.4;
  b.tangential_restitution = 0.2;
  EXPECT_FALSE(rough_rule(c, c).has_value());
  const auto ab = rough_rule(a, b);
  ASSERT_TRUE(ab.has_value());
  EXPECT_TRUE(ab->law == TangentialLaw::Walton);
  EXPECT_NEAR(ab->friction, 0.3, 1e-15);
  EXPECT_EQ(ab->beta0, 0.2);
  const auto ac = rough_rule(a, c);
  ASSERT_TRUE(ac.has_value());
  EXPECT_EQ(ac->friction, 0.2);
  EXPECT_EQ(ac->beta0, kDefaultRoughBeta0);
  c.tangential = "constant";
  c.tangential_restitution = 0.6;
  const auto cc = rough_rule(c, c);
  ASSERT_TRUE(cc.has_value());
  EXPECT_TRUE(cc->law == TangentialLaw::Constant);
  a.tangential = "fem_fit";
  try {
    (void)rough_rule(a, c);
    ADD_FAILURE() << "expected an error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("material.a.tangential"), std::string::npos) << e.what();
  }
}

// A smooth scene keeps its fast path: no spins appear, and a scene that carries spins keeps them
// unchanged (the rough operator is never called).
TEST(EdmRough, SmoothSceneCarriesNoRotation) {
  const System<3> s = test::lattice_gas<3>(5, 0.2, 1.0, 0.9, 4);
  EdmSettings set;
  set.end_time = 1.0;
  Recorder<3> rec;
  const RunResult<3> res = run_edm<3>(s, set, QueueKind::Calendar, {&rec});
  ASSERT_EQ(res.status, "ok");
  EXPECT_TRUE(res.w.empty());
  ASSERT_GT(rec.records.size(), 100u);
  for (const auto& r : rec.records) {
    EXPECT_EQ(r.wi_before, Spin<3>::Zero());
    EXPECT_EQ(r.wi_after, Spin<3>::Zero());
  }
}

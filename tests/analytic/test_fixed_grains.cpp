// Fixed grains (System::fixed, scene key [particles.NAME] fixed = true) in the three engines, against
// closed forms: a grain dropped head-on onto a fixed grain bounces as off a floor (impact times and
// speeds of the bouncing ball, docs/references.md §3.2), an oblique impact reflects the normal
// velocity component about the contact normal, a grain resting on a fixed grain under gravity has
// the static Hertz overlap of its weight with R* = R1 R2/(R1 + R2), and a fixed grain's position is
// bit-identical at the end of every run. The scene key, its refusals, `matep check` and
// `matep log verify` of a rough bed on a fixed base are tested through the command line.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <numbers>
#include <random>
#include <fstream>
#include <iomanip>
#include <limits>
#include <sstream>
#include <string>

#include "contact/fixed.hpp"
#include "engine/edm.hpp"
#include "engine/hybrid.hpp"
#include "engine/tdm.hpp"
#include "io/log_tools.hpp"
#include "io/output.hpp"
#include "io/scene.hpp"
#include "tests/support/cli.hpp"
#include "tests/support/event_log.hpp"
#include "tests/support/impact_reference.hpp"
#include "tests/support/systems.hpp"

using namespace matep;
using matep::test::Recorder;

namespace {

constexpr double kG = 9.81;

// Records a measured value in the test report (--gtest_output=xml), for the reader.
void note(const std::string& key, double value) {
  std::ostringstream s;
  s << std::setprecision(7) << value;
  ::testing::Test::RecordProperty(key, s.str());
}

// A fixed grain of radius Rf at the origin (particle 0) and a grain of radius R (particle 1) at
// horizontal offset b (along x) with its centre at height y0, at rest; gravity -g along y. Periodic
// along the other axes (half width `half`), y in [ylo, yhi]; no walls.
template <int D>
System<D> drop_on_fixed(double Rf, double R, double b, double y0, const Material& m, bool gravity = true,
                        double half = 1.0, double ylo = -1.0, double yhi = 3.0) {
  System<D> s;
  s.lower = Vec<D>::Constant(-half);
  s.upper = Vec<D>::Constant(half);
  s.lower[1] = ylo;
  s.upper[1] = yhi;
  s.periodic.fill(true);
  s.periodic[1] = false;
  if (gravity) s.gravity[1] = -kG;
  s.materials.push_back(m);
  Vec<D> x1 = Vec<D>::Zero();
  x1[0] = b;
  x1[1] = y0;
  s.x = {Vec<D>::Zero(), x1};
  s.v = {Vec<D>::Zero(), Vec<D>::Zero()};
  s.radius = {Rf, R};
  s.material = {0, 0};
  s.fixed = {1, 0};
  return s;
}

Material hard_material(double e) {
  Material m;
  m.name = "glass";
  m.density = 2500.0;
  m.restitution = Restitution::constant(e);
  return m;
}

Material hertz_material(double e, double E = 1e7, double nu = 0.3) {
  Material m = hard_material(e);
  m.contact = "hertz";
  m.young = E;
  m.poisson = nu;
  return m;
}

template <int D>
void expect_fixed_unmoved(const System<D>& sys, const RunResult<D>& res) {
  for (std::size_t i = 0; i < sys.size(); ++i) {
    if (!sys.is_fixed(i)) continue;
    for (int k = 0; k < D; ++k) {
      EXPECT_EQ(res.x[i][k], sys.x[i][k]) << "fixed grain " << i << " moved along axis " << k;
      EXPECT_EQ(res.v[i][k], 0.0) << "fixed grain " << i;
    }
    if (!res.w.empty()) {
      EXPECT_TRUE(res.w[i].isZero(0.0)) << "fixed grain " << i << " spins";
    }
  }
}

// ---- EDM ----------------------------------------------------------------------------------------

// Dropped from a gap h above the fixed grain's top, the grain bounces as a ball on a floor: the
// k-th impact at t_k = t1 (1 + 2 sum_{j=1}^{k-1} e^j), t1 = sqrt(2h/g), at speed e^(k-1) sqrt(2gh)
// (docs/references.md §3.2), and its first rebound reaches the gap e^2 h at t1 (1 + e).
template <int D>
void check_edm_head_on_bounce() {
  const double Rf = 0.1, R = 0.05, h = 1.0, e = 0.8;
  const System<D> sys = drop_on_fixed<D>(Rf, R, 0.0, Rf + R + h, hard_material(e));
  EdmSettings set;
  set.end_time = 3.9;  // 11 impacts, before the Zeno time t1 (1 + e)/(1 - e) = 4.06 s
  Recorder<D> rec;
  const RunResult<D> res = run_edm<D>(sys, set, QueueKind::Calendar, {&rec});
  ASSERT_EQ(res.status, "ok") << res.message;
  ASSERT_GE(rec.records.size(), 10u);
  const double t1 = std::sqrt(2.0 * h / kG);
  double sum = 0.0, ej = 1.0;
  for (int k = 1; k <= 10; ++k) {
    const auto& r = rec.records[k - 1];
    EXPECT_EQ(r.kind, EventKind::PairCollision);
    EXPECT_EQ(r.i, 1u);
    EXPECT_EQ(r.j, 0u);
    EXPECT_EQ(r.mj, std::numeric_limits<double>::infinity());
    EXPECT_TRUE(r.vj_before.isZero(0.0) && r.vj_after.isZero(0.0));
    const double tk = t1 * (1.0 + 2.0 * sum);
    EXPECT_NEAR(r.time, tk, 1e-10 * tk) << "impact " << k;
    const double speed = std::pow(e, k - 1) * std::sqrt(2.0 * kG * h);
    EXPECT_NEAR(-r.vi_before[1], speed, 1e-9) << "impact " << k;
    EXPECT_NEAR(r.vi_after[1], e * speed, 1e-9) << "impact " << k;
    ej *= e;
    sum += ej;
  }
  EXPECT_EQ(res.counts.pair, rec.records.size());
  expect_fixed_unmoved(sys, res);
  // The apex of the first rebound.
  set.end_time = t1 * (1.0 + e);
  const RunResult<D> apex = run_edm<D>(sys, set, QueueKind::Heap);
  ASSERT_EQ(apex.status, "ok");
  EXPECT_NEAR(apex.x[1][1], Rf + R + e * e * h, 1e-12);
  EXPECT_NEAR(apex.v[1][1], 0.0, 1e-12);
  expect_fixed_unmoved(sys, apex);
}

TEST(FixedGrains, EdmHeadOnBounce2D) { check_edm_head_on_bounce<2>(); }
TEST(FixedGrains, EdmHeadOnBounce3D) { check_edm_head_on_bounce<3>(); }

// Falling straight down at horizontal offset b < sigma = Rf + R, the grain touches the fixed one at
// height y_c = sqrt(sigma^2 - b^2), at t = sqrt(2 (y0 - y_c)/g) with v = (0, -g t); the normal is
// n = (b, y_c)/sigma and the outcome v' = v - (1 + e)(v.n) n: the normal component reversed and
// scaled by e, the tangential one kept (a fixed grain is a wall at rest with the pair's normal).
template <int D>
void check_edm_oblique_under_gravity() {
  const double Rf = 0.1, R = 0.05, b = 0.08, y0 = 1.0, e = 0.7;
  const System<D> sys = drop_on_fixed<D>(Rf, R, b, y0, hard_material(e));
  const double sigma = Rf + R;
  const double yc = std::sqrt(sigma * sigma - b * b);
  const double tc = std::sqrt(2.0 * (y0 - yc) / kG);
  Vec<D> v = Vec<D>::Zero(), n = Vec<D>::Zero();
  v[1] = -kG * tc;
  n[0] = b / sigma;
  n[1] = yc / sigma;
  const Vec<D> v_after = v - (1.0 + e) * v.dot(n) * n;
  EdmSettings set;
  set.end_time = tc * 1.01;
  Recorder<D> rec;
  const RunResult<D> res = run_edm<D>(sys, set, QueueKind::Calendar, {&rec});
  ASSERT_EQ(res.status, "ok") << res.message;
  ASSERT_EQ(rec.records.size(), 1u);
  const auto& r = rec.records[0];
  EXPECT_NEAR(r.time, tc, 1e-12 * tc);
  EXPECT_LT((r.normal - n).norm(), 1e-10);
  EXPECT_LT((r.vi_before - v).norm(), 1e-10 * v.norm());
  EXPECT_LT((r.vi_after - v_after).norm(), 1e-10 * v.norm());
  // Normal part -e times, tangential part unchanged.
  EXPECT_NEAR(r.vi_after.dot(n), -e * v.dot(n), 1e-10 * v.norm());
  EXPECT_LT(((r.vi_after - r.vi_after.dot(n) * n) - (v - v.dot(n) * n)).norm(), 1e-10 * v.norm());
  expect_fixed_unmoved(sys, res);
}

TEST(FixedGrains, EdmObliqueImpactUnderGravity2D) { check_edm_oblique_under_gravity<2>(); }
TEST(FixedGrains, EdmObliqueImpactUnderGravity3D) { check_edm_oblique_under_gravity<3>(); }

// Without gravity a grain flying at speed u along x with impact parameter b touches the fixed one
// at x_c = -sqrt(sigma^2 - b^2) and, elastic, leaves reflected about the contact normal with its
// speed kept: v' = v - 2 (v.n) n.
TEST(FixedGrains, EdmObliqueElasticReflection3D) {
  const double Rf = 0.1, R = 0.05, b = 0.1, u = 2.0;
  System<3> sys = drop_on_fixed<3>(Rf, R, 0.0, 0.0, hard_material(1.0), /*gravity=*/false);
  sys.x[1] = Vec<3>(-0.8, b, 0.0);
  sys.v[1] = Vec<3>(u, 0.0, 0.0);
  const double sigma = Rf + R, xc = -std::sqrt(sigma * sigma - b * b);
  const double tc = (xc - (-0.8)) / u;
  const Vec<3> n = Vec<3>(xc, b, 0.0) / sigma;
  const Vec<3> v = sys.v[1], v_after = v - 2.0 * v.dot(n) * n;
  EdmSettings set;
  set.end_time = 1.0;
  Recorder<3> rec;
  const RunResult<3> res = run_edm<3>(sys, set, QueueKind::Calendar, {&rec});
  ASSERT_EQ(res.status, "ok") << res.message;
  ASSERT_EQ(rec.records.size(), 1u);
  EXPECT_NEAR(rec.records[0].time, tc, 1e-13);
  EXPECT_LT((rec.records[0].vi_after - v_after).norm(), 1e-13 * u);
  EXPECT_NEAR(res.v[1].norm(), u, 1e-13 * u);
  expect_fixed_unmoved(sys, res);
}

// Two grains fly at the same fixed grain from both sides (no gravity), touching it at
// t_A = (d_A - sigma)/u and t_B = (d_B - sigma)/u. The first collision leaves the fixed grain's
// course, and so B's prediction, valid: no stale event. Thermo counts the moving grains only:
// T = (1/2) sum m v^2 / (d/2) over the two movers (kinetic energy m u^2 before and after, e = 1).
TEST(FixedGrains, EdmCollisionWithAFixedGrainLeavesOtherPredictionsValid) {
  const double Rf = 0.1, R = 0.05, u = 1.0;
  System<3> sys = drop_on_fixed<3>(Rf, R, 0.0, 0.0, hard_material(1.0), /*gravity=*/false);
  sys.x = {Vec<3>::Zero(), Vec<3>(-0.4, 0.0, 0.0), Vec<3>(0.0, 0.0, 0.7)};
  sys.v = {Vec<3>::Zero(), Vec<3>(u, 0.0, 0.0), Vec<3>(0.0, 0.0, -u)};
  sys.radius = {Rf, R, R};
  sys.material = {0, 0, 0};
  sys.fixed = {1, 0, 0};
  const double sigma = Rf + R;
  EdmSettings set;
  set.end_time = 0.6;
  set.thermo_interval = 0.1;
  Recorder<3> rec;
  const RunResult<3> res = run_edm<3>(sys, set, QueueKind::Calendar, {&rec});
  ASSERT_EQ(res.status, "ok") << res.message;
  ASSERT_EQ(rec.records.size(), 2u);
  EXPECT_NEAR(rec.records[0].time, (0.4 - sigma) / u, 1e-14);
  EXPECT_NEAR(rec.records[1].time, (0.7 - sigma) / u, 1e-14);
  EXPECT_EQ(res.counts.stale, 0u);
  const double m = sys.mass(1);
  for (const auto& s : rec.samples) {
    EXPECT_NEAR(s.kinetic_energy, m * u * u, 1e-12 * m * u * u);
    EXPECT_NEAR(s.temperature, 2.0 * m * u * u / (3.0 * 2.0), 1e-12 * m * u * u);
  }
  expect_fixed_unmoved(sys, res);
}

// A fixed grain next to a periodic face is met through its image: fixed at x = 0.95 in [-1, 1), a
// grain at x = -0.5 flying towards -x touches the image at -1.05 when its centre reaches
// -1.05 + sigma, at t = (-0.5 - (-1.05 + sigma))/u.
TEST(FixedGrains, EdmMeetsAFixedGrainThroughAPeriodicFace) {
  const double Rf = 0.1, R = 0.05, u = 2.0;
  System<3> sys = drop_on_fixed<3>(Rf, R, 0.0, 0.0, hard_material(0.5), /*gravity=*/false);
  sys.x = {Vec<3>(0.95, 0.0, 0.0), Vec<3>(-0.5, 0.0, 0.0)};
  sys.v = {Vec<3>::Zero(), Vec<3>(-u, 0.0, 0.0)};
  const double sigma = Rf + R;
  EdmSettings set;
  set.end_time = 0.5;
  Recorder<3> rec;
  const RunResult<3> res = run_edm<3>(sys, set, QueueKind::Heap, {&rec});
  ASSERT_EQ(res.status, "ok") << res.message;
  ASSERT_EQ(rec.records.size(), 1u);
  EXPECT_NEAR(rec.records[0].time, (-0.5 - (-1.05 + sigma)) / u, 1e-14);
  EXPECT_LT((rec.records[0].normal - Vec<3>(1.0, 0.0, 0.0)).norm(), 1e-14);
  EXPECT_NEAR(res.v[1][0], 0.5 * u, 1e-14);  // reflected with e = 0.5
  expect_fixed_unmoved(sys, res);
}

// The impact-time search of contact/fixed.hpp against the closed form of a vertical fall at offset
// b (as above) and a rebound: a grain leaving the contact upward comes back after 2 v_up/g.
TEST(FixedGrains, ImpactTimeUnderGravityClosedForm) {
  const Vec<3> g(0.0, -kG, 0.0);
  const double sigma = 0.15, b = 0.08, y0 = 1.0;
  const double yc = std::sqrt(sigma * sigma - b * b);
  const double t = fixed_sphere_impact_time(Vec<3>(b, y0, 0.0), Vec<3>::Zero().eval(), g, sigma);
  EXPECT_NEAR(t, std::sqrt(2.0 * (y0 - yc) / kG), 1e-14);
  // Head-on from rest: the contact at sqrt(2 (y0 - sigma)/g) (the fall continues to the far side,
  // |p| = sigma again below the centre, a root the search must not take).
  for (const double y : {y0, 0.2, 5.0})
    EXPECT_NEAR(fixed_sphere_impact_time(Vec<3>(0.0, y, 0.0), Vec<3>::Zero().eval(), g, sigma),
                std::sqrt(2.0 * (y - sigma) / kG), 1e-14 * std::sqrt(y))
        << y;
  // On top (touching), moving up at 1 m/s: the next contact after 2 v/g.
  const double t2 = fixed_sphere_impact_time(Vec<3>(0.0, sigma, 0.0), Vec<3>(0.0, 1.0, 0.0), g, sigma);
  EXPECT_NEAR(t2, 2.0 / kG, 1e-12);
  // Thrown sideways from the top fast enough to clear the sphere: the parabola y = sigma - g x^2/(2 v^2)
  // stays outside |p| = sigma when v^2 >= g sigma; it never meets it again.
  const double v_clear = std::sqrt(kG * sigma) * 1.01;
  EXPECT_EQ(fixed_sphere_impact_time(Vec<3>(0.0, sigma, 0.0), Vec<3>(v_clear, 0.0, 0.0), g, sigma), kNever);
  // Approaching while touching: now.
  EXPECT_EQ(fixed_sphere_impact_time(Vec<3>(0.0, sigma, 0.0), Vec<3>(0.0, -1.0, 0.0), g, sigma), 0.0);
  // A limit before the impact: no event.
  EXPECT_EQ(fixed_sphere_impact_time(Vec<3>(b, y0, 0.0), Vec<3>::Zero().eval(), g, sigma, 0.1), kNever);
}

// The same search against the extended-precision reference scan (tests/support/impact_reference.hpp)
// over random flights near a fixed sphere under gravity: starts outside the contact distance, any
// direction and speed, grazing passes included.
TEST(FixedGrains, ImpactTimeUnderGravityMatchesTheReferenceScan) {
  std::mt19937_64 rng(2026);
  std::uniform_real_distribution<double> unit(-1.0, 1.0), gap(0.001, 1.0), speed(0.0, 3.0);
  const double sigma = 0.3;
  const Vec<3> g(0.0, 0.0, -kG);
  int events = 0;
  for (int c = 0; c < 600; ++c) {
    Vec<3> dir(unit(rng), unit(rng), unit(rng)), vdir(unit(rng), unit(rng), unit(rng));
    if (c % 5 == 0) {  // vertical flights above or below the sphere, head-on
      dir = Vec<3>(0.0, 0.0, dir[2]);
      vdir = Vec<3>(0.0, 0.0, vdir[2]);
    }
    if (dir.norm() < 1e-3 || vdir.norm() < 1e-3) continue;
    const Vec<3> r = dir.normalized() * (sigma + gap(rng));
    const Vec<3> v = (0.8 * vdir.normalized() - dir.normalized()) * speed(rng);  // mostly towards it
    const double t_max = 2.0;
    const double t = fixed_sphere_impact_time(r, v, g, sigma, t_max);
    auto f = [&](long double s) {
      long double p2 = 0;
      for (int k = 0; k < 3; ++k) {
        const long double p = r[k] + s * (v[k] + 0.5L * s * g[k]);
        p2 += p * p;
      }
      return std::sqrt(p2) - sigma;
    };
    const long double ref = test::earliest_closing_root(f, t_max, 4000);
    if (std::isinf(static_cast<double>(ref))) {
      EXPECT_EQ(t, kNever) << "case " << c;
    } else {
      ++events;
      // The same time, or (a grazing contact, whose root is ill-conditioned) a time at which the
      // gap is closed to round-off: the position is right even where the time is not to 1e-12.
      const double at_t = static_cast<double>(f(t));
      const bool same = std::abs(t - static_cast<double>(ref)) <= 1e-12;
      const bool grazing = std::abs(at_t) <= 1e-14 && std::abs(t - static_cast<double>(ref)) <= 1e-6;
      EXPECT_TRUE(same || grazing) << "case " << c << ": t = " << t << ", reference " << static_cast<double>(ref)
                                   << ", gap at t " << at_t;
    }
  }
  EXPECT_GT(events, 100);
}

// ---- TDM ----------------------------------------------------------------------------------------

// Linear law with the force clipped at zero: restitution e exactly for m* = the moving grain's
// mass (contact/soft.hpp linear_clipped_damping_ratio), the contact lasting
// t_f = sqrt(m/k) linear_clipped_collision(zeta).time. A head-on impact at speed u without
// gravity leaves at e u.
template <int D>
void check_tdm_head_on(const char* method) {
  const double Rf = 0.1, R = 0.05, u = 1.0, e = 0.8, k = 1e5;
  Material m = test::linear_material("glass", 2500.0, k, e);
  System<D> sys = drop_on_fixed<D>(Rf, R, 0.0, Rf + R + 0.05, m, /*gravity=*/false);
  sys.v[1][1] = -u;
  const double mass = sys.mass(1);
  const double tf = std::sqrt(mass / k) * linear_clipped_collision(linear_clipped_damping_ratio(e)).time;
  TdmSettings set;
  set.end_time = 0.05 / u + 2.0 * tf;
  set.dt = tf / 200.0;
  RunResult<D> res;
  if (std::string(method) == "tdm") {
    res = run_tdm<D>(sys, set);
  } else {
    EdmSettings edm;
    edm.end_time = set.end_time;
    HybridSettings hs;
    hs.dt = set.dt;
    res = run_hybrid<D>(sys, edm, hs);
  }
  ASSERT_EQ(res.status, "ok") << res.message;
  note("rebound_over_e", res.v[1][1] / u / e);
  EXPECT_NEAR(res.v[1][1] / u, e, 2e-3) << method;
  EXPECT_NEAR(res.v[1][0], 0.0, 1e-12) << method;
  expect_fixed_unmoved(sys, res);
}

TEST(FixedGrains, TdmHeadOnRestitution2D) { check_tdm_head_on<2>("tdm"); }
TEST(FixedGrains, TdmHeadOnRestitution3D) { check_tdm_head_on<3>("tdm"); }
TEST(FixedGrains, HybridHeadOnRestitution3D) { check_tdm_head_on<3>("hybrid"); }

// Dropped from a gap h onto a fixed grain under gravity, the Hertz contact (damping exact for e)
// returns it at e sqrt(2gh): the apex of the rebound is e^2 h above the touching height (the soft
// model's tolerance: gravity acts during the contact and the overlap shifts the apex by about the
// peak overlap). Run to the apex t1 + t_c + e t1, where the height is insensitive to the time.
template <int D>
void check_soft_drop(const char* method) {
  const double Rf = 0.004, R = 0.002, h = 0.02, e = 0.7, E = 1e9;
  const Material m = hertz_material(e, E);
  const System<D> sys = drop_on_fixed<D>(Rf, R, 0.0, Rf + R + h, m, true, 0.02, -0.01, 0.04);
  const double mass = sys.mass(1), v = std::sqrt(2.0 * kG * h);
  const double Es = E / (2.0 * (1.0 - 0.09));
  const double Rs = Rf * R / (Rf + R);
  const double tc = 2.8682656992 * std::pow(mass * mass / (Rs * Es * Es * v), 0.2);  // Hertz, m* = m
  const double t1 = std::sqrt(2.0 * h / kG);
  RunResult<D> res;
  if (std::string(method) == "tdm") {
    TdmSettings set;
    set.end_time = t1 + tc + e * t1;
    set.dt = tc / 100.0;
    res = run_tdm<D>(sys, set);
  } else {
    EdmSettings edm;
    edm.end_time = t1 + e * t1;  // the first collision is hard (exact), the apex follows at once
    res = run_hybrid<D>(sys, edm, HybridSettings{});
  }
  ASSERT_EQ(res.status, "ok") << res.message;
  const double gap = res.x[1][1] - (Rf + R);
  const double tol = std::string(method) == "tdm" ? 0.01 : 1e-9;
  note("apex_over_e2h", gap / (e * e * h));
  EXPECT_NEAR(gap / (e * e * h), 1.0, tol) << method;
  expect_fixed_unmoved(sys, res);
}

TEST(FixedGrains, TdmDropBouncesToRestitutionHeight2D) { check_soft_drop<2>("tdm"); }
TEST(FixedGrains, TdmDropBouncesToRestitutionHeight3D) { check_soft_drop<3>("tdm"); }
TEST(FixedGrains, HybridDropBouncesToRestitutionHeight3D) { check_soft_drop<3>("hybrid"); }

// At rest on top of a fixed grain, the Hertz spring carries the moving grain's weight:
// (4/3) E* sqrt(R*) delta^(3/2) = m g, R* = R1 R2/(R1 + R2), E* = E/(2 (1 - nu^2)) for one
// material (contact/soft.hpp; docs/references.md §6.2). The grain starts touching and rings down.
template <int D>
void check_static_overlap(const char* method, bool friction) {
  const double Rf = 0.004, R = 0.002, e = 0.3, E = 1e7, nu = 0.3;
  Material m = hertz_material(e, E, nu);
  if (friction) m.friction = 0.5;
  const System<D> sys = drop_on_fixed<D>(Rf, R, 0.0, Rf + R, m, true, 0.02, -0.01, 0.02);
  const double mass = sys.mass(1);
  const double Es = E / (2.0 * (1.0 - nu * nu));
  const double Rs = Rf * R / (Rf + R);
  const double delta = std::pow(3.0 * mass * kG / (4.0 * Es * std::sqrt(Rs)), 2.0 / 3.0);
  RunResult<D> res;
  if (std::string(method) == "tdm") {
    TdmSettings set;
    set.end_time = 0.2;  // some 30 decay times of the ringing (2D, the heavier disk: the slowest)
    res = run_tdm<D>(sys, set);
  } else {
    EdmSettings edm;
    edm.end_time = 0.2;
    res = run_hybrid<D>(sys, edm, HybridSettings{});
    EXPECT_EQ(res.mode[0], 4) << "the fixed grain keeps its mode";
    EXPECT_EQ(res.mode[1], 1) << "the grain at rest on it is soft";
  }
  ASSERT_EQ(res.status, "ok") << res.message;
  const double measured = Rf + R - res.x[1][1];
  note("overlap_over_hertz", measured / delta);
  EXPECT_NEAR(measured / delta, 1.0, 1e-3) << method << ": delta " << measured << " expected " << delta;
  EXPECT_NEAR(res.x[1][0], 0.0, 1e-15);
  expect_fixed_unmoved(sys, res);
}

TEST(FixedGrains, TdmStaticHertzOverlap2D) { check_static_overlap<2>("tdm", false); }
TEST(FixedGrains, TdmStaticHertzOverlap3D) { check_static_overlap<3>("tdm", false); }
TEST(FixedGrains, TdmStaticHertzOverlapWithFriction3D) { check_static_overlap<3>("tdm", true); }
TEST(FixedGrains, HybridStaticHertzOverlap3D) { check_static_overlap<3>("hybrid", false); }

// Tangential springs work against a fixed grain as against any partner: a sphere hitting a fixed
// sphere nearly head-on (normal n = y, tangential velocity v_t along x, no spin) with the linear law,
// e = 1, k_t/k_n = q/(1 + q) (beta0 = 1, contact/soft.hpp linear_sticking_restitution) and a
// friction that never slides, leaves with its contact-point velocity reversed
// (docs/references.md §6.6). The contact point moves at v_c = v_x + R w_z (contact/soft.hpp
// conventions, n = y); the tangential impulse J = m (v_x' - v_t) spins the grain by
// R w_z' = R^2 J/I = (v_x' - v_t)/q, so v_c' = -v_t gives v_x' = v_t (1 - q)/(1 + q) = (3/7) v_t
// and R w_z' = -(10/7) v_t for solid spheres. The overlap is kept small against R (k = 1e9): the
// lever arm R - delta/2 differs from R by delta/2R.
TEST(FixedGrains, TdmStickingImpactReversesTheContactPointVelocity3D) {
  const double Rf = 0.1, R = 0.05, vn = 1.0, vt = 0.05, k = 1e9;
  Material m = test::linear_material("glass", 2500.0, k, 1.0);
  m.friction = 10.0;
  System<3> sys = drop_on_fixed<3>(Rf, R, 0.0, Rf + R + 1e-6, m, /*gravity=*/false);
  sys.v[1] = Vec<3>(vt, -vn, 0.0);
  const double mass = sys.mass(1), tc = std::numbers::pi * std::sqrt(mass / k);
  TdmSettings set;
  set.end_time = 1e-6 / vn + 2.0 * tc;
  set.dt = tc / 500.0;
  const RunResult<3> res = run_tdm<3>(sys, set);
  ASSERT_EQ(res.status, "ok") << res.message;
  const double q = 0.4;
  note("vy_over_vn", res.v[1][1] / vn);
  note("vx_over_3_7_vt", res.v[1][0] / ((1.0 - q) / (1.0 + q) * vt));
  EXPECT_NEAR(res.v[1][1] / vn, 1.0, 1e-3);
  EXPECT_NEAR(res.v[1][0] / vt, (1.0 - q) / (1.0 + q), 2e-3);
  EXPECT_NEAR(R * res.w[1][2] / vt, -10.0 / 7.0, 3e-3);
  const double vc = res.v[1][0] + R * res.w[1][2];
  EXPECT_NEAR(vc / vt, -1.0, 2e-3);
  expect_fixed_unmoved(sys, res);
}

// ---- scenes and the command line ----------------------------------------------------------------

const std::string kBedScene = R"(
[run]
dimension = 3
method = "edm"
end_time = 0.2
seed = 7
gravity = [0.0, 0.0, -9.81]
tc = 1e-5

[domain]
lower = [0.0, 0.0, 0.0]
upper = [0.02, 0.02, 0.04]
periodic = [true, true, false]

[material.glass]
density = 2500.0
restitution = 0.8
friction = 0.3
young = 1e7
poisson = 0.3

[wall.floor]
type = "plane"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
material = "glass"

[particles.base]
material = "glass"
radius = 0.001
count = 100
arrangement = "lattice"
region = { lower = [0.0, 0.0, 0.0], upper = [0.02, 0.02, 0.002] }
fixed = true

[particles.gas]
material = "glass"
radius = 0.001
count = 40
region = { lower = [0.0, 0.0, 0.005], upper = [0.02, 0.02, 0.04] }
velocity = [0.0, 0.0, -0.1]

[output]
dir = "out"
events = true
)";

std::filesystem::path write_scene(const std::string& name, const std::string& text) {
  const auto dir = test::fresh_dir(name);
  const auto path = dir / "scene.toml";
  std::ofstream(path) << text;
  return path;
}

TEST(FixedGrains, SceneRefusesMotionOfAFixedGroup) {
  for (const std::string key : {"velocity = [0.0, 0.0, -0.1]", "temperature = 1e-6"}) {
    std::string text = kBedScene;
    text.replace(text.find("fixed = true"), 12, "fixed = true\n" + key);
    try {
      load_scene_string(text, "bed.toml", ".");
      ADD_FAILURE() << "no error for " << key;
    } catch (const SceneError& e) {
      const std::string msg = e.what();
      const std::string k = key.substr(0, key.find(' '));
      EXPECT_NE(msg.find("bed.toml"), std::string::npos) << msg;
      EXPECT_NE(msg.find("particles.base." + k), std::string::npos) << msg;
      EXPECT_NE(msg.find("fixed = true"), std::string::npos) << msg;
      EXPECT_NE(msg.find("a fixed grain does not move"), std::string::npos) << msg;
      EXPECT_NE(msg.find(k == "velocity" ? "[0, 0, -0.1]" : "1e-06"), std::string::npos) << msg;
    }
  }
}

TEST(FixedGrains, SceneFlagsTheGroupAndDropsAFilesVelocities) {
  const Scene sc = load_scene_string(kBedScene, "bed.toml", ".");
  const auto& sys = std::get<System<3>>(sc.system);
  ASSERT_EQ(sys.fixed.size(), 140u);
  EXPECT_EQ(sys.fixed_count(), 100u);
  for (std::size_t i = 0; i < 100; ++i) EXPECT_TRUE(sys.is_fixed(i));
  for (std::size_t i = 100; i < 140; ++i) EXPECT_FALSE(sys.is_fixed(i));
  // Without the key nothing is fixed and no flags are kept.
  std::string plain = kBedScene;
  plain.replace(plain.find("fixed = true"), 12, "");
  EXPECT_TRUE(std::get<System<3>>(load_scene_string(plain, "bed.toml", ".").system).fixed.empty());
  // A file group: positions and radii from the file, velocities and spins zero.
  const auto path = write_scene("fixed_file", kBedScene);
  std::ofstream(path.parent_path() / "base.csv") << "x,y,z,vx,vy,vz,radius,wz\n0.005,0.005,0.001,1,2,3,0.001,4\n";
  std::string filed = kBedScene;
  const auto a = filed.find("radius = 0.001\ncount = 100");
  const auto z = filed.find("fixed = true");
  filed.replace(a, z - a, "file = \"base.csv\"\n");
  const Scene fs = load_scene_string(filed, "bed.toml", path.parent_path().string());
  const auto& fsys = std::get<System<3>>(fs.system);
  EXPECT_TRUE(fsys.is_fixed(0));
  EXPECT_TRUE(fsys.v[0].isZero(0.0));
  EXPECT_TRUE(fsys.w[0].isZero(0.0));
  EXPECT_EQ(fsys.x[0], Vec<3>(0.005, 0.005, 0.001));
}

// A rough gas falling on a fixed base: every collision of the event log (its header flags fixed
// grains; pair records with a fixed partner have mj = infinity) passes `matep log verify` against the scene, `matep check`
// reports the fixed grains, and the base has not moved in final_state.csv.
TEST(FixedGrains, CliCheckRunAndVerifyARoughBedOnAFixedBase) {
  const auto path = write_scene("fixed_bed", kBedScene);
  const auto out = path.parent_path() / "out";
  const test::CliResult chk = test::run_cli("check " + path.string());
  ASSERT_EQ(chk.code, 0) << chk.out;
  EXPECT_NE(chk.out.find("100 of 140 grains are fixed"), std::string::npos) << chk.out;
  const test::CliResult run = test::run_cli("run " + path.string() + " --quiet --out " + out.string());
  ASSERT_EQ(run.code, 0) << run.out;
  const std::string log = (out / "events.bin").string();
  const test::CliResult stats = test::run_cli("log stats " + log);
  ASSERT_EQ(stats.code, 0) << stats.out;
  EXPECT_NE(stats.out.find("version 4 (fixed grains)"), std::string::npos) << stats.out;
  const test::CliResult ver = test::run_cli("log verify " + log + " --scene " + path.string());
  EXPECT_EQ(ver.code, 0) << ver.out;
  // The first record with a fixed partner; a copy with a moving fixed partner (vj_after, bytes
  // 144.. of the record, README "events.bin"; checksums resealed) fails, and the log without the
  // header's fixed-grain flag, where an infinite mass is not allowed, is refused naming the field.
  std::uint64_t first = 0;
  EventLogHeader header;
  {
    EventLogReader reader(log);
    header = reader.header();
    EXPECT_EQ(header.version, kEventLogVersionIdentity);
    EXPECT_TRUE(header.fixed_grains());
    EventRecord r;
    bool found = false;
    for (std::uint64_t k = 0; !found && reader.next(r); ++k)
      if (r.mj == std::numeric_limits<double>::infinity()) {
        first = k;
        found = true;
        EXPECT_LT(r.j, 100u);
      }
    ASSERT_TRUE(found);
  }
  auto altered = [&](const std::string& name, std::uint64_t offset, const std::string& bytes) {
    const std::string copy = (path.parent_path() / name).string();
    std::filesystem::copy_file(log, copy, std::filesystem::copy_options::overwrite_existing);
    std::fstream f(copy, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(static_cast<std::streamoff>(offset));
    f.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    f.close();
    test::reseal_event_log(copy);
    return copy;
  };
  const double moved = 1e-3;
  std::string moved_bytes(8, '\0');
  std::memcpy(moved_bytes.data(), &moved, 8);
  const test::CliResult bad_v =
      test::run_cli("log verify " + altered("moving.bin", record_offset(header, first) + 144, moved_bytes));
  EXPECT_EQ(bad_v.code, 1) << bad_v.out;
  EXPECT_NE(bad_v.out.find("fixed partner"), std::string::npos) << bad_v.out;
  const std::uint32_t no_flags = 0;
  const test::CliResult bad_h =
      test::run_cli("log verify " + altered("noflag.bin", 20, std::string(reinterpret_cast<const char*>(&no_flags), 4)));
  EXPECT_EQ(bad_h.code, 2) << bad_h.out;
  EXPECT_NE(bad_h.out.find("corrupt event record " + std::to_string(first) + " at byte offset " +
                           std::to_string(record_offset(header, first)) + ": mj = inf"),
            std::string::npos)
      << bad_h.out;
  // The base's rows of final_state.csv: the lattice sites at rest.
  const Scene sc = load_scene_string(kBedScene, "bed.toml", ".");
  const auto& sys = std::get<System<3>>(sc.system);
  std::ifstream f(out / "final_state.csv");
  std::string line;
  std::getline(f, line);
  for (std::size_t i = 0; i < 100 && std::getline(f, line); ++i) {
    double id, x, y, z, vx, vy, vz;
    ASSERT_EQ(std::sscanf(line.c_str(), "%lf,%lf,%lf,%lf,%lf,%lf,%lf", &id, &x, &y, &z, &vx, &vy, &vz), 7) << line;
    EXPECT_EQ(Vec<3>(x, y, z), sys.x[i]) << line;
    EXPECT_EQ(Vec<3>(vx, vy, vz), Vec<3>::Zero().eval()) << line;
  }
  // The same scene in TDM and the hybrid (with the rest rule: grains settle on the base and sleep):
  // the base stays where it is.
  for (const std::string method : {"tdm", "hybrid"}) {
    const std::string o = (path.parent_path() / method).string();
    const std::string rest = method == "hybrid" ? " --set hybrid.rest_speed=0.005" : "";
    const test::CliResult r = test::run_cli("run " + path.string() + " --quiet --set run.method=" + method + rest +
                                            " --set output.events=false --set run.end_time=0.3 --out " + o);
    ASSERT_EQ(r.code, 0) << method << ": " << r.out;
    if (method == "hybrid") {  // the rest rule was at work next to the fixed grains
      const std::string summary = test::slurp(o + "/summary.json");
      const auto at = summary.find("\"slept\": ");
      ASSERT_NE(at, std::string::npos) << summary;
      EXPECT_GT(std::stoll(summary.substr(at + 9)), 0) << summary;
    }
    std::ifstream g(o + "/final_state.csv");
    std::getline(g, line);
    for (std::size_t i = 0; i < 100 && std::getline(g, line); ++i) {
      double id, x, y, z;
      ASSERT_EQ(std::sscanf(line.c_str(), "%lf,%lf,%lf,%lf", &id, &x, &y, &z), 4) << line;
      EXPECT_EQ(Vec<3>(x, y, z), sys.x[i]) << method << ": " << line;
    }
  }
}

}  // namespace

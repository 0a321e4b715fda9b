// The hybrid engine (engine/hybrid.hpp) against analytic answers and against pure EDM and TDM:
// the bouncing ball's rest time (Zeno), a settling bed, a dilute gas that stays hard, and the
// switches themselves (momentum to round-off, energy through both switches).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <tuple>

#include <fmt/format.h>

#include "engine/edm.hpp"
#include "engine/hybrid.hpp"
#include "engine/tdm.hpp"
#include "io/scene.hpp"
#include "tests/support/systems.hpp"

namespace matep {
namespace {

#ifdef MATEP_SANITIZED
constexpr bool kSanitized = true;  // instrumented build: smaller systems, same checks
#else
constexpr bool kSanitized = false;
#endif

constexpr double kG = 9.81;

// Records every thermo sample and every switch record.
template <int D>
struct Recorder final : Observer<D> {
  std::vector<ThermoSample> samples;
  std::vector<CollisionRecord<D>> switches;
  std::uint64_t collisions = 0;
  bool wants_collisions() const override { return true; }
  void on_collision(const CollisionRecord<D>& r) override {
    if (r.kind == EventKind::ToSoft || r.kind == EventKind::ToHard)
      switches.push_back(r);
    else
      ++collisions;
  }
  void on_sample(const ThermoSample& s) override { samples.push_back(s); }
};

// ---- bouncing ball -----------------------------------------------------------------------------

// A frictionless Hertz material with Poisson ratio 0.3.
Material hertz_material(const std::string& name, double density, double e, double young) {
  Material m;
  m.name = name;
  m.density = density;
  m.restitution = Restitution::constant(e);
  m.contact = "hertz";
  m.young = young;
  m.poisson = 0.3;
  return m;
}

// A steel ball (R = 5 cm) dropped from h = 1 m (its bottom) onto a floor, e = 0.8, Hertz contact.
System<3> ball_system(double e) {
  System<3> s;
  s.lower = Vec<3>(-0.5, -0.5, 0.0);
  s.upper = Vec<3>(0.5, 0.5, 2.0);
  s.periodic = {true, true, false};
  s.gravity = Vec<3>(0.0, 0.0, -kG);
  s.materials.push_back(hertz_material("steel", 7800.0, e, 2e11));
  s.walls.push_back(plane_wall<3>("floor", Vec<3>::Zero(), Vec<3>(0.0, 0.0, 1.0)));
  s.x.push_back(Vec<3>(0.0, 0.0, 1.05));
  s.v.push_back(Vec<3>::Zero());
  s.radius.push_back(0.05);
  s.material.push_back(0);
  return s;
}

// The last sample time at which the ball's bottom is more than eps above the floor: the height
// comes from the potential energy -m g.x of the samples.
double rest_time(const std::vector<ThermoSample>& samples, double m, double R, double eps) {
  double last = 0.0;
  for (const auto& s : samples)
    if (s.potential_energy / (m * kG) - R > eps) last = s.time;
  return last;
}

TEST(HybridBall, ComesToRestAtTheZenoTimeAndTdmAgrees) {
  const double h = 1.0, e = 0.8;
  const double zeno = std::sqrt(2.0 * h / kG) * (1.0 + e) / (1.0 - e);  // 4.0637 s
  const System<3> sys = ball_system(e);
  const double m = sys.mass(0), R = sys.radius[0];
  EdmSettings es;
  es.end_time = 4.5;
  es.thermo_interval = 2e-4;
  // Pure EDM: infinitely many bounces before the Zeno time; it stops with "collapse", there.
  {
    const RunResult<3> r = run_edm<3>(sys, es, QueueKind::Calendar);
    EXPECT_EQ(r.status, "collapse");
    EXPECT_NEAR(r.time, zeno, 1e-3 * zeno);
  }
  // Hybrid: hard bounces until they come within k t_c of each other, then the soft contact.
  Recorder<3> hy;
  const RunResult<3> rh = run_hybrid<3>(sys, es, HybridSettings{}, {&hy});
  ASSERT_EQ(rh.status, "ok") << rh.message;
  EXPECT_EQ(rh.hybrid.to_soft, 1u);
  EXPECT_EQ(rh.hybrid.by_stability, 1u);
  EXPECT_GT(rh.counts.wall, 20u);  // the early bounces stay hard
  // eps = 1 um: the remaining flight time is below 2 sqrt(2 eps/g)/(1 - e) = 4.5 ms (0.1 %).
  const double th = rest_time(hy.samples, m, R, 1e-6);
  EXPECT_NEAR(th, zeno, 0.01 * zeno);
  // Pure TDM at the same step.
  TdmSettings ts;
  ts.end_time = es.end_time;
  ts.thermo_interval = es.thermo_interval;
  Recorder<3> td;
  const RunResult<3> rt = run_tdm<3>(sys, ts, {&td});
  ASSERT_EQ(rt.status, "ok") << rt.message;
  const double tt = rest_time(td.samples, m, R, 1e-6);
  EXPECT_NEAR(tt, zeno, 0.01 * zeno);
  EXPECT_NEAR(th, tt, 0.01 * zeno);
  ::testing::Test::RecordProperty("rest_time_hybrid_tdm_zeno", fmt::format("{:.5f} {:.5f} {:.5f}", th, tt, zeno));
  ::testing::Test::RecordProperty("hard_bounces", fmt::format("{}", rh.counts.wall));
  // The ball ends at rest on the floor, overlapped by the static Hertz overlap (m g/K)^(2/3),
  // K = (4/3) E* sqrt(R) (rigid floor, E* = E/(1 - nu^2)).
  const double K = 4.0 / 3.0 * (2e11 / (1.0 - 0.09)) * std::sqrt(R);
  const double d_static = std::pow(m * kG / K, 2.0 / 3.0);
  // Still ringing on the Hertz spring (its damping vanishes with the overlap), within d_static.
  EXPECT_NEAR(rh.x[0][2], R - d_static, d_static);
  EXPECT_LT(rh.v[0].norm(), 1e-3);
}

// ---- the switches ----------------------------------------------------------------------------

// A periodic box [0, upper] with one material: unit spheres (unit mass for radius 0.5) of
// constant restitution e, linear law of the given stiffness, no grains yet.
System<3> periodic_unit_box(const Vec<3>& upper, double stiffness, double e = 1.0) {
  System<3> s;
  s.lower = Vec<3>(0.0, 0.0, 0.0);
  s.upper = upper;
  s.periodic = {true, true, true};
  Material m;
  m.name = "elastic";
  m.density = 1.0 / ball_volume<3>(0.5);
  m.restitution = Restitution::constant(e);
  m.contact = "linear";
  m.stiffness = stiffness;
  s.materials.push_back(m);
  return s;
}

// Spheres of radius 0.5 of the first material at x with velocities v.
void add_grains(System<3>& s, const std::vector<Vec<3>>& x, const std::vector<Vec<3>>& v) {
  for (std::size_t i = 0; i < x.size(); ++i) {
    s.x.push_back(x[i]);
    s.v.push_back(v[i]);
    s.radius.push_back(0.5);
    s.material.push_back(0);
  }
}

// The same grains in pure TDM on one thread to `end`, and the largest distance between a grain's
// final position there and in run r.
double worst_against_tdm(const System<3>& s, double end, const RunResult<3>& r, RunResult<3>* tdm = nullptr) {
  TdmSettings ts;
  ts.end_time = end;
  ts.threads = 1;
  const RunResult<3> rt = run_tdm<3>(s, ts);
  EXPECT_EQ(rt.status, "ok") << rt.message;
  double worst = 0.0;
  for (std::size_t i = 0; i < s.x.size(); ++i) worst = std::max(worst, (r.x[i] - rt.x[i]).norm());
  if (tdm) *tdm = rt;
  return worst;
}

// Three elastic spheres on a line, no gravity: A flies at B, B is pushed into C right away (C
// sits just beyond B), so B's second collision follows its first within k t_c: the cluster turns
// soft; once apart for the hysteresis it is released to EDM again.
// A row of four grains, each within the least capture distance (hybrid.skin, here 0.01 d) of the
// next: the first two start overlapping by 1e-6 d and push apart (elastic), the other two are
// captured. Once the contact
// has ended, no grain touches anything, but each has a soft neighbour within its skin, so the
// single-grain release never frees one; the group release (its collisions are rare: cheaper as
// events) returns all four to EDM together, and they fly on exactly as pure TDM's grains do.
TEST(HybridSwitch, AGroupOfGrainsWithinEachOthersSkinReturnsHardTogether) {
  System<3> s = periodic_unit_box(Vec<3>(40.0, 10.0, 10.0), 1e5);
  const std::vector<double> xs = {10.0, 11.0 - 1e-6, 12.004 - 1e-6, 13.008 - 1e-6};
  for (const double x : xs) {
    s.x.push_back(Vec<3>(x, 5.0, 5.0));
    s.v.push_back(Vec<3>(0.0, 0.01, 0.0));
    s.radius.push_back(0.5);
    s.material.push_back(0);
  }
  EdmSettings es;
  es.end_time = 2.0;
  es.thermo_interval = 0.5;
  HybridSettings hs;
  hs.hysteresis = 0.2;
  hs.skin = 0.01;
  const RunResult<3> r = run_hybrid<3>(s, es, hs);
  ASSERT_EQ(r.status, "ok") << r.message;
  EXPECT_EQ(r.hybrid.by_overlap, 2u);
  EXPECT_EQ(r.hybrid.by_capture, 2u);
  EXPECT_EQ(r.hybrid.released_by_cost, 4u);
  EXPECT_EQ(r.hybrid.to_hard, 4u);
  EXPECT_EQ(r.hybrid.soft_at_end, 0u);
  // The same row in pure TDM: the push apart is the same soft contact, then free flight.
  const double worst = worst_against_tdm(s, es.end_time, r);
  EXPECT_LT(worst, 1e-8);  // (a displacement of 1e-3: the two step sequences agree to 1e-6 of it)
  // The pushed pair separates at dx0 sqrt(k / m*) (the spring's energy k dx0^2 / 2 becomes
  // m* v^2 / 2; elastic, m* = m / 2): 4.47e-4, to the TDM error of dt = t_c / 50.
  const double vsep = 1e-6 * std::sqrt(1e5 / 0.5);
  EXPECT_NEAR((r.v[1] - r.v[0]).x(), vsep, 2e-3 * vsep);
  Vec<3> p = Vec<3>::Zero();
  for (int i = 0; i < 4; ++i) p += s.mass(i) * (r.v[i] - s.v[i]);
  EXPECT_LT(p.norm(), 1e-15);
  ::testing::Test::RecordProperty("worst_position_vs_tdm", fmt::format("{:.3g}", worst));
}

// Hard grains beside a periodic face, each a few capture distances from a soft pair's image on
// the other side and flying at it (one through the upper x face, one through the lower y face):
// the capture check (with four soft grains it looks at the soft set directly instead of walking
// the cells) finds the images across the faces and the grains join before they touch, so the
// contacts are soft and the run lands where pure TDM's does. Had a check missed an image, its
// grain would have passed into the pair without a force.
TEST(HybridCapture, HardGrainsMeetingSoftOnesAcrossPeriodicFacesJoinBeforeTheTouch) {
  System<3> s = periodic_unit_box(Vec<3>(5.0, 5.0, 5.0), 1e5);  // 4 cells an axis, not hashed
  // Each pair starts overlapping (soft); each grain's gap to the image of the pair's first grain
  // (at x = 5.6, and at y = -0.6) is 5e-4 d, five times the least capture distance (hybrid.skin,
  // 1e-4 d): each is captured in flight, a few substeps before it would touch.
  add_grains(s,
             {Vec<3>(0.6, 2.5, 1.0), Vec<3>(1.6 - 1e-6, 2.5, 1.0), Vec<3>(4.5995, 2.5, 1.0),
              Vec<3>(2.5, 4.4, 3.5), Vec<3>(2.5, 3.4 + 1e-6, 3.5), Vec<3>(2.5, 0.4005, 3.5)},
             {Vec<3>::Zero(), Vec<3>::Zero(), Vec<3>(0.1, 0.0, 0.0), Vec<3>::Zero(), Vec<3>::Zero(),
              Vec<3>(0.0, -0.1, 0.0)});
  EdmSettings es;
  es.end_time = 0.5;
  const RunResult<3> r = run_hybrid<3>(s, es, HybridSettings{});
  ASSERT_EQ(r.status, "ok") << r.message;
  EXPECT_EQ(r.hybrid.by_overlap, 4u);
  EXPECT_EQ(r.hybrid.by_capture, 2u);
  RunResult<3> rt;
  const double worst = worst_against_tdm(s, es.end_time, r, &rt);
  // (Missing an image, a grain would be 0.05 d from TDM's by the end; the soft contacts of the two
  // runs agree to the step's error, about 1e-7 d.)
  EXPECT_LT(worst, 1e-6);
  for (const int i : {2, 5}) {
    EXPECT_LT((r.v[i] - rt.v[i]).norm(), 1e-5) << i;
    EXPECT_LT(r.v[i].norm(), 0.02) << i;  // the grain passed most of its momentum on along the row
  }
}

// A hard grain overtaken slowly by a soft one in free flight. Three grains turn soft by the
// stability rule at once and stay soft to the end (as in HybridCoast below); after their contacts
// the front grain C flies on alone. A fourth grain D flies ahead of it, 0.01 slower along the row,
// its course set from C's in a first run of the three so that C would touch it at t = 2. The gap
// closes at 0.01 while the speeds that bound it (D's, and twice the soft set's fastest) are about
// 3: checked by that bound alone D would be looked at every substep for its last hundredths of a
// diameter (hundreds of substeps). In the soft set's free flight its check comes when the straight
// relative course (u = v_D - v_C(t - h/2) - g h / 2 at the grid points) brings it within reach:
// once, near t = 2. It joins before it touches (no join by overlap), C hands its speed on to it
// (equal masses, nearly elastic), and the run lands where the run without coasts (which checks by
// the bound at every substep) does, to round-off; without and with gravity (along the periodic y
// axis, where the leapfrog's course of a soft grain parts from a hard grain's parabola by
// g h s / 2).
TEST(HybridCapture, InTheSoftSetsFreeFlightAHardGrainIsCheckedWhenItsStraightCourseComesWithinReach) {
  for (const double g : {0.0, 0.5}) {
    SCOPED_TRACE(g);
    System<3> s = periodic_unit_box(Vec<3>(30.0, 10.0, 10.0), 1e5, 0.9999);
    s.gravity = Vec<3>(0.0, -g, 0.0);
    add_grains(s, {Vec<3>(2.999, 5.0, 5.0), Vec<3>(4.0, 5.05, 5.0), Vec<3>(5.0 + 1e-4, 5.1, 5.01)},
               {Vec<3>(1.0, 0.0, 0.0), Vec<3>::Zero(), Vec<3>(-0.1, 0.0, 0.0)});
    EdmSettings es;
    HybridSettings hs;
    hs.stability = 1e3;
    hs.repeats = 1;
    hs.speed_fall = 1.0;
    hs.hysteresis = 100.0;  // soft to the end
    // C's course after the cluster's contacts (over by t = 0.5).
    es.end_time = 0.5;
    const RunResult<3> pre = run_hybrid<3>(s, es, hs);
    ASSERT_EQ(pre.status, "ok") << pre.message;
    ASSERT_EQ(pre.hybrid.soft_at_end, 3u);
    const Vec<3> vc = pre.v[2], xc = pre.x[2];
    ASSERT_GT(vc.x(), 0.5);  // C carries the row's momentum on
    const double t_touch = 2.0;
    const Vec<3> vd = vc - Vec<3>(0.01, 0.0, 0.0);
    // D's centre 1 d ahead of C's along x at t_touch (the two fall alike under gravity).
    const Vec<3> xd = xc + vc * (t_touch - 0.5) + Vec<3>(1.0, 0.0, 0.0) - vd * t_touch -
                      0.5 * s.gravity * t_touch * t_touch + 0.5 * s.gravity * (t_touch - 0.5) * (t_touch - 0.5);
    add_grains(s, {xd}, {vd});
    es.end_time = 3.0;
    const RunResult<3> r = run_hybrid<3>(s, es, hs);
    hs.coast = false;
    const RunResult<3> step = run_hybrid<3>(s, es, hs);
    ASSERT_EQ(r.status, "ok") << r.message;
    ASSERT_EQ(step.status, "ok") << step.message;
    for (const RunResult<3>* q : {&r, &step}) {
      EXPECT_EQ(q->hybrid.by_overlap, 0u);
      EXPECT_EQ(q->hybrid.by_capture, 1u);
      EXPECT_EQ(q->hybrid.soft_at_end, 4u);
      // C handed its lead on to D (nearly elastic, equal masses, head on: they exchange their
      // speeds along the row).
      EXPECT_NEAR(q->v[3].x(), vc.x(), 1e-4);
      EXPECT_NEAR(q->v[2].x(), vd.x(), 1e-4);
    }
    double dx = 0.0, dv = 0.0;
    for (int i = 0; i < 4; ++i) {
      Vec<3> d = r.x[i] - step.x[i];
      for (int k = 0; k < 3; ++k) d[k] -= s.upper[k] * std::round(d[k] / s.upper[k]);
      dx = std::max(dx, d.norm());
      dv = std::max(dv, (r.v[i] - step.v[i]).norm());
    }
    EXPECT_LT(dx, 1e-9);
    EXPECT_LT(dv, 1e-9);
    // The substeps: coasts of at most 64 grid steps while D is an interface grain (t_touch /
    // (64 h) = 223 of them), the contacts' (about 50 each) and a few at each renewal of the soft
    // list (every 0.05 d that C flies): 753 and 880 (with gravity) when this was measured. Checked by the bound alone, D's approach
    // adds about 1 000: below 64 h times the bound (vb = 3: 0.027 d) each check finds the gap
    // 0.01 / 3 of itself smaller, down to the capture distance 2 h vb = 8e-4 d, ln(32) / (0.01 / 3)
    // checks (2 629 and 1 867 substeps in all, without and with gravity, when this was measured).
    const double h = r.soft.dt;
    EXPECT_LT(static_cast<double>(r.hybrid.substeps), t_touch / (64.0 * h) + 700.0) << r.hybrid.substeps;
    ::testing::Test::RecordProperty(g > 0.0 ? "substeps_gravity" : "substeps", std::to_string(r.hybrid.substeps));
  }
}

// The least capture distance (hybrid.skin unset) follows the scene: 1e-3 d where grains come to
// rest (gravity) or rapid sequences are strongly inelastic (a restitution that is, or can fall to,
// 0.25 or below), 1e-4 d elsewhere; an explicit skin is kept. A run reports it in metres. (At
// 1e-4 d under gravity a settling bed kept a grain moving, and at e = 0.2 four grains in a line
// ended 99 % off converged TDM; at 1e-3 d in a free gas at e = 0.5 the floor held clusters soft:
// README "Hybrid dynamics", the capture row.)
TEST(HybridCapture, TheLeastCaptureDistanceFollowsTheScene) {
  // Two grains of diameter 0.5 flying apart in a periodic box: nothing turns soft.
  const auto two_grains = [](double e) {
    System<3> s = periodic_unit_box(Vec<3>(6.0, 6.0, 6.0), 1e5, e);
    for (int k = 0; k < 2; ++k) {
      s.x.push_back(Vec<3>(2.0 + 2.0 * k, 3.0, 3.0));
      s.v.push_back(Vec<3>(k == 0 ? -0.1 : 0.1, 0.0, 0.0));
      s.radius.push_back(0.25);
      s.material.push_back(0);
    }
    return s;
  };
  EdmSettings es;
  es.end_time = 1.0;
  HybridSettings hs;
  EXPECT_EQ(least_capture(two_grains(0.5), hs), kNarrowSkin);
  EXPECT_EQ(least_capture(two_grains(0.26), hs), kNarrowSkin);
  EXPECT_EQ(least_capture(two_grains(0.25), hs), kWideSkin);
  EXPECT_EQ(least_capture(two_grains(0.1), hs), kWideSkin);
  System<3> falling = two_grains(0.5);
  falling.gravity = Vec<3>(0.0, 0.0, -1.0);
  EXPECT_EQ(least_capture(falling, hs), kWideSkin);
  System<3> power = two_grains(0.5);
  power.materials[0].restitution.model = Restitution::Model::Power;  // e = B u^-b: falls with speed
  power.materials[0].restitution.B = 0.9;
  power.materials[0].restitution.b = 0.1;
  EXPECT_EQ(least_capture(power, hs), kWideSkin);
  for (const double e : {0.5, 0.1}) {
    const RunResult<3> r = run_hybrid<3>(two_grains(e), es, hs);
    ASSERT_EQ(r.status, "ok") << r.message;
    EXPECT_DOUBLE_EQ(r.hybrid.skin, (e > 0.25 ? kNarrowSkin : kWideSkin) * 0.5) << e;
  }
  hs.skin = 0.005;
  EXPECT_EQ(least_capture(falling, hs), 0.005);
  const RunResult<3> r = run_hybrid<3>(two_grains(0.5), es, hs);
  EXPECT_DOUBLE_EQ(r.hybrid.skin, 0.005 * 0.5);
}

// A dense gas that EDM runs to its end stays mostly hard: 512 spheres at phi = 0.5, e = 0.5,
// T = 1 (the earlier stability map's worst cell). With a capture distance fixed at 0.01 d (each
// grain then has 0.7 neighbours within it), the cost rule judging single grains and rapid runs
// at any impact speed, a few seeds drew most of the gas into the soft set and held it there (39 %
// of the particle-steps soft, 28 x EDM's time); the grains now join just before a touch, a
// rattler stays hard while its cage collides slowly, and the soft share stays small.
// 512 spheres on a simple cubic lattice at T = 1 with the map's soft law (linear, k = 9e4).
System<3> linear_lattice_gas(double phi, double e, std::uint64_t seed) {
  System<3> s = test::lattice_gas<3>(8, phi, 1.0, e, seed);
  s.materials[0].contact = "linear";
  s.materials[0].stiffness = 9.0e4;
  return s;
}

TEST(HybridSwitch, ADenseGasThatEdmRunsStaysMostlyHard) {
  const System<3> s = linear_lattice_gas(0.5, 0.5, 7);
  EdmSettings es;
  es.end_time = 5.0;
  const RunResult<3> e = run_edm<3>(s, es, QueueKind::Calendar);
  ASSERT_EQ(e.status, "ok") << e.message;
  HybridSettings hs;
  hs.threads = 1;
  const RunResult<3> r = run_hybrid<3>(s, es, hs);
  ASSERT_EQ(r.status, "ok") << r.message;
  EXPECT_EQ(r.hybrid.by_cost, 0u);
  const double all = 512.0 * es.end_time / r.soft.dt;  // particle-steps of a pure TDM run
  const double share = static_cast<double>(r.hybrid.soft_particle_steps) / all;
  EXPECT_LT(share, 0.05) << r.hybrid.soft_particle_steps;
  ::testing::Test::RecordProperty("soft_share", fmt::format("{:.4f}", share));
}

// The cost rule prices what a switch draws in (HybridEngine::region_cheaper_soft). Sphere B
// bounces elastically between two fixed spheres 0.001 d away on either side: every 0.002 time
// units, 500 collisions per unit time, five times the crossover 1 / (cost_ratio h) = 100 (linear
// law, k = m* (pi / t_c)^2 for the plan's t_c = 0.05 of a pair, m* = m / 2; h = t_c / 50). Sphere D rests on top of B, 5e-5 d away
// (within the least capture distance, hybrid.skin = 1e-4 d; never collides). Alone, B and D collide at 250 per unit time on
// average: the switch pays off and B turns soft by cost. With a column of ten more resting
// spheres on D, each 5e-5 d above the one below, the capture would draw the column in at the
// first substep: twelve grains at 500 / 12 = 42 per unit time, cheaper hard, and B stays hard.
// (In cooling_clusters.toml a switch of nine rapid grains drew 76 slow neighbours in this way and
// held them soft for 3 time units.)
RunResult<3> caged_rattler(int column) {
  const double tc = 0.05;  // the plan's contact time: a pair of unit masses, m* = 1 / 2
  System<3> s = periodic_unit_box(Vec<3>(20.0, 20.0, 20.0), 0.5 * std::pow(std::acos(-1.0) / tc, 2));
  auto add = [&](double x, double y, double vx, bool fixed) {
    s.x.push_back(Vec<3>(x, y, 10.0));
    s.v.push_back(Vec<3>(vx, 0.0, 0.0));
    s.radius.push_back(0.5);
    s.material.push_back(0);
    s.fixed.push_back(fixed ? 1 : 0);
  };
  add(10.0 - 1.001, 5.0, 0.0, true);
  add(10.0 + 1.001, 5.0, 0.0, true);
  add(10.0, 5.0, 1.0, false);  // B
  for (int k = 0; k <= column; ++k) add(10.0, 5.0 + (k + 1) * 1.00005, 0.0, false);  // D and the column
  EdmSettings es;
  es.end_time = 0.5;
  HybridSettings hs;
  hs.threads = 1;
  hs.cost_ratio = 10.0;
  RunResult<3> r = run_hybrid<3>(s, es, hs);
  EXPECT_EQ(r.status, "ok") << r.message;
  EXPECT_NEAR(r.soft.dt, tc / 50.0, 1e-3 * tc / 50.0);
  return r;
}

TEST(HybridSwitch, TheCostRulePricesTheGrainsASwitchWouldCapture) {
  const RunResult<3> alone = caged_rattler(0);
  EXPECT_GE(alone.hybrid.by_cost, 1u);
  const RunResult<3> column = caged_rattler(10);
  EXPECT_EQ(column.hybrid.by_cost, 0u);
  EXPECT_EQ(column.hybrid.to_soft, 0u);
  EXPECT_GT(column.counts.collisions(), 200u);  // about 250 collisions: the rule was asked each time
}

TEST(HybridSwitch, AnElasticDenseGasStaysHardAsInEdm) {
  // 512 elastic spheres at phi = 0.4: no collision loses energy, nothing can collapse, and EDM
  // gives the exact hard-sphere answer. Before the stability rule ignored elastic collisions this
  // gas made 2 837 switches to soft by t = 5 (grains the rule turned soft, then those captured
  // next to them), at 3.7 x EDM's time.
  const System<3> s = linear_lattice_gas(0.4, 1.0, 1);
  EdmSettings es;
  es.end_time = 5.0;
  HybridSettings hs;
  hs.threads = 1;
  const RunResult<3> r = run_hybrid<3>(s, es, hs);
  ASSERT_EQ(r.status, "ok") << r.message;
  EXPECT_EQ(r.hybrid.to_soft, 0u);
  EXPECT_EQ(r.hybrid.soft_particle_steps, 0u);
  EXPECT_GT(r.counts.collisions(), 20000u);  // about 50 per grain: the rule was asked often
}

TEST(HybridSwitch, OneClusterSoftAndBackConservesMomentumAndEnergy) {
  // Nearly elastic: e = 0.9999 loses about 1e-4 of a collision's normal energy (an elastic
  // collision never counts for the stability rule: it cannot be part of a collapse).
  System<3> s = periodic_unit_box(Vec<3>(40.0, 10.0, 10.0), 1e5, 0.9999);
  const double gap = 1e-4;
  const std::vector<Vec<3>> x = {Vec<3>(10.0, 5.0, 5.0), Vec<3>(12.0, 5.1, 5.0), Vec<3>(13.0 + gap, 5.25, 5.02)};
  const std::vector<Vec<3>> v = {Vec<3>(1.0, 0.02, -0.01), Vec<3>(0.0, 0.0, 0.0), Vec<3>(-0.1, 0.0, 0.03)};
  add_grains(s, x, v);
  Vec<3> p0 = Vec<3>::Zero();
  double ke0 = 0.0;
  for (int i = 0; i < 3; ++i) {
    p0 += s.mass(i) * v[i];
    ke0 += 0.5 * s.mass(i) * v[i].squaredNorm();
  }
  EdmSettings es;
  es.end_time = 8.0;
  es.thermo_interval = 0.01;
  HybridSettings hs;
  hs.stability = 1e3;  // t_c = pi sqrt(m*/k) = 7e-3: a collision within 7 of the previous one
  hs.repeats = 1;
  hs.speed_fall = 1.0;  // (a nearly elastic run never loses the default factor 100 of its speed)
  hs.hysteresis = 0.2;
  Recorder<3> rec;
  const RunResult<3> r = run_hybrid<3>(s, es, hs, {&rec});
  ASSERT_EQ(r.status, "ok") << r.message;
  // Both switches happened, for the whole cluster, and everything is hard again at the end.
  EXPECT_EQ(r.hybrid.to_soft, 3u);
  EXPECT_EQ(r.hybrid.to_hard, 3u);
  EXPECT_EQ(r.hybrid.soft_at_end, 0u);
  ASSERT_EQ(rec.switches.size(), 6u);
  // Momentum: to round-off (pair forces are equal and opposite, switches do not touch velocities).
  Vec<3> p1 = Vec<3>::Zero();
  double ke1 = 0.0;
  for (int i = 0; i < 3; ++i) {
    p1 += s.mass(i) * r.v[i];
    ke1 += 0.5 * s.mass(i) * r.v[i].squaredNorm();
  }
  EXPECT_LT((p1 - p0).norm(), 1e-14 * p0.norm());
  ::testing::Test::RecordProperty("momentum_rel", fmt::format("{:.3g}", (p1 - p0).norm() / p0.norm()));
  // Energy: kinetic + elastic is constant through the soft phase up to the TDM error (second order,
  // dt = t_c/50), and the kinetic energy after release equals the initial one.
  double worst = 0.0;
  for (const auto& smp : rec.samples) worst = std::max(worst, std::abs(smp.kinetic_energy + smp.elastic_energy - ke0));
  EXPECT_LT(worst, 2e-3 * ke0);
  EXPECT_NEAR(ke1, ke0, 2e-3 * ke0);
  ::testing::Test::RecordProperty("energy_rel_worst_final",
                                  fmt::format("{:.3g} {:.3g}", worst / ke0, std::abs(ke1 - ke0) / ke0));
  // The switch records carry the velocities: at each switch the particle's velocity is unchanged.
  for (const auto& w : rec.switches) EXPECT_EQ(w.vi_before, w.vi_after);
}

// ---- coasts ------------------------------------------------------------------------------------

// The soft set in free flight skips its substeps (a coast) and lands where its substeps would
// have taken it: the free flight under gravity is exact for the leapfrog, so the two runs agree to
// round-off. Three grains turn soft by the stability rule (as in the test above) and stay soft to
// the end (the hysteresis is longer than the run); gravity along the periodic y axis, so that the
// closed form's g h^2 k (k + 1) / 2 is tested and the grains cross cells and the periodic faces
// during coasts. After the cluster's contacts C flies on and comes round through the periodic x
// faces to hit A: the coast before that touch must end at the last step before it, where the
// substeps' run sees the contact begin.
TEST(HybridCoast, TheSoftSetCoastsThroughFreeFlightAndLandsWhereItsSubstepsDo) {
  System<3> s = periodic_unit_box(Vec<3>(7.5, 10.0, 10.0), 1e5, 0.9999);
  s.gravity = Vec<3>(0.0, -0.5, 0.0);
  const double gap = 1e-4;
  const std::vector<Vec<3>> x = {Vec<3>(2.0, 5.0, 5.0), Vec<3>(4.0, 5.05, 5.0), Vec<3>(5.0 + gap, 5.1, 5.01)};
  const std::vector<Vec<3>> v = {Vec<3>(1.0, 0.0, 0.0), Vec<3>(0.0, 0.0, 0.0), Vec<3>(-0.1, 0.0, 0.0)};
  add_grains(s, x, v);
  EdmSettings es;
  es.end_time = 6.0;
  es.thermo_interval = 1.0;
  HybridSettings hs;
  hs.stability = 1e3;
  hs.repeats = 1;
  hs.speed_fall = 1.0;
  hs.hysteresis = 100.0;  // soft to the end
  hs.coast = false;
  const RunResult<3> step = run_hybrid<3>(s, es, hs);
  hs.coast = true;
  const RunResult<3> coast = run_hybrid<3>(s, es, hs);
  ASSERT_EQ(step.status, "ok") << step.message;
  ASSERT_EQ(coast.status, "ok") << coast.message;
  EXPECT_EQ(coast.hybrid.to_soft, 3u);
  EXPECT_EQ(coast.hybrid.soft_at_end, 3u);
  EXPECT_EQ(step.hybrid.coasts, 0u);
  // Most of the run is free flight: the coasts skip most of the grid steps.
  EXPECT_GT(coast.hybrid.coasts, 10u);
  EXPECT_GT(coast.hybrid.coasted_steps, 5 * coast.hybrid.substeps);
  EXPECT_EQ(coast.hybrid.substeps + coast.hybrid.coasted_steps, step.hybrid.substeps);
  // After the cluster's push A drifts back slowly (x speed -0.1) and C carries the momentum; C
  // comes round through the periodic x faces and hits A after t = 5, which then moves on (0.58):
  // the later contact happened in both runs.
  EXPECT_GT(step.v[0].x(), 0.3);
  EXPECT_GT(coast.v[0].x(), 0.3);
  double dx = 0.0, dv = 0.0, vmax = 0.0;
  for (int i = 0; i < 3; ++i) {
    Vec<3> d = coast.x[i] - step.x[i];
    for (int k = 0; k < 3; ++k) d[k] -= s.upper[k] * std::round(d[k] / s.upper[k]);
    dx = std::max(dx, d.norm());
    dv = std::max(dv, (coast.v[i] - step.v[i]).norm());
    vmax = std::max(vmax, step.v[i].norm());
  }
  EXPECT_LT(dx, 1e-9);
  EXPECT_LT(dv, 1e-9 * vmax);
  ::testing::Test::RecordProperty("coast_vs_steps", fmt::format("dx {:.3g} dv {:.3g}; substeps {} + {} coasted of {}",
                                                                dx, dv, coast.hybrid.substeps,
                                                                coast.hybrid.coasted_steps, step.hybrid.substeps));
}

// ---- dilute gas ------------------------------------------------------------------------------

// e = 0.95 at packing fraction 0.05 without gravity: collisions are rare and binary; the hybrid
// stays hard and follows EDM.
TEST(HybridGas, DiluteGasStaysHardAndFollowsEdm) {
  const int n = kSanitized ? 6 : 10;
  System<3> s = test::lattice_gas<3>(n, 0.05, 1.0, 0.95, 3);
  s.materials[0].contact = "hertz";
  s.materials[0].young = 1e7;  // unit mass, unit diameter: t_c ~ 3e-3 at unit speed
  s.materials[0].poisson = 0.3;
  EdmSettings es;
  es.end_time = kSanitized ? 5.0 : 20.0;
  const RunResult<3> re = run_edm<3>(s, es, QueueKind::Calendar);
  const RunResult<3> rh = run_hybrid<3>(s, es, HybridSettings{});
  ASSERT_EQ(re.status, "ok");
  ASSERT_EQ(rh.status, "ok") << rh.message;
  EXPECT_LE(rh.hybrid.to_soft, static_cast<std::uint64_t>(s.size() / 100));
  // Same physics: the collision counts and the final temperature agree statistically (different
  // trajectories once any switch happens; identical ones when none does).
  const double ce = static_cast<double>(re.counts.pair), ch = static_cast<double>(rh.counts.pair);
  EXPECT_NEAR(ch / ce, 1.0, 0.03);
  ::testing::Test::RecordProperty("switches_collisions_ratio",
                                  fmt::format("{} {} {:.4f}", rh.hybrid.to_soft, re.counts.pair, ch / ce));
  auto temp = [&](const RunResult<3>& r) {
    double mv2 = 0.0;
    for (std::size_t i = 0; i < s.size(); ++i) mv2 += s.mass(i) * r.v[i].squaredNorm();
    return mv2 / (3.0 * s.size());
  };
  EXPECT_NEAR(temp(rh) / temp(re), 1.0, 0.03);
}

// ---- settling bed ----------------------------------------------------------------------------

// n glass grains (d = 1 cm; 2D: +-10 % radii) at random in a box with floor and side walls, at rest,
// e = 0.5, frictionless: they fall and settle into a bed.
template <int D>
System<D> settling_box(int n, double width_d, std::uint64_t seed, double friction = 0.0) {
  System<D> s;
  const double d = 0.01, R = d / 2;
  const double W = width_d * d;
  s.lower = Vec<D>::Zero();
  s.upper = Vec<D>::Constant(W);
  // Height: room for the cloud at packing fraction ~0.15 above a bed.
  const double solid = n * ball_volume<D>(R);
  const double area = std::pow(W, D - 1);
  const double H = solid / ((D == 2 ? 0.45 : 0.15) * area) + 4 * d;
  s.upper[D - 1] = H + 2 * d;
  s.gravity = Vec<D>::Zero();
  s.gravity[D - 1] = -kG;
  Material m;
  m.name = "glass";
  m.density = 2500.0;
  m.restitution = Restitution::constant(0.5);
  // 3D: Hertz (E = 1e7 Pa, overlaps ~1 % of d). 2D: a linear spring-dashpot (disks have the mass
  // of a unit-thickness slab, 2500 pi R^2 = 0.2 kg/m; k = 2e7 N/m gives overlaps of a few % of d),
  // whose damping does not vanish at small overlaps: a 2D Hertz bed rings for seconds.
  if (friction > 0.0) m.friction = friction;
  if (D == 3) {
    m.contact = "hertz";
    m.young = 1e7;
    m.poisson = 0.3;
  } else {
    m.contact = "linear";
    m.stiffness = 2e7;
  }
  s.materials.push_back(m);
  for (int k = 0; k < D; ++k) {
    Vec<D> n = Vec<D>::Zero(), top = Vec<D>::Zero();
    n[k] = 1.0;
    top[k] = W;
    s.walls.push_back(plane_wall<D>("lo" + std::to_string(k), Vec<D>::Zero(), n));
    if (k == D - 1) break;  // open top
    s.walls.push_back(plane_wall<D>("hi" + std::to_string(k), top, -n));
  }
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  while (static_cast<int>(s.x.size()) < n) {
    Vec<D> x;
    for (int k = 0; k < D - 1; ++k) x[k] = R + (W - 2 * R) * u(rng);
    x[D - 1] = 3 * d + (H - 3 * d) * u(rng);
    // 2D: radii spread by +-10 % (monodisperse disks crystallise, and the packing fraction of
    // a crystal depends on its defects, not on the dynamics).
    const double r = D == 2 ? R * (0.9 + 0.2 * u(rng)) : R;
    bool ok = true;
    for (std::size_t k = 0; k < s.x.size() && ok; ++k) {
      const double sig = (r + s.radius[k]) * 1.0001;
      ok = (x - s.x[k]).squaredNorm() > sig * sig;
    }
    if (!ok) continue;
    s.x.push_back(x);
    s.v.push_back(Vec<D>::Zero());
    s.radius.push_back(r);
    s.material.push_back(0);
  }
  return s;
}

// Bed height H = 2 <z>, twice the mean height of the grains' centres (a uniform bed on the floor
// has its centre of volume at H/2), and packing fraction = solid volume / (H times the floor
// area). Averages over every grain: the top-surface roughness of a random bed would make a
// surface measure noisier than the 1 % compared.
template <int D>
std::pair<double, double> bed_measure(const RunResult<D>& r, double W) {
  double zsum = 0.0, solid = 0.0;
  for (std::size_t i = 0; i < r.x.size(); ++i) {
    zsum += r.x[i][D - 1];
    solid += ball_volume<D>(r.radius[i]);
  }
  const double H = 2.0 * zsum / static_cast<double>(r.x.size());
  return {H, solid / (H * std::pow(W, D - 1))};
}

// Mean coordination number: twice the number of touching grain pairs (centres closer than the sum
// of the radii; periodic images ignored, the beds are in closed boxes) over the number of grains.
template <int D>
double coordination(const RunResult<D>& r) {
  std::size_t pairs = 0;
  for (std::size_t i = 0; i < r.x.size(); ++i)
    for (std::size_t j = i + 1; j < r.x.size(); ++j)
      pairs += (r.x[i] - r.x[j]).norm() < r.radius[i] + r.radius[j];
  return 2.0 * static_cast<double>(pairs) / static_cast<double>(r.x.size());
}

template <int D>
void check_settling_bed(int n, double width_d, double end_time, double friction = 0.0) {
  const System<D> s = settling_box<D>(n, width_d, 11, friction);
  const double W = width_d * 0.01;
  EdmSettings es;
  es.end_time = end_time;
  // Pure EDM: inelastic collapse in the bed.
  const RunResult<D> re = run_edm<D>(s, es, QueueKind::Calendar);
  EXPECT_EQ(re.status, "collapse");
  const RunResult<D> rh = run_hybrid<D>(s, es, HybridSettings{});
  ASSERT_EQ(rh.status, "ok") << rh.message;
  TdmSettings ts;
  ts.end_time = end_time;
  ts.threads = 1;
  const RunResult<D> rt = run_tdm<D>(s, ts);
  ASSERT_EQ(rt.status, "ok") << rt.message;
  const auto [Hh, ph] = bed_measure<D>(rh, W);
  const auto [Ht, pt] = bed_measure<D>(rt, W);
  ::testing::Test::RecordProperty("wall_seconds_edm_hybrid_tdm",
                 fmt::format("{:.3g} {:.3g} {:.3g}", re.wall_seconds, rh.wall_seconds, rt.wall_seconds));
  ::testing::Test::RecordProperty("soft_dt", fmt::format("{:.3g}", rt.soft.dt));
  ::testing::Test::RecordProperty("bed_height_hybrid_tdm", fmt::format("{:.5g} {:.5g}", Hh, Ht));
  ::testing::Test::RecordProperty("packing_hybrid_tdm", fmt::format("{:.5g} {:.5g}", ph, pt));
  // One realization each: a bed of 1000 grains agrees within 1 %; the sanitizers' 200-grain bed
  // scatters by 1.3 % (frictional, seeds 11-17: hybrid/TDM height 0.985-1.017, mean 1.000; the
  // engine before the capture distance followed the speeds: 0.980-1.018), so it is held to 3 of
  // those standard deviations.
  const double tol = kSanitized ? 0.04 : 0.01;
  EXPECT_NEAR(Hh / Ht, 1.0, tol) << "hybrid " << Hh << " tdm " << Ht;
  EXPECT_NEAR(ph / pt, 1.0, tol) << "hybrid " << ph << " tdm " << pt;
  // Both at rest: the kinetic energy is a tiny fraction of the potential energy released.
  double ke = 0.0;
  for (std::size_t i = 0; i < s.size(); ++i) ke += 0.5 * s.mass(i) * rh.v[i].squaredNorm();
  double released = 0.0;
  for (std::size_t i = 0; i < s.size(); ++i) released += s.mass(i) * kG * (s.x[i][D - 1] - rh.x[i][D - 1]);
  EXPECT_LT(ke, 1e-3 * released) << "kinetic " << ke << " released " << released;
  EXPECT_GT(rh.hybrid.to_soft, s.size() / 2);
}

TEST(HybridBed, SettlesLikeTdm2D) { check_settling_bed<2>(kSanitized ? 200 : 1000, 30.0, 0.8); }
// Frictional grains (mu = 0.5): hard collisions are rough (Walton, beta0 = 0.4), soft contacts
// Hertz-Mindlin with the same friction (issue 6: the hybrid uses the rough operator for hard
// frictional clusters).
TEST(HybridBed, FrictionalSettlesLikeTdm3D) {
  check_settling_bed<3>(kSanitized ? 200 : 1000, 8.0, 0.8, 0.5);
}
TEST(HybridBed, SettlesLikeTdm3D) { check_settling_bed<3>(kSanitized ? 200 : 1000, 8.0, 0.8); }

}  // namespace
}  // namespace matep

namespace matep {
namespace {

// A very inelastic gas (e = 0.1) whose collapsing triple ends up touching without normal approach
// at round-off level: EDM must stop with "collapse" there, not repeat the event forever at one
// instant (it did: the predictor saw an approach that the collision rule did not).
TEST(EdmCollapse, TouchingWithoutApproachEndsAsCollapseNotAHang) {
  const std::string text = R"(
[run]
dimension = 3
end_time = 20.0
seed = 7
max_events = 3000000
[domain]
lower = [0.0, 0.0, 0.0]
upper = [13.891725543141451, 13.891725543141451, 13.891725543141451]
periodic = [true, true, true]
[material.grain]
density = 1.909859317102744
restitution = 0.1
contact = "linear"
stiffness = 9.0e4
[particles.gas]
material = "grain"
radius = 0.5
count = 512
arrangement = "lattice"
temperature = 1.0
)";
  const Scene scene = load_scene_string(text, "collapse.toml", "");
  EdmSettings es;
  es.end_time = scene.end_time;
  es.max_events = scene.max_events;
  const RunResult<3> r = run_edm<3>(std::get<System<3>>(scene.system), es, QueueKind::Calendar);
  EXPECT_EQ(r.status, "collapse") << r.message;
  EXPECT_LT(r.counts.total(), 100000u);
  // The hybrid engine turns the collapsing group soft instead and runs on past it.
  es.end_time = 3.0;
  const RunResult<3> rh = run_hybrid<3>(std::get<System<3>>(scene.system), es, HybridSettings{});
  EXPECT_EQ(rh.status, "ok") << rh.message;
  EXPECT_GT(rh.hybrid.by_stability, 0u);
}

}  // namespace
}  // namespace matep

// ---- rest rule ---------------------------------------------------------------------------------

namespace matep {
namespace {

// Snapshot modes, one vector per snapshot.
template <int D>
struct ModeRecorder final : Observer<D> {
  std::vector<double> t;
  std::vector<std::vector<std::uint8_t>> mode;
  std::vector<std::vector<Vec<D>>> x;
  bool wants_snapshots() const override { return true; }
  void on_snapshot(const Snapshot<D>& s) override {
    t.push_back(s.time);
    mode.push_back(s.mode);
    x.push_back(s.x);
  }
};

// Glass beads of the pour (d = 1 cm scale): E = 1e7 Pa.
Material glass_hertz(double e) { return hertz_material("glass", 2500.0, e, 1e7); }

HybridSettings resting(double speed, double time) {
  HybridSettings h;
  h.rest_speed = speed;
  h.rest_time = time;
  return h;
}

// A bed settled three ways from the same start: the hybrid with the rest rule, the hybrid
// awake, and pure TDM (one thread), with each bed's height and packing (bed_measure, width W).
template <int D>
struct ThreeBeds {
  RunResult<D> rest, awake, tdm;
  double Hs = 0.0, ps = 0.0, Ha = 0.0, pa = 0.0, Ht = 0.0, pt = 0.0;
};
template <int D>
ThreeBeds<D> settle_three_ways(const System<D>& s, double W, double end_time) {
  ThreeBeds<D> b;
  EdmSettings es;
  es.end_time = end_time;
  b.rest = run_hybrid<D>(s, es, resting(0.01, 0.02));
  b.awake = run_hybrid<D>(s, es, HybridSettings{});
  TdmSettings ts;
  ts.end_time = end_time;
  ts.threads = 1;
  b.tdm = run_tdm<D>(s, ts);
  std::tie(b.Hs, b.ps) = bed_measure<D>(b.rest, W);
  std::tie(b.Ha, b.pa) = bed_measure<D>(b.awake, W);
  std::tie(b.Ht, b.pt) = bed_measure<D>(b.tdm, W);
  return b;
}

// Every grain of the rest-rule bed asleep at the end (slept - woken = n), and the rule saved soft
// particle-steps.
template <int D>
void expect_all_asleep(const ThreeBeds<D>& b, std::size_t n) {
  EXPECT_EQ(static_cast<std::size_t>(std::count(b.rest.mode.begin(), b.rest.mode.end(), std::uint8_t{3})), n);
  EXPECT_EQ(b.rest.hybrid.slept - b.rest.hybrid.woken, n);
  EXPECT_LT(b.rest.hybrid.soft_particle_steps, 0.8 * b.awake.hybrid.soft_particle_steps);
  ::testing::Test::RecordProperty("bed_height_rest_awake_tdm", fmt::format("{:.5g} {:.5g} {:.5g}", b.Hs, b.Ha, b.Ht));
}

// A frictional 3D bed (Hertz-Mindlin, mu = 0.5) settling with the rest rule: its grains fall
// asleep one by one as they come to rest, the bed matches pure TDM, and the substeps stop.
TEST(HybridRest, SleepingBedMatchesTdmAndStopsTheSubsteps) {
  // The sanitizers' smaller bed: 200 grains (at 150 one grain still rattled at 1.2 s; at 250 the
  // rest-rule bed stood 2.5 % below TDM's: so small a frictional bed scatters by a few percent).
  const int n = kSanitized ? 200 : 500;
  const System<3> s = settling_box<3>(n, 6.0, 11, 0.5);
  // The last grains fall asleep between 0.75 and 0.95 s, depending on the seed and on round-off
  // (measured with seeds 11-14: at 0.8 s up to 5 of 500 were still settling): 1.2 s leaves margin.
  const ThreeBeds<3> b = settle_three_ways<3>(s, 0.06, 1.2);
  ASSERT_EQ(b.rest.status, "ok") << b.rest.message;
  ASSERT_EQ(b.awake.status, "ok") << b.awake.message;
  ASSERT_EQ(b.tdm.status, "ok") << b.tdm.message;
  // The rest rule changes the bed by much less than 1 % (measured: -0.02 %). Against pure TDM this
  // narrow frictional bed differs by 0.7 % with and without the rule: a frictional random packing
  // keeps the history of its preparation, here the rough hard collisions of the falling grains (the
  // 1 % beds, HybridBed above, pass).
  EXPECT_NEAR(b.Hs / b.Ha, 1.0, 0.005) << "rest rule " << b.Hs << " awake " << b.Ha;
  EXPECT_NEAR(b.ps / b.pa, 1.0, 0.005);
  // (The sanitizers' 200-grain bed scatters by 1.1 % from one realization to the next: seeds
  // 11-17, rest rule / TDM 0.994-1.028, mean 1.009; 0.975-1.012 with the engine before the capture
  // distance followed the speeds. It is held to 3 of those standard deviations.)
  EXPECT_NEAR(b.Hs / b.Ht, 1.0, kSanitized ? 0.035 : 0.02) << "rest rule " << b.Hs << " tdm " << b.Ht;
  // The contact network: a grain falls asleep only once no gap next to it is closing, at its
  // present speed or at the rate of the last check interval (rest.hpp), so the contacts a
  // compacting bed still closes are closed.
  const double Zs = coordination(b.rest), Za = coordination(b.awake), Zt = coordination(b.tdm);
  std::printf("coordination: rest rule %.4f, awake %.4f, TDM %.4f\n", Zs, Za, Zt);
  // A bed of 500 grains scatters in Z from one realization to the next: seeds 11-16 of this bed,
  // each run with two builds whose force sums differ at round-off (2026-12-06), gave TDM 4.14-4.32
  // (sd 1.6 %), the hybrid awake 4.16-4.32 (sd 1.2 %), with the rest rule 4.13-4.22 (sd 0.7 %;
  // 4.124 with the earlier creep test). The ratio of two realizations thus scatters by about 2 %
  // (awake / TDM 0.97-1.04, rest rule / TDM 0.97-1.01 over those twelve runs), and these gates
  // are 3 of those deviations: the 2000-grain pour tells the rules apart (README "Hybrid
  // dynamics", rest rule); this checks the gross failure.
  EXPECT_NEAR(Zs / Zt, 1.0, 0.06);
  EXPECT_NEAR(Za / Zt, 1.0, 0.06);
  // Every grain asleep at the end, at rest; no substep after the last one fell asleep.
  expect_all_asleep<3>(b, s.size());
  for (const auto& v : b.rest.v) EXPECT_EQ(v.squaredNorm(), 0.0);
  EXPECT_GE(b.rest.hybrid.slept, s.size());
  EXPECT_LT(b.rest.hybrid.substeps, b.awake.hybrid.substeps);
  ::testing::Test::RecordProperty("soft_particle_steps_rest_awake",
                                  fmt::format("{} {}", b.rest.hybrid.soft_particle_steps,
                                              b.awake.hybrid.soft_particle_steps));
  ::testing::Test::RecordProperty("slept_woken", fmt::format("{} {}", b.rest.hybrid.slept, b.rest.hybrid.woken));
}

// The same rule in a polydisperse 2D bed (radii +-10 %, mu = 0.5): every contact has its own
// constants, computed per list entry at each build and recomputed for the sleepers' frozen entries
// (engine/hybrid/hybrid.cpp pair_contact_of). The bed must settle as the awake hybrid and TDM do,
// every grain asleep at the end with slept - woken = n.
TEST(HybridRest, PolydisperseBedSleepsAndMatchesTdm) {
  // The sanitizers' smaller bed: 150 disks (at 100 the rest-rule bed stood 2.4 % above TDM's).
  const int n = kSanitized ? 150 : 300;
  const System<2> s = settling_box<2>(n, 20.0, 5, 0.5);
  const ThreeBeds<2> b = settle_three_ways<2>(s, 0.2, 1.2);
  ASSERT_EQ(b.rest.status, "ok") << b.rest.message;
  ASSERT_EQ(b.awake.status, "ok") << b.awake.message;
  ASSERT_EQ(b.tdm.status, "ok") << b.tdm.message;
  EXPECT_NEAR(b.Hs / b.Ha, 1.0, 0.01) << "rest rule " << b.Hs << " awake " << b.Ha;
  // Against TDM, this frictional bed of 300 disks is one realization of a random packing: from the
  // same start the two engines' grains part within the first collisions. Seeds 5-12, rest rule /
  // TDM 0.975-1.013, mean 0.997, standard deviation 1.2 % (TDM's own height over those seeds
  // 0.1457-0.1501, 1 %); with the cost rule before it priced the capture's chain, 0.991-1.015,
  // mean 1.001. Held to 3 standard deviations
  // (the sanitizers' 150-disk bed was held to the same before).
  EXPECT_NEAR(b.Hs / b.Ht, 1.0, 0.035) << "rest rule " << b.Hs << " tdm " << b.Ht;
  expect_all_asleep<2>(b, s.size());
}

// Two frictionless grains stacked on the floor (B exactly on top of A) fall asleep; a third grain
// C slides along the floor into A and knocks it away. A wakes under C's push; B, whose support is
// gone, wakes and falls to the floor (a sleeper is never left hanging).
TEST(HybridRest, SleeperWhoseSupportIsKnockedAwayFalls) {
  System<3> s;
  const double R = 0.005;
  s.lower = Vec<3>(0.0, 0.0, 0.0);
  s.upper = Vec<3>(0.4, 0.1, 0.1);
  s.gravity = Vec<3>(0.0, 0.0, -kG);
  s.materials.push_back(glass_hertz(0.5));
  for (int k = 0; k < 3; ++k) {
    Vec<3> n = Vec<3>::Zero();
    n[k] = 1.0;
    s.walls.push_back(plane_wall<3>("lo" + std::to_string(k), Vec<3>::Zero(), n));
  }
  const Vec<3> a(0.2, 0.05, R + 1e-6), b(0.2, 0.05, 3 * R + 3e-6), c(0.05, 0.05, R + 1e-6);
  for (const Vec<3>& x : {a, b, c}) {
    s.x.push_back(x);
    s.v.push_back(Vec<3>::Zero());
    s.radius.push_back(R);
    s.material.push_back(0);
  }
  s.v[2] = Vec<3>(0.5, 0.0, 0.0);  // reaches A at t ~ (0.15 - 2R)/0.5 = 0.28 s
  EdmSettings es;
  es.end_time = 0.5;
  es.snapshot_interval = 0.01;
  ModeRecorder<3> rec;
  const RunResult<3> r = run_hybrid<3>(s, es, resting(0.005, 0.01), {&rec});
  ASSERT_EQ(r.status, "ok") << r.message;
  // Before C arrives, A and B sleep on the stack, B at 3R above the floor.
  bool stacked_asleep = false;
  for (std::size_t k = 0; k < rec.t.size(); ++k)
    if (rec.t[k] > 0.2 && rec.t[k] < 0.25) {
      stacked_asleep = rec.mode[k][0] == 3 && rec.mode[k][1] == 3;
      EXPECT_NEAR(rec.x[k][1][2], 3 * R, 0.02 * R);
    }
  EXPECT_TRUE(stacked_asleep);
  // After: B on the floor, below its old place (it fell, not pushed along).
  EXPECT_NEAR(r.x[1][2], R, 0.02 * R);
  EXPECT_GT(r.x[0][0] - a[0], 2 * R);  // A was knocked away
  EXPECT_GE(r.hybrid.woken, 2u);
}

// A soft pair (overlapping at t = 0) flying out through an open face of the domain: the substeps
// stop the run with status "escaped", naming the particle, as EDM and TDM do.
TEST(HybridEscape, SoftParticleLeavingThroughAnOpenFaceStopsTheRun) {
  System<3> s;
  s.lower = Vec<3>::Zero();
  s.upper = Vec<3>(1.0, 1.0, 1.0);
  s.materials.push_back(glass_hertz(0.9));
  const double R = 0.005;
  // (Close to the face: once apart, the pair would soon return hard together, their contacts
  // being rare; here it leaves within 1 ms, still soft.)
  for (const double x : {0.98, 0.98 + 2 * R - 1e-5}) {
    s.x.push_back(Vec<3>(x, 0.5, 0.5));
    s.v.push_back(Vec<3>(20.0, 0.0, 0.0));
    s.radius.push_back(R);
    s.material.push_back(0);
  }
  EdmSettings es;
  es.end_time = 0.1;
  const RunResult<3> r = run_hybrid<3>(s, es, HybridSettings{});
  EXPECT_EQ(r.status, "escaped") << r.message;
  EXPECT_NE(r.message.find("left the domain along axis 0"), std::string::npos) << r.message;
  EXPECT_LT(r.time, 1e-3);  // it reaches the face at t = 0.5 ms and leaves while still soft
  EXPECT_EQ(r.hybrid.to_hard, 0u);
}

}  // namespace
}  // namespace matep

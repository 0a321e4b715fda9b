// The time-driven soft-sphere engine (engine/tdm.hpp) against conservation laws, exact rigid-body
// motion, the order of its integrator and its own invariants (contact history across neighbour
// list rebuilds, determinism under threads). Expected values are analytic; each comment names the
// formula. Nothing here is copied from this code's output.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <iomanip>
#include <numbers>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "engine/observer.hpp"
#include "engine/system.hpp"
#include "engine/tdm.hpp"
#include "tests/support/systems.hpp"

using namespace matep;
using matep::test::Recorder;

namespace {

constexpr double kPi = std::numbers::pi;
using V3 = Vec<3>;
using V2 = Vec<2>;

double rel(double a, double b) { return std::abs(a / b - 1.0); }

// Records a measured value in the test report (--gtest_output=xml), for the reader.
void note(const std::string& key, double value) {
  std::ostringstream s;
  s << std::setprecision(7) << value;
  ::testing::Test::RecordProperty(key, s.str());
}

// Largest |E(t)/E(0) - 1| of the kinetic + rotational + elastic (+ potential) energy over the samples.
double worst_energy_drift(const std::vector<ThermoSample>& s) {
  auto total = [](const ThermoSample& x) {
    return x.kinetic_energy + x.rotational_energy + x.elastic_energy + x.potential_energy;
  };
  const double E0 = total(s.front());
  double worst = 0.0;
  for (const auto& x : s) worst = std::max(worst, std::abs(total(x) / E0 - 1.0));
  return worst;
}

// Elastic contact duration of two unit-mass spheres (m* = 1/2) for the linear law: t_c = pi sqrt(m*/k).
double linear_pair_time(double k) { return kPi * std::sqrt(0.5 / k); }

// Elastic Hertz contact duration t_c = 2.86827 (m*^2/(R* E*^2 v))^(1/5) (Johnson 1985; Chung & Ooi
// 2011 eq. for test 1).
double hertz_time(double mstar, double Rstar, double Estar, double v) {
  return 2.8682656992 * std::pow(mstar * mstar / (Rstar * Estar * Estar * v), 0.2);
}

double max_speed(const std::vector<V3>& v) {
  double m = 0.0;
  for (const auto& x : v) m = std::max(m, x.norm());
  return m;
}

// The lattice gas of tests/support (unit diameter and mass, periodic, T = 1), frictionless and
// elastic, with the linear law of stiffness k or the Hertz law with Young's modulus E.
System<3> linear_gas(int n_side, double phi, double k, double e = 1.0, std::uint64_t seed = 42) {
  System<3> s = test::lattice_gas<3>(n_side, phi, 1.0, e, seed);
  s.materials[0].contact = "linear";
  s.materials[0].stiffness = k;
  return s;
}

constexpr double kGasNu = 0.3;

System<3> hertz_gas(int n_side, double phi, double E, std::uint64_t seed = 42) {
  System<3> s = test::lattice_gas<3>(n_side, phi, 1.0, 1.0, seed);
  s.materials[0].contact = "hertz";
  s.materials[0].young = E;
  s.materials[0].poisson = kGasNu;
  return s;
}

struct Sampled {
  RunResult<3> res;
  std::vector<ThermoSample> samples;
};

Sampled run_sampled(const System<3>& s, TdmSettings set, int samples = 100) {
  set.thermo_interval = set.end_time / samples;
  Recorder<3> rec;
  rec.collisions = false;
  std::vector<Observer<3>*> obs{&rec};
  Sampled out;
  out.res = run_tdm<3>(s, set, obs);
  out.samples = rec.samples;
  return out;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Energy of an elastic frictionless dense gas (periodic box, packing fraction 0.35, 343
// particles, dt = t_c/50, 1e5 steps; about 46000 contacts).

TEST(TdmEnergy, ElasticLinearGasConservesEnergy) {
  const double k = 0.5 * kPi * kPi / 1e-4;  // t_c = 0.01 for m* = 1/2
  const double tc = linear_pair_time(k);
  TdmSettings set;
  set.dt = tc / 50.0;
  set.end_time = 1e5 * set.dt;
  set.threads = 1;
  const Sampled r = run_sampled(linear_gas(7, 0.35, k), set);
  ASSERT_EQ(r.res.status, "ok") << r.res.message;
  ASSERT_EQ(r.res.soft.steps, 100000u);
  EXPECT_GT(r.res.counts.pair, 20000u);  // a dense gas: many contacts
  // Velocity Verlet has no secular drift; the linear spring switches on with a kink in F(t), so
  // every contact leaves a random error of order (omega dt)^2 ~ 4e-3 of its energy, which adds
  // up as a random walk: sqrt(4.6e4) * 4e-3 * 0.5 / (343 * 1.5) ~ 1e-4. Bound: 3e-4. (An
  // energy formula inconsistent with the force, or a missed contact, costs far more: the
  // elastic energy is about 4% of the total.)
  note("energy_drift", worst_energy_drift(r.samples));
  note("contacts", static_cast<double>(r.res.counts.pair));
  EXPECT_LT(worst_energy_drift(r.samples), 3e-4);
  EXPECT_LT(r.res.max_overlap_relative, 0.05);
}

TEST(TdmEnergy, ElasticHertzGasConservesEnergy) {
  // E chosen so that the elastic Hertz contact at the largest expected impact speed (twice the
  // fastest particle) lasts about 0.01; dt = t_c(v_max)/50.
  const double E = 9e5, Es = E / (2.0 * (1.0 - kGasNu * kGasNu));
  const System<3> s = hertz_gas(7, 0.35, E);
  const double tc = hertz_time(0.5, 0.25, Es, 2.0 * max_speed(s.v));
  TdmSettings set;
  set.dt = tc / 50.0;
  set.end_time = 1e5 * set.dt;
  set.threads = 1;
  const Sampled r = run_sampled(s, set);
  ASSERT_EQ(r.res.status, "ok") << r.res.message;
  EXPECT_GT(r.res.counts.pair, 20000u);
  // The Hertz force starts as delta^3/2 (no kink): Verlet's error per contact is far smaller.
  note("energy_drift", worst_energy_drift(r.samples));
  note("contacts", static_cast<double>(r.res.counts.pair));
  EXPECT_LT(worst_energy_drift(r.samples), 1e-4);
}

// Polydisperse radii 0.25..0.75 (0.5 to 1.5 times the mean), masses proportional to R^3, and the
// velocities of equipartition (the small grains are 5 times faster than the big ones): a missed
// or late contact would show up as a jump in the energy.
TEST(TdmEnergy, PolydisperseHertzGasConservesEnergy) {
  const int n = 7, N = n * n * n;
  const double a = 1.52, L = n * a;  // lattice spacing > largest diameter 1.5
  System<3> s;
  s.lower = V3::Zero();
  s.upper = V3::Constant(L);
  s.periodic = {true, true, true};
  Material m;
  m.name = "grain";
  m.density = 1.0 / ball_volume<3>(0.5);  // a sphere of radius 0.5 has unit mass
  m.contact = "hertz";
  m.young = 9e5;
  m.poisson = kGasNu;
  s.materials.push_back(m);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> ur(0.25, 0.75);
  std::normal_distribution<double> g;
  V3 p = V3::Zero();
  double M = 0.0;
  for (int i = 0; i < N; ++i) {
    const double r = ur(rng), mass = std::pow(r / 0.5, 3);
    s.x.push_back(V3((i % n + 0.5) * a, (i / n % n + 0.5) * a, (i / (n * n) + 0.5) * a));
    s.v.push_back(V3(g(rng), g(rng), g(rng)) / std::sqrt(mass));  // T = 1
    s.radius.push_back(r);
    s.material.push_back(0);
    p += mass * s.v.back();
    M += mass;
  }
  for (auto& v : s.v) v -= p / M;
  // The shortest contact: two of the smallest grains (R* = 0.125, m* = m_min/2) at twice the
  // fastest speed.
  const double Es = 9e5 / (2.0 * (1.0 - kGasNu * kGasNu));
  const double mmin = std::pow(0.25 / 0.5, 3);
  const double tc = hertz_time(0.5 * mmin, 0.125, Es, 2.0 * max_speed(s.v));
  TdmSettings set;
  set.dt = tc / 50.0;
  set.end_time = 8e4 * set.dt;
  set.threads = 1;
  const Sampled r = run_sampled(s, set);
  ASSERT_EQ(r.res.status, "ok") << r.res.message;
  EXPECT_GT(r.res.counts.pair, 3000u);
  EXPECT_GT(r.res.soft.rebuilds, 100u);
  note("energy_drift", worst_energy_drift(r.samples));
  note("contacts", static_cast<double>(r.res.counts.pair));
  note("max_overlap", r.res.max_overlap);
  EXPECT_LT(worst_energy_drift(r.samples), 1e-4);
  // No contact was found late: the deepest overlap stays below that of a head-on elastic Hertz
  // impact, delta_max = (15 m* v^2/(16 E* sqrt(R*)))^(2/5) (Johnson 1985), at twice the fastest
  // speed with the largest m* (two of the biggest grains, m = 1.5^3) and the smallest R* (two of
  // the smallest, 0.125).
  const double vmax = 2.0 * max_speed(s.v), mstar = 0.5 * std::pow(1.5, 3);
  const double dmax = std::pow(15.0 * mstar * vmax * vmax / (16.0 * Es * std::sqrt(0.125)), 0.4);
  EXPECT_LT(r.res.max_overlap, dmax);
}

// ---------------------------------------------------------------------------------------------
// Order of the integrator: one collision of two unit spheres computed with dt, dt/2 and dt/4; the
// error against dt/64 must fall by about 4 per halving (velocity Verlet is second order; the
// engine evaluates the dashpots at the predicted full-step velocity for exactly that reason, see
// engine/tdm.hpp). Most contacts start at t = 0 (touching or already overlapping); the "gap" cases
// start apart, so the first touch falls inside a step: the linear dashpot's force jumps there, and
// only the engine's first-step weight (tau/h + 1/2, contact/soft.hpp at_onset) keeps them second
// order (without it the error falls by about 2 per halving).

namespace {

struct OrderCase {
  const char* name;
  const char* law;
  double e, mu;
  double overlap0;  // initial overlap (0: touching, < 0: a gap)
  double end;       // end time in units of the contact time scale (0.5: mid-contact)
};

void PrintTo(const OrderCase& c, std::ostream* os) { *os << c.name; }

RunResult<3> order_run(const OrderCase& c, double dt, double end) {
  const double R = 0.5;
  Material m;
  m.name = "a";
  m.density = 1.0 / ball_volume<3>(R);
  m.contact = c.law;
  m.restitution = Restitution::constant(c.e);
  if (c.mu > 0.0) m.friction = c.mu;
  if (std::string(c.law) == "linear") {
    m.stiffness = 1e5;
  } else {
    m.young = 1e6;
    m.poisson = 0.3;
  }
  System<3> s;
  s.lower = V3::Constant(-5.0);
  s.upper = V3::Constant(5.0);
  s.materials = {m};
  // Oblique impact at 40 deg along a skew normal, both spheres spinning.
  const V3 n = V3(std::cos(0.3), std::sin(0.3), 0.1).normalized();
  const V3 t = V3(-n[1], n[0], 0.0).normalized();
  const double th = 40.0 * kPi / 180.0, dist = 2.0 * R - c.overlap0;
  const V3 vrel = -std::cos(th) * n + std::sin(th) * t;
  s.x = {0.5 * dist * n, -0.5 * dist * n};
  s.v = {0.5 * vrel, -0.5 * vrel};
  s.w = {Spin<3>(0.3, -0.2, 0.5), Spin<3>(-0.1, 0.4, 0.2)};
  s.radius = {R, R};
  s.material = {0, 0};
  TdmSettings set;
  set.end_time = end;
  set.dt = dt;
  set.threads = 1;
  return run_tdm<3>(s, set);
}

}  // namespace

class TdmSecondOrder : public ::testing::TestWithParam<OrderCase> {};

TEST_P(TdmSecondOrder, ErrorFallsFourfoldPerHalving) {
  const OrderCase& c = GetParam();
  // Time scale: linear pi sqrt(m*/k) = 0.007 for m* = 1/2, k = 1e5; Hertz ~0.01 here.
  const double tc = std::string(c.law) == "linear" ? kPi * std::sqrt(0.5 / 1e5) : 0.01;
  const double dt = tc / 25.0, end = c.end * tc;
  const RunResult<3> ref = order_run(c, dt / 64.0, end);
  ASSERT_EQ(ref.status, "ok");
  double err[3];
  for (int k = 0; k < 3; ++k) {
    const RunResult<3> r = order_run(c, dt / (1 << k), end);
    ASSERT_EQ(r.status, "ok");
    err[k] = (r.v[0] - ref.v[0]).norm() + (r.v[1] - ref.v[1]).norm() +
             0.5 * ((r.w[0] - ref.w[0]).norm() + (r.w[1] - ref.w[1]).norm());  // R = 0.5
  }
  const double r1 = err[0] / err[1], r2 = err[1] / err[2];
  note("err_dt", err[0]);
  note("ratio_1", r1);
  note("ratio_2", r2);
  if (c.overlap0 < 0.0) {
    // The phase of the first touch within a step changes with dt, which scatters single ratios
    // (2.9 and 4.1 here); over two halvings a second-order error falls by about 16, a
    // first-order one by 4.
    EXPECT_GT(r1 * r2, 8.0) << "errors " << err[0] << " " << err[1] << " " << err[2];
    EXPECT_LT(r1 * r2, 25.0) << "errors " << err[0] << " " << err[1] << " " << err[2];
    return;
  }
  EXPECT_GT(r1, 3.0) << "errors " << err[0] << " " << err[1] << " " << err[2];
  EXPECT_LT(r1, 5.0) << "errors " << err[0] << " " << err[1] << " " << err[2];
  EXPECT_GT(r2, 3.0) << "errors " << err[0] << " " << err[1] << " " << err[2];
  EXPECT_LT(r2, 5.0) << "errors " << err[0] << " " << err[1] << " " << err[2];
}

INSTANTIATE_TEST_SUITE_P(
    Tdm, TdmSecondOrder,
    ::testing::Values(
        // Damped, frictionless, from an initial overlap, through separation.
        OrderCase{"linear_damped_outcome", "linear", 0.6, 0.0, 0.002, 3.0},
        OrderCase{"hertz_damped_outcome", "hertz", 0.6, 0.0, 0.002, 3.0},
        // Elastic with friction (sticking then sliding) from touching, state in mid-contact.
        OrderCase{"linear_friction_midcontact", "linear", 1.0, 0.3, 0.0, 0.5},
        // Friction and damping, contact present at t = 0, state in mid-contact.
        OrderCase{"linear_friction_damped_midcontact", "linear", 0.6, 0.3, 0.002, 0.5},
        OrderCase{"hertz_friction_damped_midcontact", "hertz", 0.6, 0.3, 0.002, 0.5},
        // First touch inside a step (start 0.003 apart, approach speed 1): damped, with and
        // without friction, through separation.
        OrderCase{"linear_damped_gap", "linear", 0.6, 0.0, -0.003, 3.0},
        OrderCase{"linear_friction_damped_gap", "linear", 0.6, 0.3, -0.003, 3.0}),
    [](const auto& info) { return std::string(info.param.name); });

// ---------------------------------------------------------------------------------------------
// Momentum: pair forces are equal and opposite, so the total momentum of a periodic gas without
// walls is conserved to round-off, even inelastic, frictional, and with the force loop split over
// two threads (forces on the other thread's particles are queued and added afterwards). 4096
// particles, so that the engine does use two threads.

TEST(TdmMomentum, InelasticFrictionalGasConservesMomentum) {
  System<3> s = linear_gas(16, 0.35, 5e4, 0.7);
  s.materials[0].friction = 0.3;
  // A common drift, so that the total is not just round-off around zero.
  for (auto& v : s.v) v += V3(0.3, -0.2, 0.1);
  TdmSettings set;
  set.dt = linear_pair_time(5e4) / 20.0;
  set.end_time = 120 * set.dt;
  set.threads = 2;
  const RunResult<3> r = run_tdm<3>(s, set);
  ASSERT_EQ(r.status, "ok") << r.message;
  ASSERT_EQ(r.soft.threads, 2);
  V3 p0 = V3::Zero(), p1 = V3::Zero();
  double scale = 0.0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    p0 += s.v[i];  // unit masses
    p1 += r.v[i];
    scale += s.v[i].norm();
  }
  EXPECT_GT(r.counts.pair, 300u);
  note("momentum_change_relative", (p1 - p0).norm() / scale);
  EXPECT_LT((p1 - p0).norm(), 1e-13 * scale) << (p1 - p0).transpose();
  // And energy was lost (inelastic, frictional): the run did something.
  double k0 = 0.0, k1 = 0.0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    k0 += s.v[i].squaredNorm();
    k1 += r.v[i].squaredNorm();
  }
  EXPECT_LT(k1, 0.99 * k0);
}

// ---------------------------------------------------------------------------------------------
// Contact history (the tangential spring) survives neighbour-list rebuilds: a run whose skin is
// so small that the list is rebuilt almost every step gives the same result as a run with a
// skin so large that it is built once.

namespace {

// Two spheres pressed together along x while sliding past each other along y (A up, B down),
// with friction and damping. The tiny skin makes the cells as small as the diameter; the pair
// starts on either side of a cell boundary along y and both cross it during the contact, so the
// particle that owns the pair in the half list changes while the spring is loaded (its
// orientation must be flipped on recall).
// With `periodic`, the pair straddles the periodic boundary x = 0 and drifts in -x, so that one
// sphere is wrapped to the other side (its image shift changes) while the contact lasts.
RunResult<3> sliding_pair(double skin, bool periodic = false) {
  const double R = 0.5, gap = 1e-4;
  System<3> s;
  s.lower = V3::Zero();
  s.upper = V3::Constant(10.0);
  Material m;
  m.name = "a";
  m.density = 1.0 / ball_volume<3>(R);
  m.contact = "linear";
  m.stiffness = 100.0;  // t_c = pi sqrt(0.5/100) = 0.22
  m.restitution = Restitution::constant(0.7);
  m.friction = 0.3;
  s.materials = {m};
  // With skin 1e-6 the cells are 10/9 wide: a boundary at y = 5 * 10/9.
  const double yb = 50.0 / 9.0;
  s.x = {V3(5.0 + R + 0.5 * gap, yb - 0.08, 5.0), V3(5.0 - R - 0.5 * gap, yb + 0.08, 5.0)};
  s.v = {V3(-0.5, 0.6, 0.0), V3(0.5, -0.6, 0.0)};
  if (periodic) {
    s.periodic = {true, true, true};
    s.x[0][0] = R + 0.5 * gap;
    s.x[1][0] = 10.0 - R - 0.5 * gap;
    for (auto& v : s.v) v[0] -= 2.5;
  }
  s.radius = {R, R};
  s.material = {0, 0};
  TdmSettings set;
  set.end_time = 0.3;
  set.dt = 2e-4;
  set.skin = skin;
  set.threads = 1;
  return run_tdm<3>(s, set);
}

// A sphere (Hertz-Mindlin, R = 5 cm) on a plane inclined at theta, released at rest at its
// static overlap; gravity is tilted instead of the wall.
RunResult<3> incline_sphere(double mu, double skin, double T, double theta_deg) {
  const double R = 0.05, rho = 1000.0, E = 1e7, nu = 0.3, g = 9.81, th = theta_deg * kPi / 180.0;
  System<3> s;
  s.lower = V3(-1.0, -0.2, 0.0);
  s.upper = V3(1.0, 0.2, 0.3);
  s.gravity = V3(g * std::sin(th), 0.0, -g * std::cos(th));
  Material m;
  m.name = "ball";
  m.density = rho;
  m.contact = "hertz";
  m.young = E;
  m.poisson = nu;
  m.friction = mu;
  m.restitution = Restitution::constant(0.5);
  Material wall = m;
  wall.name = "plane";
  wall.young.reset();  // rigid
  wall.poisson.reset();
  s.materials = {m, wall};
  s.walls.push_back(plane_wall<3>("floor", V3::Zero(), V3(0, 0, 1), 1));
  const double mass = rho * ball_volume<3>(R);
  const double K = 4.0 / 3.0 * E / (1.0 - nu * nu) * std::sqrt(R);
  const double delta = std::pow(mass * g * std::cos(th) / K, 2.0 / 3.0);  // static Hertz overlap
  s.x = {V3(-0.8, 0.0, R - delta)};
  s.v = {V3::Zero()};
  s.radius = {R};
  s.material = {0};
  TdmSettings set;
  set.end_time = T;
  set.skin = skin;
  set.threads = 1;
  return run_tdm<3>(s, set);
}

}  // namespace

TEST(TdmContactHistory, PairSpringSurvivesRebuildsAndOwnerSwaps) {
  const RunResult<3> tiny = sliding_pair(1e-6), big = sliding_pair(4.0);
  ASSERT_EQ(tiny.status, "ok") << tiny.message;
  ASSERT_EQ(big.status, "ok") << big.message;
  EXPECT_EQ(tiny.counts.pair, 1u);
  EXPECT_EQ(big.counts.pair, 1u);
  EXPECT_LE(big.soft.rebuilds, 2u);
  EXPECT_GT(tiny.soft.rebuilds, 500u);
  // Both crossed the cell boundary y = 50/9 while in contact.
  EXPECT_GT(tiny.x[0][1], 50.0 / 9.0);
  EXPECT_LT(tiny.x[1][1], 50.0 / 9.0);
  // The friction did work: the tangential relative velocity changed by more than 10%.
  EXPECT_LT(tiny.v[0][1] - tiny.v[1][1], 0.9 * 1.2);
  note("rebuilds_tiny", static_cast<double>(tiny.soft.rebuilds));
  note("rebuilds_big", static_cast<double>(big.soft.rebuilds));
  note("difference", test::relative_state_difference(tiny, big));
  EXPECT_LT(test::relative_state_difference(tiny, big), 1e-12)
      << "tiny skin v0 = " << tiny.v[0].transpose() << ", big skin v0 = " << big.v[0].transpose();
}

TEST(TdmContactHistory, PairSpringSurvivesAPeriodicWrap) {
  // The big skin: as large as the periodic-axis rule allows in this box (three cells of d + skin
  // along each periodic axis: 3 (1 + 2) <= 10), still without a rebuild that matters.
  const RunResult<3> tiny = sliding_pair(1e-6, true), big = sliding_pair(2.0, true);
  ASSERT_EQ(tiny.status, "ok") << tiny.message;
  ASSERT_EQ(big.status, "ok") << big.message;
  EXPECT_EQ(tiny.counts.pair, 1u);
  EXPECT_LE(big.soft.rebuilds, 2u);
  EXPECT_GT(tiny.soft.rebuilds, 500u);
  EXPECT_GT(tiny.x[0][0], 5.0);  // sphere 0 was wrapped from x > 0 to x < 10
  EXPECT_LT(tiny.v[0][1] - tiny.v[1][1], 0.9 * 1.2);
  note("difference", test::relative_state_difference(tiny, big));
  EXPECT_LT(test::relative_state_difference(tiny, big), 1e-12)
      << "tiny skin v0 = " << tiny.v[0].transpose() << ", big skin v0 = " << big.v[0].transpose();
}

TEST(TdmContactHistory, RollingDownAnInclineSurvivesRebuilds) {
  // mu = 0.5 > (2/7) tan 20 deg: the sphere rolls without slipping, the tangential spring
  // carrying the static friction (2/7) m g sin(theta) throughout.
  const double T = 0.3, th = 20.0;
  const RunResult<3> tiny = incline_sphere(0.5, 1e-7, T, th), big = incline_sphere(0.5, 0.5, T, th);
  ASSERT_EQ(tiny.status, "ok") << tiny.message;
  ASSERT_EQ(big.status, "ok") << big.message;
  EXPECT_LE(big.soft.rebuilds, 2u);
  EXPECT_GT(tiny.soft.rebuilds, 1000u);
  note("rebuilds_tiny", static_cast<double>(tiny.soft.rebuilds));
  note("rebuilds_big", static_cast<double>(big.soft.rebuilds));
  note("difference", test::relative_state_difference(tiny, big));
  note("x_over_expected", (tiny.x[0][0] + 0.8) / (0.5 * 5.0 / 7.0 * 9.81 * std::sin(th * kPi / 180.0) * T * T));
  EXPECT_LT(test::relative_state_difference(tiny, big), 1e-12)
      << "tiny skin v = " << tiny.v[0].transpose() << ", big skin v = " << big.v[0].transpose();
  // Rolling without slipping: a = (5/7) g sin(theta) (solid sphere, I = 2/5 m R^2), and the
  // spin follows, w_y = v_x/R.
  const double g = 9.81, a = 5.0 / 7.0 * g * std::sin(th * kPi / 180.0);
  EXPECT_LT(rel(tiny.x[0][0] + 0.8, 0.5 * a * T * T), 5e-3) << tiny.x[0][0] + 0.8;
  EXPECT_LT(rel(tiny.v[0][0], a * T), 5e-3) << tiny.v[0][0];
  EXPECT_LT(rel(tiny.w[0][1] * 0.05, tiny.v[0][0]), 5e-3) << tiny.w[0][1];
}

TEST(TdmContactHistory, SlidingDownAnInclineFollowsCoulomb) {
  // mu = 0.05 < (2/7) tan 20 deg: the sphere slides throughout, a = g (sin(theta) - mu cos(theta)),
  // and the friction torque spins it up at dw/dt = mu m g cos(theta) R / I = 5 mu g cos(theta)/(2 R).
  const double T = 0.2, th = 20.0 * kPi / 180.0, g = 9.81, mu = 0.05, R = 0.05;
  const RunResult<3> r = incline_sphere(mu, 0.0, T, 20.0);
  ASSERT_EQ(r.status, "ok") << r.message;
  note("v_over_expected", r.v[0][0] / (g * (std::sin(th) - mu * std::cos(th)) * T));
  note("w_over_expected", r.w[0][1] / (2.5 * mu * g * std::cos(th) / R * T));
  EXPECT_LT(rel(r.v[0][0], g * (std::sin(th) - mu * std::cos(th)) * T), 5e-3) << r.v[0][0];
  EXPECT_LT(rel(r.w[0][1], 2.5 * mu * g * std::cos(th) / R * T), 1e-2) << r.w[0][1];
}

TEST(TdmContactHistory, SpringOfAnInitialContactStartsUnstretched) {
  // Two spheres overlapping by delta0 at t = 0 and sliding tangentially past each other: at t = 0
  // the stored elastic energy is that of the normal spring alone, k delta0^2/2; the tangential
  // spring has had no time to stretch (it grows as the integral of the sliding velocity from the
  // first touch).
  const double R = 0.5, k = 1e5, d0 = 0.002;
  Material m;
  m.name = "a";
  m.density = 1.0 / ball_volume<3>(R);
  m.contact = "linear";
  m.stiffness = k;
  m.friction = 0.5;
  System<3> s;
  s.lower = V3::Constant(-5.0);
  s.upper = V3::Constant(5.0);
  s.materials = {m};
  s.x = {V3(0, 0, R - 0.5 * d0), V3(0, 0, -R + 0.5 * d0)};
  s.v = {V3(0.5, 0, 0), V3(-0.5, 0, 0)};
  s.radius = {R, R};
  s.material = {0, 0};
  TdmSettings set;
  set.dt = 1e-4;
  set.end_time = 10 * set.dt;
  set.threads = 1;
  const Sampled r = run_sampled(s, set, 10);
  ASSERT_FALSE(r.samples.empty());
  EXPECT_NEAR(r.samples.front().elastic_energy, 0.5 * k * d0 * d0, 1e-12 * 0.5 * k * d0 * d0)
      << "excess " << r.samples.front().elastic_energy - 0.5 * k * d0 * d0;
}

// ---------------------------------------------------------------------------------------------
// Determinism: the force loop's threads own fixed particle ranges and foreign forces are added
// in range order, so a run is bitwise repeatable for a given thread count; 1 and 2 threads differ
// only by the order of floating-point sums. 4096 particles, so that the engine uses two threads;
// few steps (an OpenMP fork-join per step is slow on a busy machine).

namespace {

RunResult<3> frictional_gas_run(int threads, double steps) {
  System<3> s = linear_gas(16, 0.35, 5e4, 0.8, 3);
  s.materials[0].friction = 0.4;
  TdmSettings set;
  set.dt = linear_pair_time(5e4) / 20.0;
  set.end_time = steps * set.dt;
  set.threads = threads;
  return run_tdm<3>(s, set);
}

}  // namespace

TEST(TdmDeterminism, TwoThreadsAreBitwiseRepeatable) {
  const RunResult<3> a = frictional_gas_run(2, 120), b = frictional_gas_run(2, 120);
  ASSERT_EQ(a.status, "ok");
  ASSERT_EQ(a.soft.threads, 2);
  ASSERT_EQ(a.x.size(), b.x.size());
  EXPECT_GT(a.counts.pair, 300u);
  for (std::size_t i = 0; i < a.x.size(); ++i) {
    ASSERT_EQ(std::memcmp(a.x[i].data(), b.x[i].data(), sizeof(double) * 3), 0) << "particle " << i;
    ASSERT_EQ(std::memcmp(a.v[i].data(), b.v[i].data(), sizeof(double) * 3), 0) << "particle " << i;
    ASSERT_EQ(std::memcmp(a.w[i].data(), b.w[i].data(), sizeof(double) * 3), 0) << "particle " << i;
  }
}

TEST(TdmDeterminism, OneAndTwoThreadsAgree) {
  const RunResult<3> a = frictional_gas_run(1, 120), b = frictional_gas_run(2, 120);
  ASSERT_EQ(a.soft.threads, 1);
  ASSERT_EQ(b.soft.threads, 2);
  EXPECT_GT(a.counts.pair, 300u);
  EXPECT_EQ(a.counts.pair, b.counts.pair);
  double dx = 0.0, dv = 0.0;
  for (std::size_t i = 0; i < a.x.size(); ++i) {
    dx = std::max(dx, (a.x[i] - b.x[i]).norm());
    dv = std::max({dv, (a.v[i] - b.v[i]).norm(), 0.5 * (a.w[i] - b.w[i]).norm()});
  }
  note("dx", dx);
  note("dv", dv);
  EXPECT_LT(dx, 1e-9);  // lengths in diameters
  EXPECT_LT(dv, 1e-9);  // speeds ~ 1
}

// ---------------------------------------------------------------------------------------------
// A sphere resting on a floor under gravity settles at the static Hertz overlap
// delta = (m g / ((4/3) E* sqrt(R)))^(2/3), E* = E/(1 - nu^2) against a rigid plane.

TEST(TdmStatics, SphereSettlesAtHertzStaticOverlap) {
  const double R = 0.01, rho = 1000.0, E = 1e7, nu = 0.3, g = 9.81;
  System<3> s;
  s.lower = V3(-0.05, -0.05, 0.0);
  s.upper = V3(0.05, 0.05, 0.05);
  s.gravity = V3(0, 0, -g);
  Material m;
  m.name = "ball";
  m.density = rho;
  m.contact = "hertz";
  m.young = E;
  m.poisson = nu;
  m.restitution = Restitution::constant(0.5);
  Material wall = m;
  wall.name = "plane";
  wall.young.reset();
  wall.poisson.reset();
  s.materials = {m, wall};
  s.walls.push_back(plane_wall<3>("floor", V3::Zero(), V3(0, 0, 1), 1));
  s.x = {V3(0, 0, R)};  // touching, at rest
  s.v = {V3::Zero()};
  s.radius = {R};
  s.material = {0};
  TdmSettings set;
  set.end_time = 0.25;  // about 50 periods of the contact oscillation (5 ms)
  set.threads = 1;
  const RunResult<3> r = run_tdm<3>(s, set);
  ASSERT_EQ(r.status, "ok") << r.message;
  const double mass = rho * 4.0 / 3.0 * kPi * R * R * R;
  const double delta = std::pow(mass * g / (4.0 / 3.0 * E / (1.0 - nu * nu) * std::sqrt(R)), 2.0 / 3.0);
  note("overlap_over_hertz", (R - r.x[0][2]) / delta);
  EXPECT_LT(rel(R - r.x[0][2], delta), 0.01) << "overlap " << R - r.x[0][2] << " vs " << delta;
  EXPECT_LT(std::abs(r.v[0][2]), 1e-3 * std::sqrt(g * delta));
  EXPECT_EQ(r.soft.contacts, 1u);
}

// ---------------------------------------------------------------------------------------------
// 2D disks.

namespace {

System<2> disk_on_floor(double e, double mu, double theta_deg, double k) {
  const double R = 0.5, g = 9.81, th = theta_deg * kPi / 180.0;
  System<2> s;
  s.lower = V2(-2.0, 0.0);
  s.upper = V2(2.0, 2.0);
  s.gravity = theta_deg > 0.0 ? V2(g * std::sin(th), -g * std::cos(th)) : V2::Zero();
  Material m;
  m.name = "disk";
  m.density = 1.0;
  m.contact = "linear";
  m.stiffness = k;
  m.restitution = Restitution::constant(e);
  if (mu > 0.0) m.friction = mu;
  Material wall = m;
  wall.name = "plane";
  s.materials = {m, wall};
  s.walls.push_back(plane_wall<2>("floor", V2::Zero(), V2(0, 1), 1));
  s.radius = {R};
  s.material = {0};
  s.w = {Spin<2>::Zero()};
  return s;
}

}  // namespace

TEST(TdmDisks, LinearBounceRestitution) {
  // A disk dropped at 1 m/s on a floor, no gravity: it leaves at e times the impact speed (the
  // linear law's damping is chosen for exactly that e, contact/soft.hpp).
  for (double e : {0.8, 0.95}) {
    System<2> s = disk_on_floor(e, 0.0, 0.0, 1e4);
    s.x = {V2(0.0, 0.5 + 1e-3)};
    s.v = {V2(0.0, -1.0)};
    TdmSettings set;
    set.end_time = 0.1;
    set.threads = 1;
    const RunResult<2> r = run_tdm<2>(s, set);
    ASSERT_EQ(r.status, "ok") << r.message;
    EXPECT_EQ(r.counts.wall, 1u);
    EXPECT_EQ(r.soft.contacts, 0u);
    note("e_out_" + std::to_string(static_cast<int>(100 * e)), r.v[0][1]);
    EXPECT_LT(rel(r.v[0][1], e), 5e-3) << "e = " << e << ": rebound " << r.v[0][1];
  }
}

TEST(TdmDisks, RollingDownAnIncline) {
  // A solid disk (I = m R^2/2) rolling without slipping: a = (2/3) g sin(theta), w = -v/R
  // (moving in +x on a floor below: clockwise). mu = 0.5 > (1/3) tan 20 deg.
  const double th = 20.0, T = 0.5, g = 9.81, R = 0.5, k = 1e5;
  System<2> s = disk_on_floor(0.5, 0.5, th, k);
  const double mass = kPi * R * R;
  const double delta = mass * g * std::cos(th * kPi / 180.0) / k;  // static overlap of the spring
  s.x = {V2(-1.5, R - delta)};
  s.v = {V2::Zero()};
  TdmSettings set;
  set.end_time = T;
  set.threads = 1;
  const RunResult<2> r = run_tdm<2>(s, set);
  ASSERT_EQ(r.status, "ok") << r.message;
  const double a = 2.0 / 3.0 * g * std::sin(th * kPi / 180.0);
  note("v_over_expected", r.v[0][0] / (a * T));
  EXPECT_LT(rel(r.v[0][0], a * T), 5e-3) << r.v[0][0];
  EXPECT_LT(rel(r.x[0][0] + 1.5, 0.5 * a * T * T), 5e-3) << r.x[0][0];
  EXPECT_LT(rel(-r.w[0][0] * R, r.v[0][0]), 5e-3) << r.w[0][0];
}

// ---------------------------------------------------------------------------------------------
// RunResult::max_overlap is the largest overlap (a length) seen during the run, and
// max_overlap_relative the largest overlap over the contact distance: with two pairs at rest, a
// small one (R = 0.1, overlap 0.01, 5% of 0.2) and a big one (R = 1, overlap 0.05, 2.5% of 2),
// over ten tiny steps (the overlaps change by < 0.3%), they are 0.05 (big pair) and 0.05 (small).

TEST(TdmDiagnostics, MaxOverlapIsTheLargestOverlapSeen) {
  Material m;
  m.name = "a";
  m.density = 1.0;
  m.contact = "linear";
  m.stiffness = 1e3;
  System<3> s;
  s.lower = V3::Zero();
  s.upper = V3::Constant(20.0);
  s.materials = {m};
  s.x = {V3(1.0, 1.0, 1.0), V3(1.19, 1.0, 1.0), V3(10.0, 10.0, 10.0), V3(11.95, 10.0, 10.0)};
  s.v.assign(4, V3::Zero());
  s.radius = {0.1, 0.1, 1.0, 1.0};
  s.material = {0, 0, 0, 0};
  TdmSettings set;
  set.dt = 1e-5;
  set.end_time = 1e-4;
  set.threads = 1;
  const RunResult<3> r = run_tdm<3>(s, set);
  ASSERT_EQ(r.status, "ok") << r.message;
  note("max_overlap", r.max_overlap);
  note("max_overlap_relative", r.max_overlap_relative);
  EXPECT_NEAR(r.max_overlap, 0.05, 1e-4);
  EXPECT_NEAR(r.max_overlap_relative, 0.05, 5e-3 * 0.05);
}

// Frictionless contacts push along the line of centres: no torque, so every spin stays what the
// scene gave (Euler's equations with zero torque), through contacts and list rebuilds (the engine
// holds no spin array when none is given and no contact turns grains; its final state is then zero).
TEST(TdmDiagnostics, FrictionlessGrainsKeepTheSpinsTheSceneGives) {
  System<3> s = linear_gas(5, 0.35, 1e4);
  ASSERT_FALSE(s.materials[0].friction.has_value());  // frictionless
  std::mt19937_64 rng(7);
  std::normal_distribution<double> g(0.0, 3.0);
  s.w.resize(s.size());
  for (auto& w : s.w) w = V3(g(rng), g(rng), g(rng));
  TdmSettings set;
  set.end_time = 40.0 * linear_pair_time(1e4) * 50.0;
  set.threads = 1;
  const RunResult<3> r = run_tdm<3>(s, set);
  ASSERT_EQ(r.status, "ok") << r.message;
  EXPECT_GT(r.counts.pair, 100u);
  EXPECT_GT(r.soft.rebuilds, 2u);
  ASSERT_EQ(r.w.size(), s.w.size());
  for (std::size_t i = 0; i < s.w.size(); ++i) EXPECT_EQ(r.w[i], s.w[i]) << "grain " << i;

  System<3> z = linear_gas(5, 0.35, 1e4);
  const RunResult<3> r0 = run_tdm<3>(z, set);
  ASSERT_EQ(r0.status, "ok") << r0.message;
  EXPECT_EQ(r0.counts.pair, r.counts.pair);  // the spins change no force
  for (const auto& w : r0.w) EXPECT_TRUE(w.isZero(0.0));
}

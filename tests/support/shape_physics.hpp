// Engine-level checks shared by the wall-shape tests (tests/analytic/test_shape_*.cpp): systems
// with one material, a random hard gas, a grain resting on a wall (static Hertz overlap), a grain
// rolling in a drum (oscillation period). Expected values are closed forms in the tests.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include "engine/edm.hpp"
#include "engine/hybrid.hpp"
#include "engine/tdm.hpp"

namespace matep::test {

inline constexpr double kGrainR = 0.05;     // grain radius of the soft tests
inline constexpr double kYoung = 1e7;       // Pa
inline constexpr double kPoisson = 0.3;
inline constexpr double kDensity = 2500.0;
inline constexpr double kG = 9.81;

template <int D>
Vec<D> axis_x() {
  Vec<D> a = Vec<D>::Zero();
  a[0] = 1.0;
  return a;
}
// The vertical axis: +z in 3D, +y in 2D.
template <int D>
Vec<D> up_axis() {
  Vec<D> a = Vec<D>::Zero();
  a[D - 1] = 1.0;
  return a;
}
// Straight down: -z in 3D, -y in 2D.
template <int D>
Vec<D> down() {
  Vec<D> a = Vec<D>::Zero();
  a[D - 1] = -1.0;
  return a;
}

// One elastic hard material (density 1000), no walls yet.
template <int D>
System<D> hard_material_system(const Vec<D>& lo, const Vec<D>& hi) {
  System<D> s;
  s.lower = lo;
  s.upper = hi;
  Material m;
  m.name = "grain";
  m.density = 1000.0;
  m.restitution = Restitution::constant(1.0);
  s.materials.push_back(m);
  return s;
}

// One Hertz material (kYoung, kPoisson, kDensity), restitution e, friction mu (0: none); the walls
// are of the same material.
template <int D>
System<D> hertz_system(const Vec<D>& lo, const Vec<D>& hi, double e, double mu) {
  System<D> s;
  s.lower = lo;
  s.upper = hi;
  Material m;
  m.name = "grain";
  m.density = kDensity;
  m.restitution = Restitution::constant(e);
  m.young = kYoung;
  m.poisson = kPoisson;
  m.contact = "hertz";
  if (mu > 0.0) m.friction = mu;
  s.materials.push_back(m);
  return s;
}

template <int D>
void add_grain(System<D>& s, const Vec<D>& x, const Vec<D>& v, double R) {
  s.x.push_back(x);
  s.v.push_back(v);
  s.radius.push_back(R);
  s.material.push_back(0);
}

// n grains of radius R at random non-overlapping places of the box where inside(x), Gaussian
// velocities.
template <int D, class Inside>
void fill_gas(System<D>& s, int n, double R, Inside&& inside, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  int tries = 0;
  while (static_cast<int>(s.size()) < n && ++tries < 1000000) {
    Vec<D> x, v;
    for (int k = 0; k < D; ++k) {
      std::uniform_real_distribution<double> u(s.lower[k], s.upper[k]);
      x[k] = u(rng);
      v[k] = g(rng);
    }
    if (!inside(x)) continue;
    bool free = true;
    for (const auto& y : s.x) free = free && (x - y).norm() > 2.02 * R;
    if (free) add_grain<D>(s, x, v, R);
  }
}

template <int D>
double kinetic(const std::vector<Vec<D>>& v) {
  double e = 0.0;
  for (const auto& u : v) e += u.squaredNorm();
  return e;
}

// An elastic hard gas under gravity (g = 1 down) in the box [-0.6, 0.6]^D closed by planes, with
// `shape` inside it (grains start anywhere clear of it, on both sides of a sheet). Over 10 s:
// kinetic + potential energy is conserved to 1e-10 and no grain overlaps the shape by more than
// round-off (every 0.1 s and at the end), with at least `min_hits` wall collisions.
template <int D>
void expect_edm_gas_around(std::shared_ptr<const WallShape<D>> shape, int n, double R, std::uint64_t seed,
                           const char* name) {
  System<D> s = hard_material_system<D>(Vec<D>::Constant(-0.6), Vec<D>::Constant(0.6));
  s.gravity = -1.0 * up_axis<D>();
  for (int k = 0; k < D; ++k) {
    Vec<D> e = Vec<D>::Zero();
    e[k] = 1.0;
    s.walls.push_back(plane_wall<D>("lo", Vec<D>(-0.6 * e), e));
    s.walls.push_back(plane_wall<D>("hi", Vec<D>(0.6 * e), Vec<D>(-e)));
  }
  s.walls.push_back(Wall<D>{"shape", 0, shape});
  fill_gas<D>(s, n, R, [&](const Vec<D>& x) {
    return (x.array().abs() < 0.6 - 1.5 * R).all() && shape->at(x, R, 0.0).gap > 0.5 * R;
  }, seed);
  struct Snap final : Observer<D> {
    const WallShape<D>* shape = nullptr;
    double R = 0.0, worst = 0.0;
    bool wants_snapshots() const override { return true; }
    void on_snapshot(const Snapshot<D>& sn) override {
      for (const auto& x : sn.x) worst = std::max(worst, -shape->at(x, R, sn.time).gap);
    }
  } snap;
  snap.shape = shape.get();
  snap.R = R;
  EdmSettings es;
  es.end_time = 10.0;
  es.snapshot_interval = 0.1;
  const RunResult<D> r = run_edm<D>(s, es, QueueKind::Calendar, {&snap});
  ASSERT_EQ(r.status, "ok") << name << ": " << r.message;
  auto energy = [&](const std::vector<Vec<D>>& x, const std::vector<Vec<D>>& v) {
    double e = 0.0;
    for (std::size_t i = 0; i < x.size(); ++i) e += 0.5 * v[i].squaredNorm() - s.gravity.dot(x[i]);
    return e;
  };
  const double ratio = energy(r.x, r.v) / energy(s.x, s.v);
  std::printf("EDM gas around a %s (%s): %zu grains, %llu wall collisions, energy ratio - 1 = %.3g, "
              "worst overlap %.3g\n",
              shape->kind(), name, s.size(), static_cast<unsigned long long>(r.counts.wall), ratio - 1.0,
              std::max(snap.worst, r.max_overlap));
  EXPECT_NEAR(ratio, 1.0, 1e-10) << name;
  EXPECT_LT(snap.worst, 1e-12) << name;
  EXPECT_LT(r.max_overlap, 1e-12) << name;
  EXPECT_GT(r.counts.wall, 500u) << name;
}

// E* of the grain on a wall of its own material: 1/((1 - nu^2)/E + (1 - nu^2)/E).
inline double estar_same() { return kYoung / (2.0 * (1.0 - kPoisson * kPoisson)); }
template <int D>
double grain_mass(double R) {
  return kDensity * (D == 3 ? 4.0 / 3.0 * 3.141592653589793 * R * R * R : 3.141592653589793 * R * R);
}
// Static Hertz overlap under the normal load F: F = (4/3) E* sqrt(R) delta^(3/2) (R* = R, see the
// tests).
inline double hertz_overlap(double F, double R) {
  return std::pow(3.0 * F / (4.0 * estar_same() * std::sqrt(R)), 2.0 / 3.0);
}

struct Track final {
  std::vector<double> t;
  std::vector<std::vector<double>> x;  // per snapshot, the grain's coordinates
  std::vector<std::vector<double>> v;  // ... and velocity
};
template <int D>
struct Tracker final : Observer<D> {
  Track track;
  bool wants_snapshots() const override { return true; }
  void on_snapshot(const Snapshot<D>& s) override {
    track.t.push_back(s.time);
    track.x.push_back(std::vector<double>(s.x[0].data(), s.x[0].data() + D));
    track.v.push_back(std::vector<double>(s.v[0].data(), s.v[0].data() + D));
  }
};

// The rate (rad/s) at which a tracked grain's horizontal velocity turns: least-squares slope of
// its unwrapped direction angle over the snapshots at t >= t0 (a sphere on a turntable); the
// number of snapshots used in m.
inline double velocity_turning_rate(const Track& track, double t0, int& m) {
  const double pi = 3.141592653589793;
  double prev = 0.0, off = 0.0, sx = 0, sy = 0, sxx = 0, sxy = 0;
  m = 0;
  for (std::size_t k = 0; k < track.t.size(); ++k) {
    double a = std::atan2(track.v[k][1], track.v[k][0]);
    if (k > 0) {
      if (a + off - prev > pi) off -= 2.0 * pi;
      if (a + off - prev < -pi) off += 2.0 * pi;
    }
    a += off;
    prev = a;
    const double t = track.t[k];
    if (t < t0) continue;
    sx += t;
    sy += a;
    sxx += t * t;
    sxy += t * a;
    ++m;
  }
  return (m * sxy - sx * sy) / (m * sxx - sx * sx);
}

// Runs s with TDM (one thread) or the hybrid to end_time with snapshots every `every`.
template <int D>
RunResult<D> run_soft(const System<D>& s, bool hybrid, double end_time, double every, Observer<D>* obs) {
  std::vector<Observer<D>*> observers;
  if (obs) observers.push_back(obs);
  if (hybrid) {
    EdmSettings es;
    es.end_time = end_time;
    es.snapshot_interval = every;
    return run_hybrid<D>(s, es, HybridSettings{}, observers);
  }
  TdmSettings ts;
  ts.end_time = end_time;
  ts.threads = 1;
  ts.snapshot_interval = every;
  return run_tdm<D>(s, ts, observers);
}

// A grain of radius kGrainR placed touching `shape` at x_touch (gap 0 there, contact normal n from
// the wall to the grain), pressed in by half the expected overlap, under gravity g, with restitution
// 0.3 and friction mu, settles (1 s) at the static overlap for the normal load m |g.n|.
template <int D>
void expect_static_hertz_overlap(std::shared_ptr<const WallShape<D>> shape, const Vec<D>& x_touch, const Vec<D>& n,
                                 const Vec<D>& g, bool hybrid, double mu = 0.0, double tol = 1e-3) {
  const double R = kGrainR;
  const double expected = hertz_overlap(grain_mass<D>(R) * std::abs(g.dot(n)), R);
  Vec<D> lo, hi;
  lo = x_touch - Vec<D>::Constant(1.0);
  hi = x_touch + Vec<D>::Constant(1.0);
  Vec<D> blo, bhi;
  if (shape->bounds(blo, bhi)) {
    lo = lo.cwiseMin(blo - Vec<D>::Constant(0.1));
    hi = hi.cwiseMax(bhi + Vec<D>::Constant(0.1));
  }
  System<D> s = hertz_system<D>(lo, hi, 0.3, mu);
  s.gravity = g;
  s.walls.push_back(Wall<D>{"wall", 0, shape});
  add_grain<D>(s, Vec<D>(x_touch - 0.5 * expected * n), Vec<D>::Zero(), R);
  ASSERT_NEAR(shape->at(s.x[0], R, 0.0).gap, -0.5 * expected, 1e-9 * R);
  const RunResult<D> r = run_soft<D>(s, hybrid, 1.0, 0.0, nullptr);
  ASSERT_EQ(r.status, "ok") << r.message;
  const WallPoint<D> c = shape->at(r.x[0], R, r.time);
  const double got = -c.gap;
  std::printf("static overlap on %s (%s, %dD): %.6g, Hertz %.6g, ratio - 1 = %.3g\n", shape->kind(),
              hybrid ? "hybrid" : "TDM", D, got, expected, got / expected - 1.0);
  EXPECT_NEAR(got / expected, 1.0, tol);
  EXPECT_LT((c.normal - n).norm(), 1e-2);
}

// The period of a grain rolling at the bottom of a horizontal drum (axis x through the origin; the
// centre's rest position at distance `arm` below the axis): started at rest 0.05 rad up the side
// (already at the static overlap), friction 0.5; the period from the zero crossings of the
// sideways coordinate over about two periods.
template <int D>
double rolling_period(std::shared_ptr<const WallShape<D>> shape, double arm, bool hybrid) {
  const double R = kGrainR;
  const double delta = hertz_overlap(grain_mass<D>(R) * kG, R);
  System<D> s = hertz_system<D>(Vec<D>::Constant(-1.0), Vec<D>::Constant(1.0), 0.5, 0.5);
  s.gravity = kG * down<D>();
  s.walls.push_back(Wall<D>{"drum", 0, shape});
  const double th = 0.05, rr = arm + delta;
  Vec<D> x = Vec<D>::Zero();
  x[D - 2] = rr * std::sin(th);
  x[D - 1] = -rr * std::cos(th);
  add_grain<D>(s, x, Vec<D>::Zero(), R);
  const double T0 = 2.0 * 3.141592653589793 * std::sqrt(1.5 * arm / kG);
  Tracker<D> tr;
  const RunResult<D> r = run_soft<D>(s, hybrid, 2.3 * T0, 2e-4, &tr);
  EXPECT_EQ(r.status, "ok") << r.message;
  std::vector<double> cross;
  const auto& t = tr.track.t;
  const auto& xs = tr.track.x;
  for (std::size_t k = 1; k < t.size(); ++k) {
    const double a = xs[k - 1][D - 2], b = xs[k][D - 2];
    if ((a > 0.0) != (b > 0.0)) cross.push_back(t[k - 1] + (t[k] - t[k - 1]) * a / (a - b));
  }
  if (cross.size() < 3) {
    ADD_FAILURE() << "too few crossings: " << cross.size();
    return 0.0;
  }
  // Successive crossings are half a period apart.
  return 2.0 * (cross.back() - cross.front()) / static_cast<double>(cross.size() - 1);
}

}  // namespace matep::test

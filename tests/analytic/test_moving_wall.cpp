// Oscillating plane walls (Wall::amplitude, Wall::frequency: p(t) = p0 + A sin(2 pi f t)):
// the bracketed impact-time prediction (contact/predict.hpp) against a brute-force scan in
// extended precision, the event-driven collision rule against a moving wall, the soft-sphere
// contact with a moving floor (following it; taking off at sin(phase) = g / (A w^2)), the two
// engines against each other, and the scene keys. Expected values are analytic or come from
// independent code written here; nothing is copied from the engines' output.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <limits>
#include <numbers>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "contact/predict.hpp"
#include "engine/edm.hpp"
#include "engine/observer.hpp"
#include "engine/system.hpp"
#include "engine/tdm.hpp"
#include "io/log_tools.hpp"
#include "io/run.hpp"
#include "io/scene.hpp"
#include "tests/support/cli.hpp"
#include "tests/support/systems.hpp"

using namespace matep;
using matep::test::Recorder;

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kG = 9.81;
using V2 = Vec<2>;
using V3 = Vec<3>;

void note(const std::string& key, double value) {
  std::ostringstream s;
  s << std::setprecision(7) << value;
  ::testing::Test::RecordProperty(key, s.str());
}

// ---------------------------------------------------------------------------------------------
// Brute force in long double: G(t) = d + v t + a t^2/2 - An sin(w (t0 + t)).

struct Gap {
  long double d, v, a, An, w, t0;
  long double operator()(long double t) const { return d + t * (v + 0.5L * a * t) - An * sinl(w * (t0 + t)); }
  long double rate(long double t) const { return v + a * t - An * w * cosl(w * (t0 + t)); }
  long double M() const { return fabsl(a) + fabsl(An) * w * w; }  // bound on |G''|
};

// First root of G in [a, b] given G(a) > 0. An interval is declared root-free only when the
// interpolation bound min(G(a), G(b)) - M h^2 / 8 > 0 proves it; otherwise it is halved. A sign
// change on an interval where G is provably monotone (|G'(a)| > M h) is bisected to long-double
// precision (the point on the closed side). Returns -1 if there is no root.
long double first_root(const Gap& G, long double a, long double ga, long double b, long double gb, int depth = 0) {
  const long double M = G.M(), h = b - a;
  if (gb > 0.0L) {
    if (std::min(ga, gb) - M * h * h / 8.0L > 0.0L || depth > 90) return -1.0L;
    const long double m = 0.5L * (a + b), gm = G(m);
    const long double r = first_root(G, a, ga, m, gm, depth + 1);
    return r >= 0.0L ? r : first_root(G, m, gm, b, gb, depth + 1);
  }
  if (fabsl(G.rate(a)) > M * h || depth > 90) {  // one root: bisect
    for (int it = 0; it < 200; ++it) {
      const long double m = 0.5L * (a + b);
      if (!(m > a && m < b)) break;
      if (G(m) > 0.0L) a = m;
      else b = m;
    }
    return b;
  }
  const long double m = 0.5L * (a + b), gm = G(m);
  if (gm <= 0.0L) return first_root(G, a, ga, m, gm, depth + 1);
  const long double r = first_root(G, a, ga, m, gm, depth + 1);
  return r >= 0.0L ? r : first_root(G, m, gm, b, gb, depth + 1);
}

// Earliest root in [s, T] of a gap open at s (G(s) > 0), on a uniform grid of n intervals.
long double brute_root(const Gap& G, long double s, long double T, int n) {
  long double a = s, ga = G(s);
  for (int k = 1; k <= n; ++k) {
    const long double b = s + (T - s) * k / n, gb = G(b);
    const long double r = first_root(G, a, ga, b, gb);
    if (r >= 0.0L) return r;
    a = b;
    ga = gb;
  }
  return -1.0L;
}

struct Config {
  double d, v, a, An, w, t0;
};

Gap gap_of(const Config& c) { return Gap{c.d, c.v, c.a, c.An, c.w, c.t0}; }

// The gap at t = 0 as the prediction computes it.
double gap0(const Config& c) { return c.d - c.An * std::sin(c.w * c.t0); }

double predict(const Config& c, double limit = kNever) {
  return oscillating_gap_closing_time(c.d, c.v, c.a, c.An, c.w, c.t0, limit);
}

struct Tally {
  int checked = 0, with_root = 0, never = 0, ill_conditioned = 0;
  double worst_rel = 0.0;  // over the roots whose round-off limit is below 1e-10 relative
};

// Compares the prediction with the brute force over [s, horizon] (s: where the gap is open).
void compare(const Config& c, double s, double horizon, Tally& tally, const std::string& what) {
  const Gap G = gap_of(c);
  const int n = static_cast<int>(std::ceil(horizon * c.w / (2.0 * kPi) * 200.0));
  const long double tb = brute_root(G, s, horizon, n);
  const double tf = predict(c);
  ++tally.checked;
  if (tb < 0.0L) {
    ++tally.never;
    EXPECT_GT(tf, horizon) << what << ": predicted " << tf << " but no root before " << horizon;
    return;
  }
  ++tally.with_root;
  const double t = static_cast<double>(tb);
  // 1e-10 relative, or the accuracy the double problem allows when that is coarser: the round-off
  // of g (its terms' size, and the phase w (t0 + t) rounded at the absolute time) over its slope.
  const double eps = std::numeric_limits<double>::epsilon();
  const double roundoff = 8.0 * eps *
                          (std::abs(c.d) + t * (std::abs(c.v) + std::abs(c.a) * t) +
                           std::abs(c.An) * (1.0 + c.w * (c.t0 + t))) /
                          static_cast<double>(fabsl(G.rate(tb)));
  const double tol = std::max(1e-10 * t, roundoff);
  if (roundoff > 1e-10 * t) ++tally.ill_conditioned;
  const double rel = std::abs(tf - t) / t;
  if (roundoff <= 1e-10 * t) tally.worst_rel = std::max(tally.worst_rel, rel);
  EXPECT_LE(tf, t + tol) << what << ": later than the earliest root " << t;
  EXPECT_LE(std::abs(tf - t), tol) << what << ": predicted " << std::setprecision(17) << tf << ", root " << t << " (d " << c.d
                        << ", v " << c.v << ", a " << c.a << ", An " << c.An << ", w " << c.w << ", t0 " << c.t0
                        << ")";
  // The limit argument: a root at or beyond the limit is no event; one before it is unchanged.
  EXPECT_EQ(predict(c, t * (1.0 - 1e-6)), kNever) << what;
  EXPECT_EQ(predict(c, t * (1.0 + 1e-6)), tf) << what;
}

double loguniform(std::mt19937_64& rng, double lo, double hi) {
  return std::exp(std::uniform_real_distribution<double>(std::log(lo), std::log(hi))(rng));
}

// A random wall (frequency, signed normal amplitude), particle acceleration and start time.
Config random_wall(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> U(0.0, 1.0);
  Config c{};
  const double f = loguniform(rng, 0.5, 50.0);
  c.w = 2.0 * kPi * f;
  c.An = loguniform(rng, 1e-4, 1e-2) * (U(rng) < 0.5 ? -1.0 : 1.0);
  const double pick = U(rng);
  c.a = pick < 0.3 ? 0.0 : pick < 0.7 ? -kG : (U(rng) - 0.5) * 60.0;
  c.t0 = U(rng) * 10.0 / f;
  return c;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// (1) Prediction against the brute force.

TEST(MovingWallPredict, RandomConfigurationsMatchBruteForce) {
  std::mt19937_64 rng(20240611);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  Tally tally;
  for (int k = 0; k < 3000; ++k) {
    Config c = random_wall(rng);
    const double A = std::abs(c.An), P = 2.0 * kPi / c.w;
    c.d = (U(rng) * 5.0 - 1.0) * A;                   // from inside the band to well above it
    c.v = (U(rng) * 6.0 - 3.0) * A * c.w;             // comparable to the wall's speed
    if (!(gap0(c) > 0.0)) continue;
    compare(c, 0.0, 6.0 * P, tally, "random " + std::to_string(k));
  }
  note("configurations", tally.checked);
  note("with_root", tally.with_root);
  note("worst_relative_error", tally.worst_rel);
  note("limited_by_roundoff", tally.ill_conditioned);
  EXPECT_GT(tally.with_root, 1500);
  EXPECT_GT(tally.never, 10);
}

// Grazing configurations: the gap has a local minimum -eps at t_g (g'(t_g) = 0, g''(t_g) > 0),
// with depth eps from 1e-6 to 1e-2 of the amplitude (the particle barely touches the wall where
// their relative motion turns), and near misses with the minimum +eps just above the wall.
TEST(MovingWallPredict, GrazingConfigurationsMatchBruteForce) {
  std::mt19937_64 rng(777);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  Tally hits, misses;
  int dips_found = 0;
  for (int k = 0; k < 6000; ++k) {
    Config c = random_wall(rng);
    const double A = std::abs(c.An), P = 2.0 * kPi / c.w;
    double tg = 0.0, ph = 0.0, g2 = 0.0;
    bool ok = false;
    for (int tries = 0; tries < 50 && !ok; ++tries) {
      tg = (0.3 + 2.7 * U(rng)) * P;
      ph = c.w * (c.t0 + tg);
      g2 = c.a + c.An * c.w * c.w * std::sin(ph);  // g'' at t_g
      ok = g2 > 0.2 * (std::abs(c.a) + A * c.w * c.w);
    }
    if (!ok) continue;
    const bool miss = U(rng) < 0.25;
    const double eps = loguniform(rng, 1e-6, 1e-2) * A * (miss ? -1.0 : 1.0);
    c.v = c.An * c.w * std::cos(ph) - c.a * tg;                      // g'(t_g) = 0
    c.d = -eps - c.v * tg - 0.5 * c.a * tg * tg + c.An * std::sin(ph);  // g(t_g) = -eps
    if (!(gap0(c) > 0.0)) continue;
    Tally& t = miss ? misses : hits;
    const int before = t.with_root;
    compare(c, 0.0, 4.0 * P, t, (miss ? "near miss " : "grazing ") + std::to_string(k));
    if (!miss && t.with_root > before) {
      const double tf = predict(c);
      if (std::abs(tf - tg) < 4.0 * std::sqrt(2.0 * eps / g2)) ++dips_found;  // the root is the dip's
    }
  }
  note("grazing_configurations", hits.checked);
  note("grazing_roots_in_the_dip", dips_found);
  note("grazing_worst_relative_error", hits.worst_rel);
  note("grazing_limited_by_roundoff", hits.ill_conditioned);
  note("near_miss_configurations", misses.checked);
  note("near_miss_worst_relative_error", misses.worst_rel);
  EXPECT_GT(dips_found, 1200);
  EXPECT_GT(misses.checked, 400);
}

// A gap closed by round-off at t = 0: closing is an event now; opening is not, and the event is
// the next closing (brute force from the moment the gap has opened).
TEST(MovingWallPredict, RoundOffOverlapRules) {
  std::mt19937_64 rng(99);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  int now = 0, later = 0;
  Tally tally;
  for (int k = 0; k < 1000; ++k) {
    Config c = random_wall(rng);
    const double A = std::abs(c.An), P = 2.0 * kPi / c.w;
    c.v = (U(rng) * 6.0 - 3.0) * A * c.w;
    c.d = c.An * std::sin(c.w * c.t0) - U(rng) * 1e-15 * A;  // g(0) ~ -1e-15 A
    if (!(gap0(c) <= 0.0)) continue;
    const double r0 = c.v - c.An * c.w * std::cos(c.w * c.t0);
    if (r0 < 0.0) {
      EXPECT_EQ(predict(c), 0.0) << "closing at t = 0";
      ++now;
      continue;
    }
    if (r0 < 0.05 * A * c.w) continue;  // slowly opening: may turn before it opens
    // Opening: the gap is open by s (the rate cannot fall below r0 - M s > 0 before).
    const double s = std::min(1e-6 * P, 0.5 * r0 / (std::abs(c.a) + A * c.w * c.w));
    ASSERT_GT(gap_of(c)(s), 0.0L);
    compare(c, s, 6.0 * P, tally, "opening " + std::to_string(k));
    ++later;
  }
  note("closing_now", now);
  note("opening", later);
  note("opening_worst_relative_error", tally.worst_rel);
  note("opening_limited_by_roundoff", tally.ill_conditioned);
  EXPECT_GT(now, 300);
  EXPECT_GT(later, 300);
}

// The vector form projects on the normal: a tilted 3D wall with a tangential amplitude part.
TEST(MovingWallPredict, VectorFormProjectsOnTheNormal) {
  const V3 n = V3(0.3, -0.2, 1.0).normalized();
  const V3 p0(0.1, 0.2, -0.05), A(0.004, -0.002, 0.003);
  const V3 x(0.3, 0.1, 0.2), v(0.5, 0.2, -1.0), g(0.0, 0.0, -kG);
  const double R = 0.02, w = 2.0 * kPi * 12.0, t0 = 0.37;
  const double t = moving_wall_collision_time(x, v, g, R, p0, n, A, w, t0);
  const double ts = oscillating_gap_closing_time((x - p0).dot(n) - R, v.dot(n), g.dot(n), A.dot(n), w, t0);
  EXPECT_EQ(t, ts);
  ASSERT_LT(t, kNever);
  // At the returned time the sphere touches the moving plane.
  const V3 xt = x + v * t + 0.5 * t * t * g;
  const V3 pt = p0 + std::sin(w * (t0 + t)) * A;
  EXPECT_NEAR((xt - pt).dot(n) - R, 0.0, 1e-14);
  // A zero normal amplitude is the static closed form.
  const V3 At = A - A.dot(n) * n;
  EXPECT_EQ(moving_wall_collision_time(x, v, g, R, p0, n, At, w, t0),
            gap_closing_time((x - p0).dot(n) - R, v.dot(n), g.dot(n)));
}

// ---------------------------------------------------------------------------------------------
// (2) Event-driven engine.

namespace {

// A ball (radius R, density 1000) above a floor through the origin (normal +y) oscillating along
// y with amplitude A at frequency f; a static roof at y = 2 closes the box; the other axes are
// periodic.
template <int D>
System<D> ball_over_vibrating_floor(double A, double f, double e, double gravity, double R = 0.01) {
  System<D> s;
  s.lower = Vec<D>::Constant(-0.1);
  s.upper = Vec<D>::Constant(0.1);
  s.lower[1] = -0.05;
  s.upper[1] = 2.05;
  s.periodic.fill(true);
  s.periodic[1] = false;
  s.gravity = Vec<D>::Zero();
  s.gravity[1] = -gravity;
  Material m;
  m.name = "ball";
  m.density = 1000.0;
  m.restitution = Restitution::constant(e);
  s.materials.push_back(m);
  Vec<D> up = Vec<D>::Zero(), amp = Vec<D>::Zero(), top = Vec<D>::Zero();
  up[1] = 1.0;
  amp[1] = A;
  top[1] = 2.0;
  s.walls = {plane_wall<D>("floor", Vec<D>::Zero(), up, 0, amp, f), plane_wall<D>("roof", top, -up)};
  s.radius = {R};
  s.material = {0};
  return s;
}

template <int D>
void check_struck_at_rest() {
  // At rest with its gap to the mean plane A/2: the rising floor (p = A sin wt) reaches it at
  // sin(w t*) = 1/2, t* = 1/(12 f), moving at u = A w cos(pi/6); an elastic ball leaves at
  // v' = 2u - v = sqrt(3) A w. The tangential velocity is kept.
  const double A = 0.002, f = 25.0, w = 2.0 * kPi * f, R = 0.01;
  System<D> s = ball_over_vibrating_floor<D>(A, f, 1.0, 0.0, R);
  Vec<D> x = Vec<D>::Zero(), v = Vec<D>::Zero();
  x[1] = R + 0.5 * A;
  v[0] = 0.3;
  s.x = {x};
  s.v = {v};
  EdmSettings set;
  set.end_time = 0.2;  // the ball flies up at 0.27 m/s: it has not come back to the roof yet
  Recorder<D> rec;
  const RunResult<D> r = run_edm<D>(s, set, QueueKind::Calendar, {&rec});
  ASSERT_EQ(r.status, "ok") << r.message;
  ASSERT_EQ(rec.records.size(), 1u);
  const CollisionRecord<D>& c = rec.records[0];
  EXPECT_EQ(c.kind, EventKind::WallCollision);
  EXPECT_EQ(c.j, 0u);
  const double ts = 1.0 / (12.0 * f);
  note("struck_time_rel_error_" + std::to_string(D), std::abs(c.time / ts - 1.0));
  EXPECT_NEAR(c.time, ts, 1e-12 * ts);
  EXPECT_NEAR(c.vi_after[1], std::sqrt(3.0) * A * w, 1e-12 * A * w);
  EXPECT_EQ(c.vi_after[0], 0.3);
  EXPECT_NEAR(c.vj_before[1], A * w * std::cos(kPi / 6.0), 1e-12 * A * w);  // the wall's velocity
  EXPECT_EQ(c.e, 1.0);
  EXPECT_NEAR(r.x[0][1], R + A * std::sin(kPi / 6.0) + std::sqrt(3.0) * A * w * (0.2 - ts), 1e-12);
}

}  // namespace

TEST(MovingWallEdm, BallAtRestStruckByRisingFloor2D) { check_struck_at_rest<2>(); }
TEST(MovingWallEdm, BallAtRestStruckByRisingFloor3D) { check_struck_at_rest<3>(); }

TEST(MovingWallEdm, FastBallHitsFloorAtTheConstructedTime) {
  // Falling at V > A w (faster than the floor ever moves): g(t) = V (t* - t) + A (sin w t* -
  // sin w t) decreases strictly, so the only root is the t* the start height was built from.
  // Elastic: v' = 2 u(t*) - v.
  const double A = 0.001, f = 40.0, w = 2.0 * kPi * f, R = 0.01, V = 0.5;
  for (const double phase : {0.1, 0.3, 0.55, 0.8}) {
    const double ts = 0.5 + phase / f;
    System<3> s = ball_over_vibrating_floor<3>(A, f, 1.0, 0.0, R);
    s.x = {V3(0.0, R + V * ts + A * std::sin(w * ts), 0.0)};
    s.v = {V3(0.0, -V, 0.02)};
    EdmSettings set;
    set.end_time = ts + 0.01;
    Recorder<3> rec;
    const RunResult<3> r = run_edm<3>(s, set, QueueKind::Heap, {&rec});
    ASSERT_EQ(r.status, "ok") << r.message;
    ASSERT_EQ(rec.records.size(), 1u) << phase;
    const double u = A * w * std::cos(w * ts);
    EXPECT_NEAR(rec.records[0].time, ts, 1e-12 * ts) << phase;
    EXPECT_NEAR(rec.records[0].vi_after[1], 2.0 * u + V, 1e-12 * V) << phase;
    EXPECT_EQ(rec.records[0].vi_after[2], 0.02);
  }
}

TEST(MovingWallEdm, BouncingOnAVibratingFloorFollowsTheRuleAndStaysBounded) {
  // Gravity, e = 0.9, floor at 20 Hz with A w^2 = 1.5 g. Every impact is checked against the
  // rule with the floor's velocity computed here, and every flight between impacts against an
  // independent extended-precision scan: it starts touching the floor, flies ballistically and
  // first touches it again at the next recorded impact (none missed, none invented). Bounded:
  // launch speeds obey |v_out| <= (1 + e) A w + e |v_in| with |v_in|^2 <= v_out_prev^2 + 4 g A.
  const double e = 0.9, f = 20.0, w = 2.0 * kPi * f, A = 1.5 * kG / (w * w), R = 0.01, h = 0.02;
  System<2> s = ball_over_vibrating_floor<2>(A, f, e, kG, R);
  s.x = {V2(0.0, R + h)};
  s.v = {V2::Zero()};
  EdmSettings set;
  set.end_time = 5.0;
  Recorder<2> rec;
  const RunResult<2> r = run_edm<2>(s, set, QueueKind::Calendar, {&rec});
  ASSERT_EQ(r.status, "ok") << r.message;
  const auto& R_ = rec.records;
  ASSERT_GT(R_.size(), 50u);
  double bound_in = std::sqrt(2.0 * kG * (h + A));  // first impact speed at most
  double worst_rule = 0.0, worst_flight = 0.0, top = 0.0;
  for (std::size_t k = 0; k < R_.size(); ++k) {
    const auto& c = R_[k];
    ASSERT_EQ(c.j, 0u) << "impact " << k << " on the roof";
    const double u = A * w * std::cos(w * c.time);
    const double before = c.vi_before[1] - u, after = c.vi_after[1] - u;
    EXPECT_LT(before, 0.0) << k;
    EXPECT_EQ(c.e, e);
    worst_rule = std::max(worst_rule, std::abs(after + e * before));
    EXPECT_NEAR(after, -e * before, 1e-13) << k;
    EXPECT_EQ(c.vi_after[0], c.vi_before[0]);
    // Bounds.
    EXPECT_LE(std::abs(c.vi_before[1]), bound_in * (1.0 + 1e-9)) << k;
    const double bound_out = (1.0 + e) * A * w + e * bound_in;
    EXPECT_LE(std::abs(c.vi_after[1]), bound_out * (1.0 + 1e-9)) << k;
    bound_in = std::sqrt(bound_out * bound_out + 4.0 * kG * A);
    const double y = A * std::sin(w * c.time), vy = c.vi_after[1];
    if (vy > 0.0) top = std::max(top, y + vy * vy / (2.0 * kG));
    if (k + 1 == R_.size()) break;
    // The flight to the next impact: gap to the mean plane y - R = A sin(w t_k), rate vy.
    const auto& n = R_[k + 1];
    const double dtk = n.time - c.time;
    EXPECT_NEAR(n.vi_before[1], vy - kG * dtk, 1e-12) << k;
    const Gap G{y, vy, -kG, A, w, c.time};
    const long double M = G.M(), s0 = std::min(1e-9L, 0.5L * (vy - u) / M);  // open by s0
    ASSERT_GT(G(s0), 0.0L) << k;
    const long double tb = brute_root(G, s0, dtk * 1.5 + 1e-3, 400);
    ASSERT_GE(tb, 0.0L) << k;
    worst_flight = std::max(worst_flight, static_cast<double>(fabsl(tb - dtk) / dtk));
    EXPECT_NEAR(static_cast<double>(tb), dtk, 1e-9 * dtk + 1e-13) << "flight " << k;
  }
  note("impacts", static_cast<double>(R_.size()));
  note("worst_rule_residual", worst_rule);
  note("worst_flight_time_rel_error", worst_flight);
  note("highest_top_above_mean_floor", top);
  note("launch_speed_bound_at_end", bound_in);
}

// ---------------------------------------------------------------------------------------------
// (3) Time-driven engine: a sphere on a floor oscillating along z, linear contact.

namespace {

// Records the snapshots (positions and velocities at full steps).
template <int D>
struct Snapshots : Observer<D> {
  std::vector<double> t;
  std::vector<Vec<D>> x, v;
  bool wants_snapshots() const override { return true; }
  void on_snapshot(const Snapshot<D>& s) override {
    t.push_back(s.time);
    x.push_back(s.x[0]);
    v.push_back(s.v[0]);
  }
};

constexpr double kSoftR = 0.01, kSoftRho = 1000.0, kSoftK = 1e5;

double soft_mass() { return kSoftRho * 4.0 / 3.0 * kPi * kSoftR * kSoftR * kSoftR; }

// A sphere of radius 1 cm (m = 4.19 g) on a floor oscillating along z (A, f), linear contact
// k = 1e5 N/m (contact frequency 4886 rad/s), restitution e.
System<3> sphere_on_vibrating_floor(double A, double f, double e, double gravity) {
  System<3> s;
  s.lower = V3(-0.05, -0.05, -0.05);
  s.upper = V3(0.05, 0.05, 0.5);
  s.gravity = V3(0.0, 0.0, -gravity);
  const Material m = test::linear_material("ball", kSoftRho, kSoftK, e);
  Material plane = m;
  plane.name = "plane";
  s.materials = {m, plane};
  s.walls = {plane_wall<3>("floor", V3::Zero(), V3(0, 0, 1), 1, V3(0.0, 0.0, A), f)};
  s.radius = {kSoftR};
  s.material = {0};
  return s;
}

// Resting at the static overlap and moving with the floor at t = 0 (where p'' = 0).
Snapshots<3> run_resting(double gamma, double f, double end_time, double interval) {
  const double w = 2.0 * kPi * f, A = gamma * kG / (w * w);
  const double delta_s = soft_mass() * kG / kSoftK;
  System<3> s = sphere_on_vibrating_floor(A, f, 0.5, kG);
  s.x = {V3(0.0, 0.0, kSoftR - delta_s)};
  s.v = {V3(0.0, 0.0, A * w)};
  TdmSettings set;
  set.end_time = end_time;
  set.threads = 1;
  set.snapshot_interval = interval;
  Snapshots<3> snap;
  const RunResult<3> r = run_tdm<3>(s, set, {&snap});
  EXPECT_EQ(r.status, "ok") << r.message;
  return snap;
}

}  // namespace

TEST(MovingWallTdm, RestingSphereFollowsAGentlyVibratingFloor) {
  // A w^2 = 0.08 g: the overlap R - (z - p(t)) stays within the static overlap m g / k +-10 %.
  const double f = 10.0, w = 2.0 * kPi * f, A = 0.08 * kG / (w * w);
  const double delta_s = soft_mass() * kG / kSoftK;
  const Snapshots<3> s = run_resting(0.08, f, 0.3, 1e-4);
  ASSERT_GT(s.t.size(), 2000u);
  double worst = 0.0;
  for (std::size_t k = 0; k < s.t.size(); ++k) {
    const double delta = kSoftR - (s.x[k][2] - A * std::sin(w * s.t[k]));
    worst = std::max(worst, std::abs(delta / delta_s - 1.0));
  }
  note("worst_overlap_deviation_over_static", worst);
  EXPECT_LT(worst, 0.1);
}

TEST(MovingWallTdm, RestingSphereFollowsAStronglyVibratingFloorQuasiStatically) {
  // A w^2 = 0.6 g < g: the sphere never leaves the floor and the contact carries m (g + p''),
  // so the overlap follows delta_s (1 - 0.6 sin w t) (within 10 % of delta_s).
  const double gamma = 0.6, f = 10.0, w = 2.0 * kPi * f, A = gamma * kG / (w * w);
  const double delta_s = soft_mass() * kG / kSoftK;
  const Snapshots<3> s = run_resting(gamma, f, 0.3, 1e-4);
  double worst = 0.0, smallest = 1e300;
  for (std::size_t k = 0; k < s.t.size(); ++k) {
    const double delta = kSoftR - (s.x[k][2] - A * std::sin(w * s.t[k]));
    smallest = std::min(smallest, delta);
    worst = std::max(worst, std::abs(delta - delta_s * (1.0 - gamma * std::sin(w * s.t[k]))) / delta_s);
  }
  note("worst_deviation_from_quasi_static_over_static", worst);
  note("smallest_overlap_over_static", smallest / delta_s);
  EXPECT_LT(worst, 0.1);
  EXPECT_GT(smallest, 0.3 * delta_s);  // never lost contact (quasi-static minimum 0.4)
}

TEST(MovingWallTdm, SphereTakesOffWhereTheFloorOutAcceleratesGravity) {
  // A w^2 = 2 g: the contact force m g (1 - 2 sin w t) vanishes at sin(w t) = g / (A w^2) = 1/2,
  // i.e. phase pi/6, t = 1/(12 f): the first time the gap opens must match within a few %.
  const double gamma = 2.0, f = 10.0, w = 2.0 * kPi * f, A = gamma * kG / (w * w);
  const Snapshots<3> s = run_resting(gamma, f, 0.02, 1e-5);
  double t_off = -1.0;
  for (std::size_t k = 1; k < s.t.size() && t_off < 0.0; ++k) {
    const double g0 = s.x[k - 1][2] - kSoftR - A * std::sin(w * s.t[k - 1]);
    const double g1 = s.x[k][2] - kSoftR - A * std::sin(w * s.t[k]);
    if (g0 <= 0.0 && g1 > 0.0) t_off = s.t[k - 1] + (s.t[k] - s.t[k - 1]) * (-g0) / (g1 - g0);
  }
  ASSERT_GT(t_off, 0.0);
  const double phase = w * t_off, expected = std::asin(kG / (A * w * w));
  note("take_off_phase", phase);
  note("take_off_phase_expected", expected);
  EXPECT_LT(std::abs(phase / expected - 1.0), 0.03) << phase << " vs " << expected;
}

TEST(MovingWallTdm, FloorShakenSidewaysRollsTheSphere) {
  // The floor oscillates along x (A w^2 = 0.5 g), friction mu = 1: a solid sphere rolling without
  // slipping on it moves with 2/7 of the floor's acceleration (q / (1 + q), q = 2/5), so started
  // rolling with the floor (v = (2/7) A w, contact point at the floor's velocity A w) its centre
  // follows x = (2/7) A sin(w t). This exercises the slip relative to the wall (v - u).
  const double f = 10.0, w = 2.0 * kPi * f, A = 0.5 * kG / (w * w);
  const double delta_s = soft_mass() * kG / kSoftK;
  System<3> s = sphere_on_vibrating_floor(0.0, f, 0.5, kG);
  s.walls[0] = plane_wall<3>("floor", V3::Zero(), V3(0, 0, 1), 1, V3(A, 0.0, 0.0), f);
  s.materials[0].friction = 1.0;
  s.materials[1].friction = 1.0;
  const double vx = 2.0 / 7.0 * A * w;
  s.x = {V3(0.0, 0.0, kSoftR - delta_s)};
  s.v = {V3(vx, 0.0, 0.0)};
  s.w = {Spin<3>(0.0, (vx - A * w) / (kSoftR - delta_s), 0.0)};  // contact point moves with the floor
  TdmSettings set;
  set.end_time = 0.3;
  set.threads = 1;
  set.snapshot_interval = 1e-4;
  Snapshots<3> snap;
  const RunResult<3> r = run_tdm<3>(s, set, {&snap});
  ASSERT_EQ(r.status, "ok") << r.message;
  double worst = 0.0;
  for (std::size_t k = 0; k < snap.t.size(); ++k)
    worst = std::max(worst, std::abs(snap.x[k][0] - 2.0 / 7.0 * A * std::sin(w * snap.t[k])));
  note("rolling_worst_deviation_over_amplitude", worst / (2.0 / 7.0 * A));
  EXPECT_LT(worst, 0.02 * 2.0 / 7.0 * A);
}

// ---------------------------------------------------------------------------------------------
// (4) Both engines: first impact of a ball dropped onto a vibrating floor.

TEST(MovingWallBothEngines, FirstImpactTimeAgrees) {
  const double f = 15.0, A = 0.001, h = 0.05, e = 0.9;
  for (const double start : {0.0, 0.013, 0.031}) {  // different phases at impact
    System<3> s = sphere_on_vibrating_floor(A, f, e, kG);
    s.x = {V3(0.0, 0.0, kSoftR + h)};
    s.v = {V3(0.0, 0.0, -kG * start)};
    // EDM.
    EdmSettings es;
    es.end_time = 0.2;
    System<3> se = s;
    se.periodic = {true, true, false};
    Recorder<3> rec;
    const RunResult<3> re = run_edm<3>(se, es, QueueKind::Calendar, {&rec});
    ASSERT_EQ(re.status, "ok") << re.message;
    ASSERT_GE(rec.records.size(), 1u);
    const double t_edm = rec.records[0].time, v_edm = rec.records[0].vi_after[2];
    // TDM: the first full step with an overlap, interpolated on the gap.
    TdmSettings ts;
    ts.end_time = t_edm + 0.004;
    ts.threads = 1;
    ts.snapshot_interval = 1e-5;
    Snapshots<3> snap;
    const RunResult<3> rt = run_tdm<3>(s, ts, {&snap});
    ASSERT_EQ(rt.status, "ok") << rt.message;
    const double w = 2.0 * kPi * f;
    double t_tdm = -1.0;
    for (std::size_t k = 1; k < snap.t.size() && t_tdm < 0.0; ++k) {
      const double g0 = snap.x[k - 1][2] - kSoftR - A * std::sin(w * snap.t[k - 1]);
      const double g1 = snap.x[k][2] - kSoftR - A * std::sin(w * snap.t[k]);
      if (g0 > 0.0 && g1 <= 0.0) t_tdm = snap.t[k - 1] + (snap.t[k] - snap.t[k - 1]) * g0 / (g0 - g1);
    }
    ASSERT_GT(t_tdm, 0.0);
    // Rebound: after the contact (about 0.64 ms long), brought back to the impact time under gravity.
    const double v_tdm = snap.v.back()[2] + kG * (snap.t.back() - t_edm);
    note("edm_first_impact_" + std::to_string(start), t_edm);
    note("impact_time_rel_difference_" + std::to_string(start), t_tdm / t_edm - 1.0);
    note("rebound_rel_difference_" + std::to_string(start), v_tdm / v_edm - 1.0);
    EXPECT_LT(std::abs(t_tdm / t_edm - 1.0), 0.01);
    // The soft contact lasts 0.64 ms while the floor's velocity changes (by up to 6 % of A w):
    // the rebounds agree to a few percent, not exactly.
    EXPECT_LT(std::abs(v_tdm / v_edm - 1.0), 0.03);
  }
}

// ---------------------------------------------------------------------------------------------
// (5) Scene files: [wall.NAME] oscillation = {amplitude = [...], frequency = f}.

namespace {

// A 2D box of disks on a vibrating floor (A w^2 = 2.5 g at 25 Hz), with an event log.
std::string vibrated_scene(const std::string& oscillation) {
  return R"(
[run]
dimension = 2
end_time = 1.0
gravity = [0.0, -9.81]

[domain]
lower = [0.0, -0.01]
upper = [0.2, 0.3]
periodic = [true, false]

[material.grain]
density = 1000.0
restitution = 0.9

[wall.floor]
type = "plane"
point = [0.0, 0.0]
normal = [0.0, 1.0]
material = "grain"
)" + oscillation + R"(

[wall.lid]
type = "plane"
point = [0.0, 0.29]
normal = [0.0, -1.0]
material = "grain"

[particles.grains]
material = "grain"
radius = 0.005
count = 40
region = {lower = [0.0, 0.002], upper = [0.2, 0.1]}
temperature = 0.0

[output]
events = true
)";
}

std::string scene_error(const std::string& oscillation) {
  try {
    load_scene_string(vibrated_scene(oscillation), "vib.toml", ".");
  } catch (const SceneError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(MovingWallScene, OscillationIsReadIntoTheWall) {
  const Scene sc = load_scene_string(vibrated_scene("oscillation = {amplitude = [0.0, 0.001], frequency = 25}"),
                                     "vib.toml", ".");
  const auto& sys = std::get<System<2>>(sc.system);
  ASSERT_EQ(sys.walls.size(), 2u);
  const PlaneWall<2>& floor = *as_plane<2>(sys.walls[0].shape.get());
  const PlaneWall<2>& roof = *as_plane<2>(sys.walls[1].shape.get());
  EXPECT_TRUE(floor.oscillating());
  EXPECT_EQ(floor.amplitude, V2(0.0, 0.001));
  EXPECT_EQ(floor.frequency, 25.0);
  EXPECT_FALSE(roof.oscillating());
  // p(t) = p0 + A sin(2 pi f t), u(t) = 2 pi f A cos(2 pi f t).
  const double t = 0.0137, w = 2.0 * kPi * 25.0;
  EXPECT_NEAR(floor.position(t)[1], 0.001 * std::sin(w * t), 1e-18);
  EXPECT_NEAR(floor.velocity(t)[1], 0.001 * w * std::cos(w * t), 1e-15);
  EXPECT_EQ(floor.position(0.0), floor.point);
  EXPECT_EQ(roof.position(t), roof.point);
  EXPECT_EQ(roof.velocity(t), V2::Zero());
  EXPECT_NE(describe_scene(sc).find("oscillating: amplitude (0, 0.001) at frequency 25"), std::string::npos)
      << describe_scene(sc);
  // A zero amplitude is a static wall.
  const Scene still = load_scene_string(vibrated_scene("oscillation = {amplitude = [0, 0], frequency = 25}"),
                                        "vib.toml", ".");
  EXPECT_FALSE(as_plane<2>(std::get<System<2>>(still.system).walls[0].shape.get())->oscillating());
}

TEST(MovingWallScene, BadOscillationTablesNameFileKeyAndValue) {
  struct Case {
    std::string text, key, value;
  };
  const std::vector<Case> cases = {
      {"oscillation = {amplitude = [0.0, 0.001], frequency = 0}", "wall.floor.oscillation.frequency", "got 0"},
      {"oscillation = {amplitude = [0.0, 0.001], frequency = -3.5}", "wall.floor.oscillation.frequency", "-3.5"},
      {"oscillation = {amplitude = [0.0, 0.001], frequency = \"fast\"}", "wall.floor.oscillation.frequency",
       "\"fast\""},
      {"oscillation = {amplitude = [0.001], frequency = 25}", "wall.floor.oscillation.amplitude", "[0.001]"},
      {"oscillation = {amplitude = [0.0, 0.001, 0.0], frequency = 25}", "wall.floor.oscillation.amplitude", "3"},
      {"oscillation = {amplitude = [0.0, 0.001]}", "wall.floor.oscillation.frequency", "missing"},
      {"oscillation = {frequency = 25}", "wall.floor.oscillation.amplitude", "missing"},
      {"oscillation = {amplitude = [0.0, 0.001], frequency = 25, phase = 0.5}", "wall.floor.oscillation.phase",
       "0.5"},
      {"oscillation = 25", "wall.floor.oscillation", "25"},
      {"oscilation = {amplitude = [0.0, 0.001], frequency = 25}", "wall.floor.oscilation", "oscillation"},
  };
  for (const auto& c : cases) {
    const std::string msg = scene_error(c.text);
    EXPECT_EQ(msg.rfind("vib.toml: ", 0), 0u) << c.text << " -> " << msg;
    EXPECT_NE(msg.find(c.key), std::string::npos) << c.text << " -> " << msg;
    EXPECT_NE(msg.find(c.value), std::string::npos) << c.text << " -> " << msg;
  }
}

TEST(MovingWallScene, VibratedBedRunsAndItsEventLogVerifies) {
  // The whole path: scene -> EDM run with an oscillating floor -> events.bin, whose wall records
  // carry the floor's velocity as vj; `matep log verify` checks them in the wall's frame.
  const Scene sc = load_scene_string(vibrated_scene("oscillation = {amplitude = [0.0, 0.001], frequency = 25}"),
                                     "vib.toml", ".", {"run.tc=1e-4"});
  const std::filesystem::path d = test::fresh_dir("moving_wall");
  const RunOutcome out = run_scene(sc, d.string());
  ASSERT_EQ(out.status, "ok") << out.message;
  const VerifyResult v = verify_log((d / "events.bin").string(), &sc, 1e-12);
  EXPECT_TRUE(v.ok) << v.message;
  note("pair_collisions", static_cast<double>(v.pair));
  note("wall_collisions", static_cast<double>(v.wall));
  EXPECT_GT(v.wall, 100u);
  EXPECT_GT(v.pair, 100u);
  std::filesystem::remove_all(d);
}

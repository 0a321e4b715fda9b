// Collision prediction and hard collision operators against closed forms.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "contact/hard.hpp"
#include "contact/plane.hpp"
#include "contact/predict.hpp"
#include "contact/restitution.hpp"
#include "contact/vec.hpp"
#include "tests/support/random.hpp"

using namespace matep;

namespace {

using matep::test::random_unit;

// Earlier root of |r + v t| = sigma in long double (the closed form, evaluated in extended
// precision with the cancellation-free expression).
template <int D>
long double exact_time(const Vec<D>& r, const Vec<D>& v, double sigma) {
  long double b = 0, rr = 0, vv = 0;
  for (int k = 0; k < D; ++k) {
    b += (long double)r[k] * v[k];
    rr += (long double)r[k] * r[k];
    vv += (long double)v[k] * v[k];
  }
  const long double c = rr - (long double)sigma * sigma;
  const long double disc = b * b - vv * c;
  return c / (-b + std::sqrt(disc));
}

template <int D>
void check_pair_times() {
  std::mt19937_64 rng(42 + D);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  int tested = 0;
  double worst = 0.0;
  for (int trial = 0; trial < 20000; ++trial) {
    const double sigma = 0.2 + 2.0 * U(rng);
    // A collision at time t*: contact vector sigma*n, incoming velocity at an impact angle with
    // cos >= 0.05 (away from exact grazing, where the root is ill-conditioned in any precision).
    const Vec<D> n = random_unit<D>(rng);
    Vec<D> v = random_unit<D>(rng) * (0.01 + 10.0 * U(rng));
    if (v.dot(n) > 0) v = -v;
    if (-v.normalized().dot(n) < 0.05) continue;
    const double tstar = std::pow(10.0, -3.0 + 5.0 * U(rng));
    const Vec<D> r = sigma * n - v * tstar;
    const double t = pair_collision_time(r, v, sigma);
    const long double te = exact_time<D>(r, v, sigma);
    ASSERT_TRUE(std::isfinite(t));
    const double rel = std::abs((long double)t - te) / te;
    worst = std::max(worst, rel);
    ++tested;
  }
  EXPECT_GT(tested, 15000);
  EXPECT_LE(worst, 1e-12) << "dimension " << D;
  std::printf("worst relative error (D = %d): %.3g over %d configurations\n", D, worst, tested);
}

}  // namespace

TEST(PairPrediction, MatchesClosedFormToRoundOff2D) { check_pair_times<2>(); }
TEST(PairPrediction, MatchesClosedFormToRoundOff3D) { check_pair_times<3>(); }

TEST(PairPrediction, RecedingPairIsNeverAnEvent) {
  Vec<3> r(1.5, 0, 0), v(1.0, 0.2, 0);
  EXPECT_EQ(pair_collision_time(r, v, 1.0), kNever);
  // Even when overlapping: a receding overlapped pair is not an event (Bannerman et al. 2014).
  Vec<3> r2(0.9, 0, 0);
  EXPECT_EQ(pair_collision_time(r2, v, 1.0), kNever);
}

TEST(PairPrediction, OverlappingApproachingPairCollidesNow) {
  Vec<3> r(0.999999, 0, 0), v(-1.0, 0.1, 0);
  EXPECT_EQ(pair_collision_time(r, v, 1.0), 0.0);
}

TEST(PairPrediction, MissIsNeverAnEvent) {
  Vec<2> r(-3.0, 1.01), v(1.0, 0.0);  // passes at distance 1.01 > sigma = 1
  EXPECT_EQ(pair_collision_time(r, v, 1.0), kNever);
  Vec<2> r2(-3.0, 0.99);
  EXPECT_NEAR(pair_collision_time(r2, v, 1.0), 3.0 - std::sqrt(1.0 - 0.99 * 0.99), 1e-14);
}

TEST(GapClosing, BallisticAndUnderGravity) {
  // No acceleration: d / -v.
  EXPECT_DOUBLE_EQ(gap_closing_time(2.0, -4.0, 0.0), 0.5);
  EXPECT_EQ(gap_closing_time(2.0, 4.0, 0.0), kNever);
  // Falling from rest through height h: sqrt(2 h / g).
  EXPECT_NEAR(gap_closing_time(1.0, 0.0, -9.81), std::sqrt(2.0 / 9.81), 1e-15);
  // Thrown up at 3 m/s from the floor: back after 2 v / g.
  EXPECT_NEAR(gap_closing_time(0.0, 3.0, -9.81), 2 * 3.0 / 9.81, 1e-15);
  // Pushed away (a > 0) but moving in fast enough: smaller root of d + v t + a t^2 / 2.
  const double d = 1.0, v = -3.0, a = 2.0;
  EXPECT_NEAR(gap_closing_time(d, v, a), (-v - std::sqrt(v * v - 2 * a * d)) / a, 1e-15);
  // ... or not fast enough: never.
  EXPECT_EQ(gap_closing_time(1.0, -1.0, 2.0), kNever);
  // Round-off overlap: closing now, opening later (the turn under gravity).
  EXPECT_EQ(gap_closing_time(-1e-15, -1.0, -9.81), 0.0);
  EXPECT_NEAR(gap_closing_time(-1e-15, 1e-3, -9.81), (1e-3 + std::sqrt(1e-6 - 2 * 9.81 * 1e-15)) / 9.81, 1e-18);
}

TEST(WallPrediction, BouncingBallFlightTimes) {
  const Vec<3> g(0, 0, -9.81), p(0, 0, 0), n(0, 0, 1);
  const Vec<3> x(0, 0, 1.0 + 0.1);  // 1 m above contact, radius 0.1
  EXPECT_NEAR(wall_collision_time(x, Vec<3>::Zero().eval(), g, 0.1, p, n), std::sqrt(2.0 / 9.81), 1e-15);
}

TEST(SlabExit, PicksTheFaceReachedFirst) {
  bool up = false;
  EXPECT_NEAR(slab_exit_time(0.25, 1.0, 0.0, 0.0, 1.0, up), 0.75, 1e-15);
  EXPECT_TRUE(up);
  EXPECT_NEAR(slab_exit_time(0.25, -1.0, 0.0, 0.0, 1.0, up), 0.25, 1e-15);
  EXPECT_FALSE(up);
  // Thrown up but falls back out of the bottom face.
  const double t = slab_exit_time(0.0, 1.0, -10.0, 0.0, 1.0, up);
  EXPECT_NEAR(t, 0.2, 1e-15);
  EXPECT_FALSE(up);
}

TEST(SmoothCollision, ConservesMomentumAndRemovesOneMinusESquaredOfNormalEnergy) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> U(0.1, 3.0);
  std::normal_distribution<double> G;
  for (int trial = 0; trial < 1000; ++trial) {
    const double mi = U(rng), mj = U(rng), e = U(rng) / 3.0;
    Vec<3> n = random_unit<3>(rng);
    Vec<3> vi(G(rng), G(rng), G(rng)), vj(G(rng), G(rng), G(rng));
    if ((vi - vj).dot(n) > 0) n = -n;
    const Vec<3> p0 = mi * vi + mj * vj;
    const double u = (vi - vj).dot(n);
    const double mstar = mi * mj / (mi + mj);
    const double E0 = 0.5 * mi * vi.squaredNorm() + 0.5 * mj * vj.squaredNorm();
    const double J = smooth_pair_collision(vi, vj, mi, mj, n, e);
    EXPECT_NEAR(J, -(1 + e) * mstar * u, 1e-14 * std::abs(J));
    const Vec<3> p1 = mi * vi + mj * vj;
    EXPECT_LE((p1 - p0).norm(), 1e-14 * (std::abs(mi) + std::abs(mj)) * 10);
    const double E1 = 0.5 * mi * vi.squaredNorm() + 0.5 * mj * vj.squaredNorm();
    const double expected_loss = (1 - e * e) * 0.5 * mstar * u * u;
    EXPECT_NEAR(E0 - E1, expected_loss, 1e-12 * E0);
    EXPECT_NEAR((vi - vj).dot(n), -e * u, 1e-13);
  }
}

TEST(SmoothCollision, WallReversesNormalVelocityTimesE) {
  Vec<2> v(3.0, -4.0);
  const Vec<2> n(0.0, 1.0);
  smooth_wall_collision(v, 2.0, n, 0.5);
  EXPECT_DOUBLE_EQ(v[0], 3.0);
  EXPECT_DOUBLE_EQ(v[1], 2.0);
}

TEST(Restitution, Models) {
  Restitution c = Restitution::constant(0.7);
  EXPECT_DOUBLE_EQ(c(5.0), 0.7);
  Restitution p;
  p.model = Restitution::Model::Power;
  p.B = 0.5;
  p.b = 0.25;
  EXPECT_NEAR(p(16.0), 0.25, 1e-15);  // 0.5 * 16^-0.25
  EXPECT_DOUBLE_EQ(p(1e-8), 1.0);     // capped at 1 for slow impacts
  Restitution s;
  s.model = Restitution::Model::Schwager;
  s.e0 = 0.8;
  s.u0 = 2.0;
  s.n = 0.2;
  EXPECT_NEAR(s(2.0), 0.8, 1e-15);  // e(u0) = e0
  EXPECT_NEAR(s(64.0), 1.0 - 0.2 * std::pow(32.0, 0.2), 1e-15);
  EXPECT_DOUBLE_EQ(s(0.0), 1.0);
  s.u0 = 1e-6;  // very fast impacts would give e < 0: clamped
  EXPECT_DOUBLE_EQ(s(1e6), 0.0);
  Restitution x;
  x.model = Restitution::Model::Exponential;
  x.C = 0.9;
  x.a = 0.1;
  EXPECT_NEAR(x(10.0), 0.9 * std::exp(-1.0), 1e-15);
  EXPECT_DOUBLE_EQ(mixed_restitution(c, x, 10.0), 0.5 * (0.7 + 0.9 * std::exp(-1.0)));
}

// A plane's picture is its cut by the box: the plane x + y + z = 1.5 through the unit cube's centre
// crosses six of its edges at their midpoints (a regular hexagon of side sqrt(2)/2); z = 0.25 cuts a
// unit square; x = 1 is the cube's face; a tilted line in 2D crosses the unit square at two points on the line.
TEST(WallPicture, PlaneCutByTheBox) {
  const Vec<3> lo = Vec<3>::Zero(), hi = Vec<3>::Ones();
  SurfaceMesh m;
  PlaneWall<3>(Vec<3>(0.5, 0.5, 0.5), Vec<3>(1, 1, 1).normalized()).tessellate(0.0, lo, hi, m);
  ASSERT_EQ(m.cells.size(), 1u);
  ASSERT_EQ(m.points.size(), 6u);
  for (std::size_t k = 0; k < 6; ++k) {
    const auto& p = m.points[m.cells[0][k]];
    const auto& q = m.points[m.cells[0][(k + 1) % 6]];
    EXPECT_NEAR(p[0] + p[1] + p[2], 1.5, 1e-15);
    // Consecutive corners of the ordered polygon are one side apart.
    EXPECT_NEAR(std::hypot(p[0] - q[0], p[1] - q[1], p[2] - q[2]), std::sqrt(0.5), 1e-14);
  }
  SurfaceMesh sq;
  PlaneWall<3>(Vec<3>(0.0, 0.0, 0.25), Vec<3>(0, 0, 1)).tessellate(0.0, lo, hi, sq);
  ASSERT_EQ(sq.points.size(), 4u);
  for (const auto& p : sq.points) EXPECT_EQ(p[2], 0.25);
  // A wall on a face of the box (the usual closed box): that face, its four corners once each.
  SurfaceMesh face;
  PlaneWall<3>(Vec<3>(1.0, 0.0, 0.0), Vec<3>(-1, 0, 0)).tessellate(0.0, lo, hi, face);
  ASSERT_EQ(face.points.size(), 4u);
  for (const auto& p : face.points) EXPECT_EQ(p[0], 1.0);
  SurfaceMesh seg;
  PlaneWall<2>(Vec<2>(0.5, 0.5), Vec<2>(1, 2).normalized()).tessellate(0.0, Vec<2>::Zero(), Vec<2>::Ones(), seg);
  ASSERT_EQ(seg.cells.size(), 1u);
  ASSERT_EQ(seg.points.size(), 2u);
  for (const auto& p : seg.points) {
    EXPECT_NEAR((p[0] - 0.5) + 2.0 * (p[1] - 0.5), 0.0, 1e-15);
    EXPECT_EQ(p[2], 0.0);
  }
}

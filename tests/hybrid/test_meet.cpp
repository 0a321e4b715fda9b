// When two grains in free flight meet (engine/hybrid/meet.hpp): the pair time against closed forms
// and against the quadratic solved in long double, and the early release's cell width against
// sampled pairs at the edge of its bound.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "contact/vec.hpp"
#include "engine/hybrid/meet.hpp"

namespace matep::hybrid {
namespace {

TEST(Meet, PairTimesOfClosedForm) {
  // Head on: centres 3 apart closing at 1, touching at 1 apart: s = 2.
  EXPECT_DOUBLE_EQ(meet_time<3>(Vec<3>(3.0, 0.0, 0.0), Vec<3>(-1.0, 0.0, 0.0), 1.0), 2.0);
  // Oblique: |(5 - s, 1)| = sqrt(2) first at s = 4.
  EXPECT_NEAR(meet_time<2>(Vec<2>(5.0, 1.0), Vec<2>(-1.0, 0.0), std::sqrt(2.0)), 4.0, 1e-14);
  // Passing by at an offset of 3 > 1: never; moving apart: never.
  EXPECT_EQ(meet_time<2>(Vec<2>(5.0, 3.0), Vec<2>(-1.0, 0.0), 1.0), kMeetNever);
  EXPECT_EQ(meet_time<2>(Vec<2>(5.0, 0.0), Vec<2>(1.0, 0.0), 1.0), kMeetNever);
  // Approaching while already touching: now.
  EXPECT_EQ(meet_time<2>(Vec<2>(0.9, 0.0), Vec<2>(-1.0, 0.0), 1.0), 0.0);
  // Within a horizon: the head-on pair meets within 2.5, not within 1.5; a touching pair that
  // moves apart touches now.
  EXPECT_TRUE(meet_within<3>(Vec<3>(3.0, 0.0, 0.0), Vec<3>(-1.0, 0.0, 0.0), 1.0, 2.5));
  EXPECT_FALSE(meet_within<3>(Vec<3>(3.0, 0.0, 0.0), Vec<3>(-1.0, 0.0, 0.0), 1.0, 1.5));
  EXPECT_TRUE(meet_within<2>(Vec<2>(0.9, 0.0), Vec<2>(1.0, 0.0), 1.0, 1e-12));
}

// Against the root of |u|^2 s^2 + 2 b s + c = 0 in long double, over separations from near touch to
// 1e4 diameters and speeds over six decades (the problem's own conditioning aside: near-grazing
// courses, where b^2 - |u|^2 c cancels, and gaps below 1e-6, where c = |r|^2 - sig^2 does).
TEST(Meet, PairTimeAgreesWithTheQuadraticInLongDouble) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  int tested = 0;
  for (int n = 0; n < 20000; ++n) {
    const double scale = std::pow(10.0, 4.0 * U(rng));
    const Vec<3> r = Vec<3>(U(rng), U(rng), U(rng)) * scale + Vec<3>(1.0, 0.0, 0.0);
    const Vec<3> u = Vec<3>(U(rng), U(rng), U(rng)) * std::pow(10.0, 3.0 * U(rng));
    const long double b = static_cast<long double>(r[0]) * u[0] + static_cast<long double>(r[1]) * u[1] +
                          static_cast<long double>(r[2]) * u[2];
    const long double uu = static_cast<long double>(u[0]) * u[0] + static_cast<long double>(u[1]) * u[1] +
                           static_cast<long double>(u[2]) * u[2];
    const long double c = static_cast<long double>(r[0]) * r[0] + static_cast<long double>(r[1]) * r[1] +
                          static_cast<long double>(r[2]) * r[2] - 1.0L;
    const long double disc = b * b - uu * c;
    const double s = meet_time<3>(r, u, 1.0);
    if (!(b < 0) || disc < 0) {
      ASSERT_EQ(s, kMeetNever);
      continue;
    }
    if (!(c > 1e-6L) || disc < 1e-6L * b * b) continue;
    const long double ref = (-b - std::sqrt(disc)) / uu;
    ++tested;
    ASSERT_NEAR(s, static_cast<double>(ref), 1e-9 * static_cast<double>(ref)) << "r " << r.transpose() << " u " << u.transpose();
  }
  EXPECT_GT(tested, 1000);
}

// Every pair that can meet within the horizon is closer than the cell width, and the sample reaches
// the bound's edge: pairs farther apart than the width with one speed's worth of travel (2 rmax +
// vmax horizon) do meet, so a width without the factor 2 on vmax would fail the first check.
TEST(Meet, CellWidthHoldsEveryPairThatCanMeet) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  const double rmax = 0.5, vmax = 2.0, horizon = 0.7;
  const double width = meet_cell_width(rmax, vmax, horizon);
  const double one_speed = 2.0 * rmax + vmax * horizon;
  int meet = 0, beyond_one_speed = 0;
  for (int n = 0; n < 200000; ++n) {
    const double Ra = rmax * (0.5 + 0.5 * U(rng)), Rb = rmax * (0.5 + 0.5 * U(rng));
    // Directions: mostly head on (the edge of the bound), some at random.
    const double th = 2.0 * std::numbers::pi * U(rng);
    const Vec<2> n_ab(std::cos(th), std::sin(th));
    const double d = (Ra + Rb) + 2.2 * vmax * horizon * U(rng);
    const Vec<2> r = n_ab * d;  // a - b
    auto velocity = [&](double toward) {
      const double sp = vmax * std::sqrt(U(rng));
      if (U(rng) < 0.7) return Vec<2>(n_ab * (toward * sp));
      const double ph = 2.0 * std::numbers::pi * U(rng);
      return Vec<2>(sp * std::cos(ph), sp * std::sin(ph));
    };
    const Vec<2> va = velocity(-1.0), vb = velocity(1.0);
    if (!meet_within<2>(r, Vec<2>(va - vb), Ra + Rb, horizon)) continue;
    ++meet;
    ASSERT_LT(r.norm(), width) << "a pair " << r.norm() << " apart meets within the horizon";
    if (r.norm() > one_speed) ++beyond_one_speed;
  }
  EXPECT_GT(meet, 10000);
  EXPECT_GT(beyond_one_speed, 100);
}

}  // namespace
}  // namespace matep::hybrid

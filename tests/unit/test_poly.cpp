// contact/poly.hpp: the earliest closing root of a polynomial, checked against polynomials built
// from known roots, p(t) = s prod_k (t - r_k) (times an always-positive quadratic where noted), so
// the expected answer is the smallest root where p goes from > 0 to <= 0 (or a touch from above).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "contact/poly.hpp"

namespace matep {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

Poly from_roots(const std::vector<double>& roots, double scale = 1.0) {
  Poly p{scale};
  for (double r : roots) p = p * Poly{-r, 1.0};
  return p;
}

TEST(Poly, ArithmeticAndHorner) {
  const Poly p = from_roots({1.0, 2.0, -3.0});  // t^3 - 7 t + 6
  EXPECT_EQ(p.n, 3);
  EXPECT_DOUBLE_EQ(p.c[0], 6.0);
  EXPECT_DOUBLE_EQ(p.c[1], -7.0);
  EXPECT_DOUBLE_EQ(p.c[2], 0.0);
  EXPECT_DOUBLE_EQ(p.c[3], 1.0);
  EXPECT_DOUBLE_EQ(p(4.0), 64.0 - 28.0 + 6.0);
  const Poly d = p.derivative();  // 3 t^2 - 7
  EXPECT_EQ(d.n, 2);
  EXPECT_DOUBLE_EQ(d(2.0), 5.0);
}

TEST(Poly, SimpleRootsGiveTheFirstDownCrossing) {
  // (t - 1)(t - 2)(t - 3): negative before 1 at t = 0 (-6), so p(0) <= 0 while increasing: no event
  // at 0; p rises through 1 (up), falls through 2 (down): the answer is 2.
  EXPECT_NEAR(earliest_closing(from_roots({1.0, 2.0, 3.0})), 2.0, 1e-15);
  // -(t - 1)(t - 2)(t - 3) is > 0 at 0 and falls through 1.
  EXPECT_NEAR(earliest_closing(from_roots({1.0, 2.0, 3.0}, -1.0)), 1.0, 1e-15);
  // Positive everywhere (no real roots): never.
  EXPECT_EQ(earliest_closing(Poly{1.0, 0.0, 1.0}), kInf);
  // Roots only before 0.
  EXPECT_EQ(earliest_closing(from_roots({-1.0, -2.0})), kInf);
  // A limit before the root.
  EXPECT_EQ(earliest_closing(from_roots({1.0, 2.0, 3.0}, -1.0), 0.9), kInf);
  EXPECT_NEAR(earliest_closing(from_roots({1.0, 2.0, 3.0}, -1.0), 1.1), 1.0, 1e-15);
}

TEST(Poly, RoundOffRulesAtZero) {
  // p(0) < 0 and decreasing: now.
  EXPECT_EQ(earliest_closing(Poly{-1e-17, -1.0}), 0.0);
  // p(0) = 0 and decreasing: now.
  EXPECT_EQ(earliest_closing(Poly{0.0, -1.0, 1.0}), 0.0);
  // p(0) < 0 and increasing, turning at t = 1 while still < 0: the turning point.
  // p = -1 + 2 t - t^2 - 1e-3 = -(t - 1)^2 - 1e-3.
  EXPECT_NEAR(earliest_closing(Poly{-1.001, 2.0, -1.0}), 1.0, 1e-15);
  // p(0) < 0 increasing through zero, then back down: the down-crossing.
  EXPECT_NEAR(earliest_closing(from_roots({-0.5, 0.25, 2.0}, -1.0)), 2.0, 1e-14);  // -(t+.5)(t-.25)(t-2)
}

TEST(Poly, DoubleAndClusteredRoots) {
  // A tangent touch: (t - 1.5)^2 (t + 1) (t + 2) touches zero at 1.5 from above.
  const double t = earliest_closing(from_roots({1.5, 1.5, -1.0, -2.0}));
  EXPECT_NEAR(t, 1.5, 1e-7);  // a double root is conditioned as sqrt(eps)
  // A touch that misses by 1e-12 (p = (t - 1.5)^2 + 1e-12, times a positive factor): never.
  const Poly miss = (from_roots({1.5, 1.5}) + Poly{1e-12}) * Poly{2.0, 0.0, 1.0};
  EXPECT_EQ(earliest_closing(miss), kInf);
  // A dip 1e-12 deep: two roots 2e-6 apart, the first one counts.
  const Poly dip = (from_roots({1.5, 1.5}) - Poly{1e-12}) * Poly{2.0, 0.0, 1.0};
  EXPECT_NEAR(earliest_closing(dip), 1.5 - 1e-6, 1e-9);  // p' = 2e-6 * 4.25: cond ~ 1e-16 * 30 / 1e-5
  // Clustered: (t - 1)(t - 1 - 1e-4)(t - 1 - 2e-4)(t - 3) is 3 at 0 and falls through 1 first;
  // p'(1) = 4e-8, so a coefficient round-off of 1e-16 * 20 moves the root by ~5e-8.
  EXPECT_NEAR(earliest_closing(from_roots({1.0, 1.0 + 1e-4, 1.0 + 2e-4, 3.0})), 1.0, 5e-7);
  // Its mirror is -3 at 0, rises through 1 and falls through 1 + 1e-4 (a dip 1e-12 deep).
  EXPECT_NEAR(earliest_closing(from_roots({1.0, 1.0 + 1e-4, 1.0 + 2e-4, 3.0}, -1.0)), 1.0 + 1e-4, 5e-7);
  // -(t - 1)(t - 1 - 1e-6)(t - 5)(t + 1) is 5 > 0 at 0 and falls through 1 first.
  EXPECT_NEAR(earliest_closing(from_roots({1.0, 1.0 + 1e-6, 5.0, -1.0}, -1.0)), 1.0, 1e-9);  // p'(1) = 8e-6
}

// Random degree-8 polynomials from known roots: up to 8 real roots (simple, near-double pairs
// r +- 1e-2 whose dip is well above round-off, clusters 1e-3 apart), the rest positive quadratics,
// some of them near misses (t - a)^2 + 9e-4, all in [-0.5, 2] (a scale where the monomial basis is
// well conditioned; the shapes refine their roots against the direct gap). An exact double root is
// not representable in rounded coefficients (it may become a complex pair), so exact touches are
// tested above on exact cases.
// The expected answer comes from the sorted roots and the sign of the leading coefficient.
TEST(Poly, RandomPolynomialsFromKnownRoots) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-0.5, 2.0), s(0.1, 3.0);
  std::uniform_int_distribution<int> nreal(0, 8), kind(0, 2);
  double worst = 0.0, worst_cond = 0.0;
  int missed = 0, found = 0, none = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    const int want = nreal(rng);
    std::vector<double> roots;
    while (static_cast<int>(roots.size()) < want) {
      const double r = u(rng);
      const int k = kind(rng);
      if (k == 0 || static_cast<int>(roots.size()) + 2 > want) {
        roots.push_back(r);
      } else if (k == 1) {
        roots.push_back(r - 1e-2);
        roots.push_back(r + 1e-2);
      } else {
        roots.push_back(r);
        roots.push_back(r + 1e-3 * s(rng));
      }
    }
    const int nr = static_cast<int>(roots.size());
    const double lead = (trial % 2) ? 1.0 : -1.0;
    Poly p = from_roots(roots, lead);
    for (int q = nr; q + 2 <= 8; q += 2) {  // positive quadratics (t - a)^2 + b^2
      const double a = u(rng), b = (q % 4 == 0) ? 3e-2 : s(rng);
      p = p * Poly{a * a + b * b, -2.0 * a, 1.0};
    }
    std::sort(roots.begin(), roots.end());
    auto sign_at = [&](double t) {  // sign of p: the quadratics are positive
      double sg = lead;
      for (double r : roots) sg *= (t - r) > 0 ? 1.0 : -1.0;
      return sg;
    };
    if (sign_at(0.0) < 0.0) continue;  // p(0) < 0: the rules at 0 are tested on exact cases above
    double expected = kInf;
    for (double r : roots)
      if (r > 0.0 && sign_at(r - 1e-9) > 0.0 && sign_at(r + 1e-9) < 0.0) {
        expected = r;
        break;
      }
    const double got = earliest_closing(p);
    if (expected == kInf) {
      ++none;
      if (got != kInf) ++missed;
      continue;
    }
    if (got == kInf) {
      ++missed;
      continue;
    }
    ++found;
    // First-order conditioning of the root in rounded coefficients: eps sum |c_k| r^k / |p'(r)|.
    double mag = 0.0;
    for (int k = 0; k <= p.n; ++k) mag += std::abs(p.c[k]) * std::pow(expected, k);
    const double cond = 2.2e-16 * mag / std::abs(p.derivative()(expected));
    worst_cond = std::max(worst_cond, std::abs(got - expected) / cond);
    worst = std::max(worst, std::abs(got - expected) / std::max(1.0, expected));
  }
  EXPECT_EQ(missed, 0);
  EXPECT_GT(found, 3000);
  EXPECT_GT(none, 1000);
  // Within a few times the first-order conditioning of each root in rounded coefficients.
  EXPECT_LT(worst_cond, 16.0) << "worst error in units of the root's conditioning " << worst_cond;
  std::printf("poly: %d found, %d without a closing root, worst error %.3g (%.3g x conditioning)\n", found, none,
              worst, worst_cond);
}

}  // namespace
}  // namespace matep

// Outlet regions (contact/outlet.hpp): the entry time of a flight against a long-double scan of
// the region's own inside test, for half spaces, boxes and cylinders (2D disks), straight and
// under gravity; closed forms for a few flights.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "contact/outlet.hpp"

namespace matep {
namespace {

template <int D>
using VecL = Eigen::Matrix<long double, D, 1>;

// The region's inside test in long double on the exact flight (independent of the polynomials).
template <int D>
struct RegionLD {
  int kind = 0;  // 0 half space, 1 box, 2 cylinder
  Vec<D> p, q, a;
  double r = 0.0, L = 0.0;
  // The largest constraint value (< 0 inside).
  long double worst(const VecL<D>& x) const {
    const VecL<D> P = p.template cast<long double>();
    if (kind == 0) return (x - P).dot(a.template cast<long double>());
    if (kind == 1) {
      long double w = -INFINITY;
      for (int k = 0; k < D; ++k) w = std::max({w, (long double)p[k] - x[k], x[k] - (long double)q[k]});
      return w;
    }
    const VecL<D> rr = x - P;
    if constexpr (D == 3) {
      const VecL<D> A = a.template cast<long double>();
      const long double z = rr.dot(A);
      return std::max({(rr - z * A).squaredNorm() - (long double)r * r, -z, z - (long double)L});
    }
    return rr.squaredNorm() - (long double)r * r;
  }
};

// The earliest t in [0, T] with worst < 0: a scan of 20 000 steps, then bisection to 1e-18.
template <int D>
long double reference_entry(const RegionLD<D>& reg, const Vec<D>& x, const Vec<D>& v, const Vec<D>& g, long double T) {
  const VecL<D> X = x.template cast<long double>(), V = v.template cast<long double>(), G = g.template cast<long double>();
  auto at = [&](long double t) { return reg.worst(VecL<D>(X + t * V + 0.5L * t * t * G)); };
  if (at(0) < 0) return 0;
  const int n = 20000;
  long double prev = 0;
  for (int k = 1; k <= n; ++k) {
    const long double t = T * k / n;
    if (at(t) < 0) {
      long double lo = prev, hi = t;
      for (int it = 0; it < 200; ++it) {
        const long double mid = 0.5L * (lo + hi);
        (at(mid) < 0 ? hi : lo) = mid;
      }
      return hi;
    }
    prev = t;
  }
  return INFINITY;
}

template <int D>
Vec<D> random_vec(std::mt19937_64& rng, double s) {
  std::normal_distribution<double> nd(0.0, s);
  Vec<D> u;
  for (int k = 0; k < D; ++k) u[k] = nd(rng);
  return u;
}

template <int D>
void check_kind(int kind, bool gravity, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  int hits = 0, n = 0;
  double worst = 0.0;
  for (int c = 0; c < 1000; ++c) {
    RegionLD<D> reg;
    reg.kind = kind;
    reg.p = random_vec<D>(rng, 0.3);
    OutletRegion<D> o = OutletRegion<D>::half_space(reg.p, Vec<D>::Ones());
    if (kind == 0) {
      reg.a = random_vec<D>(rng, 1.0).normalized();
      o = OutletRegion<D>::half_space(reg.p, reg.a);
    } else if (kind == 1) {
      reg.q = reg.p + Vec<D>::Constant(0.4) + 0.8 * random_vec<D>(rng, 1.0).cwiseAbs();
      o = OutletRegion<D>::box(reg.p, reg.q);
    } else {
      reg.a = random_vec<D>(rng, 1.0).normalized();
      reg.r = 0.2 + 0.4 * u(rng);
      reg.L = 0.4 + 0.8 * u(rng);
      o = OutletRegion<D>::cylinder(reg.p, reg.a, reg.r, reg.L);
    }
    const Vec<D> x = random_vec<D>(rng, 1.0), v = random_vec<D>(rng, 1.0);
    const Vec<D> g = gravity ? random_vec<D>(rng, 3.0) : Vec<D>::Zero();
    const double T = 2.0;
    long double ref = reference_entry<D>(reg, x, v, g, T);
    const double got = o.entry_time(x, v, g, T);
    if (!(ref <= T) && got < T) {
      // A clip through an edge or corner can be shorter than the scan's step: scan finely from
      // the reported time over one step; the reference then stands if that finds no inside.
      const long double step = T / 20000.0L;
      RegionLD<D> r2 = reg;
      const Vec<D> x2 = x + got * v + 0.5 * got * got * g, v2 = v + got * g;
      const long double sub = reference_entry<D>(r2, x2, v2, g, step);
      if (sub <= step) ref = got + sub;
    }
    ++n;
    if (!(ref <= T)) {
      EXPECT_FALSE(got < T) << "case " << c << ": no entry before " << T << ", got " << got;
      continue;
    }
    ++hits;
    if (ref == 0) {
      EXPECT_EQ(got, 0.0) << "case " << c;
      continue;
    }
    const double err = std::abs(got - (double)ref) / std::max((double)ref, 1e-3);
    worst = std::max(worst, err);
    EXPECT_LE(err, 1e-10) << "case " << c << ": ref " << (double)ref << " got " << got;
  }
  std::printf("outlet region kind %d, %dD, %s: %d flights, %d enter, worst error %.3g\n", kind, D,
              gravity ? "gravity" : "straight", n, hits, worst);
  EXPECT_GT(hits, n / 20);
}

TEST(OutletRegion, EntryTimesMatchAnExtendedPrecisionScan) {
  for (const bool grav : {false, true}) {
    for (int kind = 0; kind < 3; ++kind) {
      check_kind<3>(kind, grav, 11 + kind + 3 * grav);
      check_kind<2>(kind, grav, 31 + kind + 3 * grav);
    }
  }
}

TEST(OutletRegion, ClosedFormFlights) {
  // Falling from rest at height 1 onto the half space z < 0: t = sqrt(2 / g).
  const auto hs = OutletRegion<3>::half_space(Vec<3>::Zero(), Vec<3>(0, 0, 1));
  EXPECT_NEAR(hs.entry_time(Vec<3>(0, 0, 1), Vec<3>::Zero(), Vec<3>(0, 0, -9.81), 10.0), std::sqrt(2.0 / 9.81), 1e-15);
  // A straight flight along x into the box [1, 2] x [-1, 1]^2 at speed 2 from 0: t = 0.5.
  const auto bx = OutletRegion<3>::box(Vec<3>(1, -1, -1), Vec<3>(2, 1, 1));
  EXPECT_NEAR(bx.entry_time(Vec<3>::Zero(), Vec<3>(2, 0, 0), Vec<3>::Zero(), 10.0), 0.5, 1e-15);
  // Passing beside the box: never; inside now: 0.
  EXPECT_EQ(bx.entry_time(Vec<3>(0, 2, 0), Vec<3>(2, 0, 0), Vec<3>::Zero(), 10.0),
            std::numeric_limits<double>::infinity());
  EXPECT_EQ(bx.entry_time(Vec<3>(1.5, 0, 0), Vec<3>(2, 0, 0), Vec<3>::Zero(), 10.0), 0.0);
  // Down the axis of a cylinder below z = 0 (axis -z, radius 0.1, length 1) from z = 0.5 at rest:
  // enters at z = 0, t = sqrt(2 * 0.5 / g).
  const auto cy = OutletRegion<3>::cylinder(Vec<3>::Zero(), Vec<3>(0, 0, -1), 0.1, 1.0);
  EXPECT_NEAR(cy.entry_time(Vec<3>(0, 0, 0.5), Vec<3>::Zero(), Vec<3>(0, 0, -9.81), 10.0), std::sqrt(1.0 / 9.81),
              1e-15);
  // The limit: an entry at 0.5 is not reported with limit 0.4.
  EXPECT_EQ(bx.entry_time(Vec<3>::Zero(), Vec<3>(2, 0, 0), Vec<3>::Zero(), 0.4),
            std::numeric_limits<double>::infinity());
  // No limit (an event-driven prediction with nothing else ahead): falling from z = 0.8 across the
  // side of a cylinder along x (axis at z = 0.1, radius 0.1): enters at z = 0.2, t = sqrt(2 * 0.6 / g).
  // The quartic's roots are searched up to their root bound, not over (0, 1e30).
  const auto side = OutletRegion<3>::cylinder(Vec<3>(0.2, 0.5, 0.1), Vec<3>(1, 0, 0), 0.1, 0.6);
  for (const double limit : {1.0, std::numeric_limits<double>::infinity()})
    EXPECT_NEAR(side.entry_time(Vec<3>(0.5, 0.5, 0.8), Vec<3>::Zero(), Vec<3>(0, 0, -9.81), limit),
                std::sqrt(1.2 / 9.81), 1e-15);
  // The region meets a box (a grain inside the box can reach it) or not.
  const Vec<3> lo = Vec<3>::Zero(), up = Vec<3>::Ones();
  EXPECT_TRUE(OutletRegion<3>::half_space(Vec<3>(0, 0, 0.1), Vec<3>(0, 0, 1)).meets_box(lo, up));
  EXPECT_FALSE(OutletRegion<3>::half_space(Vec<3>(0, 0, 0), Vec<3>(0, 0, 1)).meets_box(lo, up));
  EXPECT_FALSE(OutletRegion<3>::half_space(Vec<3>(0, 0, -0.5), Vec<3>(1, 1, 1)).meets_box(lo, up));
  EXPECT_TRUE(OutletRegion<3>::box(Vec<3>(0.9, 0.9, 0.9), Vec<3>(2, 2, 2)).meets_box(lo, up));
  EXPECT_FALSE(OutletRegion<3>::box(Vec<3>(1, 0, 0), Vec<3>(2, 1, 1)).meets_box(lo, up));
  EXPECT_TRUE(OutletRegion<3>::cylinder(Vec<3>(0.5, 0.5, -1), Vec<3>(0, 0, 1), 0.1, 1.05).meets_box(lo, up));
  EXPECT_FALSE(OutletRegion<3>::cylinder(Vec<3>(0.5, 0.5, -1), Vec<3>(0, 0, 1), 0.1, 0.95).meets_box(lo, up));
  // Bad parameters are refused.
  EXPECT_THROW(OutletRegion<3>::half_space(Vec<3>::Zero(), Vec<3>::Zero()), std::invalid_argument);
  EXPECT_THROW(OutletRegion<3>::box(Vec<3>::Zero(), Vec<3>(1, 0, 1)), std::invalid_argument);
  EXPECT_THROW(OutletRegion<3>::cylinder(Vec<3>::Zero(), Vec<3>(0, 0, 1), -1.0, 1.0), std::invalid_argument);
  EXPECT_THROW(OutletRegion<3>::cylinder(Vec<3>::Zero(), Vec<3>(0, 0, 1), 1.0, 0.0), std::invalid_argument);
}

}  // namespace
}  // namespace matep

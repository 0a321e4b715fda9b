// Checking a wall shape's impact_time against the extended-precision reference
// (tests/support/impact_reference.hpp) over many random flights, and the long-double geometry the
// references use (independent of the shapes' own code: distances written from scratch here).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <string>

#include <gtest/gtest.h>

#include "contact/predict.hpp"
#include "contact/vec.hpp"
#include "tests/support/impact_reference.hpp"

namespace matep::test {

template <int D>
using VecL = Eigen::Matrix<long double, D, 1>;

template <int D>
VecL<D> to_ld(const Vec<D>& v) {
  return v.template cast<long double>();
}

// Distance in the meridian half-plane from (z, rho) to the segment (0, r1)-(L, r2), long double.
inline long double segment_distance(long double z, long double rho, long double r1, long double r2, long double L) {
  const long double dz = L, dr = r2 - r1;
  long double tau = (z * dz + (rho - r1) * dr) / (dz * dz + dr * dr);
  tau = std::clamp(tau, 0.0L, 1.0L);
  return std::hypot(z - tau * dz, rho - (r1 + tau * dr));
}

// (z, rho) of point x about the axis through p along unit a (a = 0: rho = |x - p|).
template <int D>
void meridian(const VecL<D>& x, const VecL<D>& p, const VecL<D>& a, long double& z, long double& rho) {
  const VecL<D> r = x - p;
  z = r.dot(a);
  rho = (r - z * a).norm();
}

// One random flight: start x (clear of the wall), velocity v, gravity g, radius R.
template <int D>
struct FlightCase {
  Vec<D> x, v, g;
  double R = 0.0;
};

struct ImpactStats {
  int cases = 0, hits = 0, missed = 0, early = 0, late = 0;
  double worst = 0.0;  // worst |got - ref| / max(ref, floor)
  std::string worst_case;
  void print(const char* name) const {
    std::printf("%s: %d flights, %d hits, worst error %.3g, missed %d, early %d, late %d\n", name, cases, hits, worst,
                missed, early, late);
  }
};

// Adds one batch's counts to a total, keeping the worst case (or one that failed).
inline void merge(ImpactStats& total, const ImpactStats& s) {
  total.cases += s.cases;
  total.hits += s.hits;
  total.missed += s.missed;
  total.early += s.early;
  if (s.worst > total.worst || s.missed + s.early > 0) {
    total.worst = std::max(total.worst, s.worst);
    total.worst_case = s.worst_case;
  }
}

// As merge, but the first failing case is the one kept.
inline void merge_keep_first(ImpactStats& total, const ImpactStats& s) {
  total.cases += s.cases;
  total.hits += s.hits;
  total.missed += s.missed;
  total.early += s.early;
  if (s.worst > total.worst || (s.missed + s.early > 0 && total.worst_case.empty())) {
    total.worst = std::max(total.worst, s.worst);
    total.worst_case = s.worst_case;
  }
}

// Runs n flights from gen(rng) (which must return a start with a positive gap) through
// impact_time(x, v, g, R) and the reference earliest_closing_root on gap_ld(x(t), R) up to t_max.
// A reference root within t_max must be matched within rel_tol (relative, absolute below `floor`);
// no reference root: impact_time must not answer before t_max.
template <int D, class Impact, class GapLD, class Gen>
ImpactStats check_impacts(Impact&& impact, GapLD&& gap_ld, Gen&& gen, int n, double t_max, double rel_tol,
                          std::uint64_t seed, int steps = 2000, double floor = 1e-3) {
  std::mt19937_64 rng(seed);
  ImpactStats s;
  for (int k = 0; k < n; ++k) {
    const FlightCase<D> c = gen(rng);
    const VecL<D> x = to_ld<D>(c.x), v = to_ld<D>(c.v), g = to_ld<D>(c.g);
    const long double R = c.R;
    auto gap = [&](long double t) { return gap_ld(VecL<D>(x + t * v + 0.5L * t * t * g), R); };
    const long double ref = earliest_closing_root(gap, t_max, steps);
    const double got = impact(c.x, c.v, c.g, c.R);
    ++s.cases;
    const bool ref_hit = ref <= t_max;
    if (ref_hit) ++s.hits;
    const double tol = rel_tol * std::max(static_cast<double>(ref_hit ? ref : t_max), floor);
    char buf[400];
    if (ref_hit) {
      const double err = std::abs(got - static_cast<double>(ref));
      if (!(got <= static_cast<double>(ref) + tol)) ++s.missed;
      else if (got < static_cast<double>(ref) - tol) ++s.early;
      const double rel = err / std::max(static_cast<double>(ref), floor);
      if (!(rel <= s.worst)) {
        s.worst = std::isfinite(rel) ? std::max(rel, s.worst) : 1e300;
        std::snprintf(buf, sizeof buf, "case %d: ref %.17Lg got %.17g", k, ref, got);
        s.worst_case = buf;
      }
    } else if (got < t_max - tol) {
      ++s.early;
      std::snprintf(buf, sizeof buf, "case %d: no reference root before %g, got %.17g", k, t_max, got);
      s.worst_case = buf;
    }
  }
  return s;
}

template <int D>
Vec<D> random_unit(std::mt19937_64& rng) {
  std::normal_distribution<double> nd(0.0, 1.0);
  Vec<D> u;
  do {
    for (int k = 0; k < D; ++k) u[k] = nd(rng);
  } while (u.norm() < 1e-3);
  return u.normalized();
}

// The time in [0, t_max] where gap_ld along the flight c is smallest (dense scan, then golden
// section around the best sample), and that gap.
template <int D, class GapLD>
long double flight_minimum(const FlightCase<D>& c, GapLD&& gap_ld, long double t_max, long double& gmin,
                           int steps = 2000) {
  const VecL<D> x = to_ld<D>(c.x), v = to_ld<D>(c.v), g = to_ld<D>(c.g);
  auto gap = [&](long double t) { return gap_ld(VecL<D>(x + t * v + 0.5L * t * t * g), (long double)c.R); };
  const long double h = t_max / steps;
  int best = 0;
  long double gb = gap(0);
  for (int k = 1; k <= steps; ++k) {
    const long double gk = gap(k * h);
    if (gk < gb) {
      gb = gk;
      best = k;
    }
  }
  long double a = std::max(0.0L, (best - 1) * h), b = std::min(t_max, (best + 1) * h);
  const long double r = 0.6180339887498948482L;
  long double p = b - r * (b - a), q = a + r * (b - a), gp = gap(p), gq = gap(q);
  for (int it = 0; it < 120; ++it) {
    if (gp < gq) {
      b = q;
      q = p;
      gq = gp;
      p = b - r * (b - a);
      gp = gap(p);
    } else {
      a = p;
      p = q;
      gp = gq;
      q = a + r * (b - a);
      gq = gap(q);
    }
  }
  const long double t = 0.5L * (a + b);
  gmin = gap(t);
  return t;
}

// A grazing flight made from c: the whole path is shifted along the wall normal at its closest
// approach (normal(x): the shape's unit normal towards a particle at x) until the smallest gap is
// `miss` (> 0: passes clear by that much; < 0: dips in by that much). Newton steps on the shift
// (the gap's gradient is the normal); false if the closest approach is not an interior smooth
// minimum of [0, t_window] or the start would not be clear.
template <int D, class GapLD, class Normal>
bool make_graze(FlightCase<D>& c, GapLD&& gap_ld, Normal&& normal, double t_window, double miss) {
  for (int it = 0; it < 6; ++it) {
    long double gmin;
    const long double T = flight_minimum<D>(c, gap_ld, t_window, gmin);
    if (!(T > 0.02L * t_window && T < 0.98L * t_window)) return false;
    const double err = static_cast<double>(gmin - miss);
    if (std::abs(err) <= 1e-4 * std::abs(miss)) {
      const VecL<D> x0 = to_ld<D>(c.x);
      return gap_ld(x0, (long double)c.R) > 10.0L * std::abs(miss);
    }
    const double Td = static_cast<double>(T);
    const Vec<D> xT = c.x + Td * c.v + 0.5 * Td * Td * c.g;
    c.x -= err * normal(xT, c.R);
  }
  return false;
}

// impact_time with a finite limit (the engine passes its earliest event so far; the shapes are
// bracketed()): the same time when it lies before the limit, kNever when not.
template <class S, int D>
void expect_limit_consistent(const S& shape, const Vec<D>& x, const Vec<D>& v, const Vec<D>& g, double R, double t) {
  if (t < kNever && t > 0.0) {
    EXPECT_NEAR(shape.impact_time(x, v, g, R, 0.0, t * (1.0 + 1e-6)), t, 1e-12 * t);
    EXPECT_EQ(shape.impact_time(x, v, g, R, 0.0, t * (1.0 - 1e-6)), kNever);
  } else if (!(t < kNever)) {
    EXPECT_EQ(shape.impact_time(x, v, g, R, 0.0, 2.0), kNever);
  }
}

}  // namespace matep::test

// The reference for wall impact times: the earliest closing root of a gap function, found by a
// dense scan in extended precision (long double) with every sampled local minimum refined by a
// golden-section search, so a grazing dip below zero between two samples is not missed. Slow and
// simple on purpose: it checks the engines' closed forms and bracketings, it is not one of them.
#pragma once

#include <cmath>
#include <limits>

namespace matep::test {

// Earliest t in [0, t_max] at which gap(t) reaches zero from above (gap(0) > 0 assumed), refined
// by bisection to the round-off of long double; infinity if none. gap: long double -> long double.
// steps: the number of scan intervals (each interval must hold at most one local minimum of gap
// for a grazing dip to be found: choose it from the motion's time scales).
template <class Gap>
long double earliest_closing_root(Gap&& gap, long double t_max, int steps = 20000) {
  const long double inf = std::numeric_limits<long double>::infinity();
  auto refine = [&](long double a, long double b) {  // gap(a) > 0 >= gap(b)
    for (int k = 0; k < 200 && b - a > 0; ++k) {
      const long double m = 0.5L * (a + b);
      if (!(m > a && m < b)) break;
      if (gap(m) > 0) a = m;
      else b = m;
    }
    return b;
  };
  const long double h = t_max / steps;
  long double t0 = 0, g0 = gap(t0);
  if (!(g0 > 0)) return 0;
  long double gprev = inf;
  for (int k = 1; k <= steps; ++k) {
    const long double t1 = k * h, g1 = gap(t1);
    if (!(g1 > 0)) return refine(t0, t1);
    // A sampled local minimum around t0: search [t0 - h, t1] for a dip below zero.
    if (g0 <= gprev && g0 <= g1 && k > 1) {
      long double a = t0 - h, b = t1;
      const long double r = 0.6180339887498948482L;
      long double c = b - r * (b - a), d = a + r * (b - a), gc = gap(c), gd = gap(d);
      for (int it = 0; it < 200 && b - a > 0; ++it) {
        if (!(gc > 0)) return refine(a, c);
        if (!(gd > 0)) return refine(a, d);
        if (gc < gd) {
          b = d;
          d = c;
          gd = gc;
          c = b - r * (b - a);
          gc = gap(c);
        } else {
          a = c;
          c = d;
          gc = gd;
          d = a + r * (b - a);
          gd = gap(d);
        }
        if (!(c < d)) break;
      }
    }
    gprev = g0;
    t0 = t1;
    g0 = g1;
  }
  return inf;
}

}  // namespace matep::test

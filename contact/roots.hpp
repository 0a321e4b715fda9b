// Bracketed root finding shared by the contact layer.
#pragma once

#include <cmath>

namespace matep {

// Root of f on [a, b] with f(a) > 0 >= f(b), by regula falsi with the Illinois modification
// (Dowell & Jarratt, BIT 11, 168 (1971)): the retained end's value is halved when the same end
// is kept twice, which restores superlinear convergence. Stops when the bracket is shorter than
// abs_tol, when |f| <= f_tol, or after max_it steps; returns the last point on the f <= 0 side
// (b if none was found).
template <class F>
double illinois_root(F&& f, double a, double fa, double b, double fb, double abs_tol, int max_it,
                     double f_tol = 0.0) {
  int side = 0;
  for (int it = 0; it < max_it && b - a > abs_tol; ++it) {
    const double x = (a * fb - b * fa) / (fb - fa);
    if (!(x > a && x < b)) break;
    const double fx = f(x);
    if (fx > 0.0) {
      a = x;
      fa = fx;
      if (side == 1) fb *= 0.5;
      side = 1;
    } else {
      b = x;
      fb = fx;
      if (side == -1) fa *= 0.5;
      side = -1;
    }
    if (std::abs(fx) <= f_tol) return x;
  }
  return b;
}

}  // namespace matep

// When two grains in free flight relative to each other meet: the hybrid's coasts (the last
// substep before two soft grains touch) and the lookahead's early release (whether two candidates
// could meet within its window, and which pairs need the test at all).
#pragma once

#include <cmath>
#include <limits>

#include "contact/vec.hpp"

namespace matep::hybrid {

inline constexpr double kMeetNever = std::numeric_limits<double>::infinity();

// When two grains at separation r (centres) with constant relative velocity u first touch (their
// centres sig apart): the first root of |r + u s| = sig, s >= 0, in the form without cancellation
// s = c / (-b + sqrt(b^2 - |u|^2 c)) (b = r.u, c = |r|^2 - sig^2; the smaller root of
// |u|^2 s^2 + 2 b s + c = 0, Allen & Tildesley's pair time); kMeetNever when they move apart or
// pass each other, 0 when they approach already touching.
template <int D>
double meet_time(const Vec<D>& r, const Vec<D>& u, double sig) {
  const double b = r.dot(u);
  if (!(b < 0.0)) return kMeetNever;
  const double c = r.squaredNorm() - sig * sig;
  if (!(c > 0.0)) return 0.0;
  const double disc = b * b - u.squaredNorm() * c;
  return disc < 0.0 ? kMeetNever : c / (-b + std::sqrt(disc));
}

// Whether they touch now or within the time `horizon`.
template <int D>
bool meet_within(const Vec<D>& r, const Vec<D>& u, double sig, double horizon) {
  return r.squaredNorm() - sig * sig <= 0.0 || meet_time<D>(r, u, sig) < horizon;
}

// The width of cells in which every pair of grains (radii at most rmax, speeds at most vmax) that
// can meet within `horizon` lies in neighbouring cells: |r + u s| = R_a + R_b for some s < horizon
// needs |r| < R_a + R_b + |u| horizon <= 2 rmax + 2 vmax horizon (the triangle inequality, with
// |u| <= 2 vmax); a relative 1e-9 more for the round-off of the cell index.
inline double meet_cell_width(double rmax, double vmax, double horizon) {
  return (2.0 * rmax + 2.0 * vmax * horizon) * (1.0 + 1e-9);
}

}  // namespace matep::hybrid

// Inlets ([inlet.NAME]): regions where new grains enter the run at a steady rate. Grain k of an
// inlet is due at t_k = start + k / rate (k = 0, 1, ...) while t_k < min(stop, end_time) and
// k < count; the engines reserve one particle id per due grain (System::slots) and insert each at
// its time at a random place in the region where it overlaps no grain, wall or outlet, drawing its
// radius uniformly in [rmin, rmax] and its velocity as velocity + spread * (a standard normal per
// component). A grain that finds no free place in kAttempts tries is missed: the rate that could
// not be met is reported (RunResult::inlets), never made up later.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <type_traits>
#include <string>
#include <vector>

#include "contact/vec.hpp"

namespace matep {

template <int D>
struct Inlet {
  enum class Shape { Box, Cylinder };
  std::string name;
  Shape shape = Shape::Box;
  Vec<D> lower = Vec<D>::Zero(), upper = Vec<D>::Zero();  // box
  // Cylinder: from point along the unit axis for length (0: a disk of the plane through point
  // normal to the axis); 2D: the segment of half-length radius through point normal to axis
  // (length 0), or the rectangle it sweeps along the axis.
  Vec<D> point = Vec<D>::Zero(), axis = Vec<D>::Zero();
  double radius = 0.0, length = 0.0;
  int material = 0;
  double rmin = 0.0, rmax = 0.0;
  double rate = 0.0;  // grains per second
  Vec<D> velocity = Vec<D>::Zero();
  double spread = 0.0;  // standard deviation of each velocity component
  double start = 0.0, stop = std::numeric_limits<double>::infinity();
  std::uint64_t count = std::numeric_limits<std::uint64_t>::max();
  std::uint64_t seed = 1;

  static constexpr int kAttempts = 64;

  double slot_time(std::uint64_t k) const { return start + static_cast<double>(k) / rate; }

  // The number of grains due in a run that ends at end_time: the k with slot_time(k) < min(stop,
  // end_time) and k < count.
  std::uint64_t slots(double end_time) const {
    const double T = std::min(stop, end_time);
    if (!(T > start) || !(rate > 0.0)) return 0;
    double n = std::ceil((T - start) * rate);
    if (!(n < 1e15)) return std::min<std::uint64_t>(count, 1000000000000000ULL);  // more than any run numbers
    auto k = static_cast<std::uint64_t>(n);
    while (k > 0 && !(slot_time(k - 1) < T)) --k;
    while (slot_time(k) < T) ++k;
    return std::min(k, count);
  }

  // A random point of the region.
  template <class Rng>
  Vec<D> sample_point(Rng& rng) const {
    std::uniform_real_distribution<double> u(0.0, 1.0);
    if (shape == Shape::Box) {
      Vec<D> x;
      for (int k = 0; k < D; ++k) x[k] = lower[k] + u(rng) * (upper[k] - lower[k]);
      return x;
    }
    // Two unit vectors normal to the axis (3D), one (2D).
    Vec<D> x = point + (length > 0.0 ? u(rng) * length : 0.0) * axis;
    if constexpr (D == 3) {
      const Vec<3> a = axis;
      const Vec<3> e1 = (std::abs(a[0]) < 0.9 ? Vec<3>(1, 0, 0) : Vec<3>(0, 1, 0)).cross(a).normalized();
      const Vec<3> e2 = a.cross(e1);
      const double r = radius * std::sqrt(u(rng)), phi = 2.0 * std::acos(-1.0) * u(rng);
      x += r * (std::cos(phi) * e1 + std::sin(phi) * e2);
    } else {
      const Vec<2> e(-axis[1], axis[0]);
      x += (2.0 * u(rng) - 1.0) * radius * e;
    }
    return x;
  }
  template <class Rng>
  double sample_radius(Rng& rng) const {
    if (rmax == rmin) return rmin;
    return std::uniform_real_distribution<double>(rmin, rmax)(rng);
  }
  template <class Rng>
  Vec<D> sample_velocity(Rng& rng) const {
    Vec<D> v = velocity;
    if (spread > 0.0) {
      std::normal_distribution<double> n(0.0, spread);
      for (int k = 0; k < D; ++k) v[k] += n(rng);
    }
    return v;
  }
};

// The grains due from all inlets of a run ending at end_time (the ids the engines reserve after the
// initial particles).
template <int D>
std::uint64_t inlet_slots(const std::vector<Inlet<D>>& inlets, double end_time) {
  std::uint64_t n = 0;
  for (const auto& in : inlets) n += in.slots(end_time);
  return n;
}

// What a run reports per inlet.
struct InletReport {
  std::string name;
  std::uint64_t due = 0, inserted = 0, missed = 0;
};

// One inlet's schedule in a run: the next grain due, its random stream, and the figures reported.
template <int D>
struct InletClock {
  const Inlet<D>* inlet = nullptr;
  std::uint64_t next = 0, slots = 0;  // next grain due, grains due in the run
  std::uint64_t inserted = 0, missed = 0;
  std::mt19937_64 rng;

  InletClock(const Inlet<D>& in, std::size_t index, double end_time)
      : inlet(&in), slots(in.slots(end_time)), rng(in.seed * 0x9e3779b97f4a7c15ULL + index + 1) {}
  bool pending() const { return next < slots; }
  // Checkpoints (engine/state_archive.hpp): what changes as grains are drawn.
  template <class A>
  void archive(A& a) {
    static_assert(std::is_trivially_copyable_v<std::mt19937_64>);
    a(next);
    a(slots);
    a(inserted);
    a(missed);
    a(rng);
  }
  InletReport report() const { return {inlet->name, slots, inserted, missed}; }
  double next_time() const { return inlet->slot_time(next); }

  // Draws grain `next`: its radius and velocity, then up to kAttempts places until free(x, R) holds.
  // Returns whether it found one (x, R, v set); either way the grain is no longer due.
  template <class Free>
  bool draw(Free&& free, Vec<D>& x, double& R, Vec<D>& v) {
    ++next;
    R = inlet->sample_radius(rng);
    v = inlet->sample_velocity(rng);
    for (int a = 0; a < Inlet<D>::kAttempts; ++a) {
      x = inlet->sample_point(rng);
      if (free(x, R)) {
        ++inserted;
        return true;
      }
    }
    ++missed;
    return false;
  }
};


}  // namespace matep

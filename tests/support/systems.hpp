// Test helpers: ready-made systems built without a scene file.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "engine/edm.hpp"
#include "engine/result.hpp"
#include "engine/system.hpp"

namespace matep::test {

// The largest difference of two runs' final velocities and surface spin speeds R w, relative to
// the largest of them in a (two runs of one system that should agree: e.g. with a list rebuilt
// every step and built once).
template <int D>
double relative_state_difference(const RunResult<D>& a, const RunResult<D>& b) {
  double d = 0.0, scale = 0.0;
  for (std::size_t i = 0; i < a.v.size(); ++i) {
    const double R = a.radius[i];
    d = std::max({d, (a.v[i] - b.v[i]).norm(), R * (a.w[i] - b.w[i]).norm()});
    scale = std::max({scale, a.v[i].norm(), R * a.w[i].norm()});
  }
  return d / scale;
}

// A material with the linear spring-dashpot law: stiffness k [N/m], constant restitution e.
inline Material linear_material(const std::string& name, double density, double k, double e) {
  Material m;
  m.name = name;
  m.density = density;
  m.contact = "linear";
  m.stiffness = k;
  m.restitution = Restitution::constant(e);
  return m;
}

// A periodic box of n^D unit-diameter, unit-mass particles on a simple cubic / square lattice
// at packing fraction phi, Maxwellian velocities rescaled to temperature T exactly and zero
// total momentum, constant restitution e.
template <int D>
System<D> lattice_gas(int n_side, double phi, double T, double e, std::uint64_t seed) {
  System<D> s;
  const double r = 0.5;
  const int N = static_cast<int>(std::pow(n_side, D));
  const double vol_one = ball_volume<D>(r);
  const double L = std::pow(N * vol_one / phi, 1.0 / D);
  s.lower = Vec<D>::Zero();
  s.upper = Vec<D>::Constant(L);
  s.periodic.fill(true);
  Material m;
  m.name = "grain";
  m.density = 1.0 / vol_one;  // unit mass
  m.restitution = Restitution::constant(e);
  s.materials.push_back(m);
  const double a = L / n_side;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  Vec<D> ptot = Vec<D>::Zero();
  for (int i = 0; i < N; ++i) {
    Vec<D> x;
    int k = i;
    for (int d = 0; d < D; ++d) {
      x[d] = (k % n_side + 0.5) * a;
      k /= n_side;
    }
    Vec<D> v;
    for (int d = 0; d < D; ++d) v[d] = gauss(rng);
    s.x.push_back(x);
    s.v.push_back(v);
    s.radius.push_back(r);
    s.material.push_back(0);
    ptot += v;
  }
  double mv2 = 0.0;
  for (auto& v : s.v) {
    v -= ptot / N;
    mv2 += v.squaredNorm();
  }
  const double scale = std::sqrt(T * D * N / mv2);
  for (auto& v : s.v) v *= scale;
  return s;
}

// Contact value of g(r) (Carnahan-Starling 3D, Henderson 2D) and the compressibility factor.
inline double g_contact(int d, double phi) {
  return d == 3 ? (1.0 - phi / 2.0) / std::pow(1.0 - phi, 3)
                : (1.0 - 7.0 * phi / 16.0) / std::pow(1.0 - phi, 2);
}
inline double Z_eos(int d, double phi) {
  return d == 3 ? (1.0 + phi + phi * phi - phi * phi * phi) / std::pow(1.0 - phi, 3)
                : (1.0 + phi * phi / 8.0) / std::pow(1.0 - phi, 2);
}
// Enskog collision frequency per particle for sigma = m = 1 (docs/references.md §2.1).
inline double enskog_rate(int d, double phi, double T) {
  return (d == 3 ? 24.0 : 8.0) * phi * g_contact(d, phi) / std::sqrt(std::numbers::pi) * std::sqrt(T);
}

// Whether two arrays hold the same bytes (a run repeated, resumed or re-sorted: bit for bit).
template <class T>
bool same_bits(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

// Records every observer callback.
template <int D>
struct Recorder : Observer<D> {
  bool collisions = true;
  std::vector<CollisionRecord<D>> records;
  std::vector<ThermoSample> samples;
  bool wants_collisions() const override { return collisions; }
  void on_collision(const CollisionRecord<D>& r) override { records.push_back(r); }
  void on_sample(const ThermoSample& s) override { samples.push_back(s); }
};

}  // namespace matep::test

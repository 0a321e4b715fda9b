// Random test inputs.
#pragma once

#include <random>

#include "contact/vec.hpp"

namespace matep::test {

// A direction uniformly distributed on the unit sphere (circle in 2D).
template <int D>
Vec<D> random_unit(std::mt19937_64& rng) {
  std::normal_distribution<double> g;
  Vec<D> v;
  for (int k = 0; k < D; ++k) v[k] = g(rng);
  return v.normalized();
}

}  // namespace matep::test

// Vectors and spins as three components for the file formats (2D: z = 0, the disk spin in z).
#pragma once

#include "contact/vec.hpp"

namespace matep {

template <int D>
void to3(const Vec<D>& v, double* out) {
  out[0] = v[0];
  out[1] = v[1];
  out[2] = D == 3 ? v[D - 1] : 0.0;
}

template <int D>
void spin3(const Spin<D>& w, double* out) {
  if constexpr (D == 2) {
    out[0] = 0.0;
    out[1] = 0.0;
    out[2] = w[0];
  } else {
    out[0] = w[0];
    out[1] = w[1];
    out[2] = w[2];
  }
}

}  // namespace matep

// Small fixed-size vectors: Vec<D> for positions and velocities, Spin<D> for angular velocity
// (a scalar in 2D, a 3-vector in 3D).
#pragma once

#include <Eigen/Core>

namespace matep {

template <int D>
using Vec = Eigen::Matrix<double, D, 1>;

template <int D>
using Spin = Eigen::Matrix<double, (D == 2 ? 1 : 3), 1>;

}  // namespace matep

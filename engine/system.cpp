// Out-of-line members of System<D> and the ball volume (explicitly instantiated for D = 2, 3).
#include "engine/system.hpp"

#include <numbers>

namespace matep {

template <int D>
double ball_volume(double r) {
  static_assert(D == 2 || D == 3, "only 2D and 3D systems exist");
  if constexpr (D == 2) {
    return std::numbers::pi * r * r;
  } else {
    return 4.0 / 3.0 * std::numbers::pi * r * r * r;
  }
}

template <int D>
double System<D>::mass(std::size_t i) const {
  return materials[static_cast<std::size_t>(material[i])].density * ball_volume<D>(radius[i]);
}

template double ball_volume<2>(double);
template double ball_volume<3>(double);
template double System<2>::mass(std::size_t) const;
template double System<3>::mass(std::size_t) const;

}  // namespace matep

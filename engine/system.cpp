// Out-of-line members of System<D> and the ball volume (explicitly instantiated for D = 2, 3).
#include "engine/system.hpp"

#include <fmt/format.h>

#include <numbers>
#include <stdexcept>

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

template <int D>
void System<D>::check_fixed() const {
  if (fixed.empty()) return;
  if (fixed.size() != size())
    throw std::invalid_argument(
        fmt::format("System::fixed has {} flags for {} particles (empty or one per particle)", fixed.size(), size()));
  for (std::size_t i = 0; i < size(); ++i) {
    if (!fixed[i]) continue;
    const bool spins = !w.empty() && !w[i].isZero(0.0);
    if (!v[i].isZero(0.0) || spins)
      throw std::invalid_argument(fmt::format(
          "particle {} is fixed but has a nonzero {}: a fixed grain does not move", i, spins ? "spin" : "velocity"));
  }
}

template double ball_volume<2>(double);
template double ball_volume<3>(double);
template double System<2>::mass(std::size_t) const;
template double System<3>::mass(std::size_t) const;
template void System<2>::check_fixed() const;
template void System<3>::check_fixed() const;

}  // namespace matep

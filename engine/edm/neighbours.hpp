// Which pair candidates the event-driven core tests (EdmSettings::neighbours): the 3^D cells
// around a particle, or its neighbour list (engine/edm/core.hpp "neighbour lists").
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

namespace matep::edm {

// The packing fraction from which neighbour lists beat the cells in a gas without gravity
// (bench/README.md "Neighbour lists"): elastic spheres, N = 32 768, one core, 0.125-diameter
// shells, after a lattice melts: over 10 collisions per particle 0.78 x the cells' collision rate
// at packing 0.367; over 64-128 about 1.0 x at 0.445 and 1.11 x at 0.497.
inline constexpr double kListsFromPacking = 0.45;

// Whether "auto" chooses lists: a gas of moving grains at least this dense (their volume over the
// domain's), without gravity (under gravity the shells are cubes, which lost to the cells in both
// gases measured, packing 0.26 and 0.445).
inline bool lists_pay(double packing, bool gravity) { return !gravity && packing >= kListsFromPacking; }
// A list entry holds its partner's index and image shift in one 32-bit word (engine/edm/core.hpp
// nb_), the index in the low kListIdBits bits: lists serve runs of up to kListsUpTo particle slots.
inline constexpr unsigned kListIdBits = 27;
inline constexpr std::size_t kListsUpTo = (std::size_t{1} << kListIdBits) - 1;
// Whether a run of n particle slots takes the lists: asked for (run.neighbours = "lists"), or
// "auto" where they pay; never above kListsUpTo (the cells then).
inline bool lists_chosen(bool lists, bool automatic, double packing, bool gravity, std::size_t n) {
  return n <= kListsUpTo && (lists || (automatic && lists_pay(packing, gravity)));
}

// Re-sorting the particles' storage in space (engine/edm/core.hpp "re-sorting"): from how many
// particles, below which packing, and how often (particle events per particle between two
// re-sorts) "auto" does it. Elastic spheres, one core, 40 collisions per particle after the lattice
// melts, re-sorted every 32 against the lattice's rows (bench/README.md "Re-sorting the EDM
// storage", medians of three alternated pairs): at N = 1 000 000, 0.89 x the time per collision at
// rho sigma^3 = 0.5 (packing 0.26; 0.88 from a shuffled start) but 1.06 x at 0.85 (packing 0.445,
// where the grains stay near their start); the Z order from the start gained nothing measurable at
// 262 144 or 32 768.
inline constexpr int kResortFrom = 500000;
inline constexpr double kResortBelowPacking = 0.35;
inline constexpr double kResortEvery = 32.0;
// The interval "auto" (resort < 0) gives a run of n particles whose moving grains fill `packing`
// of the domain; 0 = never.
inline double resort_interval(double resort, std::size_t n, double packing) {
  if (resort >= 0.0) return resort;
  return n >= static_cast<std::size_t>(kResortFrom) && packing < kResortBelowPacking ? kResortEvery : 0.0;
}

// The hybrid's run.resort: "auto" (< 0) is never. It starts in space order (engine/renumber.hpp),
// and re-sorting a million-grain gas every 8 events per particle made it 1.08-1.17 x slower (0.62 s
// a re-sort against EDM's 0.23 s: it permutes its own arrays too; bench/README.md "Re-sorting the
// EDM storage").
inline double hybrid_resort(double resort) { return resort < 0.0 ? 0.0 : resort; }

// The Z (Morton) order's key of a cell's coordinates (each below 2^21 in 3D, 2^32 in 2D): their
// bits interleaved, axis 0 lowest, so that cells near in space are mostly near in the order
// (Morton 1966; the shift-and-mask spreading of each coordinate's bits is the standard one).
template <int D>
inline std::uint64_t morton_key(const std::array<std::uint32_t, D>& c) {
  std::uint64_t key = 0;
  for (int k = 0; k < D; ++k) {
    std::uint64_t x = c[k];
    if constexpr (D == 3) {
      x &= 0x1fffff;
      x = (x | x << 32) & 0x1f00000000ffffULL;
      x = (x | x << 16) & 0x1f0000ff0000ffULL;
      x = (x | x << 8) & 0x100f00f00f00f00fULL;
      x = (x | x << 4) & 0x10c30c30c30c30c3ULL;
      x = (x | x << 2) & 0x1249249249249249ULL;
    } else {
      x &= 0xffffffffULL;
      x = (x | x << 16) & 0x0000ffff0000ffffULL;
      x = (x | x << 8) & 0x00ff00ff00ff00ffULL;
      x = (x | x << 4) & 0x0f0f0f0f0f0f0f0fULL;
      x = (x | x << 2) & 0x3333333333333333ULL;
      x = (x | x << 1) & 0x5555555555555555ULL;
    }
    key |= x << k;
  }
  return key;
}

// The interval "auto" (resort < 0) gives a run of n particles; 0 = never.
inline double resort_interval(double resort, std::size_t n) {
  if (resort >= 0.0) return resort;
  return n >= static_cast<std::size_t>(kResortFrom) ? kResortEvery : 0.0;
}

}  // namespace matep::edm

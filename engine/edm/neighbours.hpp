// Which pair candidates the event-driven core tests (EdmSettings::neighbours): the 3^D cells
// around a particle, or its neighbour list (engine/edm/core.hpp "neighbour lists").
#pragma once

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

}  // namespace matep::edm

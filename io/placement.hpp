// Initial particle placement for scenes: a uniform overlap grid (minimum image on periodic
// axes), plane-wall checks, random sequential placement with a bounded number of trials,
// simple cubic / square lattices, and Maxwellian velocities with an exact group temperature.
// Nothing here reads TOML or throws SceneError; io/scene.cpp turns results into messages.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <random>
#include <vector>

#include "engine/system.hpp"
#include "contact/vec.hpp"

namespace matep::placement {

// Deterministic, portable random numbers: std::mt19937_64 seeded through std::seed_seq from
// (seed, stream) and hand-written uniform / normal transforms (the std distributions are
// implementation-defined).
class Rng {
 public:
  Rng(std::uint64_t seed, std::uint64_t stream);
  double uniform();                   // [0, 1)
  double uniform(double a, double b); // [a, b)
  double normal();                    // standard normal (Box-Muller)

 private:
  std::mt19937_64 gen_;
  bool has_spare_ = false;
  double spare_ = 0.0;
};

// Uniform grid over the domain for O(1) overlap queries. Cells are at least `min_cell` wide
// (use the largest diameter that will ever be stored or queried); the number of cells is capped
// (cells grow) so that a huge domain with few particles stays small.
template <int D>
class OverlapGrid {
 public:
  struct Hit {
    std::size_t tag;   // as given to insert()
    Vec<D> x;
    double r;
    double distance;   // minimum-image centre distance
  };

  OverlapGrid(const Vec<D>& lower, const Vec<D>& upper, const std::array<bool, D>& periodic,
              double min_cell, std::size_t expected);

  void insert(const Vec<D>& x, double r, std::size_t tag);
  // Some stored particle j with distance < (r + r_j) * (1 - rel_tol), if any.
  std::optional<Hit> first_overlap(const Vec<D>& x, double r, double rel_tol = 0.0) const;
  // Minimum-image separation vector on periodic axes.
  Vec<D> min_image(Vec<D> d) const;
  std::size_t size() const { return entries_.size(); }

 private:
  struct Entry {
    Vec<D> x;
    double r;
    std::size_t tag;
    std::int64_t next;
  };
  std::array<std::int64_t, D> cell_of(const Vec<D>& x) const;
  std::size_t flat(const std::array<std::int64_t, D>& c) const;

  Vec<D> lower_, upper_, length_, cell_;
  std::array<bool, D> periodic_;
  std::array<std::int64_t, D> n_{};
  bool hashed_ = false;       // a mostly empty domain: cells of min_cell stored in hash buckets
  std::uint64_t mask_ = 0;
  std::vector<std::int64_t> head_;
  std::vector<Entry> entries_;
};

// Index of some wall whose surface is nearer than r * (1 - rel_tol) to x at t = 0 (signed: negative
// behind it), and that distance.
template <int D>
std::optional<std::pair<std::size_t, double>> wall_overlap(const std::vector<Wall<D>>& walls,
                                                          const Vec<D>& x, double r,
                                                          double rel_tol = 0.0);

// Random sequential placement of particles with the given radii in [region_lower, region_upper]:
// fully inside the region on non-periodic axes (centre within [lower + r, upper - r]), centre
// inside it on periodic ones; no overlap with anything in `grid` or with a wall. Placed
// particles are inserted into `grid` with tags first_tag, first_tag + 1, ... Stops after
// max_attempts trials in total, or earlier once the recent cost per placed particle shows that
// the rest cannot be placed within that budget.
struct RandomPlacement {
  std::size_t placed = 0;
  std::uint64_t attempts = 0;
  bool gave_up_early = false;  // stopped before max_attempts (budget would not suffice)
};
template <int D>
RandomPlacement place_random(OverlapGrid<D>& grid, const std::vector<Wall<D>>& walls,
                             const Vec<D>& region_lower, const Vec<D>& region_upper,
                             const std::array<bool, D>& periodic, const std::vector<double>& radius,
                             std::size_t first_tag, std::uint64_t max_attempts, Rng& rng,
                             std::vector<Vec<D>>& x);

// Simple cubic (3D) / square (2D) lattice in a region: n[k] sites along axis k at
// lower + (i + 0.5) * L_k / n[k]; the largest spacing a with prod floor(L_k / a) >= count.
template <int D>
struct Lattice {
  std::array<std::int64_t, D> n{};
  double spacing = 0.0;  // min_k L_k / n[k]
  double sites() const;
  // Site `index` in lexicographic order with the first axis fastest and the last axis slowest
  // (layers of constant last coordinate fill from the bottom up).
  Vec<D> site(const Vec<D>& lower, const Vec<D>& upper, std::uint64_t index) const;
};
template <int D>
Lattice<D> lattice_for(const Vec<D>& lower, const Vec<D>& upper, std::uint64_t count);

// Maxwellian velocities at temperature T (variance T / m per component), then zero total
// momentum (mass-weighted mean removed; skipped for a single particle, which could not keep any
// velocity otherwise), then rescaled so that (1/N) sum m v^2 / D == T exactly. T = 0 gives zeros.
template <int D>
void thermal_velocities(const std::vector<double>& mass, double T, Rng& rng, std::vector<Vec<D>>& v);

// (1/N) sum m v^2 / D.
template <int D>
double group_temperature(const std::vector<double>& mass, const std::vector<Vec<D>>& v);

}  // namespace matep::placement

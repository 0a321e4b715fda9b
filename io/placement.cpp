#include "io/placement.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "engine/grid.hpp"

namespace matep::placement {

// ------------------------------------------------------------------------------------- Rng

Rng::Rng(std::uint64_t seed, std::uint64_t stream) {
  std::seed_seq seq{static_cast<std::uint32_t>(seed), static_cast<std::uint32_t>(seed >> 32),
                    static_cast<std::uint32_t>(stream), static_cast<std::uint32_t>(stream >> 32),
                    0x6d617465u};
  gen_.seed(seq);
}

double Rng::uniform() { return static_cast<double>(gen_() >> 11) * 0x1.0p-53; }

double Rng::uniform(double a, double b) { return a + (b - a) * uniform(); }

double Rng::normal() {
  if (has_spare_) {
    has_spare_ = false;
    return spare_;
  }
  const double u1 = 1.0 - uniform();  // (0, 1]
  const double u2 = uniform();
  const double rho = std::sqrt(-2.0 * std::log(u1));
  const double th = 2.0 * std::numbers::pi * u2;
  spare_ = rho * std::sin(th);
  has_spare_ = true;
  return rho * std::cos(th);
}

// ----------------------------------------------------------------------------- OverlapGrid

template <int D>
OverlapGrid<D>::OverlapGrid(const Vec<D>& lower, const Vec<D>& upper, const std::array<bool, D>& periodic,
                            double min_cell, std::size_t expected)
    : lower_(lower), upper_(upper), length_(upper - lower), periodic_(periodic) {
  double cell = (min_cell > 0.0 && std::isfinite(min_cell)) ? min_cell : length_.maxCoeff();
  const double cap = static_cast<double>(std::max<std::size_t>(4 * expected, std::size_t{1} << 12));
  // A mostly empty domain (more than eight times the cells the grains need): cells of min_cell in a
  // hash table of about 4 buckets per grain (as engine/grid.hpp), instead of cells coarsened until
  // each holds many grains.
  {
    double natural = 1.0;
    for (int k = 0; k < D; ++k) natural *= std::max(1.0, std::min(length_[k] / cell, 1e15));
    if (natural > 8.0 * cap) {
      hashed_ = true;
      std::uint64_t b = 1;
      while (static_cast<double>(b) < cap) b *= 2;
      mask_ = b - 1;
      for (int k = 0; k < D; ++k) {
        n_[k] = std::max<std::int64_t>(1, static_cast<std::int64_t>(std::min(length_[k] / cell, 1e15)));
        cell_[k] = length_[k] / static_cast<double>(n_[k]);
      }
      head_.assign(b, -1);
      entries_.reserve(expected);
      return;
    }
  }
  for (;;) {
    double total = 1.0;
    for (int k = 0; k < D; ++k) {
      n_[k] = std::max<std::int64_t>(1, static_cast<std::int64_t>(std::min(length_[k] / cell, 1e15)));
      total *= static_cast<double>(n_[k]);
    }
    if (total <= cap) break;
    cell *= 1.25;
  }
  for (int k = 0; k < D; ++k) cell_[k] = length_[k] / static_cast<double>(n_[k]);
  std::size_t total = 1;
  for (int k = 0; k < D; ++k) total *= static_cast<std::size_t>(n_[k]);
  head_.assign(total, -1);
  entries_.reserve(expected);
}

template <int D>
std::array<std::int64_t, D> OverlapGrid<D>::cell_of(const Vec<D>& x) const {
  std::array<std::int64_t, D> c{};
  for (int k = 0; k < D; ++k) {
    const double f = std::floor((x[k] - lower_[k]) / cell_[k]);
    std::int64_t i = static_cast<std::int64_t>(std::clamp(f, -1e15, 1e15));
    if (periodic_[k]) {
      i %= n_[k];
      if (i < 0) i += n_[k];
    } else {
      i = std::clamp<std::int64_t>(i, 0, n_[k] - 1);
    }
    c[k] = i;
  }
  return c;
}

template <int D>
std::size_t OverlapGrid<D>::flat(const std::array<std::int64_t, D>& c) const {
  if (hashed_) return static_cast<std::size_t>(cell_hash(c) & mask_);  // engine/grid.hpp
  std::size_t f = 0;
  for (int k = D - 1; k >= 0; --k) f = f * static_cast<std::size_t>(n_[k]) + static_cast<std::size_t>(c[k]);
  return f;
}

template <int D>
Vec<D> OverlapGrid<D>::min_image(Vec<D> d) const {
  for (int k = 0; k < D; ++k) {
    if (periodic_[k]) d[k] -= length_[k] * std::round(d[k] / length_[k]);
  }
  return d;
}

template <int D>
void OverlapGrid<D>::insert(const Vec<D>& x, double r, std::size_t tag) {
  const std::size_t f = flat(cell_of(x));
  entries_.push_back(Entry{x, r, tag, head_[f]});
  head_[f] = static_cast<std::int64_t>(entries_.size() - 1);
}

template <int D>
std::optional<typename OverlapGrid<D>::Hit> OverlapGrid<D>::first_overlap(const Vec<D>& x, double r,
                                                                          double rel_tol) const {
  if (entries_.empty()) return std::nullopt;
  const auto c = cell_of(x);
  // Neighbour cell indices per axis, without repeats (an axis may have fewer than 3 cells).
  std::array<std::array<std::int64_t, 3>, D> nb{};
  std::array<int, D> cnt{};
  for (int k = 0; k < D; ++k) {
    for (const int o : {0, -1, 1}) {  // own cell first: a failing trial usually stops there
      std::int64_t i = c[k] + o;
      if (periodic_[k]) {
        i = (i % n_[k] + n_[k]) % n_[k];
      } else if (i < 0 || i >= n_[k]) {
        continue;
      }
      bool seen = false;
      for (int s = 0; s < cnt[k]; ++s) seen = seen || nb[k][s] == i;
      if (!seen) nb[k][cnt[k]++] = i;
    }
  }
  std::array<int, D> it{};
  for (;;) {
    std::array<std::int64_t, D> cc{};
    for (int k = 0; k < D; ++k) cc[k] = nb[k][it[k]];
    for (std::int64_t e = head_[flat(cc)]; e >= 0; e = entries_[e].next) {
      const Entry& en = entries_[e];
      const double dist = min_image(x - en.x).norm();
      if (dist < (r + en.r) * (1.0 - rel_tol)) return Hit{en.tag, en.x, en.r, dist};
    }
    int k = 0;
    while (k < D && ++it[k] == cnt[k]) it[k++] = 0;
    if (k == D) break;
  }
  return std::nullopt;
}

// ----------------------------------------------------------------------------------- walls

template <int D>
std::optional<std::pair<std::size_t, double>> wall_overlap(const std::vector<Wall<D>>& walls, const Vec<D>& x,
                                                          double r, double rel_tol) {
  for (std::size_t w = 0; w < walls.size(); ++w) {
    const double s = walls[w].geometry().at(x, r, 0.0).gap + r;  // centre's distance to the surface
    if (s < r * (1.0 - rel_tol)) return std::make_pair(w, s);
  }
  return std::nullopt;
}

// ---------------------------------------------------------------------------------- random

template <int D>
RandomPlacement place_random(OverlapGrid<D>& grid, const std::vector<Wall<D>>& walls, const Vec<D>& region_lower,
                             const Vec<D>& region_upper, const std::array<bool, D>& periodic,
                             const std::vector<double>& radius, std::size_t first_tag,
                             std::uint64_t max_attempts, Rng& rng, std::vector<Vec<D>>& x) {
  RandomPlacement res;
  const std::size_t N = radius.size();
  x.assign(N, Vec<D>::Zero());
  // Attempts used when each particle was placed, for the early give-up below.
  std::vector<std::uint64_t> used;
  used.reserve(N + 1);
  used.push_back(0);
  const std::size_t window = std::clamp<std::size_t>(N / 50, 20, 2000);
  for (std::size_t i = 0; i < N; ++i) {
    // The acceptance rate of random sequential placement only falls as the region fills, so the
    // recent cost per particle is a lower bound on the cost of each remaining one. Give up as
    // soon as that bound (with a margin for noise) no longer fits in the remaining budget.
    if (i >= 20) {
      const std::size_t w = std::min(window, i);
      const double rate = static_cast<double>(used[i] - used[i - w]) / static_cast<double>(w);
      const double remaining = static_cast<double>(max_attempts - std::min(max_attempts, res.attempts));
      if (rate * static_cast<double>(N - i) > 2.0 * remaining) {
        res.gave_up_early = true;
        return res;
      }
    }
    const double r = radius[i];
    Vec<D> lo = region_lower, hi = region_upper;
    for (int k = 0; k < D; ++k) {
      if (!periodic[k]) {
        lo[k] += r;
        hi[k] -= r;
      }
    }
    bool done = false;
    while (!done) {
      if (res.attempts >= max_attempts) return res;
      ++res.attempts;
      Vec<D> p;
      for (int k = 0; k < D; ++k) {
        p[k] = rng.uniform(lo[k], hi[k]);
        if (!periodic[k]) p[k] = std::clamp(p[k], lo[k], hi[k]);
      }
      if (wall_overlap<D>(walls, p, r)) continue;
      if (grid.first_overlap(p, r)) continue;
      grid.insert(p, r, first_tag + i);
      x[i] = p;
      done = true;
    }
    ++res.placed;
    used.push_back(res.attempts);
  }
  return res;
}

// --------------------------------------------------------------------------------- lattice

namespace {

template <int D>
double lattice_sites(const Vec<D>& L, double a) {
  double total = 1.0;
  for (int k = 0; k < D; ++k) total *= std::floor(L[k] / a * (1.0 + 1e-12));
  return total;
}

}  // namespace

template <int D>
double Lattice<D>::sites() const {
  double total = 1.0;
  for (int k = 0; k < D; ++k) total *= static_cast<double>(n[k]);
  return total;
}

template <int D>
Vec<D> Lattice<D>::site(const Vec<D>& lower, const Vec<D>& upper, std::uint64_t index) const {
  Vec<D> p;
  for (int k = 0; k < D; ++k) {
    const auto nk = static_cast<std::uint64_t>(n[k]);
    const auto i = index % nk;
    index /= nk;
    p[k] = lower[k] + (static_cast<double>(i) + 0.5) * (upper[k] - lower[k]) / static_cast<double>(n[k]);
  }
  return p;
}

template <int D>
Lattice<D> lattice_for(const Vec<D>& lower, const Vec<D>& upper, std::uint64_t count) {
  const Vec<D> L = upper - lower;
  const double want = static_cast<double>(std::max<std::uint64_t>(count, 1));
  // a_lo holds at least `want` sites, a_hi fewer (or exactly the largest possible spacing).
  const double m = std::ceil(std::pow(want, 1.0 / D)) + 1.0;
  double a_lo = L.minCoeff() / m;
  double a_hi = L.maxCoeff() * 2.0;
  for (int iter = 0; iter < 200 && a_hi - a_lo > 1e-15 * a_hi; ++iter) {
    const double mid = 0.5 * (a_lo + a_hi);
    if (lattice_sites<D>(L, mid) >= want) {
      a_lo = mid;
    } else {
      a_hi = mid;
    }
  }
  Lattice<D> lat;
  lat.spacing = std::numeric_limits<double>::infinity();
  for (int k = 0; k < D; ++k) {
    lat.n[k] = std::max<std::int64_t>(1, static_cast<std::int64_t>(std::floor(L[k] / a_lo * (1.0 + 1e-12))));
    lat.spacing = std::min(lat.spacing, L[k] / static_cast<double>(lat.n[k]));
  }
  return lat;
}

// ------------------------------------------------------------------------------ velocities

template <int D>
double group_temperature(const std::vector<double>& mass, const std::vector<Vec<D>>& v) {
  if (v.empty()) return 0.0;
  double s = 0.0;
  for (std::size_t i = 0; i < v.size(); ++i) s += mass[i] * v[i].squaredNorm();
  return s / (static_cast<double>(v.size()) * D);
}

template <int D>
void thermal_velocities(const std::vector<double>& mass, double T, Rng& rng, std::vector<Vec<D>>& v) {
  const std::size_t N = mass.size();
  v.assign(N, Vec<D>::Zero());
  if (N == 0 || !(T > 0.0)) return;
  for (int tries = 0; tries < 100; ++tries) {
    for (std::size_t i = 0; i < N; ++i) {
      const double s = std::sqrt(T / mass[i]);
      for (int k = 0; k < D; ++k) v[i][k] = s * rng.normal();
    }
    if (N > 1) {
      Vec<D> p = Vec<D>::Zero();
      double M = 0.0;
      for (std::size_t i = 0; i < N; ++i) {
        p += mass[i] * v[i];
        M += mass[i];
      }
      const Vec<D> mean = p / M;
      for (auto& vi : v) vi -= mean;
    }
    const double now = group_temperature<D>(mass, v);
    if (now > 0.0 && std::isfinite(now)) {
      const double f = std::sqrt(T / now);
      for (auto& vi : v) vi *= f;
      return;
    }
  }
  v.assign(N, Vec<D>::Zero());  // unreachable in practice
}

// ------------------------------------------------------------------------ instantiations

#define MATEP_PLACEMENT_INSTANTIATE(D)                                                                     \
  template class OverlapGrid<D>;                                                                           \
  template std::optional<std::pair<std::size_t, double>> wall_overlap<D>(const std::vector<Wall<D>>&,      \
                                                                         const Vec<D>&, double, double);   \
  template RandomPlacement place_random<D>(OverlapGrid<D>&, const std::vector<Wall<D>>&, const Vec<D>&,    \
                                           const Vec<D>&, const std::array<bool, D>&,                      \
                                           const std::vector<double>&, std::size_t, std::uint64_t, Rng&,   \
                                           std::vector<Vec<D>>&);                                          \
  template struct Lattice<D>;                                                                              \
  template Lattice<D> lattice_for<D>(const Vec<D>&, const Vec<D>&, std::uint64_t);                         \
  template double group_temperature<D>(const std::vector<double>&, const std::vector<Vec<D>>&);            \
  template void thermal_velocities<D>(const std::vector<double>&, double, Rng&, std::vector<Vec<D>>&);

MATEP_PLACEMENT_INSTANTIATE(2)
MATEP_PLACEMENT_INSTANTIATE(3)

#undef MATEP_PLACEMENT_INSTANTIATE

}  // namespace matep::placement

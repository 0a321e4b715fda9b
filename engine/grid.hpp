// The one cell grid of the engines: the EDM core's cells (filled as linked lists, kept up to date at
// every cell crossing), the hybrid's soft-set list builds and TDM's list builds (both filled by a
// counting sort). The grid fixes the cell geometry, the coarsening, the walk over the cells around
// a cell with the periodic wrap, and TDM's half stencil; the fills are the engines' own.
//
// The periodic-axis rule, the same for every method: a periodic axis holds at least three cells of
// the neighbour cut-off (the largest diameter plus the method's list skin; EDM: no skin), so that a
// particle never meets two images of one neighbour. check_periodic_axes states it with one message.
#pragma once

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "contact/vec.hpp"

namespace matep {

// Throws std::invalid_argument ("domain.upper: periodic axis x is L long, ...") when a periodic
// axis holds fewer than three cells of the neighbour cut-off (largest diameter dmax plus the list
// skin), counted as CellGrid::build counts them.
template <int D>
void check_periodic_axes(const Vec<D>& lower, const Vec<D>& upper, const std::array<bool, D>& periodic, double dmax,
                         double skin) {
  const double cut = dmax + skin, need = 3.0 * cut;
  for (int k = 0; k < D; ++k) {
    const double L = upper[k] - lower[k];
    if (periodic[k] && !(std::floor(L / cut) >= 3.0))
      throw std::invalid_argument(fmt::format(
          "domain.upper: periodic axis {} is {} long, shorter than three times the largest diameter {} plus the "
          "neighbour skin {} ({}); enlarge the domain (got [{}])",
          "xyz"[k], L, dmax, skin, need, fmt::join(upper, ", ")));
  }
}

// The one message of a particle that leaves the domain across a closed axis with no wall there
// (status "escaped"), for every method.
inline std::string escape_message(std::uint64_t id, int axis, double t, double x) {
  return fmt::format("particle {} left the domain along axis {} at t = {:.17g} (position {:.6g}); add a wall there "
                     "or make the axis periodic",
                     id, axis, t, x);
}

// The periodic wrap of a coordinate into [lo, hi) (a position rounding onto the upper face maps
// to lo).
inline double wrap_periodic(double x, double lo, double hi) {
  const double L = hi - lo;
  double y = lo + (x - lo) - L * std::floor((x - lo) / L);
  if (y >= hi) y = lo;
  return y;
}

// A hashed cell's key: its (non-negative) coordinates mixed by a multiply-xorshift finaliser (after
// splitmix64); the caller masks it to its table's power-of-two size (CellGrid, placement's grid).
template <class Int, std::size_t N>
std::uint64_t cell_hash(const std::array<Int, N>& c) {
  std::uint64_t h = 0;
  for (std::size_t k = 0; k < N; ++k) h = (h ^ static_cast<std::uint64_t>(c[k])) * 0x9E3779B97F4A7C15ull;
  h ^= h >> 31;
  h *= 0xBF58476D1CE4E5B9ull;
  h ^= h >> 27;
  return h;
}

template <int D>
class CellGrid {
 public:
  static constexpr int kStencil = D == 3 ? 27 : 9;

  // Cells at least `width` wide over [lo, hi] (on a periodic axis: the domain, wrapped). When that
  // makes more than max_cells cells: coarsened uniformly (by 0.8 per round; a periodic axis keeps
  // three cells) until there are at most max_cells, or, with `hash` and more than kHashFactor
  // times max_cells (a mostly empty domain: a pipe, a tall hopper), kept at their width and stored
  // in a hash table of at least max_cells buckets (spatial hashing, Teschner et al., VMV 2003):
  // memory then grows with the grains, not with the domain's volume, and the cells stay narrow.
  // Returns false when a periodic axis has fewer than three cells of `width`.
  static constexpr double kHashFactor = 8.0;
  // The number of cells of at least `width` over [lo, hi] before any coarsening or hashing.
  static double natural_cells(const Vec<D>& lo, const Vec<D>& hi, double width, double max_per_axis = 1 << 20) {
    double total = 1.0;
    for (int k = 0; k < D; ++k)
      total *= width > 0.0 ? std::max(1.0, std::min(max_per_axis, std::floor((hi[k] - lo[k]) / width))) : 1.0;
    return total;
  }
  bool build(const Vec<D>& lo, const Vec<D>& hi, const std::array<bool, D>& periodic, double width, double max_cells,
             double max_per_axis = 1 << 20, bool hash = false) {
    lo_ = lo;
    len_ = hi - lo;
    periodic_ = periodic;
    hashed_ = false;
    bool ok = true;
    double total = 1.0;
    for (int k = 0; k < D; ++k) {
      int n = width > 0.0 ? static_cast<int>(std::min(max_per_axis, std::floor(len_[k] / width))) : 1;
      n = std::max(1, n);
      ok = ok && !(periodic_[k] && n < 3);
      n_[k] = n;
      w_[k] = len_[k] / n;
      total *= n;
    }
    if (hash && total > kHashFactor * max_cells) {
      hashed_ = true;
      std::uint64_t b = 64;
      while (static_cast<double>(b) < max_cells) b *= 2;
      mask_ = b - 1;
      cells_ = static_cast<int>(b);
      for (int k = 0; k < D; ++k) stride_[k] = 0;  // no linear layout
      offsets_all_.clear();
      for (auto& l : offsets_layer_) l.clear();
      return ok;
    }
    for (;;) {
      total = 1.0;
      for (int k = 0; k < D; ++k) total *= n_[k];
      if (total <= max_cells) break;
      for (int k = 0; k < D; ++k) {
        n_[k] = std::max(periodic_[k] ? 3 : 1, static_cast<int>(n_[k] * 0.8));
        w_[k] = len_[k] / n_[k];
      }
    }
    stride_[0] = 1;
    for (int k = 1; k < D; ++k) stride_[k] = stride_[k - 1] * n_[k - 1];
    cells_ = stride_[D - 1] * n_[D - 1];
    // Linear offsets of the 3^D neighbour cells, and of the 3^(D-1) cells of each face layer.
    offsets_all_.clear();
    for (auto& l : offsets_layer_) l.clear();
    for (int m = 0; m < kStencil; ++m) {
      int off = 0, rest = m;
      std::array<int, D> o{};
      for (int k = 0; k < D; ++k) {
        o[k] = rest % 3 - 1;
        rest /= 3;
        off += o[k] * stride_[k];
      }
      offsets_all_.push_back(off);
      for (int k = 0; k < D; ++k)
        if (o[k] != 0) offsets_layer_[2 * k + (o[k] > 0)].push_back(off);
    }
    return ok;
  }

  // Whether the cells are hashed (then cells() counts buckets, a bucket may hold grains of several
  // far-apart cells, and there is no linear layout: interior() is false, half_stencil() unused).
  bool hashed() const { return hashed_; }
  int cells() const { return cells_; }
  int count(int k) const { return n_[k]; }
  double width(int k) const { return w_[k]; }
  double length(int k) const { return len_[k]; }  // the domain's along axis k (a periodic image's shift)
  const Vec<D>& lower() const { return lo_; }
  bool periodic(int k) const { return periodic_[k]; }
  int stride(int k) const { return stride_[k]; }

  // The cell of coordinate x along axis k (clamped to the grid).
  int coord(int k, double x) const {
    return std::clamp(static_cast<int>(std::floor((x - lo_[k]) / w_[k])), 0, n_[k] - 1);
  }
  std::array<int, D> coords(const Vec<D>& x) const {
    std::array<int, D> c{};
    for (int k = 0; k < D; ++k) c[k] = coord(k, x[k]);
    return c;
  }
  // The cell's index: its place in the dense layout, or its hash bucket.
  int linear(const std::array<int, D>& c) const {
    if (hashed_) return bucket(c);
    int l = 0;
    for (int k = 0; k < D; ++k) l += c[k] * stride_[k];
    return l;
  }
  // Whether the 3^D cells around c lie inside the grid (their linear offsets are then fixed).
  bool interior(const std::array<int, D>& c) const {
    if (hashed_) return false;
    bool in = true;
    for (int k = 0; k < D; ++k) in = in && c[k] >= 1 && c[k] < n_[k] - 1;
    return in;
  }
  // The linear offsets of all 3^D cells around a cell (layer_axis < 0), or of the face layer one
  // cell further along layer_axis in direction layer_dir.
  const std::vector<int>& offsets(int layer_axis = -1, int layer_dir = 0) const {
    return layer_axis < 0 ? offsets_all_ : offsets_layer_[2 * layer_axis + (layer_dir > 0)];
  }

  // cell(l, shift) for every cell l around c (all 3^D, or the face layer as in offsets()), with
  // the image shift to add to a position in l to bring it next to c (non-zero across a periodic
  // face). A cell is visited once per image; cells beyond a closed face are skipped.
  template <class Cell>
  void around(const std::array<int, D>& c, Cell&& cell, int layer_axis = -1, int layer_dir = 0) const {
    around_rings<1>(c, cell, layer_axis, layer_dir);
  }
  // The same over the 5^D cells within two cells of c (a reach of up to two cell widths). A
  // periodic axis has at least three cells, so each offset -2..2 is a cell of its own or another
  // image of one (never the same cell and image twice).
  template <class Cell>
  void around_wide(const std::array<int, D>& c, Cell&& cell) const {
    around_rings<2>(c, cell, -1, 0);
  }

  // The index of an image shift as passed by around() (j's image x_j + shift next to i) in
  // shift_table()'s numbering, whose entries are added to x_i - x_j: sum_k (1 - shift_k / L_k) 3^k.
  std::uint8_t shift_index(const Vec<D>& shift) const {
    int idx = 0;
    for (int k = 0, p = 1; k < D; ++k, p *= 3)
      idx += (1 - static_cast<int>(std::lround(shift[k] / len_[k]))) * p;
    return static_cast<std::uint8_t>(idx);
  }

  // The half stencil (TDM's list build): for every cell c the neighbour cells of larger linear
  // index, each once, with the index of the image shift to add to x_i - x_j (index
  // sum_k (s_k + 1) 3^k; a neighbour reached by wrapping below a periodic face lies at x_j - L, so
  // s_k = +1). CSR: cells off[c] .. off[c + 1] of `cell` and `shift`.
  void half_stencil(std::vector<std::uint32_t>& off, std::vector<std::uint32_t>& cell,
                    std::vector<std::uint8_t>& shift) const {
    const std::size_t ncell = static_cast<std::size_t>(cells_);
    off.assign(ncell + 1, 0);
    cell.clear();
    shift.clear();
    std::vector<std::pair<std::uint32_t, std::uint8_t>> found;
    std::array<int, D> cc{};
    for (std::size_t c = 0; c < ncell; ++c) {
      std::size_t r = c;
      for (int k = 0; k < D; ++k) {
        cc[k] = static_cast<int>(r % n_[k]);
        r /= n_[k];
      }
      found.clear();
      for (int s = 0; s < kStencil; ++s) {
        int rr = s, sh = 0;
        std::size_t idx = 0, p = 1;
        bool ok = true;
        for (int k = 0, p3 = 1; k < D; ++k, p3 *= 3) {
          int ck = cc[k] + (rr % 3) - 1;
          rr /= 3;
          int sk = 0;
          if (ck < 0 || ck >= n_[k]) {
            if (!periodic_[k]) {
              ok = false;
              break;
            }
            sk = ck < 0 ? 1 : -1;
            ck = (ck + n_[k]) % n_[k];
          }
          sh += (sk + 1) * p3;
          idx += static_cast<std::size_t>(ck) * p;
          p *= static_cast<std::size_t>(n_[k]);
        }
        if (ok && idx > c) found.push_back({static_cast<std::uint32_t>(idx), static_cast<std::uint8_t>(sh)});
      }
      std::sort(found.begin(), found.end());
      found.erase(std::unique(found.begin(), found.end(), [](const auto& a, const auto& b) { return a.first == b.first; }),
                  found.end());
      for (const auto& [c2, sh] : found) {
        cell.push_back(c2);
        shift.push_back(sh);
      }
      off[c + 1] = static_cast<std::uint32_t>(cell.size());
    }
  }

  // The image shifts by index (sum_k (s_k + 1) 3^k, s_k in {-1, 0, 1}): s_k times the axis length.
  // Checkpoints (engine/state_archive.hpp): a grid rebuilt as the run goes (the hybrid's soft grid).
  template <class A>
  void archive(A& a) {
    a(lo_);
    a(len_);
    a(w_);
    a(periodic_);
    a(n_);
    a(stride_);
    a(cells_);
    a(hashed_);
    a(mask_);
    a(offsets_all_);
    for (auto& o : offsets_layer_) a(o);
  }
  std::array<Vec<D>, kStencil> shift_table() const {
    std::array<Vec<D>, kStencil> t;
    for (int s = 0; s < kStencil; ++s) {
      int r = s;
      for (int k = 0; k < D; ++k) {
        t[s][k] = (static_cast<double>(r % 3) - 1.0) * len_[k];
        r /= 3;
      }
    }
    return t;
  }

 private:
  template <int R, class Cell>
  void around_rings(const std::array<int, D>& c, Cell&& cell, int layer_axis, int layer_dir) const {
    constexpr int W = 2 * R + 1;
    std::array<int, W> ck[D];
    std::array<double, W> sk[D];
    std::array<int, D> cnt{};
    for (int k = 0; k < D; ++k) {
      const int olo = (k == layer_axis) ? layer_dir : -R;
      const int ohi = (k == layer_axis) ? layer_dir : R;
      for (int o = olo; o <= ohi; ++o) {
        int cc = c[k] + o;
        double s = 0.0;
        if (cc < 0) {
          if (!periodic_[k]) continue;
          cc += n_[k];
          s = -len_[k];
        } else if (cc >= n_[k]) {
          if (!periodic_[k]) continue;
          cc -= n_[k];
          s = len_[k];
        }
        ck[k][cnt[k]] = cc;
        sk[k][cnt[k]] = s;
        ++cnt[k];
      }
    }
    // Hashed cells: two cells of the stencil may share a bucket; each (bucket, shift) is visited
    // once (a second visit would list its grains twice).
    constexpr int kCells = D == 3 ? W * W * W : W * W;
    std::array<std::pair<int, Vec<D>>, kCells> seen;
    int nseen = 0;
    auto visit = [&](const std::array<int, D>& cc, const Vec<D>& s) {
      const int l = linear(cc);
      if (hashed_) {
        for (int q = 0; q < nseen; ++q)
          if (seen[q].first == l && seen[q].second == s) return;
        seen[nseen++] = {l, s};
      }
      cell(l, s);
    };
    if constexpr (D == 2) {
      for (int a = 0; a < cnt[0]; ++a)
        for (int b = 0; b < cnt[1]; ++b) visit({ck[0][a], ck[1][b]}, Vec<D>(sk[0][a], sk[1][b]));
    } else {
      for (int a = 0; a < cnt[0]; ++a)
        for (int b = 0; b < cnt[1]; ++b)
          for (int e = 0; e < cnt[2]; ++e)
            visit({ck[0][a], ck[1][b], ck[2][e]}, Vec<D>(sk[0][a], sk[1][b], sk[2][e]));
    }
  }

  Vec<D> lo_ = Vec<D>::Zero(), len_ = Vec<D>::Ones(), w_ = Vec<D>::Ones();
  std::array<bool, D> periodic_{};
  std::array<int, D> n_{}, stride_{};
  int cells_ = 1;
  bool hashed_ = false;
  std::uint64_t mask_ = 0;
  int bucket(const std::array<int, D>& c) const { return static_cast<int>(cell_hash(c) & mask_); }
  std::vector<int> offsets_all_;
  std::array<std::vector<int>, 2 * D> offsets_layer_;
};

}  // namespace matep

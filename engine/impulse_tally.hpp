// Hard collisions as data (Snapshot::contacts, kind 0): the impulses of each pair's (or grain and
// wall's) collisions summed between two snapshots. Divided by the interval they are the mean force
// over it, the hard-sphere counterpart of a contact force (the collisional part of the stress:
// Allen & Tildesley, Computer Simulation of Liquids, 2nd ed., §2.4 and §3.7). The EDM core adds
// every collision it resolves (engine/edm/core.hpp), the pure EDM's and the hybrid's hard grains'.
#pragma once

#include <cstdint>
#include <unordered_map>
#include <vector>

#include "engine/observer.hpp"

namespace matep {

template <int D>
class ImpulseTally {
 public:
  // The impulse dp on grain i from grain j (j >= 0) or from wall `wall` (j < 0) at the contact
  // point, n the unit normal of the collision (the normal part of dp is along it).
  void add(std::uint32_t i, std::int64_t j, std::int32_t wall, const Vec<D>& point, const Vec<D>& dp,
           const Vec<D>& n) {
    Vec<D> p = dp;
    if (j >= 0 && static_cast<std::uint32_t>(j) < i) {  // rows hold the impulse on the smaller id
      const std::uint32_t k = static_cast<std::uint32_t>(j);
      j = i;
      i = k;
      p = -dp;
    }
    auto [it, fresh] = index_.try_emplace(key_of(i, j, wall), static_cast<std::uint32_t>(rows_.size()));
    if (fresh) {
      ContactRow<D> r;
      r.kind = 0;
      r.i = i;
      r.j = j;
      r.wall = j >= 0 ? -1 : wall;
      rows_.push_back(r);
    }
    ContactRow<D>& r = rows_[it->second];
    const Vec<D> pn = p.dot(n) * n;
    r.fn += pn;  // impulses until rows(): divided by the interval there
    r.ft += p - pn;
    r.point = point;
    ++r.collisions;
  }

  // The rows over an interval of length dt (mean forces), appended to `out`; the tally restarts.
  void take(double dt, std::vector<ContactRow<D>>& out) {
    const double inv = dt > 0.0 ? 1.0 / dt : 0.0;
    for (ContactRow<D>& r : rows_) {
      r.fn *= inv;
      r.ft *= inv;
      out.push_back(r);
    }
    rows_.clear();
    index_.clear();
  }

  bool empty() const { return rows_.empty(); }

  // The engine renumbered its grains (grain i is now to[i]): the rows follow, each pair's row
  // still on its smaller id (rename_contact).
  void renumber(const std::vector<std::uint32_t>& to) {
    if (rows_.empty()) return;
    index_.clear();
    for (std::size_t k = 0; k < rows_.size(); ++k) {
      ContactRow<D>& r = rows_[k];
      rename_contact(r, [&](std::uint64_t i) { return to[i]; });
      index_[key_of(r.i, r.j, r.wall)] = static_cast<std::uint32_t>(k);
    }
  }

  // Checkpoints (engine/state_archive.hpp): the rows; the index is made again on loading.
  template <class A>
  void archive(A& a) {
    a(rows_);
    if constexpr (A::loading) {
      index_.clear();
      for (std::size_t k = 0; k < rows_.size(); ++k)
        index_[key_of(rows_[k].i, rows_[k].j, rows_[k].wall)] = static_cast<std::uint32_t>(k);
    }
  }

 private:
  // A pair (i, j) or a grain and a wall (j < 0): i in the high half, j or the wall (flagged by bit 31)
  // in the low half.
  static std::uint64_t key_of(std::uint32_t i, std::int64_t j, std::int32_t wall) {
    const std::uint64_t low = j >= 0 ? static_cast<std::uint64_t>(j)
                                     : (std::uint64_t{1} << 31) | static_cast<std::uint32_t>(wall);
    return (std::uint64_t{i} << 32) | low;
  }
  std::vector<ContactRow<D>> rows_;
  std::unordered_map<std::uint64_t, std::uint32_t> index_;
};

}  // namespace matep

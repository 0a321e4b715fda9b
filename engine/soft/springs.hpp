// Contact history carried across neighbour-list rebuilds, for TDM and the hybrid's soft set: before
// a rebuild every touching contact is remembered by particle ids (a pair by its lower and higher
// id, with its tangential spring, and its rolling spring torque when the scene has one, oriented for
// the lower one; a wall contact by the particle's id and the wall's slot); the new list recalls them. A contact that is not recalled starts
// untouched with no spring.
#pragma once

#include <algorithm>
#include <cstdint>
#include <vector>

#include "contact/vec.hpp"

namespace matep::soft {

template <int D>
class SpringMemory {
 public:
  void clear() {
    pairs_.clear();
    walls_.clear();
  }
  // A touching pair (ids a, b) whose spring xi (and rolling spring torque mr) is oriented for a.
  void remember_pair(std::uint32_t a, std::uint32_t b, const Vec<D>& xi, const Spin<D>& mr = Spin<D>::Zero()) {
    pairs_.push_back(a < b ? Entry{key(a, b), xi, mr} : Entry{key(b, a), Vec<D>(-xi), Spin<D>(-mr)});
  }
  void remember_wall(std::uint32_t i, std::uint32_t w, const Vec<D>& xi, const Spin<D>& mr = Spin<D>::Zero()) {
    walls_.push_back({key(i, w), xi, mr});
  }
  // Call once everything is remembered, before the recalls.
  void sort() {
    auto by_key = [](const Entry& p, const Entry& q) { return p.key < q.key; };
    std::sort(pairs_.begin(), pairs_.end(), by_key);
    std::sort(walls_.begin(), walls_.end(), by_key);
    index(pairs_, pair_at_);
    index(walls_, wall_at_);
  }
  bool empty() const { return pairs_.empty() && walls_.empty(); }
  // Checkpoints (engine/state_archive.hpp). (The index is made again by sort(), before any recall.)
  template <class A>
  void archive(A& a) {
    a(pairs_);
    a(walls_);
  }
  // Whether the pair (a, b) was touching; then xi (and *mr) = its springs oriented for a.
  bool recall_pair(std::uint32_t a, std::uint32_t b, Vec<D>& xi, Spin<D>* mr = nullptr) const {
    const Entry* e = find(pairs_, pair_at_, a < b ? key(a, b) : key(b, a));
    if (!e) return false;
    xi = a < b ? e->xi : Vec<D>(-e->xi);
    if (mr) *mr = a < b ? e->mr : Spin<D>(-e->mr);
    return true;
  }
  bool recall_wall(std::uint32_t i, std::uint32_t w, Vec<D>& xi, Spin<D>* mr = nullptr) const {
    const Entry* e = find(walls_, wall_at_, key(i, w));
    if (!e) return false;
    xi = e->xi;
    if (mr) *mr = e->mr;
    return true;
  }

  static std::uint64_t key(std::uint32_t a, std::uint32_t b) { return (std::uint64_t(a) << 32) | b; }

 private:
  struct Entry {
    std::uint64_t key;
    Vec<D> xi;
    Spin<D> mr;
  };
  // Where the entries of each lower id begin in the sorted entries: a lookup scans the few entries
  // of its lower id (a grain's contacts) instead of searching the whole list. Indexed by id; a
  // generation stamp marks the ids of the current build, so the index is never cleared.
  struct Index {
    std::vector<std::uint32_t> start, stamp;
    std::uint32_t gen = 0;
  };
  static void index(const std::vector<Entry>& v, Index& at) {
    if (++at.gen == 0) {  // the stamps wrapped: start afresh
      at.stamp.assign(at.stamp.size(), 0);
      at.gen = 1;
    }
    for (std::size_t p = 0; p < v.size(); ++p) {
      const std::uint64_t a = v[p].key >> 32;
      if (p > 0 && v[p - 1].key >> 32 == a) continue;
      if (a >= at.stamp.size()) {
        at.stamp.resize(a + 1, 0);
        at.start.resize(a + 1, 0);
      }
      at.stamp[a] = at.gen;
      at.start[a] = static_cast<std::uint32_t>(p);
    }
  }
  static const Entry* find(const std::vector<Entry>& v, const Index& at, std::uint64_t k) {
    const std::uint64_t a = k >> 32;
    if (a >= at.stamp.size() || at.stamp[a] != at.gen) return nullptr;
    for (std::size_t p = at.start[a]; p < v.size() && v[p].key <= k; ++p)
      if (v[p].key == k) return &v[p];
    return nullptr;
  }
  std::vector<Entry> pairs_, walls_;
  Index pair_at_, wall_at_;
};

}  // namespace matep::soft

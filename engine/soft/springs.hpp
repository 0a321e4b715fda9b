// Contact history carried across neighbour-list rebuilds, for TDM and the hybrid's soft set: before
// a rebuild every touching contact is remembered by particle ids (a pair by its lower and higher
// id, with its tangential spring, and its rolling spring torque when the scene has one, oriented for
// the lower one; a wall contact by the particle's id and the wall's slot); the new list recalls them.
// A contact that is not recalled starts untouched with no spring. The rolling spring torques are kept
// only when set_rolling(true) (an Epsd scene), apart from the entries: the others need 32 bytes a
// contact in 3D, not 56.
#pragma once

#include <algorithm>
#include <cstdint>
#include <type_traits>
#include <vector>

#include "contact/vec.hpp"

namespace matep::soft {

template <int D>
class SpringMemory {
 public:
  // Whether the rolling spring torques are kept (else remembered as zero).
  void set_rolling(bool rolling) { rolling_ = rolling; }
  void clear() {
    pairs_.clear();
    walls_.clear();
    pair_mr_.clear();
    wall_mr_.clear();
  }
  // Room for this many contacts, cleared: storage too small is given anew at the exact size, not
  // doubled step by step as the contacts are remembered (a rebuild's peak holds it).
  void reserve(std::size_t pairs, std::size_t walls) {
    clear();
    auto room = [](auto& v, std::size_t n) {
      if (v.capacity() >= n) return;
      std::decay_t<decltype(v)>().swap(v);
      v.reserve(n);
    };
    room(pairs_, pairs);
    room(walls_, walls);
    if (rolling_) {
      room(pair_mr_, pairs);
      room(wall_mr_, walls);
    }
  }
  // Frees the storage (clear() keeps it for the next rebuild).
  void release() {
    const bool rolling = rolling_;
    *this = SpringMemory();
    rolling_ = rolling;
  }
  // A touching pair (ids a, b) whose spring xi (and rolling spring torque mr) is oriented for a.
  void remember_pair(std::uint32_t a, std::uint32_t b, const Vec<D>& xi, const Spin<D>& mr = Spin<D>::Zero()) {
    pairs_.push_back(a < b ? Entry{key(a, b), xi} : Entry{key(b, a), Vec<D>(-xi)});
    if (rolling_) pair_mr_.push_back(a < b ? mr : Spin<D>(-mr));
  }
  void remember_wall(std::uint32_t i, std::uint32_t w, const Vec<D>& xi, const Spin<D>& mr = Spin<D>::Zero()) {
    walls_.push_back({key(i, w), xi});
    if (rolling_) wall_mr_.push_back(mr);
  }
  // Call once everything is remembered, before the recalls.
  void sort() {
    sort_by_key(pairs_, pair_mr_);
    sort_by_key(walls_, wall_mr_);
    index(pairs_, pair_at_);
    index(walls_, wall_at_);
  }
  bool empty() const { return pairs_.empty() && walls_.empty(); }
  // Checkpoints (engine/state_archive.hpp). (The index is made again by sort(), before any recall.)
  template <class A>
  void archive(A& a) {
    a(pairs_);
    a(walls_);
    a(pair_mr_);
    a(wall_mr_);
  }
  // Whether the pair (a, b) was touching; then xi (and *mr) = its springs oriented for a.
  bool recall_pair(std::uint32_t a, std::uint32_t b, Vec<D>& xi, Spin<D>* mr = nullptr) const {
    const std::ptrdiff_t p = find(pairs_, pair_at_, a < b ? key(a, b) : key(b, a));
    if (p < 0) return false;
    const Entry& e = pairs_[static_cast<std::size_t>(p)];
    xi = a < b ? e.xi : Vec<D>(-e.xi);
    if (mr) *mr = !rolling_ ? Spin<D>(Spin<D>::Zero()) : a < b ? pair_mr_[p] : Spin<D>(-pair_mr_[p]);
    return true;
  }
  bool recall_wall(std::uint32_t i, std::uint32_t w, Vec<D>& xi, Spin<D>* mr = nullptr) const {
    const std::ptrdiff_t p = find(walls_, wall_at_, key(i, w));
    if (p < 0) return false;
    xi = walls_[static_cast<std::size_t>(p)].xi;
    if (mr) *mr = rolling_ ? wall_mr_[static_cast<std::size_t>(p)] : Spin<D>(Spin<D>::Zero());
    return true;
  }

  static std::uint64_t key(std::uint32_t a, std::uint32_t b) { return (std::uint64_t(a) << 32) | b; }

 private:
  struct Entry {
    std::uint64_t key;
    Vec<D> xi;
  };
  // Entries by key, their rolling spring torques (when kept) alongside.
  static void sort_by_key(std::vector<Entry>& v, std::vector<Spin<D>>& mr) {
    auto by_key = [](const Entry& p, const Entry& q) { return p.key < q.key; };
    if (mr.empty()) {
      std::sort(v.begin(), v.end(), by_key);
      return;
    }
    std::vector<std::uint32_t> order(v.size());
    for (std::size_t k = 0; k < order.size(); ++k) order[k] = static_cast<std::uint32_t>(k);
    std::sort(order.begin(), order.end(), [&](std::uint32_t p, std::uint32_t q) { return v[p].key < v[q].key; });
    std::vector<Entry> v2(v.size());
    std::vector<Spin<D>> mr2(mr.size());
    for (std::size_t k = 0; k < order.size(); ++k) {
      v2[k] = v[order[k]];
      mr2[k] = mr[order[k]];
    }
    v.swap(v2);
    mr.swap(mr2);
  }
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
  // The entry of key k, or -1.
  static std::ptrdiff_t find(const std::vector<Entry>& v, const Index& at, std::uint64_t k) {
    const std::uint64_t a = k >> 32;
    if (a >= at.stamp.size() || at.stamp[a] != at.gen) return -1;
    for (std::size_t p = at.start[a]; p < v.size() && v[p].key <= k; ++p)
      if (v[p].key == k) return static_cast<std::ptrdiff_t>(p);
    return -1;
  }
  std::vector<Entry> pairs_, walls_;
  std::vector<Spin<D>> pair_mr_, wall_mr_;  // rolling_: per entry, in the same order
  Index pair_at_, wall_at_;
  bool rolling_ = false;
};

}  // namespace matep::soft

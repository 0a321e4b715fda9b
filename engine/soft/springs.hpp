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
  }
  bool empty() const { return pairs_.empty() && walls_.empty(); }
  // Checkpoints (engine/state_archive.hpp).
  template <class A>
  void archive(A& a) {
    a(pairs_);
    a(walls_);
  }
  // Whether the pair (a, b) was touching; then xi (and *mr) = its springs oriented for a.
  bool recall_pair(std::uint32_t a, std::uint32_t b, Vec<D>& xi, Spin<D>* mr = nullptr) const {
    const Entry* e = find(pairs_, a < b ? key(a, b) : key(b, a));
    if (!e) return false;
    xi = a < b ? e->xi : Vec<D>(-e->xi);
    if (mr) *mr = a < b ? e->mr : Spin<D>(-e->mr);
    return true;
  }
  bool recall_wall(std::uint32_t i, std::uint32_t w, Vec<D>& xi, Spin<D>* mr = nullptr) const {
    const Entry* e = find(walls_, key(i, w));
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
  static const Entry* find(const std::vector<Entry>& v, std::uint64_t k) {
    auto it = std::lower_bound(v.begin(), v.end(), k, [](const Entry& p, std::uint64_t q) { return p.key < q; });
    return (it != v.end() && it->key == k) ? &*it : nullptr;
  }
  std::vector<Entry> pairs_, walls_;
};

}  // namespace matep::soft

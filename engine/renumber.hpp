// The hybrid's particles in space order. The EDM core keeps its per-particle state in particle
// order and the hybrid's soft set walks it in that order, so grains that touch should lie near
// each other in memory: in a scene whose ids are scattered in space (grains placed at random, read
// from a file, a shuffled lattice) each soft contact otherwise reads its partner's state from far
// away: a dense soft gas with its ids shuffled ran at 0.48 of TDM's speed per particle-step on one
// thread (0.35 on two), 0.66 (0.74) in space order (bench/README.md, "Where the hybrid stands"). So run_hybrid
// renumbers the grains once, at the start, in cell order, and maps every id it reports back to the
// scene's: the observers' records (UserIds), the final state (to_user), its messages (IdMap).
// A grain an inlet inserts keeps its id (it comes after the initial ones).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <numeric>
#include <utility>
#include <vector>

#include "engine/observer.hpp"
#include "engine/result.hpp"
#include "engine/system.hpp"

namespace matep {

// Engine index -> the scene's particle id. Indices beyond the initial grains (inlets') and an
// empty map are their own ids.
class IdMap {
 public:
  IdMap() = default;
  explicit IdMap(std::vector<std::uint32_t> user) : user_(std::move(user)) {}
  std::uint64_t user(std::uint64_t k) const { return k < user_.size() ? user_[k] : k; }
  bool identity() const { return user_.empty(); }
  // The engine has permuted its n indices (index k now holds what index from[k] held): the map
  // follows (engine/edm/core.hpp "re-sorting").
  void permute(const std::vector<std::uint32_t>& from) {
    std::vector<std::uint32_t> u(from.size());
    for (std::size_t k = 0; k < from.size(); ++k) u[k] = static_cast<std::uint32_t>(user(from[k]));
    user_ = std::move(u);
  }
  std::vector<std::uint32_t>& entries() { return user_; }  // checkpoints

 private:
  std::vector<std::uint32_t> user_;
};

// The initial grains in cell order: element k is the id of the grain that becomes particle k.
// Cells are one largest diameter wide; the domain's longest axis varies slowest and its shortest
// fastest (grains a cell apart along the slowest axis are then the fewest rows apart); within a
// cell, by id. Positions are clamped into the domain (a grain may stick out on a closed axis).
template <int D>
std::vector<std::uint32_t> spatial_order(const System<D>& s) {
  const std::size_t n = s.size();
  std::vector<std::uint32_t> order(n);
  std::iota(order.begin(), order.end(), 0u);
  const double cell = 2.0 * s.radius_range().second;
  if (n < 2 || !(cell > 0.0)) return order;
  std::array<int, D> axis;  // slowest first
  std::iota(axis.begin(), axis.end(), 0);
  const Vec<D> ext = s.upper - s.lower;
  std::stable_sort(axis.begin(), axis.end(), [&](int a, int b) { return ext[a] > ext[b]; });
  std::array<std::uint64_t, D> count;
  for (int k = 0; k < D; ++k) count[k] = static_cast<std::uint64_t>(std::max(1.0, std::ceil(ext[k] / cell)));
  std::vector<std::uint64_t> key(n);
  for (std::size_t i = 0; i < n; ++i) {
    std::uint64_t c = 0;
    for (const int k : axis) {
      const double f = std::floor((s.x[i][k] - s.lower[k]) / cell);
      const std::uint64_t ck = f <= 0.0 ? 0 : std::min<std::uint64_t>(count[k] - 1, static_cast<std::uint64_t>(f));
      c = c * count[k] + ck;
    }
    key[i] = c;
  }
  // By key, ids in order within a key: a counting sort when the cells are few against the grains
  // (a scene's box), else the comparison sort (a mostly empty domain), the same order either way.
  std::uint64_t cells = 1;
  for (int k = 0; k < D && cells <= 4 * n; ++k) cells *= count[k];
  if (cells <= 4 * n) {
    std::vector<std::uint32_t> start(cells + 1, 0u);
    for (std::size_t i = 0; i < n; ++i) ++start[key[i] + 1];
    for (std::uint64_t c = 0; c < cells; ++c) start[c + 1] += start[c];
    for (std::size_t i = 0; i < n; ++i) order[start[key[i]]++] = static_cast<std::uint32_t>(i);
    return order;
  }
  std::stable_sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) { return key[a] < key[b]; });
  return order;
}

// a[k] = a[from[k]] for every k, for an array with one element per index of `from` (an array of
// another size, such as an empty optional one, is left as it is).
template <class V, class I>
void gather(V& a, const std::vector<I>& from) {
  if (a.size() != from.size()) return;
  V b = a;
  for (std::size_t k = 0; k < from.size(); ++k) b[k] = a[from[k]];
  a = std::move(b);
}

// The system with its initial grains in `order` (spatial_order): every per-particle array.
template <int D>
void reorder(System<D>& s, const std::vector<std::uint32_t>& order) {
  gather(s.x, order);
  gather(s.v, order);
  gather(s.w, order);
  gather(s.radius, order);
  gather(s.material, order);
  gather(s.fixed, order);
}

// A per-particle state (a RunResult's final state, a Snapshot) from engine order to the scene's:
// rows sorted by the scene's id, id filled where the engine filled it (grains are missing:
// keep_present; otherwise row k is particle k in both orders, the map being one-to-one), soft-cluster
// labels renumbered in order of first appearance (as the engine numbers them).
template <class State>
void rows_to_user(State& s, const IdMap& m) {
  const std::size_t rows = s.x.size();
  std::vector<std::uint64_t> uid(rows);
  for (std::size_t r = 0; r < rows; ++r) uid[r] = m.user(s.id.empty() ? r : s.id[r]);
  // The rows by scene id (the ids are distinct): placed by id when they are dense (at most twice as
  // many id values as rows: a run's grains, some removed or inserted), else sorted.
  std::vector<std::size_t> p(rows);
  std::uint64_t top = 0;
  for (const std::uint64_t u : uid) top = std::max(top, u);
  bool placed = false;
  if (top < 2 * static_cast<std::uint64_t>(rows)) {
    std::vector<std::size_t> at(static_cast<std::size_t>(top) + 1, rows);
    for (std::size_t r = 0; r < rows; ++r) at[uid[r]] = r;
    std::size_t k = 0;
    for (const std::size_t r : at)
      if (r < rows) p[k++] = r;
    placed = k == rows;  // (not when an id repeats)
  }
  if (!placed) {
    std::iota(p.begin(), p.end(), std::size_t{0});
    std::sort(p.begin(), p.end(), [&](std::size_t a, std::size_t b) { return uid[a] < uid[b]; });
  }
  for_each_row_array(s, [&](auto& a) { gather(a, p); });
  if constexpr (requires { s.cluster; }) {
    std::vector<std::int32_t> relabel;
    std::int32_t next = 0;
    for (std::int32_t& c : s.cluster) {
      if (c < 0) continue;
      if (static_cast<std::size_t>(c) >= relabel.size()) relabel.resize(static_cast<std::size_t>(c) + 1, -1);
      if (relabel[c] < 0) relabel[c] = next++;
      c = relabel[c];
    }
  }
  if (s.id.empty()) return;
  s.id.clear();
  for (std::size_t r = 0; r < rows; ++r) s.id.push_back(static_cast<std::uint32_t>(uid[p[r]]));
}

// A contact row's grains by the scene's ids, i < j kept for pairs (swapping them turns the force
// on i into the force on the other grain).
template <int D>
void contact_to_user(ContactRow<D>& c, const IdMap& m) {
  rename_contact(c, [&](std::uint64_t k) { return m.user(k); });
}

// The final state of a run in the scene's ids.
template <int D>
void to_user(RunResult<D>& r, const IdMap& m) {
  if (m.identity()) return;
  rows_to_user(r, m);
}

// An observer that passes on what an engine running in another order reports, in the scene's ids.
template <int D>
class UserIds final : public Observer<D> {
 public:
  UserIds(Observer<D>& to, const IdMap& m) : to_(to), m_(m) {}
  bool wants_collisions() const override { return to_.wants_collisions(); }
  void on_collision(const CollisionRecord<D>& c) override {
    CollisionRecord<D> u = c;
    u.i = static_cast<std::uint32_t>(m_.user(c.i));
    // j is a grain in a pair collision and in a switch's record (the grain itself); a wall's index
    // in a wall collision.
    if (c.kind == EventKind::PairCollision || c.kind == EventKind::ToSoft || c.kind == EventKind::ToHard)
      u.j = static_cast<std::uint32_t>(m_.user(c.j));
    to_.on_collision(u);
  }
  void on_sample(const ThermoSample& s) override { to_.on_sample(s); }
  bool wants_snapshots() const override { return to_.wants_snapshots(); }
  bool wants_contacts() const override { return to_.wants_contacts(); }
  void on_snapshot(const Snapshot<D>& s) override {
    Snapshot<D> u = s;
    rows_to_user(u, m_);
    for (ContactRow<D>& c : u.contacts) contact_to_user(c, m_);
    to_.on_snapshot(u);
  }
  void on_outflow(const OutflowRecord<D>& o) override {
    OutflowRecord<D> u = o;
    u.id = static_cast<std::uint32_t>(m_.user(o.id));
    to_.on_outflow(u);
  }
  void on_inflow(const InflowRecord<D>& i) override {
    InflowRecord<D> u = i;
    u.id = static_cast<std::uint32_t>(m_.user(i.id));
    to_.on_inflow(u);
  }
  void on_progress(double t, std::uint64_t events) override { to_.on_progress(t, events); }

 private:
  Observer<D>& to_;
  const IdMap& m_;
};

// The run's observers, each wrapped to hear the scene's ids through map m (which may change as the
// engine renumbers: EdmCore::track_ids).
template <int D>
class UserIdObservers {
 public:
  UserIdObservers(const std::vector<Observer<D>*>& observers, const IdMap& m) {
    for (Observer<D>* o : observers) {
      if (!o) continue;
      wrapped_.push_back(std::make_unique<UserIds<D>>(*o, m));
      list_.push_back(wrapped_.back().get());
    }
  }
  const std::vector<Observer<D>*>& list() const { return list_; }

 private:
  std::vector<std::unique_ptr<UserIds<D>>> wrapped_;
  std::vector<Observer<D>*> list_;
};

// Runs an engine on the system's grains in space order and reports in the scene's ids:
// run(system, observers, ids) builds the engine on the reordered system with the wrapped
// observers, hands it the ids (EdmCore::track_ids: the engine keeps the map up to date as it
// re-sorts) and returns its result, which comes back here in the scene's order.
template <int D, class Run>
RunResult<D> run_in_space_order(System<D> system, const std::vector<Observer<D>*>& observers, Run&& run) {
  system.check_fixed();  // its message names the scene's ids
  const std::vector<std::uint32_t> order = spatial_order(system);
  reorder(system, order);
  IdMap ids(order);
  const UserIdObservers<D> obs(observers, ids);
  RunResult<D> r = run(std::move(system), obs.list(), ids);
  to_user(r, ids);
  return r;
}

}  // namespace matep

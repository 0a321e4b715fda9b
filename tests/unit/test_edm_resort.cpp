// Re-sorting the EDM particles' storage in space as a run goes (engine/edm/core.hpp "re-sorting",
// EdmSettings::resort): the Z-order key, and whole runs re-sorted many times against the same runs
// never re-sorted. Re-sorting moves each particle's records and renames it in the engine only: the
// predictions are the same numbers, so the collisions, the inflow and outflow, the snapshots'
// contacts and the final state must come out the same, in the scene's ids, bit for bit (a pair's
// collision may be reported from either grain: the queue breaks exact ties by engine index).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <random>
#include <string>
#include <tuple>
#include <variant>
#include <vector>

#include "engine/edm.hpp"
#include "engine/edm/neighbours.hpp"
#include "engine/hybrid.hpp"
#include "io/scene.hpp"
#include "tests/support/flows.hpp"
#include "tests/support/scene_errors.hpp"
#include "tests/support/systems.hpp"

namespace matep {
namespace {

// The key written out from its definition: bit b of coordinate k goes to bit D b + k.
template <int D>
std::uint64_t slow_key(const std::array<std::uint32_t, D>& c) {
  std::uint64_t key = 0;
  for (int b = 0; b < 64 / D; ++b)
    for (int k = 0; k < D; ++k) key |= std::uint64_t((c[k] >> b) & 1u) << (D * b + k);
  return key;
}

TEST(EdmResort, TheZOrderKeyInterleavesTheCoordinatesBits) {
  EXPECT_EQ(edm::morton_key<3>({1, 0, 0}), 1u);
  EXPECT_EQ(edm::morton_key<3>({0, 1, 0}), 2u);
  EXPECT_EQ(edm::morton_key<3>({0, 0, 1}), 4u);
  EXPECT_EQ(edm::morton_key<3>({3, 0, 0}), 9u);
  EXPECT_EQ(edm::morton_key<2>({0, 3}), 10u);
  std::mt19937 rng(7);
  auto bits21 = [&] { return static_cast<std::uint32_t>(rng() & 0x1fffff); };
  for (int n = 0; n < 1000; ++n) {
    const std::array<std::uint32_t, 3> c3 = {bits21(), bits21(), bits21()};
    ASSERT_EQ(edm::morton_key<3>(c3), slow_key<3>(c3)) << c3[0] << " " << c3[1] << " " << c3[2];
    const std::array<std::uint32_t, 2> c2 = {static_cast<std::uint32_t>(rng()), static_cast<std::uint32_t>(rng())};
    ASSERT_EQ(edm::morton_key<2>(c2), slow_key<2>(c2)) << c2[0] << " " << c2[1];
  }
}

TEST(EdmResort, AutoReSortsLargeGasesOnly) {
  EXPECT_EQ(edm::resort_interval(-1.0, 100000, 0.26), 0.0);
  EXPECT_EQ(edm::resort_interval(-1.0, edm::kResortFrom, 0.26), edm::kResortEvery);
  EXPECT_EQ(edm::resort_interval(-1.0, 5000000, 0.445), 0.0);  // dense: no gain measured
  EXPECT_EQ(edm::resort_interval(0.0, 5000000, 0.26), 0.0);
  EXPECT_EQ(edm::resort_interval(2.5, 10, 0.6), 2.5);
  const System<3> sys = test::lattice_gas<3>(5, 0.3, 1.0, 1.0, 4);
  EdmSettings s;
  s.end_time = 1.0;
  EXPECT_EQ(run_edm<3>(sys, s, QueueKind::Calendar).resorts, 0u);  // "auto" on 125 grains
}

// Everything a run reports about grains, by the scene's ids.
template <int D>
struct Reports final : Observer<D> {
  std::vector<CollisionRecord<D>> collisions;
  std::vector<InflowRecord<D>> in;
  std::vector<OutflowRecord<D>> out;
  std::vector<Snapshot<D>> snaps;
  bool wants_collisions() const override { return true; }
  void on_collision(const CollisionRecord<D>& c) override { collisions.push_back(c); }
  void on_inflow(const InflowRecord<D>& r) override { in.push_back(r); }
  void on_outflow(const OutflowRecord<D>& r) override { out.push_back(r); }
  bool wants_snapshots() const override { return true; }
  bool wants_contacts() const override { return true; }
  void on_snapshot(const Snapshot<D>& s) override { snaps.push_back(s); }
};

// The records in the order of the run, but a substep's switches (the hybrid's, reported in the
// engine's index order) by kind and grain.
template <int D>
std::vector<CollisionRecord<D>> switches_sorted(std::vector<CollisionRecord<D>> c) {
  const auto is_switch = [](const CollisionRecord<D>& r) {
    return r.kind == EventKind::ToSoft || r.kind == EventKind::ToHard;
  };
  for (std::size_t k = 0; k < c.size();) {
    std::size_t e = k;
    while (e < c.size() && is_switch(c[e]) && c[e].time == c[k].time) ++e;
    if (e > k + 1)
      std::sort(c.begin() + static_cast<std::ptrdiff_t>(k), c.begin() + static_cast<std::ptrdiff_t>(e),
                [](const CollisionRecord<D>& u, const CollisionRecord<D>& w) {
                  return std::make_pair(u.kind, u.i) < std::make_pair(w.kind, w.i);
                });
    k = std::max(e, k + 1);
  }
  return c;
}

// The two runs' reports are the same, bit for bit, a pair's collision from either grain.
template <int D>
void expect_same_reports(const Reports<D>& a, const Reports<D>& b) {
  const std::vector<CollisionRecord<D>> ca = switches_sorted(a.collisions), cb = switches_sorted(b.collisions);
  ASSERT_EQ(ca.size(), cb.size());
  for (std::size_t k = 0; k < ca.size(); ++k) {
    const auto& x = ca[k];
    const auto& y = cb[k];
    ASSERT_EQ(x.kind, y.kind) << "collision " << k;
    ASSERT_EQ(x.time, y.time) << "collision " << k;
    const bool swapped = x.kind == EventKind::PairCollision && x.i == y.j && x.j == y.i && x.i != y.i;
    ASSERT_TRUE(swapped || (x.i == y.i && x.j == y.j)) << "collision " << k << ": " << x.i << "-" << x.j << " and "
                                                       << y.i << "-" << y.j;
    const Vec<D>& vy = swapped ? y.vj_after : y.vi_after;
    ASSERT_TRUE(x.vi_after == vy) << "collision " << k;
  }
  ASSERT_EQ(a.in.size(), b.in.size());
  for (std::size_t k = 0; k < a.in.size(); ++k) {
    EXPECT_EQ(a.in[k].id, b.in[k].id);
    EXPECT_EQ(a.in[k].time, b.in[k].time);
    EXPECT_TRUE(a.in[k].x == b.in[k].x);
  }
  ASSERT_EQ(a.out.size(), b.out.size());
  for (std::size_t k = 0; k < a.out.size(); ++k) {
    EXPECT_EQ(a.out[k].id, b.out[k].id);
    EXPECT_EQ(a.out[k].time, b.out[k].time);
    EXPECT_TRUE(a.out[k].v == b.out[k].v);
  }
  ASSERT_EQ(a.snaps.size(), b.snaps.size());
  for (std::size_t k = 0; k < a.snaps.size(); ++k) {
    const Snapshot<D>& p = a.snaps[k];
    const Snapshot<D>& q = b.snaps[k];
    EXPECT_EQ(p.id, q.id) << "snapshot " << k;
    EXPECT_TRUE(test::same_bits(p.x, q.x)) << "snapshot " << k;
    EXPECT_TRUE(test::same_bits(p.v, q.v)) << "snapshot " << k;
    // The contacts' rows: the same set (their order is the tally's first-seen order, which an
    // exact tie may change), each with the same mean force.
    ASSERT_EQ(p.contacts.size(), q.contacts.size()) << "snapshot " << k;
    auto rows = [](std::vector<ContactRow<D>> c) {
      std::sort(c.begin(), c.end(), [](const ContactRow<D>& u, const ContactRow<D>& w) {
        return std::tie(u.i, u.j, u.wall) < std::tie(w.i, w.j, w.wall);
      });
      return c;
    };
    const auto pr = rows(p.contacts), qr = rows(q.contacts);
    for (std::size_t m = 0; m < pr.size(); ++m) {
      EXPECT_EQ(pr[m].i, qr[m].i);
      EXPECT_EQ(pr[m].j, qr[m].j);
      EXPECT_EQ(pr[m].collisions, qr[m].collisions);
      EXPECT_LT((pr[m].fn - qr[m].fn).norm(), 1e-12 * (1.0 + pr[m].fn.norm()));
    }
  }
}

template <int D>
void expect_same_state(const RunResult<D>& a, const RunResult<D>& b) {
  EXPECT_EQ(a.status, b.status);
  EXPECT_EQ(a.id, b.id);
  EXPECT_TRUE(test::same_bits(a.x, b.x)) << "final positions differ";
  EXPECT_TRUE(test::same_bits(a.v, b.v)) << "final velocities differ";
  EXPECT_TRUE(test::same_bits(a.w, b.w)) << "spins differ";
  EXPECT_EQ(a.radius, b.radius);
  EXPECT_EQ(a.counts.pair, b.counts.pair);
  EXPECT_EQ(a.counts.wall, b.counts.wall);
}

// A gas whose ids are scattered in space (the positions shuffled), with cells and with lists, in
// 3D and 2D: re-sorted every half event per particle, the same run.
template <int D>
void check_gas(int n_side, double phi, double e, bool lists) {
  SCOPED_TRACE(::testing::Message() << D << "D, lists " << lists);
  System<D> sys = test::lattice_gas<D>(n_side, phi, 1.0, e, 3);
  std::mt19937 rng(9);
  std::shuffle(sys.x.begin(), sys.x.end(), rng);
  EdmSettings s;
  s.end_time = 3.0;
  s.thermo_interval = 0.5;
  s.snapshot_interval = 1.0;
  s.lists = lists;
  s.resort = 0.0;
  Reports<D> plain, sorted;
  const RunResult<D> a = run_edm<D>(sys, s, QueueKind::Calendar, {&plain});
  s.resort = 0.5;
  const RunResult<D> b = run_edm<D>(sys, s, QueueKind::Calendar, {&sorted});
  ASSERT_EQ(a.status, "ok") << a.message;
  EXPECT_EQ(a.resorts, 0u);
  // The first re-sort undoes the shuffle; each later one follows the grains' mixing.
  EXPECT_GT(b.resorts, 10u);
  EXPECT_GT(plain.collisions.size(), 5000u);
  expect_same_reports(plain, sorted);
  expect_same_state(a, b);
}

TEST(EdmResort, AGasWithScatteredIdsIsTheSameRunReSorted) {
  check_gas<3>(10, 0.3, 0.95, false);
  check_gas<3>(10, 0.47, 1.0, true);
  check_gas<2>(30, 0.5, 0.9, false);
}

// A hopper of rough grains (spins) fed by an inlet and drained through the floor's orifice:
// inserted grains, removed grains, wall collisions and gravity, re-sorted every quarter event per
// particle, against the run never re-sorted.
TEST(EdmResort, AFedAndDrainedHopperOfRoughGrainsIsTheSameRunReSorted) {
  const Scene sc = load_scene_string(test::kFeed, "feed.toml", ".",
                                     {"run.method=edm", "run.end_time=0.25", "particles.bed.count=60",
                                      "material.glass.restitution=0.95", "material.glass.friction=0.3"});
  const System<3>& sys = std::get<System<3>>(sc.system);
  EdmSettings s;
  s.end_time = sc.end_time;
  s.thermo_interval = 0.01;
  s.snapshot_interval = 0.05;
  s.resort = 0.0;
  Reports<3> plain, sorted;
  const RunResult<3> a = run_edm<3>(sys, s, QueueKind::Calendar, {&plain});
  s.resort = 0.25;
  const RunResult<3> b = run_edm<3>(sys, s, QueueKind::Calendar, {&sorted});
  ASSERT_EQ(a.status, "ok") << a.message;
  EXPECT_GT(b.resorts, 20u);
  EXPECT_GT(plain.in.size(), 200u);
  EXPECT_GT(plain.out.size(), 20u);
  ASSERT_FALSE(a.w.empty());
  std::size_t contacts = 0;
  for (const auto& sn : plain.snaps) contacts += sn.contacts.size();
  EXPECT_GT(contacts, 50u);
  expect_same_reports(plain, sorted);
  expect_same_state(a, b);
}

// The hybrid re-sorts while no grain is soft (engine/hybrid/hybrid.cpp ext_can_resort): its own
// arrays by index move with the core's (ext_permute), and its switching rule's memory of partners
// is renamed. A gas with its ids scattered, re-sorted often: an elastic one that stays hard, on
// cells and on lists (53 and 104 re-sorts); an inelastic one whose grains turn soft and back
// between re-sorts (52 switches to soft; about 300 re-sorts). Every collision, switch, snapshot and the final state as in the run never
// re-sorted, bit for bit.
void check_hybrid_gas(double e, bool lists, bool expect_soft, double every) {
  SCOPED_TRACE(::testing::Message() << "e " << e << ", lists " << lists);
  System<3> sys = test::lattice_gas<3>(8, 0.3, 1.0, e, 4);
  sys.materials[0] = test::linear_material("grain", sys.materials[0].density, 1.0e5, e);
  std::mt19937 rng(11);
  std::shuffle(sys.x.begin(), sys.x.end(), rng);
  EdmSettings s;
  s.end_time = 3.0;
  s.thermo_interval = 0.5;
  s.snapshot_interval = 1.0;
  s.lists = lists;
  s.resort = 0.0;
  HybridSettings hs;
  hs.threads = 1;
  Reports<3> plain, sorted;
  const RunResult<3> a = run_hybrid<3>(sys, s, hs, {&plain});
  s.resort = every;
  const RunResult<3> b = run_hybrid<3>(sys, s, hs, {&sorted});
  ASSERT_EQ(a.status, "ok") << a.message;
  EXPECT_EQ(a.resorts, 0u);
  EXPECT_GT(b.resorts, 5u);
  if (expect_soft) {
    EXPECT_GT(a.hybrid.to_soft, 20u);
    EXPECT_GT(a.hybrid.to_hard, 20u);
  } else {
    EXPECT_EQ(a.hybrid.to_soft, 0u);
  }
  EXPECT_EQ(a.hybrid.to_soft, b.hybrid.to_soft);
  EXPECT_EQ(a.hybrid.soft_particle_steps, b.hybrid.soft_particle_steps);
  expect_same_reports(plain, sorted);
  expect_same_state(a, b);
}

TEST(EdmResort, TheHybridReSortsWhileNoGrainIsSoft) {
  check_hybrid_gas(1.0, false, false, 0.5);
  check_hybrid_gas(1.0, true, false, 0.5);
  // Re-sorted every 1/50 event per particle (ten events of the gas): a re-sort falls between a
  // grain's collisions and the stability switch that draws its recent partners in.
  check_hybrid_gas(0.3, false, true, 0.02);
  check_hybrid_gas(0.3, true, true, 0.02);
}

TEST(EdmResort, SceneKeys) {
  using test::small_gas_scene;
  auto load = [](const std::string& line) { return load_scene_string(small_gas_scene(line), "s.toml", ".", {}).resort; };
  EXPECT_LT(load(""), 0.0);
  EXPECT_LT(load("resort = \"auto\"\n"), 0.0);
  EXPECT_EQ(load("resort = \"off\"\n"), 0.0);
  EXPECT_EQ(load("resort = 12.5\n"), 12.5);
  test::expect_scene_error(small_gas_scene("resort = \"often\"\n"), "s.toml", ".", {"run.resort", "often"});
  test::expect_scene_error(small_gas_scene("resort = 0\n"), "s.toml", ".", {"run.resort", "0"});
  test::expect_scene_error(small_gas_scene("resort = -3.0\n"), "s.toml", ".", {"run.resort", "-3"});
}

}  // namespace
}  // namespace matep

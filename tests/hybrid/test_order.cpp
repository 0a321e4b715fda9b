// The hybrid runs its grains in space order (engine/renumber.hpp) and reports them by the scene's
// ids: the order itself, the map back, and whole runs whose ids are scattered in space checked
// against pure EDM (which keeps the scene's order): the same collisions between the same grains,
// the same final state per grain, snapshots and messages naming the scene's grains.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include "engine/edm.hpp"
#include "engine/hybrid.hpp"
#include "engine/renumber.hpp"
#include "tests/support/systems.hpp"

namespace matep {
namespace {

TEST(SpatialOrder, GroupsGrainsByCellWithTheLongestAxisSlowest) {
  // A 4 x 1 x 2 box of unit-diameter grains: cells of one diameter, x (longest) slowest, then z,
  // then y. Grains listed out of order; two share the cell (1, 0, 1) and keep their id order.
  System<3> s;
  s.upper = Vec<3>(4.0, 1.0, 2.0);
  const std::vector<Vec<3>> x = {{3.5, 0.5, 0.5}, {0.5, 0.5, 1.5}, {1.2, 0.5, 1.5}, {0.5, 0.5, 0.5},
                                 {1.7, 0.4, 1.6}, {1.5, 0.5, 0.5}};
  for (const auto& p : x) {
    s.x.push_back(p);
    s.v.push_back(Vec<3>::Zero());
    s.radius.push_back(0.5);
    s.material.push_back(0);
  }
  EXPECT_EQ(spatial_order(s), (std::vector<std::uint32_t>{3, 1, 5, 2, 4, 0}));
}

// The order by cells, stable in the ids, whichever way it is sorted: by counting when the cells
// are few against the grains (a box of 100 x 10 cells, 300 grains), by comparison in a mostly
// empty domain (10 000 x 10 cells): both against the order written out from the definition.
TEST(SpatialOrder, CountingAndComparisonSortsGiveTheCellOrder) {
  for (const double width : {100.0, 10000.0}) {
    System<2> s;
    s.upper = Vec<2>(width, 10.0);
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> ux(0.0, 100.0), uy(0.0, 10.0);
    for (int k = 0; k < 300; ++k) {
      s.x.push_back(Vec<2>(ux(rng), uy(rng)));
      s.v.push_back(Vec<2>::Zero());
      s.radius.push_back(k % 3 == 0 ? 0.5 : 0.3);  // cells of one largest diameter: 1
      s.material.push_back(0);
    }
    std::vector<std::uint32_t> want(s.size());
    std::iota(want.begin(), want.end(), 0u);
    auto key = [&](std::uint32_t i) {  // x (the longer axis) slowest
      return std::floor(s.x[i][0]) * 10.0 + std::floor(s.x[i][1]);
    };
    std::stable_sort(want.begin(), want.end(), [&](std::uint32_t a, std::uint32_t b) { return key(a) < key(b); });
    EXPECT_EQ(spatial_order(s), want) << "domain width " << width;
  }
}

TEST(SpatialOrder, TheMapBackRestoresTheScenesRowsAndContacts) {
  System<3> s = test::lattice_gas<3>(6, 0.2, 1.0, 1.0, 3);
  std::mt19937 rng(5);
  std::shuffle(s.x.begin(), s.x.end(), rng);
  for (std::size_t i = 0; i < s.size(); ++i) s.radius[i] = 0.4 + 0.001 * static_cast<double>(i);
  System<3> r = s;
  const std::vector<std::uint32_t> order = spatial_order(r);
  reorder(r, order);
  ASSERT_NE(r.x, s.x);  // the shuffle scattered the ids
  const IdMap ids(order);
  // A final state in engine order, its last engine grain gone, comes back in the scene's order.
  RunResult<3> res;
  for (std::size_t k = 0; k + 1 < r.size(); ++k) {
    res.id.push_back(static_cast<std::uint32_t>(k));
    res.x.push_back(r.x[k]);
    res.v.push_back(r.v[k]);
    res.radius.push_back(r.radius[k]);
    res.material.push_back(r.material[k]);
  }
  to_user(res, ids);
  ASSERT_EQ(res.id.size(), s.size() - 1);
  for (std::size_t row = 0; row < res.id.size(); ++row) {
    const std::uint32_t u = res.id[row];
    EXPECT_NE(u, order.back());
    if (row > 0) {
      EXPECT_LT(res.id[row - 1], u);
    }
    EXPECT_EQ(res.x[row], s.x[u]);
    EXPECT_EQ(res.v[row], s.v[u]);
    EXPECT_EQ(res.radius[row], s.radius[u]);
  }
  // A pair contact keeps i < j in the scene's ids, its force then the one on the new i.
  ContactRow<3> c;
  c.i = 0;
  c.j = 1;
  c.fn = Vec<3>(1.0, 0.0, 0.0);
  contact_to_user(c, IdMap({7, 2}));
  EXPECT_EQ(c.i, 2u);
  EXPECT_EQ(c.j, 7);
  EXPECT_EQ(c.fn, Vec<3>(-1.0, 0.0, 0.0));
}

TEST(SpatialOrder, ObserversHearTheScenesIdsAndClusterLabelsInTheirOrder) {
  // Engine order 0 1 2 3 = scene ids 3 1 0 2 (inlet grains from 4 on keep theirs).
  struct Sink final : Observer<3> {
    Snapshot<3> snap;
    std::vector<std::uint32_t> out, in;
    std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;
    bool wants_collisions() const override { return true; }
    void on_collision(const CollisionRecord<3>& c) override { pairs.emplace_back(c.i, c.j); }
    bool wants_snapshots() const override { return true; }
    void on_snapshot(const Snapshot<3>& s) override { snap = s; }
    void on_outflow(const OutflowRecord<3>& o) override { out.push_back(o.id); }
    void on_inflow(const InflowRecord<3>& i) override { in.push_back(i.id); }
  } sink;
  const IdMap ids({3, 1, 0, 2});
  UserIds<3> u(sink, ids);
  EXPECT_TRUE(u.wants_collisions() && u.wants_snapshots());
  CollisionRecord<3> pc;
  pc.kind = EventKind::PairCollision;
  pc.i = 0;
  pc.j = 2;
  u.on_collision(pc);
  CollisionRecord<3> wc;
  wc.kind = EventKind::WallCollision;
  wc.i = 3;
  wc.j = 1;  // the wall's index: not a grain
  u.on_collision(wc);
  EXPECT_EQ(sink.pairs, (std::vector<std::pair<std::uint32_t, std::uint32_t>>{{3, 0}, {2, 1}}));
  OutflowRecord<3> o;
  o.id = 1;
  u.on_outflow(o);
  InflowRecord<3> in;
  in.id = 5;
  u.on_inflow(in);
  EXPECT_EQ(sink.out, std::vector<std::uint32_t>{1});
  EXPECT_EQ(sink.in, std::vector<std::uint32_t>{5});
  // A snapshot whose engine grain 1 (scene id 1) has left: rows by scene id, clusters renumbered
  // in the order the scene's ids meet them.
  Snapshot<3> s;
  s.id = {0, 2, 3, 4};
  for (double z : {0.0, 2.0, 3.0, 4.0}) {
    s.x.push_back(Vec<3>(0.0, 0.0, z));
    s.v.push_back(Vec<3>::Zero());
    s.radius.push_back(0.5);
  }
  s.mode = {1, 0, 1, 1};
  s.cluster = {0, -1, 1, 1};
  u.on_snapshot(s);
  EXPECT_EQ(sink.snap.id, (std::vector<std::uint32_t>{0, 2, 3, 4}));
  EXPECT_EQ(sink.snap.x[0].z(), 2.0);  // scene id 0 = engine 2
  EXPECT_EQ(sink.snap.x[1].z(), 3.0);  // scene id 2 = engine 3
  EXPECT_EQ(sink.snap.x[2].z(), 0.0);  // scene id 3 = engine 0
  EXPECT_EQ(sink.snap.x[3].z(), 4.0);  // an inlet grain
  EXPECT_EQ(sink.snap.mode, (std::vector<std::uint8_t>{0, 1, 1, 1}));
  EXPECT_EQ(sink.snap.cluster, (std::vector<std::int32_t>{-1, 0, 1, 0}));
}

struct Recorder final : Observer<3> {
  std::vector<CollisionRecord<3>> coll;
  std::vector<Snapshot<3>> snaps;
  bool wants_collisions() const override { return true; }
  void on_collision(const CollisionRecord<3>& c) override {
    if (c.kind == EventKind::PairCollision) coll.push_back(c);
  }
  bool wants_snapshots() const override { return true; }
  void on_snapshot(const Snapshot<3>& s) override { snaps.push_back(s); }
};

TEST(HybridIds, ADiluteGasWithScatteredIdsMatchesEdmGrainByGrain) {
  // 512 elastic spheres at phi = 0.1, ids shuffled in space: the hybrid keeps every grain hard
  // and must report the same collisions (same grains, same times) and end states as EDM.
  System<3> s = test::lattice_gas<3>(8, 0.1, 1.0, 1.0, 9);
  s.materials[0] = test::linear_material("grain", s.materials[0].density, 1.0e6, 1.0);
  std::mt19937 rng(2);
  std::shuffle(s.x.begin(), s.x.end(), rng);
  std::vector<std::uint32_t> same(s.size());
  std::iota(same.begin(), same.end(), 0u);
  ASSERT_NE(spatial_order(s), same);  // the hybrid runs the grains in another order than EDM
  EdmSettings es;
  es.end_time = 2.0;
  es.snapshot_interval = 0.5;
  Recorder edm, hyb;
  const RunResult<3> a = run_edm<3>(s, es, QueueKind::Calendar, {&edm});
  const RunResult<3> b = run_hybrid<3>(s, es, HybridSettings{}, {&hyb});
  ASSERT_EQ(b.status, "ok");
  ASSERT_EQ(b.hybrid.to_soft, 0u);
  ASSERT_GT(edm.coll.size(), 300u);
  for (std::size_t k = 0; k < 300; ++k) {
    EXPECT_EQ(std::minmax(edm.coll[k].i, edm.coll[k].j), std::minmax(hyb.coll[k].i, hyb.coll[k].j)) << k;
    EXPECT_NEAR(edm.coll[k].time, hyb.coll[k].time, 1e-9) << k;
  }
  // The first and second snapshots (before chaos amplifies the round-off) and the final state.
  ASSERT_EQ(edm.snaps.size(), hyb.snaps.size());
  for (std::size_t n = 0; n < 2; ++n)
    for (std::size_t i = 0; i < s.size(); ++i) EXPECT_LT((edm.snaps[n].x[i] - hyb.snaps[n].x[i]).norm(), 1e-6) << n;
  ASSERT_EQ(a.x.size(), b.x.size());
  for (std::size_t i = 0; i < s.size(); ++i) EXPECT_EQ(a.radius[i], b.radius[i]);
  EXPECT_TRUE(b.id.empty());
}

TEST(HybridIds, AnEscapeNamesTheScenesGrain) {
  // Three grains; grain 0 lies last in space order and flies out through the open top (no wall).
  System<3> s;
  s.upper = Vec<3>(4.0, 4.0, 4.0);
  s.materials.push_back(test::linear_material("grain", 1.0, 1.0e6, 0.9));
  const std::vector<Vec<3>> x = {{3.5, 3.5, 3.5}, {0.5, 0.5, 0.5}, {0.5, 2.5, 0.5}};
  for (const auto& p : x) {
    s.x.push_back(p);
    s.v.push_back(Vec<3>::Zero());
    s.radius.push_back(0.5);
    s.material.push_back(0);
  }
  ASSERT_EQ(spatial_order(s).back(), 0u);
  s.v[0] = Vec<3>(0.0, 0.0, 1.0);
  EdmSettings es;
  es.end_time = 2.0;
  const RunResult<3> r = run_hybrid<3>(s, es, HybridSettings{});
  EXPECT_EQ(r.status, "escaped");
  EXPECT_NE(r.message.find("particle 0 left the domain along axis 2"), std::string::npos) << r.message;
}

}  // namespace
}  // namespace matep

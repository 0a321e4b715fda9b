// The hybrid's hard side on neighbour lists (run.neighbours = "lists"; engine/hybrid/hybrid.cpp
// ext_lists) against the same runs on cells. Every grain keeps a shell and a list, soft and
// sleeping ones too, and a hard grain lists each grain it may be captured by; so the two runs make
// the same hard collisions and the same switches, at the same substeps, until round-off (the
// shells' exits advance grains at other moments than the cells' crossings) has grown through
// chaos, or until a capture chain: a grain captured at a substep may capture a neighbour in the
// same pass or at the next substep, as the checks' order has it, and on lists the hard grains are
// marked for the checks in another order. A capture the lists missed would show as a switch out
// of turn: the grain would join later, by overlap, or not at all.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <tuple>
#include <utility>
#include <vector>

#include "engine/edm.hpp"
#include "engine/hybrid.hpp"
#include "tests/support/systems.hpp"

namespace matep {
namespace {

using test::Recorder;

// The hybrid on cells or lists, one thread.
template <int D>
RunResult<D> run(const System<D>& sys, double end, bool lists, Recorder<D>& rec) {
  EdmSettings es;
  es.end_time = end;
  es.thermo_interval = end / 10;
  es.lists = lists;
  HybridSettings hs;
  hs.threads = 1;
  return run_hybrid<D>(sys, es, hs, {&rec});
}

// Whether two records are the same event: kind, grains (a pair's in either order), time within
// tol (relative) and the velocities after it within 1e3 tol.
template <int D>
bool same_event(const CollisionRecord<D>& x, const CollisionRecord<D>& y, double tol) {
  if (x.kind != y.kind) return false;
  const bool swapped = x.kind == EventKind::PairCollision && x.i == y.j && x.j == y.i;
  if (!(swapped || (x.i == y.i && x.j == y.j))) return false;
  if (!(std::abs(x.time - y.time) <= tol * std::max(1.0, std::abs(x.time)))) return false;
  const Vec<D>& vy = swapped ? y.vj_after : y.vi_after;
  return (x.vi_after - vy).norm() <= 1e3 * tol * std::max(1.0, vy.norm());
}

// The number of leading records the two runs share. Records of one instant (a substep's switches
// and soft contacts, whose order follows the soft set's lists) are compared as sets of kinds and
// grains; a substep's time itself may differ by round-off (its grid starts at a collision's time).
template <int D>
std::size_t common_prefix(const Recorder<D>& a, const Recorder<D>& b, double tol) {
  const auto& A = a.records;
  const auto& B = b.records;
  const auto group_end = [&](const std::vector<CollisionRecord<D>>& r, std::size_t k) {
    std::size_t e = k + 1;
    while (e < r.size() && std::abs(r[e].time - r[k].time) <= tol * std::max(1.0, std::abs(r[k].time))) ++e;
    return e;
  };
  const auto key = [](const CollisionRecord<D>& r) {
    return std::make_tuple(static_cast<int>(r.kind), std::min(r.i, r.j), std::max(r.i, r.j));
  };
  std::size_t k = 0;
  while (k < A.size() && k < B.size()) {
    const std::size_t ea = group_end(A, k), eb = group_end(B, k);
    if (ea != eb) break;
    if (ea == k + 1) {
      if (!same_event(A[k], B[k], tol)) break;
    } else {
      if (!(std::abs(A[k].time - B[k].time) <= tol * std::max(1.0, std::abs(A[k].time)))) break;
      std::vector<std::tuple<int, std::uint32_t, std::uint32_t>> ka, kb;
      for (std::size_t q = k; q < ea; ++q) {
        ka.push_back(key(A[q]));
        kb.push_back(key(B[q]));
      }
      std::sort(ka.begin(), ka.end());
      std::sort(kb.begin(), kb.end());
      if (ka != kb) break;
    }
    k = ea;
  }
  return k;
}

template <int D>
std::size_t switches(const Recorder<D>& r, std::size_t upto) {
  std::size_t n = 0;
  for (std::size_t k = 0; k < std::min(upto, r.records.size()); ++k)
    n += r.records[k].kind == EventKind::ToSoft || r.records[k].kind == EventKind::ToHard;
  return n;
}

// A dense elastic gas (512 spheres at packing 0.45, periodic) stays hard: the hybrid on lists
// makes the collisions of the hybrid on cells, and of pure EDM on lists.
TEST(HybridLists, ADenseElasticGasMakesTheCollisionsOfTheCells) {
  System<3> s = test::lattice_gas<3>(8, 0.45, 1.0, 1.0, 3);
  s.materials[0].contact = "linear";
  s.materials[0].stiffness = 9.0e4;
  Recorder<3> cells, lists;
  const RunResult<3> a = run<3>(s, 2.0, false, cells);
  const RunResult<3> b = run<3>(s, 2.0, true, lists);
  ASSERT_EQ(a.status, "ok") << a.message;
  ASSERT_EQ(b.status, "ok") << b.message;
  EXPECT_FALSE(a.lists);
  EXPECT_TRUE(b.lists);
  EXPECT_EQ(b.hybrid.to_soft, 0u);
  EXPECT_GT(b.counts.cell, 100u);  // shells' exits
  const std::size_t k = common_prefix(cells, lists, 1e-9);
  EXPECT_GE(k, 1500u);
  // Pure EDM on lists: the same collisions (no grain turns soft: the hybrid is its core).
  Recorder<3> edm;
  EdmSettings es;
  es.end_time = 2.0;
  es.thermo_interval = 0.2;
  es.lists = true;
  const RunResult<3> e = run_edm<3>(s, es, QueueKind::Calendar, {&edm});
  ASSERT_EQ(e.status, "ok") << e.message;
  EXPECT_GE(common_prefix(edm, lists, 1e-9), 1500u);
  EXPECT_NEAR(lists.samples.back().kinetic_energy, lists.samples.front().kinetic_energy,
              1e-11 * lists.samples.front().kinetic_energy);
}

// The hybrid on cells and on lists from s to `end`: both reach the end, share at least `common`
// leading records with at least `switched` switches among them, and turn grains soft as often
// within the fraction `tol`. The two runs' records and samples (cells, lists).
template <int D>
std::pair<Recorder<D>, Recorder<D>> expect_alike(const System<D>& s, double end, std::size_t common,
                                                 std::size_t switched, double tol) {
  Recorder<D> cells, lists;
  const RunResult<D> a = run<D>(s, end, false, cells);
  const RunResult<D> b = run<D>(s, end, true, lists);
  EXPECT_EQ(a.status, "ok") << a.message;
  EXPECT_EQ(b.status, "ok") << b.message;
  EXPECT_TRUE(b.lists);
  const std::size_t k = common_prefix(cells, lists, 1e-9);
  EXPECT_GE(k, common);
  EXPECT_GE(switches(cells, k), switched);
  EXPECT_NEAR(static_cast<double>(b.hybrid.to_soft), static_cast<double>(a.hybrid.to_soft), tol * a.hybrid.to_soft);
  EXPECT_EQ(b.hybrid.by_overlap, a.hybrid.by_overlap);
  return {std::move(cells), std::move(lists)};
}

// A strongly inelastic dense gas (512 spheres, packing 0.3, e = 0.1), where the stability rule
// turns clusters soft within the first collisions and the soft grains capture their neighbours:
// the lists run makes the same collisions and the same switches, grain for grain and substep for
// substep, as the cells run, through dozens of switches; then chaos parts them (a grazing
// collision turns round-off of 1e-16 into 1e-10) or a capture chain does, and what is left to
// compare is the counts. Measured: 268, 312 and 240 records in common, with 71, 82 and 35
// switches (held to about half: a build with other optimisations rounds differently); 789-856
// switches to soft in a run, the two runs within 0.5 % of each other.
TEST(HybridLists, AnInelasticGasSwitchesAsOnTheCells) {
  for (const std::uint64_t seed : {1u, 2u, 3u}) {
    SCOPED_TRACE(::testing::Message() << "seed " << seed);
    System<3> s = test::lattice_gas<3>(8, 0.3, 1.0, 0.1, seed);
    s.materials[0].contact = "linear";
    s.materials[0].stiffness = 9.0e4;
    const auto [cells, lists] = expect_alike<3>(s, 1.0, 150, 20, 0.02);
    EXPECT_NEAR(lists.samples.back().kinetic_energy, cells.samples.back().kinetic_energy,
                1e-3 * cells.samples.back().kinetic_energy);
  }
}

// Under gravity the shells are cubes: 400 disks at packing 0.3 between a floor and a lid,
// periodic sideways, e = 0.3, fall into a bed that goes soft. Measured: 657 and 329 records in
// common, with 96 and 14 switches (each run parts at a capture chain); about 2 100 switches to
// soft a run (within 1.6 %); the same height (potential energy within 2.5e-4 of each other; two
// seeds' beds differ by 2 %).
TEST(HybridLists, ABedUnderGravitySwitchesAsOnTheCells) {
  for (const std::uint64_t seed : {1u, 2u}) {
    SCOPED_TRACE(::testing::Message() << "seed " << seed);
    System<2> s = test::lattice_gas<2>(20, 0.3, 1.0, 0.3, seed);
    s.materials[0].contact = "linear";
    s.materials[0].stiffness = 9.0e4;
    s.periodic[1] = false;
    s.upper[1] *= 2.0;
    s.gravity = Vec<2>(0.0, -2.0);
    s.walls.push_back(plane_wall<2>("floor", Vec<2>::Zero(), Vec<2>(0.0, 1.0)));
    s.walls.push_back(plane_wall<2>("lid", s.upper, Vec<2>(0.0, -1.0)));
    const auto [cells, lists] = expect_alike<2>(s, 4.0, 200, 10, 0.05);
    EXPECT_NEAR(lists.samples.back().potential_energy, cells.samples.back().potential_energy,
                1e-3 * cells.samples.back().potential_energy);
  }
}

}  // namespace
}  // namespace matep

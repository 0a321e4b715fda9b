// EDM pair candidates from neighbour lists (engine/edm/core.hpp "neighbour lists") against the
// cells: the same collisions, in the same order, at the same times up to round-off (the shells'
// exits advance particles at other moments than the cell crossings, so the last bits differ and
// chaos amplifies them: only the first collisions are compared), in ball shells (no gravity) and
// cube shells (gravity, walls, periodic wraps), and the rule that chooses between them.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstring>
#include <vector>

#include "engine/edm.hpp"
#include "engine/edm/neighbours.hpp"
#include "engine/state_archive.hpp"
#include "io/scene.hpp"
#include "tests/support/scene_errors.hpp"
#include "tests/support/systems.hpp"

namespace matep {
namespace {

using test::lattice_gas;
using test::Recorder;

template <int D>
RunResult<D> run(const System<D>& sys, double end, bool lists, Recorder<D>& rec, double shell = 0.125) {
  EdmSettings s;
  s.end_time = end;
  s.thermo_interval = end / 4;
  s.lists = lists;
  s.shell = shell;
  return run_edm<D>(sys, s, QueueKind::Calendar, {&rec});
}

// The first n collisions of the two runs: the same pair (or wall), at the same time within tol.
template <int D>
void expect_same_collisions(const Recorder<D>& a, const Recorder<D>& b, std::size_t n, double tol) {
  ASSERT_GE(a.records.size(), n);
  ASSERT_GE(b.records.size(), n);
  for (std::size_t k = 0; k < n; ++k) {
    const auto& x = a.records[k];
    const auto& y = b.records[k];
    ASSERT_EQ(x.kind, y.kind) << "collision " << k;
    // A pair's event is predicted by both grains: either may report it (i and j swapped).
    const bool swapped = x.kind == EventKind::PairCollision && x.i == y.j && x.j == y.i;
    ASSERT_TRUE(swapped || (x.i == y.i && x.j == y.j)) << "collision " << k << ": " << x.i << "-" << x.j << " and "
                                                       << y.i << "-" << y.j;
    ASSERT_NEAR(x.time, y.time, tol * std::max(1.0, std::abs(x.time))) << "collision " << k;
    const Vec<D>& vy = swapped ? y.vj_after : y.vi_after;
    for (int d = 0; d < D; ++d) ASSERT_NEAR(x.vi_after[d], vy[d], 1e3 * tol) << "collision " << k;
  }
}

// No pair overlaps at the end, and the kinetic energy of an elastic gas is kept.
template <int D>
void expect_sound(const RunResult<D>& r, const Recorder<D>& rec) {
  EXPECT_EQ(r.status, "ok") << r.message;
  EXPECT_LT(r.max_overlap, 1e-9);
  ASSERT_GE(rec.samples.size(), 2u);
  EXPECT_NEAR(rec.samples.back().kinetic_energy, rec.samples.front().kinetic_energy,
              1e-11 * rec.samples.front().kinetic_energy);
}

TEST(EdmLists, SameCollisionsAsTheCellsInADense3DGas) {
  // 512 spheres at packing 0.45 in a periodic box: wraps across every face, lists of about ten.
  const System<3> sys = lattice_gas<3>(8, 0.45, 1.0, 1.0, 5);
  Recorder<3> cells, lists;
  const RunResult<3> a = run<3>(sys, 2.0, false, cells);
  const RunResult<3> b = run<3>(sys, 2.0, true, lists);
  EXPECT_FALSE(a.lists);
  EXPECT_TRUE(b.lists);
  expect_sound(a, cells);
  expect_sound(b, lists);
  expect_same_collisions(cells, lists, 1500, 1e-9);
  // The shells' exits happen (they are the lists' crossings) and at most every few collisions.
  EXPECT_GT(b.counts.cell, 100u);
  EXPECT_LT(b.counts.cell, b.counts.collisions());
  // Past the compared collisions the two runs part (chaos), but their collision counts agree
  // within the scatter of a short run.
  const double ra = static_cast<double>(a.counts.pair), rb = static_cast<double>(b.counts.pair);
  EXPECT_NEAR(rb / ra, 1.0, 0.05);
}

TEST(EdmLists, SameCollisionsAsTheCellsInADense2DGasWithLargeShells) {
  // Disks at packing 0.6; shells of half a diameter: longer lists, fewer exits, same collisions.
  const System<2> sys = lattice_gas<2>(20, 0.6, 1.0, 1.0, 9);
  for (const double shell : {0.05, 0.5}) {
    SCOPED_TRACE(shell);
    Recorder<2> cells, lists;
    const RunResult<2> a = run<2>(sys, 1.0, false, cells);
    const RunResult<2> b = run<2>(sys, 1.0, true, lists, shell);
    expect_sound(b, lists);
    expect_same_collisions(cells, lists, 1000, 1e-9);
  }
}

// A 2D gas under gravity between a floor and a lid, periodic across: cube shells, wall
// collisions, inelastic pairs.
System<2> gravity_box() {
  System<2> s = lattice_gas<2>(12, 0.35, 1.0, 0.9, 3);
  const double L = s.upper[0];
  s.periodic = {true, false};
  s.upper[1] = 1.5 * L;  // room above the gas
  s.gravity = Vec<2>(0.0, -1.0);
  s.walls.push_back(plane_wall<2>("floor", Vec<2>(0.0, 0.0), Vec<2>(0.0, 1.0)));
  s.walls.push_back(plane_wall<2>("lid", Vec<2>(0.0, 1.5 * L), Vec<2>(0.0, -1.0)));
  return s;
}

TEST(EdmLists, SameCollisionsAsTheCellsUnderGravityWithWalls) {
  const System<2> sys = gravity_box();
  Recorder<2> cells, lists;
  const RunResult<2> a = run<2>(sys, 6.0, false, cells);
  const RunResult<2> b = run<2>(sys, 6.0, true, lists);
  ASSERT_EQ(a.status, "ok") << a.message;
  ASSERT_EQ(b.status, "ok") << b.message;
  EXPECT_LT(b.max_overlap, 1e-9);
  std::size_t walls = 0;
  for (std::size_t k = 0; k < 1000 && k < cells.records.size(); ++k)
    walls += cells.records[k].kind == EventKind::WallCollision;
  EXPECT_GT(walls, 10u);  // the comparison covers wall collisions too
  expect_same_collisions(cells, lists, 1000, 1e-9);
}

TEST(EdmLists, AGrainLeavingAClosedFaceWithoutOutletStopsTheRunAsWithCells) {
  // One grain flying out of a closed box with no wall: "escaped", the same message either way.
  System<3> s = lattice_gas<3>(3, 0.1, 1.0, 1.0, 1);
  s.periodic = {true, true, false};
  for (auto& v : s.v) v = Vec<3>(0.1, 0.0, 0.0);
  s.v[13] = Vec<3>(0.0, 0.0, 1.0);
  Recorder<3> cells, lists;
  const RunResult<3> a = run<3>(s, 50.0, false, cells);
  const RunResult<3> b = run<3>(s, 50.0, true, lists);
  EXPECT_EQ(a.status, "escaped");
  EXPECT_EQ(b.status, "escaped");
  // The same grain along the same axis, at the same time up to round-off.
  const std::string who = a.message.substr(0, a.message.find(" at t = "));
  EXPECT_NE(who.find("left the domain along axis 2"), std::string::npos) << a.message;
  EXPECT_EQ(b.message.rfind(who + " at t = ", 0), 0u) << b.message;
  EXPECT_NEAR(a.time, b.time, 1e-12);
}

TEST(EdmLists, ResumedFromACheckpointTheRunIsTheSameBitForBit) {
  const System<3> sys = lattice_gas<3>(6, 0.45, 1.0, 0.95, 2);
  EdmSettings s;
  s.end_time = 1.0;
  s.thermo_interval = 0.1;
  s.lists = true;
  const RunResult<3> whole = run_edm<3>(sys, s, QueueKind::Calendar);
  ASSERT_EQ(whole.status, "ok") << whole.message;
  // Stopped at t = 0.4 (an interval checkpoint), continued from there.
  std::vector<std::vector<std::uint8_t>> states;
  CheckpointHooks keep;
  keep.interval = 0.4;
  keep.save = [&](double, const auto& st) { states.push_back(archive_bytes(st)); };
  EdmSettings s1 = s;
  s1.checkpoint = &keep;
  run_edm<3>(sys, s1, QueueKind::Calendar);
  ASSERT_GE(states.size(), 2u);
  CheckpointHooks resume;
  resume.interval = keep.interval;  // the same system events as the run that saved it
  resume.resume = &states[0];
  EdmSettings s2 = s;
  s2.checkpoint = &resume;
  const RunResult<3> cont = run_edm<3>(sys, s2, QueueKind::Calendar);
  ASSERT_EQ(cont.status, "ok") << cont.message;
  EXPECT_EQ(cont.counts.pair, whole.counts.pair);
  ASSERT_EQ(cont.x.size(), whole.x.size());
  EXPECT_EQ(std::memcmp(cont.x.data(), whole.x.data(), whole.x.size() * sizeof(Vec<3>)), 0);
  EXPECT_EQ(std::memcmp(cont.v.data(), whole.v.data(), whole.v.size() * sizeof(Vec<3>)), 0);
  // A state saved with lists is refused by a run with cells (a different engine state).
  EdmSettings s3 = s2;
  s3.lists = false;
  EXPECT_THROW(run_edm<3>(sys, s3, QueueKind::Calendar), StateError);
}

TEST(EdmLists, AutoChoosesListsForADenseGasWithoutGravityOnly) {
  EXPECT_TRUE(edm::lists_pay(0.48, false));
  EXPECT_FALSE(edm::lists_pay(0.48, true));
  EXPECT_FALSE(edm::lists_pay(0.30, false));
  for (const double phi : {0.3, 0.48}) {
    SCOPED_TRACE(phi);
    const System<3> sys = lattice_gas<3>(5, phi, 1.0, 1.0, 4);
    EdmSettings s;
    s.end_time = 0.2;
    s.lists_auto = true;
    const RunResult<3> r = run_edm<3>(sys, s, QueueKind::Calendar);
    EXPECT_EQ(r.lists, phi >= edm::kListsFromPacking);
  }
}

// A list entry packs its partner's index into kListIdBits bits: a run with more particle slots
// than they can number takes the cells, whatever was asked.
TEST(EdmLists, ARunTooLargeForTheListsEntriesTakesTheCells) {
  EXPECT_EQ(edm::kListsUpTo, (std::size_t{1} << 27) - 1);
  EXPECT_TRUE(edm::lists_chosen(true, false, 0.1, true, edm::kListsUpTo));
  EXPECT_FALSE(edm::lists_chosen(true, false, 0.1, true, edm::kListsUpTo + 1));
  EXPECT_TRUE(edm::lists_chosen(false, true, 0.48, false, edm::kListsUpTo));
  EXPECT_FALSE(edm::lists_chosen(false, true, 0.48, false, edm::kListsUpTo + 1));
  EXPECT_FALSE(edm::lists_chosen(false, false, 0.48, false, 1000));
}

TEST(EdmLists, SceneKeys) {
  using test::small_gas_scene;
  const Scene a = load_scene_string(small_gas_scene("neighbours = \"auto\"\nshell = 0.3\n"), "s.toml", ".", {});
  EXPECT_EQ(a.neighbours, "auto");
  EXPECT_DOUBLE_EQ(a.shell, 0.3);
  EXPECT_EQ(load_scene_string(small_gas_scene(""), "s.toml", ".", {}).neighbours, "cells");
  test::expect_scene_error(small_gas_scene("neighbours = \"verlet\"\n"), "s.toml", ".", {"run.neighbours", "verlet"});
  test::expect_scene_error(small_gas_scene("shell = 0.0\n"), "s.toml", ".", {"run.shell", "0"});
  test::expect_scene_error(small_gas_scene("shell = 5.0\n"), "s.toml", ".", {"run.shell", "5"});
}

}  // namespace
}  // namespace matep

// Cells that cost memory only where grains are (engine/grid.hpp, hashed cells): the same grains in
// the same walls give the same run whether the domain is the walls' box or a box a million times
// larger in volume around it (which would need ~1e13 dense cells: only the hashed grid can run
// it). Positions agree to round-off (the event and force orders differ in the last bits).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "engine/edm.hpp"
#include "engine/grid.hpp"
#include "engine/hybrid.hpp"
#include "engine/tdm.hpp"
#include "tests/support/systems.hpp"

namespace matep {
namespace {

// n grains of radius 0.02 at random non-overlapping places inside the unit box closed by planes,
// with random velocities; the domain is the box (scale 1) or the box centred in a cube `scale`
// times wider.
template <int D>
System<D> walled_gas(int n, double scale, const Material& m, bool gravity) {
  System<D> s;
  const double half = 0.5 * scale;
  s.lower = Vec<D>::Constant(0.5 - half);
  s.upper = Vec<D>::Constant(0.5 + half);
  s.materials.push_back(m);
  if (gravity) s.gravity[D - 1] = -9.81;
  for (int k = 0; k < D; ++k) {
    Vec<D> n0 = Vec<D>::Zero();
    n0[k] = 1.0;
    s.walls.push_back(plane_wall<D>("lo", Vec<D>::Zero(), n0));
    s.walls.push_back(plane_wall<D>("hi", Vec<D>::Ones(), -n0));
  }
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0.03, 0.97), vel(-1.0, 1.0);
  const double R = 0.02;
  while (static_cast<int>(s.x.size()) < n) {
    Vec<D> x;
    for (int k = 0; k < D; ++k) x[k] = u(rng);
    bool ok = true;
    for (const auto& y : s.x) ok = ok && (x - y).norm() > 2.0 * R * 1.05;
    if (!ok) continue;
    Vec<D> v;
    for (int k = 0; k < D; ++k) v[k] = vel(rng);
    s.x.push_back(x);
    s.v.push_back(v);
    s.radius.push_back(R);
    s.material.push_back(0);
  }
  return s;
}

template <int D>
void expect_same_states(const RunResult<D>& a, const RunResult<D>& b, double tol) {
  ASSERT_EQ(a.status, "ok");
  ASSERT_EQ(b.status, "ok");
  ASSERT_EQ(a.x.size(), b.x.size());
  double worst = 0.0;
  for (std::size_t i = 0; i < a.x.size(); ++i) worst = std::max(worst, (a.x[i] - b.x[i]).norm());
  EXPECT_LT(worst, tol);
}

TEST(SparseCells, TheGridHashesAMostlyEmptyDomainAndKeepsItsCellsNarrow) {
  CellGrid<3> g;
  const std::array<bool, 3> closed{};
  g.build(Vec<3>::Zero(), Vec<3>::Constant(1000.0), closed, 0.05, 2000.0, 1 << 20, true);
  EXPECT_TRUE(g.hashed());
  EXPECT_GE(g.cells(), 2000);
  EXPECT_LT(g.cells(), 4096 + 1);  // the next power of two: memory with the grains
  EXPECT_NEAR(g.width(0), 0.05, 1e-12);
  // The 27 cells around one cell are visited once each, with their images on periodic axes.
  const std::array<bool, 3> per{true, true, true};
  g.build(Vec<3>::Zero(), Vec<3>::Constant(1000.0), per, 0.05, 2000.0, 1 << 20, true);
  int visits = 0;
  g.around({0, 5, 7}, [&](int, const Vec<3>&) { ++visits; });
  EXPECT_EQ(visits, 27);
  // A compact box is not hashed (the dense layout, as before).
  g.build(Vec<3>::Zero(), Vec<3>::Ones(), closed, 0.05, 2000.0, 1 << 20, true);
  EXPECT_FALSE(g.hashed());
}

template <int D>
void check_edm(int n, double end) {
  Material m;
  m.name = "g";
  m.density = 1000.0;
  m.restitution = Restitution::constant(0.9);
  EdmSettings set;
  set.end_time = end;
  const auto a = run_edm<D>(walled_gas<D>(n, 1.0, m, false), set, QueueKind::Calendar);
  const auto b = run_edm<D>(walled_gas<D>(n, 1e2, m, false), set, QueueKind::Calendar);
  EXPECT_EQ(a.counts.pair, b.counts.pair);
  EXPECT_EQ(a.counts.wall, b.counts.wall);
  EXPECT_GT(a.counts.pair, static_cast<std::uint64_t>(n / 2));
  expect_same_states<D>(a, b, 1e-9);
}

// Short runs (a few collisions per grain): the trajectories are chaotic, and the round-off of the
// two runs' different event orders must not grow beyond the tolerance.
TEST(SparseCells, EdmRunsTheSameInAHugeDomain2D) { check_edm<2>(300, 0.05); }
TEST(SparseCells, EdmRunsTheSameInAHugeDomain3D) { check_edm<3>(400, 0.6); }

TEST(SparseCells, TdmRunsTheSameInAHugeDomain3D) {
  const Material m = test::linear_material("g", 1000.0, 1e4, 0.5);
  TdmSettings set;
  set.end_time = 0.1;
  set.threads = 1;
  std::vector<Observer<3>*> none;
  RunResult<3> a, b;
  try {
    a = run_tdm<3>(walled_gas<3>(400, 1.0, m, true), set);
    b = run_tdm<3>(walled_gas<3>(400, 1e2, m, true), set);
  } catch (const std::exception& ex) {
    FAIL() << ex.what();
  }
  EXPECT_GT(a.counts.pair, 50u);  // contacts begun
  EXPECT_EQ(a.counts.pair, b.counts.pair);
  expect_same_states<3>(a, b, 1e-9);
}

// The hybrid's trajectories depend on the domain through its cell layout (the substeps interleave
// with the cell crossings' bookkeeping), so a settling pile's round-off differences grow; what must
// not change is the physics: the soft set works (no grain passes through another: overlaps stay at
// the soft model's few per cent) and the pile settles to the same height.
TEST(SparseCells, HybridSettlesTheSamePileInAHugeDomain2D) {
  const Material m = test::linear_material("g", 1000.0, 1e4, 0.5);
  EdmSettings e;
  e.end_time = 1.0;
  HybridSettings h;
  h.dt = 1e-4;
  const auto a = run_hybrid<2>(walled_gas<2>(300, 1.0, m, true), e, h);
  const auto b = run_hybrid<2>(walled_gas<2>(300, 1e2, m, true), e, h);
  ASSERT_EQ(a.status, "ok");
  ASSERT_EQ(b.status, "ok");
  EXPECT_GT(b.hybrid.soft_particle_steps, 100000u);
  EXPECT_LT(b.max_overlap_relative, 2.0 * a.max_overlap_relative + 1e-3);
  double ya = 0.0, yb = 0.0;
  for (std::size_t i = 0; i < a.x.size(); ++i) {
    ya += a.x[i][1];
    yb += b.x[i][1];
  }
  EXPECT_NEAR(yb / ya, 1.0, 0.02);
}

}  // namespace
}  // namespace matep

// Flow geometry at length: an elastic hard-sphere gas in a closed tube (a finite cylinder, touched
// from both sides, capped by two planes) keeps its kinetic energy over more than 10^6 collisions,
// a quarter of them with the curved wall, and no grain is ever found beyond the walls: every
// impact time on the tube (offset cylinder and rim tori, contact/shape_features.hpp) is exact.
// The same for a gas in a closed pipe bend (a quarter torus between two straight runs, closed by
// its end caps: contact/pipe.hpp) and for a gas in a closed box made of 12 triangles (contact/mesh.hpp): faces, the concave
// edges and corners. A box mesh and the six equivalent planes give the same settled bed (TDM and
// the hybrid): mean height within 0.5 %, and from one settled state the same forces (the two runs
// stay together to round-off).
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>

#include "contact/cylinder.hpp"
#include "contact/mesh.hpp"
#include "contact/pipe.hpp"
#include "engine/edm.hpp"
#include "engine/hybrid.hpp"
#include "engine/tdm.hpp"
#include "tests/support/mesh_shapes.hpp"
#include "tests/support/shape_physics.hpp"

namespace matep {
namespace {

TEST(FlowGeometryValidation, ElasticGasInAClosedTubeKeepsItsEnergyOverAMillionCollisions) {
  System<3> s;
  const double Rc = 0.05, L = 0.2, R = 0.002;
  s.lower = Vec<3>(-0.06, -0.06, -0.01);
  s.upper = Vec<3>(0.06, 0.06, 0.21);
  Material m;
  m.name = "g";
  m.density = 2500.0;
  m.restitution = Restitution::constant(1.0);
  s.materials.push_back(m);
  s.walls.push_back(Wall<3>{"tube", 0, std::make_shared<CylinderWall<3>>(Vec<3>::Zero(), Vec<3>(0, 0, 1), Rc, L)});
  s.walls.push_back(plane_wall<3>("bottom", Vec<3>::Zero(), Vec<3>(0, 0, 1)));
  s.walls.push_back(plane_wall<3>("top", Vec<3>(0, 0, L), Vec<3>(0, 0, -1)));
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::normal_distribution<double> g;
  while (s.x.size() < 2000) {
    const Vec<3> x(0.045 * u(rng), 0.045 * u(rng), 0.1 + 0.097 * u(rng));
    if (std::hypot(x[0], x[1]) > Rc - 1.01 * R) continue;
    bool ok = true;
    for (const auto& y : s.x) ok = ok && (x - y).norm() > 2.02 * R;
    if (!ok) continue;
    s.x.push_back(x);
    s.v.push_back(Vec<3>(g(rng), g(rng), g(rng)));
    s.radius.push_back(R);
    s.material.push_back(0);
  }
  double ke0 = 0.0;
  for (const auto& v : s.v) ke0 += 0.5 * s.mass(0) * v.squaredNorm();
  EdmSettings set;
  set.end_time = 5.0;
  const RunResult<3> r = run_edm<3>(s, set, QueueKind::Calendar);
  ASSERT_EQ(r.status, "ok");
  EXPECT_GT(r.counts.pair + r.counts.wall, 1000000u);
  EXPECT_GT(r.counts.wall, 200000u);
  double ke = 0.0, worst = 0.0;
  for (std::size_t i = 0; i < r.x.size(); ++i) {
    ke += 0.5 * s.mass(i) * r.v[i].squaredNorm();
    const Vec<3>& x = r.x[i];
    worst = std::max({worst, std::hypot(x[0], x[1]) + R - Rc, R - x[2], x[2] + R - L});
  }
  EXPECT_NEAR(ke / ke0, 1.0, 1e-10);
  EXPECT_LT(worst, 1e-12);
}

// Whether a grain of radius R at x lies clear inside the cube [0, L]^3 (gas placement).
auto inside_cube(double L, double R) {
  return [=](const Vec<3>& x) { return (x.array() > 1.01 * R).all() && (x.array() < L - 1.01 * R).all(); };
}

TEST(FlowGeometryValidation, ElasticGasInAPipeBendKeepsItsEnergyOverAMillionCollisions) {
  // Radius 0.03, from the origin along +x: 0.1 straight, a 90 degree bend of radius 0.08 about z
  // (towards +y), 0.1 straight; hemispherical caps close both ends.
  const double Rp = 0.03, R = 0.0015;
  auto pipe = std::make_shared<PipeWall<3>>(
      Vec<3>::Zero(), Vec<3>(1, 0, 0), Rp,
      std::vector<PipePiece<3>>{PipePiece<3>::straight(0.1), PipePiece<3>::arc(0.08, 0.5 * 3.141592653589793,
                                                                                Vec<3>(0, 0, 1)),
                                PipePiece<3>::straight(0.1)});
  System<3> s = test::hard_material_system<3>(Vec<3>(-0.05, -0.05, -0.05), Vec<3>(0.25, 0.25, 0.05));
  s.walls.push_back(Wall<3>{"bend", 0, pipe});
  test::fill_gas<3>(s, 2000, R, [&](const Vec<3>& x) { return pipe->at(x, R, 0.0).gap > 0.01 * R; }, 6);
  ASSERT_EQ(s.size(), 2000u);
  const double ke0 = test::kinetic<3>(s.v);
  EdmSettings set;
  set.end_time = 5.5;
  const RunResult<3> r = run_edm<3>(s, set, QueueKind::Calendar);
  ASSERT_EQ(r.status, "ok") << r.message;
  double worst = 0.0;
  for (const auto& x : r.x) worst = std::max(worst, -pipe->at(x, R, r.time).gap);
  std::printf("EDM gas in a pipe bend: %llu pair and %llu wall collisions, energy ratio - 1 = %.3g, worst overlap %.3g\n",
              static_cast<unsigned long long>(r.counts.pair), static_cast<unsigned long long>(r.counts.wall),
              test::kinetic<3>(r.v) / ke0 - 1.0, worst);
  EXPECT_GT(r.counts.pair + r.counts.wall, 1000000u);
  EXPECT_GT(r.counts.wall, 100000u);
  EXPECT_NEAR(test::kinetic<3>(r.v) / ke0, 1.0, 1e-10);
  EXPECT_LT(worst, 1e-12);
  EXPECT_LT(r.max_overlap, 1e-12);
}

TEST(FlowGeometryValidation, ElasticGasInAMeshBoxKeepsItsEnergyOverAMillionCollisions) {
  const double L = 0.1, R = 0.0015;
  System<3> s = test::hard_material_system<3>(Vec<3>::Constant(-0.001), Vec<3>::Constant(L + 0.001));
  s.walls.push_back(Wall<3>{"box", 0, test::box_mesh(Vec<3>::Zero(), Vec<3>::Constant(L), true)});
  test::fill_gas<3>(
      s, 2000, R, inside_cube(L, R), 8);
  ASSERT_EQ(s.size(), 2000u);
  const double ke0 = test::kinetic<3>(s.v);
  EdmSettings set;
  set.end_time = 6.0;
  const RunResult<3> r = run_edm<3>(s, set, QueueKind::Calendar);
  ASSERT_EQ(r.status, "ok") << r.message;
  std::printf("EDM gas in a mesh box: %llu pair and %llu wall collisions, energy ratio - 1 = %.3g\n",
              static_cast<unsigned long long>(r.counts.pair), static_cast<unsigned long long>(r.counts.wall),
              test::kinetic<3>(r.v) / ke0 - 1.0);
  EXPECT_GT(r.counts.pair + r.counts.wall, 1000000u);
  EXPECT_GT(r.counts.wall, 100000u);
  EXPECT_NEAR(test::kinetic<3>(r.v) / ke0, 1.0, 1e-10);
  double worst = 0.0;
  for (const auto& x : r.x) worst = std::max({worst, R - x.minCoeff(), x.maxCoeff() + R - L});
  EXPECT_LT(worst, 1e-12);
}

// A bed of 400 Hertz grains with friction poured into a box 5 cm wide, closed by six planes or by
// one mesh of 12 triangles.
System<3> bed(bool mesh) {
  const double L = 0.05, H = 0.2, R = 0.0025;
  System<3> s = test::hertz_system<3>(Vec<3>::Zero(), Vec<3>(L, L, H), 0.5, 0.5);
  s.gravity = Vec<3>(0, 0, -9.81);
  if (mesh) {
    s.walls.push_back(Wall<3>{"box", 0, test::box_mesh(Vec<3>::Zero(), Vec<3>(L, L, H), true)});
  } else {
    for (int k = 0; k < 3; ++k) {
      Vec<3> e = Vec<3>::Zero();
      e[k] = 1.0;
      s.walls.push_back(plane_wall<3>("lo", Vec<3>::Zero(), e));
      s.walls.push_back(plane_wall<3>("hi", Vec<3>(L, L, H), Vec<3>(-e)));
    }
  }
  test::fill_gas<3>(s, 400, R, [&](const Vec<3>& x) {
    return (x.array() > 1.05 * R).all() && x[0] < L - 1.05 * R && x[1] < L - 1.05 * R && x[2] < H - 1.05 * R;
  }, 12);
  for (auto& v : s.v) v *= 0.1;
  return s;
}

double mean_height(const std::vector<Vec<3>>& x) {
  double z = 0.0;
  for (const auto& p : x) z += p[2];
  return z / static_cast<double>(x.size());
}

// Poured and settled (0.8 s) in the planes' box and in the mesh box from the same start: the beds
// are two realizations of one random packing (a pour is chaotic: the round-off of the two wall
// computations grows into different packings), so their mean heights agree only statistically;
// 400 grains give about 0.3 % between realizations, and the test allows 1.5 % (the 0.5 % figure
// is measured on 2000-grain pours: tests/validation/README.md). The forces themselves are the same
// to round-off (the test below).
void expect_same_bed(bool hybrid) {
  const System<3> planes = bed(false), mesh = bed(true);
  ASSERT_EQ(planes.x, mesh.x);
  const RunResult<3> a = test::run_soft<3>(planes, hybrid, 0.8, 0.0, nullptr);
  const RunResult<3> b = test::run_soft<3>(mesh, hybrid, 0.8, 0.0, nullptr);
  ASSERT_EQ(a.status, "ok") << a.message;
  ASSERT_EQ(b.status, "ok") << b.message;
  const double za = mean_height(a.x), zb = mean_height(b.x);
  std::printf("settled bed (%s): mean height %.6g (planes), %.6g (mesh), ratio - 1 = %.3g\n",
              hybrid ? "hybrid" : "TDM", za, zb, zb / za - 1.0);
  EXPECT_NEAR(zb / za, 1.0, 0.015);
  double lo = 1.0, hi = 0.0;
  for (const auto& x : b.x) {
    lo = std::min(lo, x.minCoeff());
    hi = std::max(hi, std::max(x[0], x[1]));
  }
  EXPECT_GT(lo, 0.0025 * 0.99);  // no grain through the mesh
  EXPECT_LT(hi, 0.05 - 0.0025 * 0.99);
}
TEST(FlowGeometryValidation, AMeshBoxAndSixPlanesGiveTheSameBedTdm) { expect_same_bed(false); }
TEST(FlowGeometryValidation, AMeshBoxAndSixPlanesGiveTheSameBedHybrid) { expect_same_bed(true); }

// From one settled state (the planes' bed), 0.05 s more with the planes and with the mesh: the
// same contacts and forces, so the grains stay together to round-off (TDM, one thread; the hybrid).
void expect_same_forces(bool hybrid) {
  System<3> planes = bed(false);
  const RunResult<3> settled = test::run_soft<3>(planes, false, 0.6, 0.0, nullptr);
  ASSERT_EQ(settled.status, "ok");
  System<3> mesh = bed(true);
  for (System<3>* s : {&planes, &mesh}) {
    s->x = settled.x;
    s->v = settled.v;
    if (!settled.w.empty()) s->w = settled.w;
  }
  const RunResult<3> a = test::run_soft<3>(planes, hybrid, 0.05, 0.0, nullptr);
  const RunResult<3> b = test::run_soft<3>(mesh, hybrid, 0.05, 0.0, nullptr);
  double worst = 0.0;
  for (std::size_t i = 0; i < a.x.size(); ++i) worst = std::max(worst, (a.x[i] - b.x[i]).norm());
  std::printf("settled bed (%s), planes vs mesh after 0.05 s: largest separation %.3g m\n",
              hybrid ? "hybrid" : "TDM", worst);
  EXPECT_LT(worst, 1e-9);
}
TEST(FlowGeometryValidation, AMeshBoxAndSixPlanesGiveTheSameForcesOnASettledBedTdm) { expect_same_forces(false); }
TEST(FlowGeometryValidation, AMeshBoxAndSixPlanesGiveTheSameForcesOnASettledBedHybrid) { expect_same_forces(true); }

// An elastic hard-sphere gas in the two boxes from the same start: the same collisions (EDM), so
// after 0.02 s (a few thousand collisions) the grains are where they are in the other box.
TEST(FlowGeometryValidation, AMeshBoxAndSixPlanesGiveTheSameEdmCollisions) {
  const double L = 0.1, R = 0.0015;
  System<3> s = test::hard_material_system<3>(Vec<3>::Constant(-0.001), Vec<3>::Constant(L + 0.001));
  test::fill_gas<3>(
      s, 1000, R, inside_cube(L, R), 9);
  System<3> mesh = s;
  mesh.walls.push_back(Wall<3>{"box", 0, test::box_mesh(Vec<3>::Zero(), Vec<3>::Constant(L), true)});
  for (int k = 0; k < 3; ++k) {
    Vec<3> e = Vec<3>::Zero();
    e[k] = 1.0;
    s.walls.push_back(plane_wall<3>("lo", Vec<3>::Zero(), e));
    s.walls.push_back(plane_wall<3>("hi", Vec<3>::Constant(L), Vec<3>(-e)));
  }
  EdmSettings set;
  set.end_time = 0.02;
  const RunResult<3> a = run_edm<3>(s, set, QueueKind::Calendar);
  const RunResult<3> b = run_edm<3>(mesh, set, QueueKind::Calendar);
  ASSERT_EQ(a.status, "ok");
  ASSERT_EQ(b.status, "ok");
  EXPECT_EQ(a.counts.pair, b.counts.pair);
  EXPECT_EQ(a.counts.wall, b.counts.wall);
  EXPECT_GT(a.counts.wall, 500u);
  double worst = 0.0;
  for (std::size_t i = 0; i < a.x.size(); ++i) worst = std::max(worst, (a.x[i] - b.x[i]).norm());
  std::printf("EDM gas, planes vs mesh after 0.02 s: %llu collisions, largest separation %.3g m\n",
              static_cast<unsigned long long>(a.counts.pair + a.counts.wall), worst);
  EXPECT_LT(worst, 1e-9);
}

}  // namespace
}  // namespace matep

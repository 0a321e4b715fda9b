// MeshWall (contact/mesh.hpp): triangle meshes.
// Geometry: the nearest point of a triangle against a long-double distance written here (the
// projection onto the plane when it falls inside, else the nearest of the three edges); the
// contact ownership rule: a grain in a concave corner of a box has one contact per face, a grain
// outside a convex edge or corner exactly one, a grain over a face split into two triangles one,
// continuous across the diagonal.
// Impact times against the extended-precision reference (tests/support/impact_reference.hpp on the
// long-double distance to the triangle set): a closed convex octahedron (flights inside and
// outside), an open height field with convex and concave edges (flights above and below), a box
// split into 12 triangles (flights inside); straight and parabolic; grazing flights that dip in or
// pass clear by 1e-9 R. Checkpoints (the shape's search horizon) are followed as the engine does.
// kQuick flights per case, kLong (4 000, 24 000 in all) in the *Long* test.
// Engines: a grain at rest on a mesh floor has the static Hertz overlap (TDM, hybrid); an elastic
// EDM gas around a closed mesh keeps its energy and never overlaps it.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>

#include "contact/mesh.hpp"
#include "tests/support/mesh_shapes.hpp"
#include "tests/support/shape_check.hpp"
#include "tests/support/shape_physics.hpp"

namespace matep {
namespace {

using test::FlightCase;
using test::ImpactStats;
using test::merge;
using test::VecL;

constexpr int kQuick = 2000;
constexpr int kLong = 4000;  // per case: 24 000 flights over the six
constexpr double kTmax = 3.0;
constexpr double kTol = 1e-10;

enum class Kind { Octahedron, HeightField, Box };

std::shared_ptr<const MeshWall> random_mesh(std::mt19937_64& rng, Kind k) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  if (k == Kind::Octahedron) return test::octahedron(Vec<3>(0.2 * u(rng), 0.2 * u(rng), 0.2 * u(rng)), 0.6, rng());
  if (k == Kind::HeightField) return test::height_field(0.7, 0.25, rng());
  return test::box_mesh(Vec<3>(-0.8, -0.7, -0.6), Vec<3>(0.8, 0.7, 0.6), true);
}

FlightCase<3> random_flight(std::mt19937_64& rng, const MeshWall& m, bool gravity) {
  std::uniform_real_distribution<double> u(-1.0, 1.0), u01(0.0, 1.0);
  FlightCase<3> f;
  for (;;) {
    f.R = 0.02 + 0.13 * u01(rng);
    for (int k = 0; k < 3; ++k) f.x[k] = 0.9 * u(rng);
    f.v = (0.3 + 1.7 * u01(rng)) * test::random_unit<3>(rng);
    f.g = gravity ? Vec<3>((0.5 + 4.5 * u01(rng)) * test::random_unit<3>(rng)) : Vec<3>::Zero();
    if (test::mesh_gap_ld(m, test::to_ld<3>(f.x), f.R) > 1e-9L) return f;
  }
}

void expect_case(const char* name, Kind kind, bool gravity, int n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  ImpactStats total;
  for (int block = 0; block < n / 50; ++block) {
    const auto m = random_mesh(rng, kind);
    merge(total, test::check_impacts<3>(
                     [&](const Vec<3>& x, const Vec<3>& v, const Vec<3>& g, double R) {
                       const double t = test::impact_following_checkpoints<3>(*m, x, v, g, R, kNever);
                       // A limit just past the time finds it; one just short of it does not.
                       if (t < kNever && t > 0.0) {
                         EXPECT_NEAR(test::impact_following_checkpoints<3>(*m, x, v, g, R, t * (1.0 + 1e-6)), t, 1e-12 * t);
                         EXPECT_EQ(test::impact_following_checkpoints<3>(*m, x, v, g, R, t * (1.0 - 1e-6)), kNever);
                       }
                       return t;
                     },
                     [&](const VecL<3>& x, long double R) { return test::mesh_gap_ld(*m, x, R); },
                     [&](std::mt19937_64& r) { return random_flight(r, *m, gravity); }, 50, kTmax, kTol, rng()));
  }
  total.print(name);
  EXPECT_EQ(total.missed, 0) << name << " " << total.worst_case;
  EXPECT_EQ(total.early, 0) << name << " " << total.worst_case;
  EXPECT_LE(total.worst, kTol) << name << " " << total.worst_case;
  EXPECT_GT(total.hits, total.cases / 10) << name;
}

void all_cases(int n) {
  expect_case("octahedron, straight", Kind::Octahedron, false, n, 1);
  expect_case("octahedron, gravity", Kind::Octahedron, true, n, 2);
  expect_case("height field, straight", Kind::HeightField, false, n, 3);
  expect_case("height field, gravity", Kind::HeightField, true, n, 4);
  expect_case("box of 12 triangles, straight", Kind::Box, false, n, 5);
  expect_case("box of 12 triangles, gravity", Kind::Box, true, n, 6);
}

TEST(MeshImpact, MatchesTheReference) { all_cases(kQuick); }
TEST(MeshImpact, MatchesTheReferenceLong) { all_cases(kLong); }

// Grazing flights (test::make_graze): faces under gravity, edges and corners; tolerance kTol =
// 1e-10 relative (a grazing root's conditioning: see test_shape_cylinder.cpp).
TEST(MeshImpact, GrazingFlightsTouchOrMissAsTheReferenceSays) {
  for (const Kind kind : {Kind::Octahedron, Kind::HeightField}) {
    for (const bool gravity : {false, true}) {
      std::mt19937_64 rng(40 + 2 * static_cast<int>(kind) + gravity);
      ImpactStats total;
      int made = 0;
      const int n = 300;
      for (int k = 0; k < n; ++k) {
        const auto m = random_mesh(rng, kind);
        const double miss = (k % 2 ? 1e-9 : -1e-9);
        FlightCase<3> f = random_flight(rng, *m, gravity);
        auto gld = [&](const VecL<3>& x, long double R) { return test::mesh_gap_ld(*m, x, R); };
        if (!test::make_graze<3>(f, gld, [&](const Vec<3>& x, double R) { return m->at(x, R, 0.0).normal; }, kTmax,
                                 miss * f.R))
          continue;
        ++made;
        merge(total, test::check_impacts<3>(
                         [&](const Vec<3>& x, const Vec<3>& v, const Vec<3>& g, double R) {
                           return test::impact_following_checkpoints<3>(*m, x, v, g, R, kNever);
                         },
                         gld, [&](std::mt19937_64&) { return f; }, 1, kTmax, kTol, 0));
      }
      const std::string name = std::string("graze ") + (kind == Kind::Octahedron ? "octahedron" : "height field") +
                               (gravity ? ", gravity" : ", straight");
      total.print(name.c_str());
      EXPECT_GT(made, n / 8) << name;
      EXPECT_EQ(total.missed, 0) << name << " " << total.worst_case;
      EXPECT_EQ(total.early, 0) << name << " " << total.worst_case;
      EXPECT_LE(total.worst, kTol) << name << " " << total.worst_case;
    }
  }
}

// Hand-made flights on the unit box [0, 1]^3 (12 triangles): a fall onto the floor, a flight into
// the concave edge and corner (first touch of the nearer face), an outside flight onto a convex
// edge (the offset cylinder) and a corner (the offset sphere).
TEST(MeshImpact, ClosedFormFlights) {
  const auto box = test::box_mesh(Vec<3>::Zero(), Vec<3>::Ones(), true);
  const double R = 0.1;
  auto hit = [&](const Vec<3>& x, const Vec<3>& v, const Vec<3>& g) {
    return test::impact_following_checkpoints<3>(*box, x, v, g, R, kNever);
  };
  EXPECT_NEAR(hit(Vec<3>(0.3, 0.6, 0.8), Vec<3>(0, 0, -1), Vec<3>::Zero()), 0.7, 1e-14);
  EXPECT_NEAR(hit(Vec<3>(0.3, 0.6, 0.8), Vec<3>::Zero(), Vec<3>(0, 0, -2)), std::sqrt(0.7), 1e-14);
  // Towards the corner (0, 0, 0) along (-1, -2, -3)/|.|: the face z = R first.
  const Vec<3> d = Vec<3>(-1, -2, -3).normalized();
  EXPECT_NEAR(hit(Vec<3>(0.5, 0.5, 0.5), d, Vec<3>::Zero()), (0.5 - R) / (-d[2]), 1e-14);
  // Outside, along -x at height 1 + R/2 above the top edge x = 1, z = 1 (y = 0.5): the edge's
  // cylinder, where (x - 1)^2 + (R/2)^2 = R^2.
  EXPECT_NEAR(hit(Vec<3>(2.0, 0.5, 1.0 + 0.5 * R), Vec<3>(-1, 0, 0), Vec<3>::Zero()),
              1.0 - std::sqrt(0.75) * R, 1e-14);
  // Outside, along the diagonal towards the corner (1, 1, 1): the corner's sphere.
  const Vec<3> e = Vec<3>::Ones().normalized();
  EXPECT_NEAR(hit(Vec<3>(Vec<3>::Ones() + 2.0 * e), -e, Vec<3>::Zero()), 2.0 - R, 1e-14);
  // Leaving the floor: never (the box is closed, the next face is the lid: 1 - 2R later).
  EXPECT_NEAR(hit(Vec<3>(0.3, 0.6, R), Vec<3>(0, 0, 1), Vec<3>::Zero()), 1.0 - 2.0 * R, 1e-14);
}

// The nearest point of a triangle against the long-double reference.
TEST(MeshShape, NearestPointOfATriangleMatchesTheReference) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int k = 0; k < 20000; ++k) {
    Vec<3> a, b, c, x;
    for (int j = 0; j < 3; ++j) {
      a[j] = u(rng);
      b[j] = u(rng);
      c[j] = u(rng);
      x[j] = 2.0 * u(rng);
    }
    const TriangleFoot f = nearest_on_triangle(x, a, b, c);
    const long double ref = test::triangle_distance(test::to_ld<3>(x), test::to_ld<3>(a), test::to_ld<3>(b), test::to_ld<3>(c));
    EXPECT_NEAR((x - f.point).norm(), static_cast<double>(ref), 1e-12);
  }
}

// How many contacts (overlaps) a grain at x has with the mesh, through the engines' interface.
std::vector<WallPoint<3>> contacts(const MeshWall& m, const Vec<3>& x, double R) {
  std::vector<std::uint32_t> fs;
  m.features_near(x, R, 0.0, 0.0, fs);
  std::vector<WallPoint<3>> out;
  for (const auto f : fs) {
    const WallPoint<3> c = m.at_feature(x, R, 0.0, f);
    if (c.gap < 0.0) out.push_back(c);
  }
  return out;
}

TEST(MeshShape, OneContactPerFaceInAConcaveCornerOnePerConvexEdgeOrCorner) {
  const auto box = test::box_mesh(Vec<3>::Zero(), Vec<3>::Ones(), true);
  EXPECT_EQ(box->triangles(), 12u);
  EXPECT_EQ(box->facets(), 6u);  // the diagonals join each side's two triangles
  const double R = 0.1;
  // Inside, pressed into the corner (0, 0, 0): three contacts, the three faces' normals.
  auto c = contacts(*box, Vec<3>(0.09, 0.095, 0.098), R);
  ASSERT_EQ(c.size(), 3u);
  Vec<3> sum = Vec<3>::Zero();
  for (const auto& p : c) sum += p.normal;
  EXPECT_LT((sum - Vec<3>::Ones()).norm(), 1e-12);
  // Inside, on the floor right over a diagonal of its two triangles: one contact.
  c = contacts(*box, Vec<3>(0.4, 0.4, 0.09), R);
  ASSERT_EQ(c.size(), 1u);
  EXPECT_NEAR(c[0].gap, -0.01, 1e-15);
  EXPECT_LT((c[0].normal - Vec<3>(0, 0, 1)).norm(), 1e-15);
  // Across the diagonal (x = y) the floor contact is the same feature with the same gap.
  std::vector<std::uint32_t> f1, f2;
  box->features_near(Vec<3>(0.41, 0.39, 0.09), R, 0.0, 0.0, f1);
  box->features_near(Vec<3>(0.39, 0.41, 0.09), R, 0.0, 0.0, f2);
  EXPECT_EQ(f1, f2);
  // Outside, off the convex edge x = 1, z = 1 at 45 degrees: one contact, radial from the edge.
  const Vec<3> n45 = Vec<3>(1, 0, 1).normalized();
  c = contacts(*box, Vec<3>(Vec<3>(1, 0.5, 1) + 0.09 * n45), R);
  ASSERT_EQ(c.size(), 1u);
  EXPECT_NEAR(c[0].gap, -0.01, 1e-15);
  EXPECT_LT((c[0].normal - n45).norm(), 1e-14);
  // Outside, off the corner (1, 1, 1) along the diagonal: one contact.
  const Vec<3> e = Vec<3>::Ones().normalized();
  c = contacts(*box, Vec<3>(Vec<3>::Ones() + 0.09 * e), R);
  ASSERT_EQ(c.size(), 1u);
  EXPECT_LT((c[0].normal - e).norm(), 1e-14);
  // Outside, over the top face near the edge but still in the face's region: the face only.
  c = contacts(*box, Vec<3>(0.97, 0.5, 1.09), R);
  ASSERT_EQ(c.size(), 1u);
  EXPECT_LT((c[0].normal - Vec<3>(0, 0, 1)).norm(), 1e-15);
  // at(): the nearest contact; at_impact(): in the corner, the face approached fastest.
  const Vec<3> x(0.1, 0.1, 0.5);
  EXPECT_NEAR(box->at(x, R, 0.0).gap, 0.0, 1e-15);
  const WallPoint<3> hit = box->at_impact(x, Vec<3>(-0.1, -1.0, 0.0), R, 0.0);
  EXPECT_LT((hit.normal - Vec<3>(0, 1, 0)).norm(), 1e-14);
  Vec<3> lo, hi;
  EXPECT_TRUE(box->bounds(lo, hi));
  EXPECT_EQ(lo, Vec<3>::Zero());
  EXPECT_EQ(hi, Vec<3>::Ones());
  EXPECT_STREQ(box->kind(), "mesh");
  SurfaceMesh pic;
  box->tessellate(0.0, lo, hi, pic);
  EXPECT_EQ(pic.cells.size(), 12u);
}

TEST(MeshShape, DegenerateAndNonManifoldMeshesAreRejected) {
  using V = std::vector<Vec<3>>;
  using T = std::vector<std::array<std::uint32_t, 3>>;
  const V p{Vec<3>(0, 0, 0), Vec<3>(1, 0, 0), Vec<3>(0, 1, 0), Vec<3>(0, 0, 1), Vec<3>(0, 0, -1), Vec<3>(2, 0, 0)};
  EXPECT_NO_THROW(MeshWall(p, T{{0, 1, 2}}));
  // Collinear vertices: zero area.
  try {
    MeshWall(p, T{{0, 1, 5}});
    ADD_FAILURE() << "a degenerate triangle was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("triangle 1 is degenerate"), std::string::npos) << e.what();
  }
  EXPECT_THROW(MeshWall(p, T{{0, 0, 2}}), std::invalid_argument);
  // Three triangles on the edge (0, 1): non-manifold.
  try {
    MeshWall(p, T{{0, 1, 2}, {0, 1, 3}, {0, 1, 4}});
    ADD_FAILURE() << "a non-manifold mesh was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("non-manifold"), std::string::npos) << e.what();
  }
  EXPECT_THROW(MeshWall(p, T{}), std::invalid_argument);
}

// ---- engines ---------------------------------------------------------------------------------

// A grain at rest on the floor of a box mesh (the centre of a side's diagonal, the worst place
// for a triangulation) has the static Hertz overlap.
void check_static(bool hybrid) {
  const auto box = test::box_mesh(Vec<3>(-0.5, -0.5, 0.0), Vec<3>(0.5, 0.5, 1.0), true);
  test::expect_static_hertz_overlap<3>(box, Vec<3>(0.0, 0.0, test::kGrainR), Vec<3>(0, 0, 1), Vec<3>(0, 0, -test::kG), hybrid,
                                       0.5);
}
TEST(MeshEngines, GrainAtRestOnAMeshFloorHasTheStaticHertzOverlapTdm) { check_static(false); }
TEST(MeshEngines, GrainAtRestOnAMeshFloorHasTheStaticHertzOverlapHybrid) { check_static(true); }

// A grain at rest in a V-shaped trough of two mesh faces at +-45 degrees: each face carries
// m g / sqrt(2), so each overlap is the Hertz overlap of that load.
void check_trough(bool hybrid) {
  const double R = test::kGrainR;
  const double s = 0.5;
  using V = std::vector<Vec<3>>;
  const V p{Vec<3>(-s, -s, s), Vec<3>(-s, s, s), Vec<3>(0, -s, 0), Vec<3>(0, s, 0), Vec<3>(s, -s, s), Vec<3>(s, s, s)};
  auto trough = std::make_shared<MeshWall>(p, std::vector<std::array<std::uint32_t, 3>>{
                                                  {0, 2, 3}, {0, 3, 1}, {2, 4, 5}, {2, 5, 3}});
  EXPECT_EQ(trough->facets(), 2u);
  const double load = test::grain_mass<3>(R) * test::kG / std::sqrt(2.0);
  const double expected = test::hertz_overlap(load, R);
  System<3> sys = test::hertz_system<3>(Vec<3>(-1, -1, -1), Vec<3>(1, 1, 1), 0.3, 0.0);
  sys.gravity = Vec<3>(0, 0, -test::kG);
  sys.walls.push_back(Wall<3>{"trough", 0, trough});
  test::add_grain<3>(sys, Vec<3>(0, 0, std::sqrt(2.0) * (R - 0.5 * expected)), Vec<3>::Zero(), R);
  const RunResult<3> r = test::run_soft<3>(sys, hybrid, 1.0, 0.0, nullptr);
  ASSERT_EQ(r.status, "ok") << r.message;
  const auto c = contacts(*trough, r.x[0], R);
  ASSERT_EQ(c.size(), 2u);
  for (const auto& k : c) {
    std::printf("trough (%s): overlap %.6g, Hertz %.6g\n", hybrid ? "hybrid" : "TDM", -k.gap, expected);
    EXPECT_NEAR(-k.gap / expected, 1.0, 1e-3);
  }
}
TEST(MeshEngines, GrainInAVTroughHasTheHertzOverlapOnEachFaceTdm) { check_trough(false); }
TEST(MeshEngines, GrainInAVTroughHasTheHertzOverlapOnEachFaceHybrid) { check_trough(true); }

TEST(MeshEngines, ElasticEdmGasAroundAClosedMeshKeepsItsEnergy) {
  test::expect_edm_gas_around<3>(test::octahedron(Vec<3>(0.05, -0.02, 0.03), 0.35, 9), 120, 0.03, 3, "octahedron");
  test::expect_edm_gas_around<3>(test::height_field(0.5, 0.15, 11), 120, 0.03, 4, "height field");
}

}  // namespace
}  // namespace matep

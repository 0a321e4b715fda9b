// Scene keys of the wall shapes (io/scene.cpp read_wall_shape): each type builds the shape it
// names with the geometry given, and every impossible value ends with one message naming the file,
// the key and the value (exit 2 at the CLI, nothing written: the scene is refused before a run).
#include <gtest/gtest.h>

#include <string>
#include <variant>

#include "contact/cone.hpp"
#include "contact/cylinder.hpp"
#include "contact/plane_patch.hpp"
#include "io/scene.hpp"

namespace matep {
namespace {

const std::string kDir = std::string(MATEP_SOURCE_DIR) + "/tests/data/scene";

// A 3D scene of 20 grains inside a drum (a cylinder along z), with `wall` appended.
std::string scene3d(const std::string& wall) {
  return R"([run]
dimension = 3
method = "tdm"
end_time = 0.01
[domain]
lower = [-0.2, -0.2, -0.2]
upper = [0.2, 0.2, 0.2]
[material.glass]
density = 2500.0
contact = "linear"
stiffness = 1000.0
restitution = 0.5
[particles.p]
material = "glass"
radius = 0.01
count = 20
region = {lower = [-0.05, -0.05, -0.05], upper = [0.05, 0.05, 0.05]}
)" + wall + "material = \"glass\"\n";
}

std::string scene2d(const std::string& wall) {
  return R"([run]
dimension = 2
method = "tdm"
end_time = 0.01
[domain]
lower = [-0.2, -0.2]
upper = [0.2, 0.2]
[material.glass]
density = 2500.0
contact = "linear"
stiffness = 1000.0
restitution = 0.5
[particles.p]
material = "glass"
radius = 0.01
count = 10
region = {lower = [-0.05, -0.05], upper = [0.05, 0.05]}
)" + wall + "material = \"glass\"\n";
}

template <int D>
const WallShape<D>& only_wall(const Scene& sc) {
  const auto& s = std::get<System<D>>(sc.system);
  EXPECT_EQ(s.walls.size(), 1u);
  return s.walls.at(0).geometry();
}

void expect_error(const std::string& text, std::initializer_list<std::string> parts) {
  try {
    load_scene_string(text, "walls.toml", kDir, {});
    ADD_FAILURE() << "no SceneError; expected one containing " << *parts.begin();
  } catch (const SceneError& e) {
    const std::string msg = e.what();
    EXPECT_EQ(msg.rfind("walls.toml:", 0), 0u) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    for (const auto& p : parts) EXPECT_NE(msg.find(p), std::string::npos) << "'" << p << "' not in: " << msg;
  }
}

TEST(SceneWalls, EachTypeBuildsTheShapeItNames) {
  {
    const Scene sc = load_scene_string(scene3d(R"([wall.drum]
type = "cylinder"
point = [0.0, 0.0, -0.1]
axis = [0.0, 0.0, 2.0]
radius = 0.15
rotation = {angular_velocity = 3.0}
)"),
                                       "walls.toml", kDir, {});
    const auto* c = dynamic_cast<const CylinderWall<3>*>(&only_wall<3>(sc));
    ASSERT_NE(c, nullptr);
    EXPECT_EQ(c->radius(), 0.15);
    EXPECT_EQ(c->axis(), Vec<3>(0, 0, 1));  // normalised
    EXPECT_FALSE(c->finite());
    EXPECT_TRUE(c->inside());
    EXPECT_EQ(c->omega(), 3.0);
    // The surface moves at w x r: at the wall point (0.15, 0, z), (0, 3 * 0.15, 0).
    const WallPoint<3> p = c->at(Vec<3>(0.1, 0.0, 0.0), 0.01, 0.0);
    EXPECT_NEAR(p.gap, 0.04, 1e-15);
    EXPECT_NEAR(p.velocity[1], 0.45, 1e-15);
  }
  {
    const Scene sc = load_scene_string(scene3d(R"([wall.hopper]
type = "cone"
point = [0.0, 0.0, 0.1]
axis = [0.0, 0.0, -1.0]
radii = [0.15, 0.03]
length = 0.2
)"),
                                       "walls.toml", kDir, {});
    const auto* c = dynamic_cast<const ConeWall<3>*>(&only_wall<3>(sc));
    ASSERT_NE(c, nullptr);
    EXPECT_EQ(c->r1(), 0.15);
    EXPECT_EQ(c->r2(), 0.03);
    EXPECT_EQ(c->length(), 0.2);
  }
  {
    const Scene sc = load_scene_string(scene3d(R"([wall.floor]
type = "plane"
point = [0.0, 0.0, -0.1]
normal = [0.0, 0.0, 1.0]
hole = {shape = "disk", radius = 0.02}
)"),
                                       "walls.toml", kDir, {});
    const WallShape<3>& w = only_wall<3>(sc);
    ASSERT_NE(dynamic_cast<const BoundedPlane<3>*>(&w), nullptr);
    EXPECT_STREQ(w.kind(), "plane with hole");
    // Above the solid floor the gap is the height; above the hole's centre, the distance to the
    // rim: sqrt(0.02^2 + 0.05^2) - R.
    EXPECT_NEAR(w.at(Vec<3>(0.1, 0.0, -0.05), 0.01, 0.0).gap, 0.04, 1e-15);
    EXPECT_NEAR(w.at(Vec<3>(0.0, 0.0, -0.05), 0.01, 0.0).gap, std::hypot(0.02, 0.05) - 0.01, 1e-15);
  }
  {
    const Scene sc = load_scene_string(scene3d(R"([wall.plate]
type = "plane"
point = [0.0, 0.0, -0.1]
normal = [0.0, 0.0, 1.0]
patch = {shape = "rectangle", size = [0.2, 0.1], direction = [1.0, 0.0, 0.0]}
)"),
                                       "walls.toml", kDir, {});
    const WallShape<3>& w = only_wall<3>(sc);
    EXPECT_STREQ(w.kind(), "plane patch");
    Vec<3> lo, hi;
    ASSERT_TRUE(w.bounds(lo, hi));
    EXPECT_NEAR(hi[0] - lo[0], 0.2, 1e-15);  // size is the full side
    EXPECT_NEAR(hi[1] - lo[1], 0.1, 1e-15);
  }
  {
    const Scene sc = load_scene_string(scene2d(R"([wall.drum]
type = "cylinder"
point = [0.0, 0.0]
radius = 0.15
)"),
                                       "walls.toml", kDir, {});
    EXPECT_NE(dynamic_cast<const CylinderWall<2>*>(&only_wall<2>(sc)), nullptr);
  }
}

TEST(SceneWalls, ImpossibleShapesAreRefusedNamingKeyAndValue) {
  const std::string cyl = "[wall.drum]\ntype = \"cylinder\"\npoint = [0.0, 0.0, 0.0]\n";
  expect_error(scene3d(cyl + "axis = [0.0, 0.0, 1.0]\nradius = -0.1\n"), {"wall.drum.radius", "-0.1"});
  expect_error(scene3d(cyl + "axis = [0.0, 0.0, 1.0]\nradius = 0\n"), {"wall.drum.radius", "0"});
  expect_error(scene3d(cyl + "axis = [0.0, 0.0, 0.0]\nradius = 0.15\n"), {"wall.drum.axis", "nonzero"});
  expect_error(scene3d(cyl + "axis = [0.0, 0.0, 1.0]\nradius = 0.15\nlength = 0.1\nside = \"inside\"\n"),
               {"wall.drum.side", "finite"});
  expect_error(scene3d(cyl + "axis = [0.0, 0.0, 1.0]\nradius = 0.15\nside = \"middle\"\n"),
               {"wall.drum.side", "middle"});
  expect_error(scene3d(cyl + "axis = [0.0, 0.0, 1.0]\nradius = 0.15\nheight = 2\n"), {"wall.drum.height"});
  // A finite tube reaching beyond the domain.
  expect_error(scene3d("[wall.tube]\ntype = \"cylinder\"\npoint = [0.0, 0.0, -0.1]\naxis = [0.0, 0.0, 1.0]\n"
                       "radius = 0.15\nlength = 0.5\n"),
               {"wall.tube", "outside the domain", "0.4"});
  const std::string cone = "[wall.hopper]\ntype = \"cone\"\npoint = [0.0, 0.0, 0.1]\naxis = [0.0, 0.0, -1.0]\n";
  expect_error(scene3d(cone + "radii = [0.0, 0.0]\nlength = 0.1\n"), {"wall.hopper.radii", "not both 0"});
  expect_error(scene3d(cone + "radii = [0.1, 0.05]\nlength = 0\n"), {"wall.hopper.length", "0"});
  expect_error(scene3d(cone + "radii = [0.1, -0.05]\nlength = 0.1\n"), {"wall.hopper.radii"});
  const std::string plane = "[wall.floor]\ntype = \"plane\"\npoint = [0.0, 0.0, -0.1]\nnormal = [0.0, 0.0, 1.0]\n";
  expect_error(scene3d(plane + "patch = {shape = \"disk\", radius = 0.1}\nhole = {shape = \"disk\", radius = 0.01}\n"),
               {"wall.floor.hole", "not both"});
  expect_error(scene3d(plane + "hole = {shape = \"disk\", radius = -1}\n"), {"wall.floor.hole.radius", "-1"});
  expect_error(scene3d(plane + "hole = {shape = \"triangle\"}\n"), {"wall.floor.hole.shape", "triangle"});
  expect_error(scene3d(plane + "rotation = {angular_velocity = 1.0}\n"), {"wall.floor.rotation", "infinite plane"});
  expect_error(scene3d(plane + "hole = {shape = \"disk\", radius = 0.02}\nrotation = {angular_velocity = 1.0}\n"),
               {"wall.floor.rotation"});
  expect_error(scene3d(plane + "patch = {shape = \"rectangle\", size = [0.1, 0.1], direction = [0.0, 0.0, 1.0]}\n"),
               {"wall.floor.patch.direction", "parallel"});
  expect_error(scene3d(plane + "patch = {shape = \"disk\", radius = 0.1}\noscillation = {amplitude = [0.0, 0.0, 0.01], "
                               "frequency = 10.0}\n"),
               {"wall.floor.oscillation"});
  expect_error(scene3d("[wall.drum]\ntype = \"sphere\"\n"), {"wall.drum.type", "sphere"});
  // 2D: a circle has no axis or length.
  expect_error(scene2d("[wall.drum]\ntype = \"cylinder\"\npoint = [0.0, 0.0]\nradius = 0.15\nlength = 0.1\n"),
               {"wall.drum.length"});
}

TEST(SceneWalls, GrainsInsideAWallAreRefused) {
  // The grains' lattice lies outside a drum of radius 0.04 around (0.15, 0.15, 0): they are in its
  // wall (the one-sided infinite cylinder). (Random placement avoids walls: it would report the
  // region as too full instead.)
  std::string s = scene3d("[wall.drum]\ntype = \"cylinder\"\npoint = [0.15, 0.15, 0.0]\naxis = [0.0, 0.0, 1.0]\n"
                       "radius = 0.04\n");
  s.replace(s.find("count = 20\n"), 11, "count = 20\narrangement = \"lattice\"\n");
  expect_error(s, {"wall.drum", "overlaps"});
}

}  // namespace
}  // namespace matep

// The mesh wall's scene keys and its STL files (io/scene.cpp read_mesh, io/stl.cpp): ASCII and
// binary files give the same mesh, scale and translate place it, and every bad file (missing,
// empty, truncated, malformed, non-manifold, degenerate) or impossible value ends with one message
// naming the scene file, the key and the value (the STL file and what is wrong in it); at the CLI
// exit 2 and nothing written.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <variant>

#include "contact/mesh.hpp"
#include "contact/rotating.hpp"
#include "io/scene.hpp"
#include "io/stl.hpp"
#include "tests/support/cli.hpp"
#include "tests/support/mesh_shapes.hpp"

namespace matep {
namespace {

namespace fs = std::filesystem;

// 20 grains inside a box mesh [-0.1, 0.1]^3 (the wall table appended).
std::string scene(const std::string& wall, int dim = 3) {
  const std::string d3 = R"([run]
dimension = 3
method = "tdm"
end_time = 0.001
[domain]
lower = [-0.2, -0.2, -0.2]
upper = [0.2, 0.2, 0.2]
[particles.p]
material = "glass"
radius = 0.01
count = 20
region = {lower = [-0.05, -0.05, -0.05], upper = [0.05, 0.05, 0.05]}
)";
  const std::string d2 = R"([run]
dimension = 2
method = "tdm"
end_time = 0.001
[domain]
lower = [-0.2, -0.2]
upper = [0.2, 0.2]
[particles.p]
material = "glass"
radius = 0.01
count = 5
region = {lower = [-0.05, -0.05], upper = [0.05, 0.05]}
)";
  return (dim == 3 ? d3 : d2) + R"([material.glass]
density = 2500.0
contact = "linear"
stiffness = 1000.0
restitution = 0.5
)" + wall + "material = \"glass\"\n";
}

struct Files {
  fs::path dir = test::fresh_dir("scene_mesh");
  Files() {
    std::vector<Vec<3>> v;
    test::MeshTris t;
    test::box_triangles(Vec<3>::Constant(-100.0), Vec<3>::Constant(100.0), true, v, t);  // millimetres
    test::write_stl_ascii((dir / "box_ascii.stl").string(), v, t);
    test::write_stl_binary((dir / "box_binary.stl").string(), v, t);
    // The domain's own box, in float: 0.2 is 0.200000003 (a CAD export made to the domain's size).
    test::box_triangles(Vec<3>::Constant(-0.2), Vec<3>::Constant(0.2), true, v, t);
    test::write_stl_binary((dir / "domain_box.stl").string(), v, t);
    std::ofstream(dir / "empty.stl").close();
    std::ofstream(dir / "no_facets.stl") << "solid nothing\nendsolid nothing\n";
    std::ofstream(dir / "malformed.stl") << "solid x\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n"
                                            "   vertex 1 0\n";
    std::ofstream(dir / "cut.stl") << "solid x\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n";
    {  // a binary file cut short: its header counts 12 triangles, 3 are there
      std::string bytes = test::slurp(dir / "box_binary.stl");
      std::ofstream(dir / "truncated.stl", std::ios::binary) << bytes.substr(0, 84 + 3 * 50);
    }
    // Three triangles on one edge; a triangle with two equal vertices' coordinates.
    const std::vector<Vec<3>> p{Vec<3>(0, 0, 0), Vec<3>(0.1, 0, 0), Vec<3>(0, 0.1, 0), Vec<3>(0, 0, 0.1),
                                Vec<3>(0, 0, -0.1), Vec<3>(0.2, 0, 0)};
    test::write_stl_ascii((dir / "fin.stl").string(), p, test::MeshTris{{0, 1, 2}, {0, 1, 3}, {0, 1, 4}});
    test::write_stl_ascii((dir / "sliver.stl").string(), p, test::MeshTris{{0, 1, 2}, {0, 1, 5}});
  }
  ~Files() { fs::remove_all(dir); }
};

const Files& files() {
  static const Files f;
  return f;
}

const MeshWall& mesh_of(const Scene& sc) {
  const auto& s = std::get<System<3>>(sc.system);
  EXPECT_EQ(s.walls.size(), 1u);
  const auto* m = dynamic_cast<const MeshWall*>(&s.walls.at(0).geometry());
  EXPECT_NE(m, nullptr);
  return *m;
}

void expect_error(const std::string& text, std::initializer_list<std::string> parts) {
  try {
    load_scene_string(text, "mesh.toml", files().dir.string(), {});
    ADD_FAILURE() << "no SceneError; expected one containing " << *parts.begin();
  } catch (const SceneError& e) {
    const std::string msg = e.what();
    EXPECT_EQ(msg.rfind("mesh.toml:", 0), 0u) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    for (const auto& p : parts) EXPECT_NE(msg.find(p), std::string::npos) << "'" << p << "' not in: " << msg;
  }
}

TEST(SceneMesh, AsciiAndBinaryFilesGiveTheSameMeshScaledAndMoved) {
  const std::string dir = files().dir.string();
  for (const char* f : {"box_ascii.stl", "box_binary.stl"}) {
    const Scene sc = load_scene_string(
        scene(std::string("[wall.box]\ntype = \"mesh\"\nfile = \"") + f +
              "\"\nscale = 0.001\ntranslate = [0.0, 0.0, 0.05]\n"),
        "mesh.toml", dir, {});
    const MeshWall& m = mesh_of(sc);
    EXPECT_EQ(m.triangles(), 12u) << f;
    EXPECT_EQ(m.vertices().size(), 8u) << f;  // shared vertices merged
    EXPECT_EQ(m.facets(), 6u) << f;
    Vec<3> lo, hi;
    ASSERT_TRUE(m.bounds(lo, hi));
    EXPECT_LT((lo - Vec<3>(-0.1, -0.1, -0.05)).norm(), 1e-15) << f;
    EXPECT_LT((hi - Vec<3>(0.1, 0.1, 0.15)).norm(), 1e-15) << f;
    // A grain at the centre, 0.1 from the sides, 0.1 above the floor at z = -0.05.
    EXPECT_NEAR(m.at(Vec<3>(0.0, 0.0, 0.05), 0.01, 0.0).gap, 0.09, 1e-12) << f;
  }
  // A mesh made to the domain's size in float coordinates fits (float round-off is tolerated).
  EXPECT_NO_THROW(load_scene_string(scene("[wall.box]\ntype = \"mesh\"\nfile = \"domain_box.stl\"\n"), "mesh.toml", dir, {}));
  const StlMesh a = read_stl(dir + "/box_ascii.stl"), b = read_stl(dir + "/box_binary.stl");
  EXPECT_FALSE(a.binary);
  EXPECT_TRUE(b.binary);
  EXPECT_EQ(a.triangles, b.triangles);
  EXPECT_EQ(a.vertices, b.vertices);  // +-100 is exact in float
}

TEST(SceneMesh, BadFilesAndValuesAreRefusedNamingFileKeyAndValue) {
  const std::string w = "[wall.hopper]\ntype = \"mesh\"\n";
  expect_error(scene(w + "file = \"missing.stl\"\n"), {"wall.hopper.file", "missing.stl", "no such file"});
  expect_error(scene(w + "file = \"empty.stl\"\n"), {"wall.hopper.file", "empty.stl", "empty"});
  expect_error(scene(w + "file = \"no_facets.stl\"\n"), {"wall.hopper.file", "no_facets.stl", "no triangles"});
  expect_error(scene(w + "file = \"malformed.stl\"\n"), {"wall.hopper.file", "malformed.stl", "line 5", "three numbers"});
  expect_error(scene(w + "file = \"cut.stl\"\n"), {"wall.hopper.file", "cut.stl", "truncated"});
  expect_error(scene(w + "file = \"truncated.stl\"\n"),
               {"wall.hopper.file", "truncated.stl", "12 triangles", "truncated"});
  expect_error(scene(w + "file = \"fin.stl\"\n"), {"wall.hopper.file", "fin.stl", "non-manifold"});
  expect_error(scene(w + "file = \"sliver.stl\"\n"), {"wall.hopper.file", "sliver.stl", "triangle 2 is degenerate"});
  expect_error(scene(w + "file = \"box_ascii.stl\"\nscale = -1.0\n"), {"wall.hopper.scale", "-1"});
  expect_error(scene(w + "file = \"box_ascii.stl\"\nscale = 0.001\norigin = [0.0, 0.0, 0.0]\n"),
               {"wall.hopper.origin"});
  expect_error(scene(w + "file = \"box_ascii.stl\"\nscale = 0.001\nrotation = {angular_velocity = 1.0}\n"),
               {"wall.hopper.rotation"});
  // In millimetres the box (+-100) does not fit the domain (+-0.2).
  expect_error(scene(w + "file = \"box_ascii.stl\"\n"), {"wall.hopper", "outside the domain", "100"});
  expect_error(scene(w + "file = \"box_ascii.stl\"\n", 2), {"wall.hopper.type", "3D"});
}

// rotation = {angular_velocity, point, axis}: any bounded shape turning about that axis
// (contact/rotating.hpp); without point, only shapes of revolution about their own axis.
TEST(SceneMesh, RotationAboutAGivenAxisTurnsAnyBoundedShape) {
  const std::string dir = files().dir.string();
  {
    const Scene sc = load_scene_string(scene("[wall.mixer]\ntype = \"mesh\"\nfile = \"box_ascii.stl\"\nscale = 0.0005\n"
                                             "rotation = {angular_velocity = 2.0, point = [0.0, 0.0, 0.0], "
                                             "axis = [0.0, 0.0, 3.0]}\n"),
                                       "mesh.toml", dir, {});
    const auto& w = std::get<System<3>>(sc.system).walls.at(0).geometry();
    const auto* r = dynamic_cast<const RotatingWall<3>*>(&w);
    ASSERT_NE(r, nullptr);
    EXPECT_EQ(r->rotation().omega, 2.0);
    EXPECT_EQ(r->rotation().axis, Vec<3>(0, 0, 1));
    EXPECT_NE(dynamic_cast<const MeshWall*>(&r->body()), nullptr);
    // A quarter turn later (t = pi/4 s) the box [-0.05, 0.05]^3 is the same box: the gap from its
    // centre is 0.05 - R; the surface there moves at 2 z x (c - 0).
    const WallPoint<3> c = w.at(Vec<3>(0.02, 0.0, 0.0), 0.01, 0.25 * 3.141592653589793);
    EXPECT_NEAR(c.gap, 0.02, 1e-12);
    EXPECT_LT((c.velocity - Vec<3>(0, 0.1, 0)).norm(), 1e-12);
  }
  {
    const Scene sc = load_scene_string(
        scene("[wall.paddle]\ntype = \"plane\"\npoint = [0.05, 0.0, 0.0]\nnormal = [0.0, 1.0, 0.0]\n"
              "patch = {shape = \"rectangle\", size = [0.08, 0.1], direction = [1.0, 0.0, 0.0]}\n"
              "rotation = {angular_velocity = -1.0, point = [0.0, 0.0, 0.0], axis = [0.0, 0.0, 1.0]}\n"),
        "mesh.toml", dir, {});
    EXPECT_NE(dynamic_cast<const RotatingWall<3>*>(&std::get<System<3>>(sc.system).walls.at(0).geometry()), nullptr);
  }
  const std::string plane = "[wall.floor]\ntype = \"plane\"\npoint = [0.0, 0.0, -0.1]\nnormal = [0.0, 0.0, 1.0]\n";
  expect_error(scene(plane + "hole = {shape = \"disk\", radius = 0.02}\nrotation = {angular_velocity = 1.0, point = "
                             "[0.0, 0.0, 0.0], axis = [1.0, 0.0, 0.0]}\n"),
               {"wall.floor.rotation", "unbounded"});
  expect_error(scene("[wall.m]\ntype = \"mesh\"\nfile = \"box_ascii.stl\"\nscale = 0.0005\nrotation = "
                     "{angular_velocity = 1.0, point = [0.0, 0.0, 0.0], axis = [0.0, 0.0, 0.0]}\n"),
               {"wall.m.rotation.axis", "nonzero"});
  expect_error(scene("[wall.m]\ntype = \"mesh\"\nfile = \"box_ascii.stl\"\nscale = 0.0005\nrotation = "
                     "{angular_velocity = 1.0, point = [0.0, 0.0, 0.0]}\n"),
               {"wall.m.rotation.axis", "missing"});
  expect_error(scene("[wall.m]\ntype = \"mesh\"\nfile = \"box_ascii.stl\"\nscale = 0.0005\nrotation = "
                     "{angular_velocity = 1.0, point = [0.0, 0.0, 0.0], axis = [0.0, 0.0, 1.0], speed = 2}\n"),
               {"wall.m.rotation.speed"});
}

TEST(SceneMesh, AMissingMeshEndsTheCliWithExit2AndWritesNothing) {
  const fs::path dir = test::fresh_dir("scene_mesh_cli");
  std::ofstream(dir / "s.toml") << scene("[wall.box]\ntype = \"mesh\"\nfile = \"nowhere.stl\"\n");
  const test::CliResult r = test::run_cli("run " + (dir / "s.toml").string() + " --out " + (dir / "out").string());
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("wall.box.file"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("nowhere.stl"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(dir / "out"));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace matep

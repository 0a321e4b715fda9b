// Scene keys of [outlet.NAME] (io/scene.cpp read_outlet) and the outputs of a run with outlets:
// each type builds the region it names; impossible values end with one message naming the file,
// the key and the value (exit 2 at the CLI, nothing written); a region no grain can reach is run
// with a warning; outflow.csv lists every grain that left once, and thermo.csv, final_state.csv
// and summary.json agree with it.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <variant>

#include "io/scene.hpp"
#include "tests/support/cli.hpp"
#include "tests/support/scene_errors.hpp"

namespace matep {
namespace {

const std::string kDir = std::string(MATEP_SOURCE_DIR) + "/tests/data/scene";

// 40 grains falling onto a holed floor, periodic along x and y; `extra` is appended (outlets).
std::string scene3d(const std::string& extra, const std::string& periodic = "[true, true, false]") {
  return R"([run]
dimension = 3
method = "tdm"
end_time = 0.3
seed = 2
gravity = [0.0, 0.0, -9.81]
[domain]
lower = [0.0, 0.0, -0.02]
upper = [0.04, 0.04, 0.1]
periodic = )" + periodic + R"(
[material.glass]
density = 2500.0
contact = "linear"
stiffness = 2000.0
restitution = 0.5
[particles.p]
material = "glass"
radius = 0.002
count = 40
region = {lower = [0.0, 0.0, 0.01], upper = [0.04, 0.04, 0.09]}
[wall.floor]
type = "plane"
point = [0.02, 0.02, 0.0]
normal = [0.0, 0.0, 1.0]
hole = {shape = "disk", radius = 0.012}
material = "glass"
[output]
thermo_interval = 0.02
)" + extra;
}

std::string scene2d(const std::string& extra) {
  return R"([run]
dimension = 2
method = "edm"
end_time = 0.01
[domain]
lower = [0.0, 0.0]
upper = [1.0, 1.0]
[material.glass]
density = 1.0
restitution = 1.0
[particles.p]
material = "glass"
radius = 0.01
count = 10
region = {lower = [0.0, 0.0], upper = [0.5, 0.5]}
)" + extra;
}

void expect_error(const std::string& text, std::initializer_list<std::string> parts) {
  test::expect_scene_error(text, "outlets.toml", kDir, parts);
}

TEST(SceneOutlets, EachTypeBuildsTheRegionItNames) {
  const Scene sc = load_scene_string(
      scene3d("[outlet.bottom]\ntype = \"face\"\nface = \"z-\"\n"
              "[outlet.cut]\ntype = \"plane\"\npoint = [0.0, 0.0, -0.01]\nnormal = [0.0, 0.0, 2.0]\n"
              "[outlet.bin]\ntype = \"box\"\nlower = [0.0, 0.0, -0.02]\nupper = [0.01, 0.01, -0.015]\n"
              "[outlet.pipe]\ntype = \"cylinder\"\npoint = [0.02, 0.02, -0.02]\naxis = [0.0, 0.0, 1.0]\n"
              "radius = 0.005\nlength = 0.01\n"),
      "outlets.toml", kDir, {});
  const auto& s = std::get<System<3>>(sc.system);
  ASSERT_EQ(s.outlets.size(), 4u);
  EXPECT_TRUE(sc.warnings.empty());
  // In file order, each region holding the points it should.
  EXPECT_EQ(s.outlets[0].name, "bottom");
  EXPECT_EQ(s.outlets[0].face, 4);  // 2 * axis z + lower
  EXPECT_TRUE(s.outlets[0].region.inside(Vec<3>(0.02, 0.02, -0.0201)));
  EXPECT_FALSE(s.outlets[0].region.inside(Vec<3>(0.02, 0.02, -0.0199)));
  EXPECT_EQ(s.outlets[1].face, -1);
  EXPECT_TRUE(s.outlets[1].region.inside(Vec<3>(0.5, 0.5, -0.0101)));   // the normal is made unit
  EXPECT_FALSE(s.outlets[1].region.inside(Vec<3>(0.5, 0.5, -0.0099)));
  EXPECT_TRUE(s.outlets[2].region.inside(Vec<3>(0.005, 0.005, -0.017)));
  EXPECT_FALSE(s.outlets[2].region.inside(Vec<3>(0.015, 0.005, -0.017)));
  EXPECT_TRUE(s.outlets[3].region.inside(Vec<3>(0.024, 0.02, -0.015)));
  EXPECT_FALSE(s.outlets[3].region.inside(Vec<3>(0.026, 0.02, -0.015)));
  EXPECT_FALSE(s.outlets[3].region.inside(Vec<3>(0.02, 0.02, -0.009)));
  // 2D: a disk; an upper face.
  const Scene s2 = load_scene_string(scene2d("[outlet.hole]\ntype = \"cylinder\"\npoint = [0.8, 0.8]\nradius = 0.1\n"
                                             "[outlet.top]\ntype = \"face\"\nface = \"y+\"\n"),
                                     "outlets.toml", kDir, {});
  const auto& t = std::get<System<2>>(s2.system);
  ASSERT_EQ(t.outlets.size(), 2u);
  EXPECT_TRUE(t.outlets[0].region.inside(Vec<2>(0.85, 0.75)));
  EXPECT_FALSE(t.outlets[0].region.inside(Vec<2>(0.95, 0.75)));
  EXPECT_EQ(t.outlets[1].face, 3);
  EXPECT_TRUE(t.outlets[1].region.inside(Vec<2>(0.5, 1.0001)));
}

TEST(SceneOutlets, ImpossibleOutletsAreRefusedNamingKeyAndValue) {
  expect_error(scene3d("[outlet.o]\ntype = \"hole\"\n"), {"outlet.o.type", "hole"});
  expect_error(scene3d("[outlet.o]\ntype = \"face\"\nface = \"w-\"\n"), {"outlet.o.face", "w-"});
  expect_error(scene3d("[outlet.o]\ntype = \"face\"\nface = \"z-\"\npoint = [0.0, 0.0, 0.0]\n"), {"outlet.o.point"});
  expect_error(scene3d("[outlet.o]\ntype = \"face\"\nface = \"x+\"\n"),
               {"outlet.o.face", "periodic along x"});
  expect_error(scene3d("[outlet.o]\ntype = \"plane\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 0.0]\n"),
               {"outlet.o.normal", "nonzero"});
  expect_error(scene3d("[outlet.o]\ntype = \"box\"\nlower = [0.0, 0.0, -0.02]\nupper = [0.01, 0.0, -0.01]\n"),
               {"outlet.o.upper", "along y"});
  expect_error(scene3d("[outlet.o]\ntype = \"cylinder\"\npoint = [0.0, 0.0, -0.02]\naxis = [0.0, 0.0, 1.0]\n"
                       "radius = -0.01\nlength = 0.01\n"),
               {"outlet.o.radius", "-0.01"});
  expect_error(scene3d("[outlet.o]\ntype = \"cylinder\"\npoint = [0.0, 0.0, -0.02]\naxis = [0.0, 0.0, 1.0]\n"
                       "radius = 0.01\n"),
               {"outlet.o.length", "missing"});
  expect_error(scene2d("[outlet.o]\ntype = \"cylinder\"\npoint = [0.8, 0.8]\nradius = 0.1\nlength = 1.0\n"),
               {"outlet.o.length"});
  expect_error(scene3d("[outlet.o]\ntype = \"box\"\nlower = [0.0, 0.0, -0.02]\nupper = [0.01, 0.01, -0.01]\n"
                       "rate = 3\n"),
               {"outlet.o.rate"});
  // A grain that would leave at t = 0 (the box holds part of the grains' region).
  expect_error(scene3d("[outlet.o]\ntype = \"box\"\nlower = [0.0, 0.0, 0.0]\nupper = [0.04, 0.04, 0.05]\n"),
               {"particles.p", "inside outlet.o"});
}

TEST(SceneOutlets, AnOutletNoGrainCanReachIsRunWithAWarning) {
  const Scene sc = load_scene_string(
      scene3d("[outlet.far]\ntype = \"box\"\nlower = [1.0, 1.0, 1.0]\nupper = [2.0, 2.0, 2.0]\n"
              "[outlet.below]\ntype = \"plane\"\npoint = [0.0, 0.0, -0.02]\nnormal = [0.0, 0.0, 1.0]\n"),
      "outlets.toml", kDir, {});
  ASSERT_EQ(sc.warnings.size(), 2u);
  EXPECT_NE(sc.warnings[0].find("outlet.far"), std::string::npos) << sc.warnings[0];
  EXPECT_NE(sc.warnings[0].find("no grain can reach it"), std::string::npos) << sc.warnings[0];
  EXPECT_NE(sc.warnings[1].find("type = \"face\""), std::string::npos) << sc.warnings[1];
}

std::vector<std::vector<std::string>> read_csv(const std::filesystem::path& p) {
  std::vector<std::vector<std::string>> rows;
  std::ifstream f(p);
  std::string line;
  while (std::getline(f, line)) {
    std::vector<std::string> cells;
    std::stringstream ss(line);
    std::string c;
    while (std::getline(ss, c, ',')) cells.push_back(c);
    rows.push_back(cells);
  }
  return rows;
}

TEST(SceneOutlets, OutputsAgreeWithEachOther) {
  const auto dir = test::fresh_dir("outlet_outputs");
  {
    std::ofstream f(dir / "drain.toml");
    f << scene3d("[outlet.bottom]\ntype = \"face\"\nface = \"z-\"\n");
  }
  for (const std::string method : {"tdm", "hybrid"}) {
    SCOPED_TRACE(method);
    const auto out = dir / ("out_" + method);
    const test::CliResult r =
        test::run_cli("run " + (dir / "drain.toml").string() + " --set run.method=" + method + " --out " + out.string() +
                      " --quiet");
    ASSERT_EQ(r.code, 0) << r.out;
    const auto outflow = read_csv(out / "outflow.csv");
    ASSERT_GE(outflow.size(), 2u);
    EXPECT_EQ(outflow[0], (std::vector<std::string>{"time", "id", "outlet", "mass", "x", "y", "z", "vx", "vy", "vz"}));
    std::set<std::string> gone;
    for (std::size_t k = 1; k < outflow.size(); ++k) {
      EXPECT_EQ(outflow[k][2], "bottom");
      EXPECT_TRUE(gone.insert(outflow[k][1]).second) << outflow[k][1];
      EXPECT_LE(std::stod(outflow[k][6]), -0.02 + 1e-12);  // on the face (an event) or beyond it (a step)
    }
    const auto thermo = read_csv(out / "thermo.csv");
    const auto& h = thermo[0];
    ASSERT_GE(h.size(), 14u);
    EXPECT_EQ(std::vector<std::string>(h.end() - 5, h.end()),
              (std::vector<std::string>{"grains", "grains_in", "mass_in", "grains_out", "mass_out"}));
    for (std::size_t k = 1; k < thermo.size(); ++k) {
      EXPECT_EQ(thermo[k][h.size() - 4], "0");  // no inlets
      EXPECT_EQ(std::stoul(thermo[k][h.size() - 5]) + std::stoul(thermo[k][h.size() - 2]), 40u);
    }
    EXPECT_EQ(std::stoul(thermo.back()[h.size() - 2]), gone.size());
    const auto final_state = read_csv(out / "final_state.csv");
    EXPECT_EQ(final_state.size() - 1 + gone.size(), 40u);
    for (std::size_t k = 1; k < final_state.size(); ++k) EXPECT_EQ(gone.count(final_state[k][0]), 0u);
    const std::string summary = test::slurp(out / "summary.json");
    EXPECT_NE(summary.find("\"outflow\": {\"grains\": " + std::to_string(gone.size())), std::string::npos) << summary;
  }
  // Without outlets: no outflow.csv and the thermo columns as before.
  const auto closed = dir / "closed";
  {
    std::ofstream f(dir / "closed.toml");
    f << scene3d("[wall.plug]\ntype = \"plane\"\npoint = [0.02, 0.02, 0.0]\nnormal = [0.0, 0.0, 1.0]\n"
                 "patch = {shape = \"disk\", radius = 0.015}\nmaterial = \"glass\"\n");
  }
  const test::CliResult r = test::run_cli("run " + (dir / "closed.toml").string() + " --out " + closed.string() + " --quiet");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_FALSE(std::filesystem::exists(closed / "outflow.csv"));
  EXPECT_EQ(read_csv(closed / "thermo.csv")[0].back(), "soft");
}

TEST(SceneOutlets, TheCliRefusesBadOutletsWritingNothing) {
  const auto dir = test::fresh_dir("outlet_bad");
  {
    std::ofstream f(dir / "bad.toml");
    f << scene3d("[outlet.o]\ntype = \"face\"\nface = \"z-\"\nradius = 1.0\n");
  }
  const test::CliResult r = test::run_cli("run " + (dir / "bad.toml").string() + " --out " + (dir / "out").string());
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("outlet.o.radius"), std::string::npos) << r.out;
  EXPECT_FALSE(std::filesystem::exists(dir / "out"));
  // The warning reaches the user; the run goes on.
  {
    std::ofstream f(dir / "warn.toml");
    f << scene3d("[outlet.far]\ntype = \"box\"\nlower = [1.0, 1.0, 1.0]\nupper = [2.0, 2.0, 2.0]\n"
                 "[wall.plug]\ntype = \"plane\"\npoint = [0.02, 0.02, 0.0]\nnormal = [0.0, 0.0, 1.0]\n"
                 "patch = {shape = \"disk\", radius = 0.015}\nmaterial = \"glass\"\n");
  }
  const test::CliResult w = test::run_cli("check " + (dir / "warn.toml").string());
  EXPECT_EQ(w.code, 0) << w.out;
  EXPECT_NE(w.out.find("warning: "), std::string::npos) << w.out;
  EXPECT_NE(w.out.find("outlet.far"), std::string::npos) << w.out;
}

}  // namespace
}  // namespace matep

// Scene keys of [inlet.NAME] (io/scene.cpp read_inlet): each type builds the region it names, a mass
// rate becomes the grain rate of the radius distribution's mean mass, and every impossible inlet
// (outside the domain, inside a wall, a rate <= 0, an undefined material) ends with one message
// naming the file, the key and the value (exit 2 at the CLI, nothing written). At the CLI, the
// event log of a fed run passes `matep log verify` with the scene, and a rate the region cannot take
// is reported.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>
#include <variant>

#include "io/scene.hpp"
#include "tests/support/cli.hpp"
#include "tests/support/scene_errors.hpp"

namespace matep {
namespace {

const std::string kDir = std::string(MATEP_SOURCE_DIR) + "/tests/data/scene";

// A box with a floor, periodic along x and y; `extra` is appended (inlets). No [particles] table:
// an inlet is enough.
std::string scene3d(const std::string& extra) {
  return R"([run]
dimension = 3
method = "edm"
end_time = 0.2
seed = 4
gravity = [0.0, 0.0, -9.81]
[domain]
lower = [0.0, 0.0, 0.0]
upper = [0.05, 0.05, 0.1]
periodic = [true, true, false]
[material.glass]
density = 2500.0
restitution = 1.0
contact = "linear"
stiffness = 2000.0
[wall.floor]
type = "plane"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
material = "glass"
[wall.lid]
type = "plane"
point = [0.0, 0.0, 0.1]
normal = [0.0, 0.0, -1.0]
material = "glass"
)" + extra;
}

const std::string kInlet = "[inlet.feed]\nmaterial = \"glass\"\ngrain_radius = 0.002\nrate = 500\n";

void expect_error(const std::string& text, std::initializer_list<std::string> parts) {
  test::expect_scene_error(text, "inlets.toml", kDir, parts);
}

TEST(SceneInlets, EachTypeBuildsTheRegionItNames) {
  const Scene sc = load_scene_string(
      scene3d(kInlet + "type = \"box\"\nlower = [0.01, 0.01, 0.08]\nupper = [0.04, 0.04, 0.09]\nvelocity = [0.0, 0.0, "
                       "-1.0]\nspread = 0.1\ncount = 40\nstart = 0.01\nstop = 0.15\n"
                       "[inlet.shower]\ntype = \"disk\"\npoint = [0.025, 0.025, 0.09]\nnormal = [0.0, 0.0, -2.0]\n"
                       "radius = 0.01\nmaterial = \"glass\"\ngrain_radius = [0.001, 0.002]\nmass_rate = 0.01\n"
                       "[inlet.pipe]\ntype = \"cylinder\"\npoint = [0.025, 0.025, 0.05]\naxis = [0.0, 0.0, 1.0]\n"
                       "radius = 0.005\nlength = 0.03\nmaterial = \"glass\"\ngrain_radius = 0.002\nrate = 100\n"),
      "inlets.toml", kDir, {});
  const auto& s = std::get<System<3>>(sc.system);
  EXPECT_EQ(s.size(), 0u);
  ASSERT_EQ(s.inlets.size(), 3u);
  const Inlet<3>& box = s.inlets[0];
  EXPECT_EQ(box.name, "feed");
  EXPECT_EQ(box.shape, Inlet<3>::Shape::Box);
  EXPECT_EQ(box.rate, 500.0);
  EXPECT_EQ(box.count, 40u);
  EXPECT_EQ(box.start, 0.01);
  EXPECT_EQ(box.stop, 0.15);
  EXPECT_EQ(box.spread, 0.1);
  EXPECT_EQ(box.velocity, Vec<3>(0, 0, -1));
  EXPECT_EQ(box.slots(0.2), 40u);  // 0.01 + k / 500 < 0.15 gives 70, capped by count
  // A disk of the plane: every sample on the plane within the radius (normal made unit).
  const Inlet<3>& disk = s.inlets[1];
  EXPECT_EQ(disk.shape, Inlet<3>::Shape::Cylinder);
  EXPECT_EQ(disk.length, 0.0);
  EXPECT_NEAR(disk.axis.norm(), 1.0, 1e-15);
  std::mt19937_64 rng(1);
  for (int k = 0; k < 100; ++k) {
    const Vec<3> x = disk.sample_point(rng);
    EXPECT_NEAR(x[2], 0.09, 1e-15);
    EXPECT_LE(std::hypot(x[0] - 0.025, x[1] - 0.025), 0.01 + 1e-15);
  }
  // kg/s over the mean mass: <R^3> of R uniform in [1, 2] mm is (2^4 - 1) / 4 mm^3.
  const double mean_mass = 2500.0 * 4.0 / 3.0 * std::numbers::pi * (15.0 / 4.0) * 1e-9;
  EXPECT_NEAR(disk.rate, 0.01 / mean_mass, 1e-9 * disk.rate);
  EXPECT_EQ(disk.rmin, 0.001);
  EXPECT_EQ(disk.rmax, 0.002);
  const Inlet<3>& pipe = s.inlets[2];
  for (int k = 0; k < 100; ++k) {
    const Vec<3> x = pipe.sample_point(rng);
    EXPECT_GE(x[2], 0.05);
    EXPECT_LE(x[2], 0.08);
    EXPECT_LE(std::hypot(x[0] - 0.025, x[1] - 0.025), 0.005 + 1e-15);
  }
}

TEST(SceneInlets, ImpossibleInletsAreRefusedNamingKeyAndValue) {
  const std::string box = "type = \"box\"\nlower = [0.01, 0.01, 0.05]\nupper = [0.04, 0.04, 0.09]\n";
  expect_error(scene3d(kInlet + "type = \"box\"\nlower = [0.01, 0.01, 0.05]\nupper = [0.04, 0.04, 0.2]\n"),
               {"inlet.feed", "outside the domain", "0.2"});
  expect_error(scene3d(kInlet + "type = \"disk\"\npoint = [0.025, 0.025, 0.05]\nnormal = [1.0, 0.0, 0.0]\n"
                                "radius = 0.2\n"),
               {"inlet.feed", "outside the domain"});
  expect_error(scene3d(kInlet + "type = \"box\"\nlower = [0.01, 0.01, 0.0]\nupper = [0.04, 0.04, 0.001]\n"),
               {"inlet.feed", "inside wall.floor"});
  expect_error(scene3d("[inlet.feed]\nmaterial = \"glass\"\ngrain_radius = 0.002\nrate = -5\n" + box),
               {"inlet.feed.rate", "-5"});
  expect_error(scene3d("[inlet.feed]\nmaterial = \"glass\"\ngrain_radius = 0.002\nrate = 0\n" + box),
               {"inlet.feed.rate", "0"});
  expect_error(scene3d("[inlet.feed]\nmaterial = \"glass\"\ngrain_radius = 0.002\n" + box),
               {"inlet.feed", "exactly one of rate"});
  expect_error(scene3d(kInlet + "mass_rate = 1.0\n" + box), {"inlet.feed", "exactly one of rate"});
  expect_error(scene3d("[inlet.feed]\nmaterial = \"sand\"\ngrain_radius = 0.002\nrate = 5\n" + box),
               {"inlet.feed.material", "sand"});
  expect_error(scene3d("[inlet.feed]\nmaterial = \"glass\"\ngrain_radius = [0.003, 0.002]\nrate = 5\n" + box),
               {"inlet.feed.grain_radius"});
  expect_error(scene3d(kInlet + box + "start = 0.1\nstop = 0.05\n"), {"inlet.feed.stop", "after start"});
  expect_error(scene3d(kInlet + box + "count = 0\n"), {"inlet.feed.count", "0"});
  expect_error(scene3d(kInlet + box + "spread = -1\n"), {"inlet.feed.spread", "-1"});
  expect_error(scene3d(kInlet + box + "radius = 0.01\n"), {"inlet.feed.radius", "not a key"});
  expect_error(scene3d(kInlet + box + "temperature = 1\n"), {"inlet.feed.temperature"});
  expect_error(scene3d(kInlet + "type = \"funnel\"\n"), {"inlet.feed.type", "funnel"});
  // Without particles and without an inlet a scene has nothing to run.
  expect_error(scene3d(""), {"particles", "or an inlet"});
}

TEST(SceneInlets, AFedRunVerifiesAndReportsAMissedRate) {
  const auto dir = test::fresh_dir("inlet_cli");
  {
    std::ofstream f(dir / "feed.toml");
    f << scene3d(kInlet + "type = \"box\"\nlower = [0.0, 0.0, 0.06]\nupper = [0.05, 0.05, 0.09]\n"
                          "velocity = [0.3, 0.1, -0.5]\n[output]\nevents = true\nthermo_interval = 0.02\n");
  }
  const auto out = dir / "out";
  const test::CliResult r = test::run_cli("run " + (dir / "feed.toml").string() + " --out " + out.string() + " --quiet");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(r.out.find("warning"), std::string::npos) << r.out;
  const test::CliResult v =
      test::run_cli("log verify " + (out / "events.bin").string() + " --scene " + (dir / "feed.toml").string());
  EXPECT_EQ(v.code, 0) << v.out;
  EXPECT_NE(v.out.find("100 non-collision records skipped"), std::string::npos) << v.out;
  const std::string summary = test::slurp(out / "summary.json");
  EXPECT_NE(summary.find("\"inlets\": [{\"name\": \"feed\", \"due\": 100, \"inserted\": 100, \"missed\": 0}]"),
            std::string::npos)
      << summary;
  // A region too small for the rate: the CLI says how many grains it could not insert.
  {
    std::ofstream f(dir / "full.toml");
    f << scene3d(kInlet + "type = \"box\"\nlower = [0.02, 0.02, 0.05]\nupper = [0.03, 0.03, 0.052]\n");
  }
  const test::CliResult w = test::run_cli("run " + (dir / "full.toml").string() + " --set 'run.gravity=[0.0,0.0,0.0]' --out " +
                                          (dir / "full_out").string() + " --quiet");
  EXPECT_EQ(w.code, 0) << w.out;
  EXPECT_NE(w.out.find("warning: "), std::string::npos) << w.out;
  EXPECT_NE(w.out.find("inlet.feed: "), std::string::npos) << w.out;
  EXPECT_NE(w.out.find("found no free place"), std::string::npos) << w.out;
}

}  // namespace
}  // namespace matep

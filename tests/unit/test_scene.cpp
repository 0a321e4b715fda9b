// Scene loading: valid 2D/3D round trips, placement guarantees, error messages, --set.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <initializer_list>
#include <numbers>
#include <string>
#include <variant>
#include <vector>

#include "io/scene.hpp"

namespace {

using matep::Scene;
using matep::SceneError;
using matep::System;
using matep::Vec;

const std::string kDataDir = std::string(MATEP_SOURCE_DIR) + "/tests/data/scene";

// A valid 2D scene: a thermal gas, a lattice block moving right, a floor wall, periodic in x.
const std::string kScene2D = R"(
[run]
dimension = 2
method = "edm"
end_time = 10.0
seed = 42
gravity = [0.0, -1.0]
queue = "heap"
tc = 1e-6
collapse_decades = 6
max_events = 100000

[domain]
lower = [0.0, 0.0]
upper = [20.0, 20.0]
periodic = [true, false]

[material.glass]
density = 2.5
restitution = 0.8
young = 6e10
poisson = 0.22
friction = 0.3

[material.rubber]
density = 1.2
restitution = { model = "schwager", e0 = 0.9, u0 = 2.0 }
contact = "hertz"
stiffness = 1e5
dissipation = 0.5
tangential_restitution = -0.4

[wall.floor]
type = "plane"
point = [0.0, 0.0]
normal = [0.0, 2.0]
material = "glass"

[particles.gas]
material = "glass"
radius = 0.3
count = 150
temperature = 2.0

[particles.block]
material = "rubber"
radius = [0.2, 0.4]
count = 30
arrangement = "lattice"
region = { lower = [2.0, 12.0], upper = [8.0, 18.0] }
velocity = [1.5, 0.0]

[output]
dir = "results"
thermo_interval = 0.1
events = true
)";

const std::string kBase = "test.toml";

Scene load(const std::string& text, const std::vector<std::string>& overrides = {}) {
  return matep::load_scene_string(text, kBase, kDataDir, overrides);
}

// Expects a SceneError whose message contains every one of `parts`.
void expect_error(const std::string& text, std::initializer_list<std::string> parts,
                  const std::vector<std::string>& overrides = {}) {
  try {
    load(text, overrides);
    ADD_FAILURE() << "no SceneError; expected one containing " << *parts.begin();
  } catch (const SceneError& e) {
    const std::string msg = e.what();
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    EXPECT_EQ(msg.rfind(kBase + ":", 0), 0u) << "message does not start with the file name: " << msg;
    for (const auto& p : parts) EXPECT_NE(msg.find(p), std::string::npos) << "'" << p << "' not in: " << msg;
  }
}

// Replaces the first occurrence of `from` in `text`.
std::string edit(std::string text, const std::string& from, const std::string& to) {
  const auto pos = text.find(from);
  EXPECT_NE(pos, std::string::npos) << from;
  if (pos != std::string::npos) text.replace(pos, from.size(), to);
  return text;
}

template <int D>
double min_gap(const System<D>& s) {
  double worst = INFINITY;
  for (std::size_t i = 0; i < s.size(); ++i) {
    for (std::size_t j = i + 1; j < s.size(); ++j) {
      Vec<D> d = s.x[i] - s.x[j];
      for (int k = 0; k < D; ++k) {
        if (s.periodic[k]) {
          const double L = s.upper[k] - s.lower[k];
          d[k] -= L * std::round(d[k] / L);
        }
      }
      worst = std::min(worst, d.norm() - s.radius[i] - s.radius[j]);
    }
  }
  return worst;
}

template <int D>
void expect_group_thermal(const Scene& sc, const System<D>& s, int group, double T) {
  Vec<D> p = Vec<D>::Zero();
  double scale = 0.0, twoK = 0.0;
  int n = 0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (sc.group[i] != group) continue;
    const double m = s.mass(i);
    p += m * s.v[i];
    scale += m * s.v[i].norm();
    twoK += m * s.v[i].squaredNorm();
    ++n;
  }
  ASSERT_GT(n, 0);
  EXPECT_NEAR(twoK / (n * D), T, 1e-12 * T);
  EXPECT_LT(p.norm(), 1e-12 * scale);
}

TEST(Scene, Valid2DRoundTrip) {
  const Scene sc = load(kScene2D);
  EXPECT_EQ(sc.path, kBase);
  EXPECT_EQ(sc.dimension, 2);
  EXPECT_EQ(sc.method, matep::Method::Edm);
  EXPECT_EQ(sc.queue, "heap");
  EXPECT_EQ(sc.end_time, 10.0);
  EXPECT_EQ(sc.seed, 42u);
  EXPECT_EQ(sc.tc, 1e-6);
  EXPECT_EQ(sc.collapse_decades, 6.0);
  EXPECT_EQ(sc.max_events, 100000u);
  EXPECT_FALSE(sc.dt.has_value());
  EXPECT_FALSE(sc.threads.has_value());
  EXPECT_EQ(sc.output.dir, "results");
  EXPECT_EQ(sc.output.thermo_interval, 0.1);
  EXPECT_TRUE(sc.output.events);
  EXPECT_EQ(sc.output.snapshot_interval, 0.0);
  ASSERT_EQ(sc.group_names, (std::vector<std::string>{"gas", "block"}));

  ASSERT_TRUE(std::holds_alternative<System<2>>(sc.system));
  const auto& s = std::get<System<2>>(sc.system);
  EXPECT_EQ(s.gravity, Vec<2>(0.0, -1.0));
  EXPECT_TRUE(s.periodic[0]);
  EXPECT_FALSE(s.periodic[1]);
  ASSERT_EQ(s.materials.size(), 2u);
  EXPECT_EQ(s.materials[0].name, "glass");
  EXPECT_EQ(s.materials[0].restitution.model, matep::Restitution::Model::Constant);
  EXPECT_EQ(s.materials[0].restitution.e, 0.8);
  EXPECT_EQ(s.materials[0].young, 6e10);
  EXPECT_EQ(s.materials[0].poisson, 0.22);
  EXPECT_EQ(s.materials[0].friction, 0.3);
  EXPECT_EQ(s.materials[0].contact, "");
  EXPECT_EQ(s.materials[1].restitution.model, matep::Restitution::Model::Schwager);
  EXPECT_EQ(s.materials[1].restitution.e0, 0.9);
  EXPECT_EQ(s.materials[1].restitution.u0, 2.0);
  EXPECT_EQ(s.materials[1].restitution.n, 0.2);
  EXPECT_EQ(s.materials[1].contact, "hertz");
  EXPECT_EQ(s.materials[1].stiffness, 1e5);
  EXPECT_EQ(s.materials[1].dissipation, 0.5);
  EXPECT_EQ(s.materials[1].tangential_restitution, -0.4);
  ASSERT_EQ(s.walls.size(), 1u);
  EXPECT_EQ(s.walls[0].name, "floor");
  ASSERT_NE(as_plane<2>(s.walls[0].shape.get()), nullptr);
  EXPECT_EQ(as_plane<2>(s.walls[0].shape.get())->normal, Vec<2>(0.0, 1.0));

  ASSERT_EQ(s.size(), 180u);
  ASSERT_EQ(sc.group.size(), 180u);
  ASSERT_EQ(s.v.size(), 180u);
  ASSERT_EQ(s.w.size(), 180u);
  for (std::size_t i = 0; i < s.size(); ++i) {
    const int g = i < 150 ? 0 : 1;
    EXPECT_EQ(sc.group[i], g);
    EXPECT_EQ(s.material[i], g);
    const double r = s.radius[i];
    if (g == 0) {
      EXPECT_EQ(r, 0.3);
    } else {
      EXPECT_GE(r, 0.2);
      EXPECT_LE(r, 0.4);
      EXPECT_EQ(s.v[i], Vec<2>(1.5, 0.0));
      EXPECT_GE(s.x[i][0] - r, 2.0);
      EXPECT_LE(s.x[i][0] + r, 8.0);
      EXPECT_GE(s.x[i][1] - r, 12.0);
      EXPECT_LE(s.x[i][1] + r, 18.0);
    }
    EXPECT_DOUBLE_EQ(s.mass(i), s.materials[static_cast<std::size_t>(g)].density * std::numbers::pi * r * r);
    EXPECT_GE(s.x[i][1] - r, 0.0);  // non-periodic y: fully inside
    EXPECT_LE(s.x[i][1] + r, 20.0);
    EXPECT_GE(s.x[i][0], 0.0);      // periodic x: centre inside
    EXPECT_LT(s.x[i][0], 20.0);
  }
  EXPECT_GE(min_gap(s), 0.0);
  expect_group_thermal(sc, s, 0, 2.0);
}

TEST(Scene, Valid3DWithFileAndPolydisperseGas) {
  const Scene sc = matep::load_scene(kDataDir + "/box3d.toml");
  EXPECT_EQ(sc.dimension, 3);
  EXPECT_EQ(sc.end_time, 2.5);
  EXPECT_EQ(sc.seed, 7u);
  ASSERT_EQ(sc.group_names, (std::vector<std::string>{"grains", "gas"}));
  const auto& s = std::get<System<3>>(sc.system);
  ASSERT_EQ(s.size(), 204u);
  // File particles come first, exactly as written (columns in any order, wz only).
  EXPECT_EQ(s.x[0], Vec<3>(1, 1, 1));
  EXPECT_EQ(s.v[0], Vec<3>(1, 0, 0));
  EXPECT_EQ(s.w[0], Vec<3>(0, 0, 0.5));
  EXPECT_EQ(s.radius[2], 0.25);
  EXPECT_EQ(s.x[2], Vec<3>(5, 5, 5));
  EXPECT_EQ(s.v[2], Vec<3>(0, 0, 1));
  EXPECT_EQ(s.w[2], Vec<3>(0, 0, -2));
  EXPECT_EQ(s.v[3], Vec<3>(0, 0, -0.1));
  for (std::size_t i = 0; i < s.size(); ++i) {
    EXPECT_EQ(sc.group[i], i < 4 ? 0 : 1);
    EXPECT_DOUBLE_EQ(s.mass(i), 7.8 * 4.0 / 3.0 * std::numbers::pi * std::pow(s.radius[i], 3));
    if (i >= 4) {
      EXPECT_GE(s.radius[i], 0.1);
      EXPECT_LE(s.radius[i], 0.3);
    }
    for (int k = 0; k < 3; ++k) {
      EXPECT_GE(s.x[i][k] - s.radius[i], 0.0);
      EXPECT_LE(s.x[i][k] + s.radius[i], 10.0);
    }
  }
  EXPECT_EQ(matep::ball_volume<3>(2.0), 4.0 / 3.0 * std::numbers::pi * 8.0);
  EXPECT_EQ(matep::ball_volume<2>(2.0), std::numbers::pi * 4.0);
  EXPECT_GE(min_gap(s), 0.0);  // the gas avoids the file grains, and each other
  expect_group_thermal(sc, s, 1, 0.5);
}

TEST(Scene, DeterministicWithSeedAndDifferentOtherwise) {
  const auto a = std::get<System<2>>(load(kScene2D).system);
  const auto b = std::get<System<2>>(load(kScene2D).system);
  const auto c = std::get<System<2>>(load(kScene2D, {"run.seed=43"}).system);
  ASSERT_EQ(a.size(), b.size());
  ASSERT_EQ(a.size(), c.size());
  bool differs = false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a.x[i], b.x[i]);
    EXPECT_EQ(a.v[i], b.v[i]);
    EXPECT_EQ(a.radius[i], b.radius[i]);
    differs = differs || a.x[i] != c.x[i] || a.v[i] != c.v[i];
  }
  EXPECT_TRUE(differs);
}

TEST(Scene, GroupsOfOneAndColdGroups) {
  const std::string text = edit(edit(kScene2D, "count = 150", "count = 1"), "count = 30\n", "count = 4\n");
  const Scene sc = load(text);
  const auto& s = std::get<System<2>>(sc.system);
  ASSERT_EQ(s.size(), 5u);
  EXPECT_NEAR(s.mass(0) * s.v[0].squaredNorm() / 2.0, 2.0, 1e-12);  // one particle at T = 2
  const Scene cold = load(kScene2D, {"particles.gas.temperature=0"});
  const auto& sc0 = std::get<System<2>>(cold.system);
  for (std::size_t i = 0; i < 150; ++i) EXPECT_EQ(sc0.v[i], Vec<2>::Zero());
}

TEST(Scene, LatticeFillsTheFirstSites) {
  // 4 x 4 sites of spacing 1 in [0, 4]^2; 10 particles fill the bottom two rows and two more.
  const std::string text = R"(
[run]
dimension = 2
end_time = 1
[domain]
lower = [0, 0]
upper = [4, 4]
[material.m]
density = 1
[particles.p]
material = "m"
radius = 0.5
count = 10
arrangement = "lattice"
)";
  const auto s = std::get<System<2>>(load(text).system);
  ASSERT_EQ(s.size(), 10u);
  EXPECT_EQ(s.x[0], Vec<2>(0.5, 0.5));
  EXPECT_EQ(s.x[3], Vec<2>(3.5, 0.5));
  EXPECT_EQ(s.x[4], Vec<2>(0.5, 1.5));
  EXPECT_EQ(s.x[9], Vec<2>(1.5, 2.5));
  EXPECT_GE(min_gap(s), -1e-12);
  // 17 particles need spacing < 1 in the same box: too dense for radius 0.5.
  expect_error(text, {"particles.p.count", "17", "lattice"}, {"particles.p.count=17"});
}

TEST(Scene, SoftSphereKeysAreStored) {
  const Scene sc = load(kScene2D, {"run.dt=1e-5", "run.threads=4", "run.method=tdm"});
  EXPECT_EQ(sc.dt, 1e-5);
  EXPECT_EQ(sc.threads, 4);
  EXPECT_EQ(sc.method, matep::Method::Tdm);
  expect_error(kScene2D, {"run.dt", "must be > 0", "0"}, {"run.dt=0"});
  expect_error(kScene2D, {"run.threads", "0"}, {"run.threads=0"});
  expect_error(kScene2D, {"material.rubber.contact", "\"spring\""}, {"material.rubber.contact=spring"});
}

// hybrid.cost_ratio: a number, or "measured" (the crossover follows the run's own costs).
TEST(Scene, HybridCostRatioIsANumberOrMeasured) {
  const Scene fixed = load(kScene2D, {"hybrid.cost_ratio=25"});
  EXPECT_EQ(fixed.hybrid.cost_ratio, 25.0);
  EXPECT_FALSE(fixed.hybrid.cost_measured);
  const Scene measured = load(kScene2D, {"hybrid.cost_ratio=measured"});
  EXPECT_TRUE(measured.hybrid.cost_measured);
  EXPECT_FALSE(measured.hybrid.cost_ratio.has_value());
  expect_error(kScene2D, {"hybrid.cost_ratio", "\"measured\"", "\"timed\""}, {"hybrid.cost_ratio=timed"});
  expect_error(kScene2D, {"hybrid.cost_ratio", "0"}, {"hybrid.cost_ratio=0"});
}

TEST(Scene, TangentialRuleKey) {
  for (const char* law : {"walton", "constant", "fem_fit"}) {
    const Scene sc = load(kScene2D, {std::string("material.rubber.tangential=") + law});
    EXPECT_EQ(std::get<System<2>>(sc.system).materials[1].tangential, law);
  }
  EXPECT_EQ(std::get<System<2>>(load(kScene2D).system).materials[1].tangential, "");
  expect_error(kScene2D, {"material.rubber.tangential", "\"coulomb\"", "walton"},
               {"material.rubber.tangential=coulomb"});
  expect_error(kScene2D, {"material.rubber.tangential", "string"}, {"material.rubber.tangential=3"});
}

// ------------------------------------------------------------------------------- overrides

TEST(Scene, OverridesNumberStringVectorAndNestedKey) {
  const Scene sc = load(kScene2D, {"run.end_time=5", "run.queue=calendar", "run.gravity=[0, -9.81]",
                                   "material.glass.restitution=0.5", "material.rubber.restitution.u0 = 3",
                                   "output.snapshot_interval=0.5", "output.dir=my results"});
  EXPECT_EQ(sc.end_time, 5.0);
  EXPECT_EQ(sc.queue, "calendar");
  EXPECT_EQ(sc.output.snapshot_interval, 0.5);
  EXPECT_EQ(sc.output.dir, "my results");
  const auto& s = std::get<System<2>>(sc.system);
  EXPECT_EQ(s.gravity, Vec<2>(0.0, -9.81));
  EXPECT_EQ(s.materials[0].restitution.e, 0.5);
  EXPECT_EQ(s.materials[1].restitution.u0, 3.0);
  // A whole table as the value, and intermediate tables created on the way.
  const Scene sc2 = load(kScene2D, {"material.glass.restitution={model = \"power\", B = 0.9, b = 0.1}",
                                    "material.new.density=4", "particles.gas.material=new"});
  const auto& s2 = std::get<System<2>>(sc2.system);
  EXPECT_EQ(s2.materials[0].restitution.model, matep::Restitution::Model::Power);
  EXPECT_EQ(s2.materials[0].restitution.b, 0.1);
  ASSERT_EQ(s2.materials.size(), 3u);
  EXPECT_EQ(s2.materials[2].name, "new");
  EXPECT_EQ(s2.material[0], 2);
}

TEST(Scene, BadOverrides) {
  expect_error(kScene2D, {"--set", "\"runseed\""}, {"runseed"});
  expect_error(kScene2D, {"--set", "\"=3\""}, {"=3"});
  expect_error(kScene2D, {"run..seed", "empty"}, {"run..seed=3"});
  expect_error(kScene2D, {"run.seed.x", "run.seed", "not a table", "42"}, {"run.seed.x=1"});
  // A bare word that lands where a number is needed: the value is named as a string.
  expect_error(kScene2D, {"run.end_time", "expected a number", "\"soon\""}, {"run.end_time=soon"});
  expect_error(kScene2D, {"run.warp", "unknown key", "9"}, {"run.warp=9"});
}

// ---------------------------------------------------------------------------------- errors

TEST(SceneErrors, UnknownKeys) {
  expect_error("colour = \"red\"\n" + kScene2D, {"colour", "unknown key", "\"red\""});
  expect_error(edit(kScene2D, "seed = 42", "seed = 42\nend_tiem = 3"),
               {"run.end_tiem", "unknown key", "3", "did you mean 'end_time'"});
  expect_error(edit(kScene2D, "density = 2.5", "density = 2.5\nhardness = 7"),
               {"material.glass.hardness", "unknown key", "7"});
  expect_error(edit(kScene2D, "e0 = 0.9,", "e0 = 0.9, e1 = 0.5,"),
               {"material.rubber.restitution.e1", "unknown key", "0.5"});
  expect_error(edit(kScene2D, "temperature = 2.0", "temperature = 2.0\nspin = 1"),
               {"particles.gas.spin", "unknown key", "1"});
  expect_error(edit(kScene2D, "region = { lower", "region = { middle = 1, lower"),
               {"particles.block.region.middle", "unknown key", "1"});
  expect_error(edit(kScene2D, "[wall.floor]\n", "[wall.floor]\ncolor = 1\n"), {"wall.floor.color", "unknown key"});
  expect_error(edit(kScene2D, "events = true", "events = true\nvtk = true"), {"output.vtk", "unknown key", "true"});
  expect_error(edit(kScene2D, "upper = [20.0, 20.0]", "upper = [20.0, 20.0]\nshape = \"box\""),
               {"domain.shape", "unknown key", "\"box\""});
}

TEST(SceneErrors, WrongTypes) {
  expect_error(edit(kScene2D, "end_time = 10.0", "end_time = \"ten\""),
               {"run.end_time", "expected a number", "a string", "\"ten\""});
  expect_error(edit(kScene2D, "seed = 42", "seed = 4.2"), {"run.seed", "expected an integer", "4.2"});
  expect_error(edit(kScene2D, "count = 150", "count = \"many\""), {"particles.gas.count", "integer", "\"many\""});
  expect_error(edit(kScene2D, "events = true", "events = 1"), {"output.events", "boolean", "1"});
  expect_error(edit(kScene2D, "periodic = [true, false]", "periodic = [1, 0]"),
               {"domain.periodic", "boolean", "[1, 0]"});
  expect_error(edit(kScene2D, "queue = \"heap\"", "queue = \"stack\""),
               {"run.queue", "\"calendar\"", "\"stack\""});
  expect_error(edit(kScene2D, "dimension = 2", "dimension = 4"), {"run.dimension", "2 or 3", "4"});
  expect_error(edit(kScene2D, "restitution = 0.8", "restitution = \"high\""),
               {"material.glass.restitution", "a string", "\"high\""});
  expect_error(kScene2D, {"material.rubber.restitution.model", "\"linear\""},
               {"material.rubber.restitution.model=\"linear\""});
  expect_error(kScene2D, {"particles.gas.arrangement", "\"hexagonal\""}, {"particles.gas.arrangement=hexagonal"});
}

TEST(SceneErrors, MissingKeys) {
  expect_error(edit(kScene2D, "end_time = 10.0", ""), {"run.end_time", "missing"});
  expect_error(edit(kScene2D, "dimension = 2", ""), {"run.dimension", "missing"});
  expect_error(edit(kScene2D, "density = 2.5", ""), {"material.glass.density", "missing"});
  expect_error(edit(kScene2D, "material = \"glass\"\nradius", "radius"), {"particles.gas.material", "missing"});
  expect_error(edit(kScene2D, "count = 150", ""), {"particles.gas.count", "missing"});
  expect_error(edit(kScene2D, "e0 = 0.9,", ""), {"material.rubber.restitution.e0", "missing"});
  expect_error(edit(kScene2D, "lower = [0.0, 0.0]\n", ""), {"domain.lower", "missing"});
  expect_error(kScene2D, {"particles.gas.material", "no such material", "\"sand\""}, {"particles.gas.material=sand"});
}

TEST(SceneErrors, WrongDimensionVectors) {
  expect_error(edit(kScene2D, "lower = [0.0, 0.0]", "lower = [0.0, 0.0, 0.0]"),
               {"domain.lower", "2 numbers", "[0, 0, 0]"});
  expect_error(edit(kScene2D, "gravity = [0.0, -1.0]", "gravity = [-1.0]"), {"run.gravity", "2 numbers", "[-1]"});
  expect_error(edit(kScene2D, "velocity = [1.5, 0.0]", "velocity = [1.5, 0.0, 0.0]"),
               {"particles.block.velocity", "[1.5, 0, 0]"});
  expect_error(edit(kScene2D, "normal = [0.0, 2.0]", "normal = [0.0, 0.0]"), {"wall.floor.normal", "nonzero", "[0, 0]"});
  expect_error(kScene2D, {"run.gravity", "element 1", "[0, \"down\"]"}, {"run.gravity=[0, \"down\"]"});
}

TEST(SceneErrors, ImpossibleValues) {
  expect_error(edit(kScene2D, "radius = 0.3", "radius = -0.5"), {"particles.gas.radius", "must be > 0", "-0.5"});
  expect_error(edit(kScene2D, "radius = [0.2, 0.4]", "radius = [0.4, 0.2]"),
               {"particles.block.radius", "rmax", "[0.4, 0.2]"});
  expect_error(edit(kScene2D, "density = 2.5", "density = -2"), {"material.glass.density", "must be > 0", "-2"});
  expect_error(edit(kScene2D, "restitution = 0.8", "restitution = 1.5"),
               {"material.glass.restitution", "[0, 1]", "1.5"});
  expect_error(edit(kScene2D, "e0 = 0.9", "e0 = -0.1"), {"material.rubber.restitution.e0", "[0, 1]", "-0.1"});
  expect_error(edit(kScene2D, "poisson = 0.22", "poisson = 0.7"), {"material.glass.poisson", "(-1, 0.5]", "0.7"});
  expect_error(edit(kScene2D, "end_time = 10.0", "end_time = 0"), {"run.end_time", "must be > 0", "0"});
  expect_error(edit(kScene2D, "upper = [20.0, 20.0]", "upper = [20.0, -1.0]"), {"domain.upper", "[20, -1]"});
  expect_error(edit(kScene2D, "collapse_decades = 6", "collapse_decades = 0.5"),
               {"run.collapse_decades", "at least 1", "0.5"});
  expect_error(edit(kScene2D, "collapse_decades = 6", "collapse_decades = 31"), {"run.collapse_decades", "31"});
  // The keys of the absolute-window detector are refused with the key that replaced them.
  expect_error(edit(kScene2D, "collapse_decades = 6", "collapse_window = 1e-8"),
               {"run.collapse_window", "run.collapse_decades"});
  expect_error(edit(kScene2D, "temperature = 2.0", "temperature = -1"), {"particles.gas.temperature", "-1"});
  expect_error(edit(kScene2D, "upper = [8.0, 18.0]", "upper = [8.0, 25.0]"),
               {"particles.block.region.upper", "outside the domain", "[8, 25]"});
  expect_error(edit(kScene2D, "temperature = 2.0", "temperature = 2.0\nvelocity = [1, 0]"),
               {"particles.gas.velocity", "temperature", "[1, 0]"});
}

TEST(SceneErrors, TomlSyntaxError) {
  try {
    load("[run]\ndimension = 2\nend_time = = 3\n");
    FAIL() << "no error";
  } catch (const SceneError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("test.toml"), std::string::npos) << msg;
    EXPECT_NE(msg.find("line 3"), std::string::npos) << msg;
    EXPECT_NE(msg.find("column"), std::string::npos) << msg;
  }
}

TEST(SceneErrors, MissingSceneFile) {
  try {
    matep::load_scene(kDataDir + "/no_such_scene.toml");
    FAIL() << "no error";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("no_such_scene.toml"), std::string::npos) << e.what();
  }
}

const std::string kFileScene = R"(
[run]
dimension = 2
end_time = 1
[domain]
lower = [0, 0]
upper = [10, 10]
[material.m]
density = 1
[particles.p]
material = "m"
file = "FILE"
)";

TEST(SceneErrors, ParticleFiles) {
  const auto with = [](const std::string& f) { return edit(kFileScene, "FILE", f); };
  // Overlap: both particles named, with positions and the overlap.
  expect_error(with("overlap2d.csv"), {"particles.p.file", "\"overlap2d.csv\"", "particles.p[2]", "particles.p[1]",
                                       "(3.9, 3)", "(3, 3)", "overlaps", "by 0.1 "});
  expect_error(with("outside2d.csv"), {"particles.p.file", "\"outside2d.csv\"", "particles.p[1]", "line 3", "(9.8, 5)", "outside"});
  expect_error(with("negradius2d.csv"), {"particles.p.file", "\"negradius2d.csv\"", "particles.p[1]", "radius -0.5"});
  expect_error(with("badcolumn2d.csv"), {"particles.p.file", "\"badcolumn2d.csv\"", "unknown column 'colour'"});
  expect_error(with("badnumber2d.csv"), {"particles.p.file", "\"badnumber2d.csv\"", "line 3", "\"abc\""});
  expect_error(with("missing.csv"), {"particles.p.file", "\"missing.csv\"", kDataDir + "/missing.csv", "cannot read"});
  // A 3D file read as 2D: the z column is unknown.
  expect_error(with("grains3d.csv"), {"particles.p.file", "unknown column"});
  // File particles must not overlap a wall: particle 0 at (1, 1) lies 0.1 above this floor.
  expect_error(with("outside2d.csv"), {"particles.p.file", "particles.p[0]", "wall.w", "by 0.4"},
               {"domain.upper=[20, 20]", "wall.w.type=plane", "wall.w.point=[0, 0.9]", "wall.w.normal=[0, 1]",
                "wall.w.material=m"});
  // File particles of different groups must not overlap either.
  expect_error(with("outside2d.csv"), {"particles.q.file", "particles.q[0]", "particles.p[0]", "\"outside2d.csv\""},
               {"domain.upper=[20, 20]", "particles.q.material=m", "particles.q.file=outside2d.csv"});
  expect_error(with("overlap2d.csv"), {"particles.p.radius", "file"}, {"particles.p.radius=1"});
}

TEST(SceneErrors, UnplaceableCountFailsFast) {
  const auto t0 = std::chrono::steady_clock::now();
  // More volume than close packing allows: rejected at once.
  expect_error(kScene2D, {"particles.gas.count", "could not place 5000 particles", "densest packing", "5000"},
               {"particles.gas.count=5000", "particles.gas.radius=0.5"});
  // Below close packing but far beyond what random sequential placement reaches (~0.55 in 2D):
  // gives up after a bounded number of trials.
  expect_error(kScene2D, {"particles.gas.count", "could not place 420 particles", "attempts", "420"},
               {"particles.gas.count=420", "particles.gas.radius=0.5"});
  // Large monodisperse requests beyond the jamming density of random sequential placement: at once.
  expect_error(kScene2D, {"particles.gas.count", "random placement can reach", "lattice", "1000"},
               {"particles.gas.count=1000", "particles.gas.radius=0.3"});
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_LT(secs, 5.0);
}

}  // namespace

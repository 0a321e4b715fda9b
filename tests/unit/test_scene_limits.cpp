// Input limits checked before any work (README.md, "Limits"): nesting and size of the scene text,
// radii the cell grids can hold, grain counts against memory, and the output plan. Each defect
// found on main is reproduced here: in-process through load_scene_string, and end to end through
// the binary run as a child (a crash shows as a signal; a hang is cut by a timeout).
#include <gtest/gtest.h>

#include <algorithm>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "io/run.hpp"
#include "io/scene.hpp"
#include "io/scene_limits.hpp"
#include "tests/support/cli.hpp"
#include "tests/support/scene_errors.hpp"

namespace fs = std::filesystem;
using matep::test::expect_scene_error;

namespace {

const std::string kRun = "[run]\ndimension = 3\nend_time = 1.0\n";

// A 2D box of side L with one group of `count` grains of radius r (random placement).
std::string box2d(const std::string& L, const std::string& r, const std::string& count) {
  return "[run]\ndimension = 2\nend_time = 1.0\n[domain]\nlower = [0.0, 0.0]\nupper = [" + L + ", " + L +
         "]\n[material.m]\ndensity = 1.0\n[particles.g]\nmaterial = \"m\"\nradius = " + r + "\ncount = " + count +
         "\n";
}

// A periodic 3D gas of 2744 grains on a lattice at T = 1 (cases/elastic_gas.toml without outputs).
std::string gas(const std::string& output) {
  return kRun + "seed = 7\n[domain]\nlower = [0.0, 0.0, 0.0]\nupper = [16.6, 16.6, 16.6]\n"
                "periodic = [true, true, true]\n[material.hard]\ndensity = 1.9\n[particles.gas]\nmaterial = \"hard\"\n"
                "radius = 0.5\ncount = 2744\narrangement = \"lattice\"\ntemperature = 1.0\n[output]\n" +
         output;
}

std::string deep_dotted_key(int levels) {
  std::string k = "a";
  for (int i = 1; i < levels; ++i) k += ".a";
  return kRun + k + " = 1\n";
}

std::string write_file(const fs::path& p, const std::string& text) {
  std::ofstream(p, std::ios::binary) << text;
  return p.string();
}

std::string what_of(const std::string& text) {
  try {
    const matep::Scene s = matep::load_scene_string(text, "s.toml", ".", {});
    (void)matep::describe_scene(s);
  } catch (const matep::SceneError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(SceneLimits, DeepDottedKeyIsRefusedBeforeTheParserNamingTheLine) {
  expect_scene_error(deep_dotted_key(50000), "s.toml", ".", {"s.toml: line 4:", "more than 64 levels"});
}

TEST(SceneLimits, DeepHeadersInlineTablesAndArraysAreRefused) {
  std::string header = "[a";
  for (int i = 0; i < 70; ++i) header += ".b";
  expect_scene_error(kRun + header + "]\nx = 1\n", "s.toml", ".", {"line 4", "more than 64"});
  std::string inl = "x = ", close;
  for (int i = 0; i < 70; ++i) {
    inl += "{a = ";
    close += "}";
  }
  expect_scene_error(kRun + inl + "1" + close + "\n", "s.toml", ".", {"line 4", "more than 64"});
  expect_scene_error(kRun + "\n\nx = " + std::string(100, '[') + std::string(100, ']') + "\n", "s.toml", ".",
                     {"line 6", "more than 64"});
}

// Depth is counted outside strings and comments, and levels close again: a scene may hold many
// shallow tables and brackets inside strings and comments.
TEST(SceneLimits, NestingIsCountedOutsideStringsAndCommentsAndClosesAgain) {
  std::string text = box2d("10.0", "0.5", "3");
  text += "# " + std::string(500, '[') + " a.b.c.d.e.f.g.h.i.j.k.l.m.n.o.p.q.r.s.t.u.v.w.x.y.z\n";
  text += "[output]\ndir = \"" + std::string(300, '{') + "\"\n";
  for (int i = 0; i < 100; ++i) text += "[material.m" + std::to_string(i) + "]\ndensity = 1.5\n";
  const matep::Scene s = matep::load_scene_string(text, "s.toml", ".", {});
  EXPECT_EQ(s.output.dir, std::string(300, '{'));
  // [run] and 63 dots: 64 levels pass the scan (the reader then names the unknown key); 65 do not.
  expect_scene_error(deep_dotted_key(64), "s.toml", ".", {"run.a: unknown key"});
  expect_scene_error(deep_dotted_key(65), "s.toml", ".", {"more than 64"});
}

TEST(SceneLimits, AnOversizedSceneIsRefusedBeforeParsing) {
  const std::string text = kRun + "# " + std::string(matep::scene_detail::kMaxSceneBytes, 'x') + "\n";
  expect_scene_error(text, "s.toml", ".", {"bytes, more than the limit of 16.8 MB", "particles.NAME.file"});
  const fs::path d = matep::test::fresh_dir("limits_size");
  try {
    matep::load_scene(write_file(d / "big.toml", text));
    ADD_FAILURE() << "a 16 MiB scene was read";
  } catch (const matep::SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("big.toml: the scene is"), std::string::npos) << e.what();
  }
  fs::remove_all(d);
}

TEST(SceneLimits, ADeepSetOverrideIsRefused) {
  std::string key = "run";
  for (int i = 0; i < 100; ++i) key += ".a";
  try {
    matep::load_scene_string(box2d("10.0", "0.5", "3"), "s.toml", ".", {key + "=1"});
    ADD_FAILURE() << "no SceneError";
  } catch (const matep::SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("s.toml: --set: the key has more than 64 levels"), std::string::npos)
        << e.what();
  }
  try {
    matep::load_scene_string(box2d("10.0", "0.5", "3"), "s.toml", ".",
                             {"run.x=" + std::string(100, '[') + std::string(100, ']')});
    ADD_FAILURE() << "no SceneError";
  } catch (const matep::SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("more than 64 levels"), std::string::npos) << e.what();
  }
}

TEST(SceneLimits, SubnormalAndTinyRadiiAreRefusedNamingTheKey) {
  // The grid loop of main hung on this one (cell *= 1.25 cannot grow a cell of two subnormal ulps).
  expect_scene_error(box2d("1e-321", "5e-324", "1"), "s.toml", ".",
                     {"particles.g.radius", "not a normal positive number", "(got 5e-324)"});
  expect_scene_error(box2d("1.0", "1e-300", "1"), "s.toml", ".",
                     {"particles.g.radius", "too small for the domain", "limit of 1e+09", "(got 1e-300)"});
  expect_scene_error(box2d("1.0", "[1e-300, 0.1]", "1"), "s.toml", ".", {"particles.g.radius", "too small"});
  // The limit itself: a domain 1e9 diameters wide passes the radius check.
  const matep::Scene ok = matep::load_scene_string(box2d("1e9", "0.5", "1"), "s.toml", ".", {});
  EXPECT_EQ(ok.group.size(), 1u);
  expect_scene_error(box2d("1.0000001e9", "0.5", "1"), "s.toml", ".", {"particles.g.radius", "too small"});
}

TEST(SceneLimits, TinyRadiiInAParticleFileAndAnInletAreRefused) {
  const fs::path d = matep::test::fresh_dir("limits_radii");
  write_file(d / "p.csv", "x,y,vx,vy,radius\n0.5,0.5,0,0,0.1\n0.2,0.2,0,0,1e-300\n");
  std::string text = box2d("1.0", "0.1", "1");
  text = text.substr(0, text.find("[particles.g]")) + "[particles.g]\nmaterial = \"m\"\nfile = \"p.csv\"\n";
  expect_scene_error(text, "s.toml", d.string(), {"particles.g.file", "p.csv line 3", "too small for the domain"});
  std::string inlet = box2d("1.0", "0.1", "1") +
                      "[inlet.feed]\ntype = \"box\"\nlower = [0.1, 0.1]\nupper = [0.9, 0.9]\nmaterial = \"m\"\n"
                      "grain_radius = 1e-320\nrate = 10.0\n";
  expect_scene_error(inlet, "s.toml", ".", {"inlet.feed.grain_radius", "not a normal positive number"});
  fs::remove_all(d);
}

TEST(SceneLimits, ADomainWiderThanADoubleIsRefused) {
  std::string text = box2d("1e308", "1.0", "1");
  text.replace(text.find("lower = [0.0, 0.0]"), 18, "lower = [-1e308, 0.0]");
  expect_scene_error(text, "s.toml", ".", {"domain.upper", "wider along x than a number can hold"});
}

// main ended this one with "std::bad_alloc" and no key.
TEST(SceneLimits, CountsBeyondMemoryOrIdsAreRefusedNamingTheKey) {
  expect_scene_error(box2d("1e6", "0.5", "1000000000000"), "s.toml", ".",
                     {"particles.g.count", "asks for 1000000000000 grains", "limit of 2147483647"});
  const double mem = matep::scene_detail::physical_memory_bytes();
  ASSERT_GT(mem, 0.0);
  const auto n = static_cast<long long>(mem / matep::scene_detail::kBytesPerParticle) + 1;
  if (n < 2147483647) {
    expect_scene_error(box2d("1e6", "0.5", std::to_string(n)), "s.toml", ".",
                       {"particles.g.count", "memory", "more than this machine's"});
  }
  // Two groups add up.
  const std::string half = std::to_string(std::min(n, 2147483647LL) / 2 + 1);
  std::string two = box2d("1e6", "0.5", half);
  two += "[particles.h]\nmaterial = \"m\"\nradius = 0.5\ncount = " + half + "\n";
  expect_scene_error(two, "s.toml", ".", {"particles.h.count", "in all with the grains before"});
}

TEST(SceneLimits, AnInletDueMoreGrainsThanARunCanHoldIsRefusedWithoutHanging) {
  const std::string inlet = box2d("1.0", "0.1", "1") +
                            "[inlet.feed]\ntype = \"box\"\nlower = [0.1, 0.1]\nupper = [0.9, 0.9]\nmaterial = \"m\"\n"
                            "grain_radius = 0.01\n";
  expect_scene_error(inlet + "rate = 1e300\n", "s.toml", ".", {"inlet.feed.rate", "has due by run.end_time"});
  expect_scene_error(inlet + "mass_rate = 1e300\n", "s.toml", ".", {"inlet.feed.mass_rate", "grains"});
  // A count caps what is due: the same rate with count = 5 is fine.
  const matep::Scene s = matep::load_scene_string(inlet + "rate = 1e300\ncount = 5\n", "s.toml", ".", {});
  EXPECT_EQ(std::get<matep::System<2>>(s.system).inlets.at(0).slots(s.end_time), 5u);
}

TEST(SceneLimits, AnOutputPlanAboveMaxBytesIsRefusedNamingTheLargestPart) {
  // main wrote hundreds of MB a minute for this one.
  const std::string thermo = what_of(gas("thermo_interval = 1e-300\n"));
  EXPECT_EQ(thermo.rfind("s.toml: output.thermo_interval: the outputs would take about", 0), 0u) << thermo;
  EXPECT_NE(thermo.find("more than output.max_bytes = 10 GB"), std::string::npos) << thermo;
  EXPECT_NE(thermo.find("(got 1e-300)"), std::string::npos) << thermo;
  // 1e4 rows of 9 columns: about 2.2 MB, refused under 1 MB and accepted under 10 MB.
  EXPECT_NE(what_of(gas("thermo_interval = 1e-4\nmax_bytes = 1e6\n")).find("output.thermo_interval"),
            std::string::npos);
  EXPECT_EQ(what_of(gas("thermo_interval = 1e-4\nmax_bytes = 1e7\n")), "");
  // Snapshots: 2744 grains x 120 bytes (binary VTK) x 1002 snapshots is 330 MB; in ASCII (280 bytes
  // a grain) 770 MB, and with a second format the sum.
  const std::string snaps = what_of(gas("snapshot_interval = 1e-3\nmax_bytes = 3e8\n"));
  EXPECT_NE(snaps.find("output.snapshot_interval"), std::string::npos) << snaps;
  EXPECT_NE(snaps.find("snapshots of 2744 grains"), std::string::npos) << snaps;
  EXPECT_EQ(what_of(gas("snapshot_interval = 1e-3\nmax_bytes = 4e8\n")), "");
  EXPECT_NE(what_of(gas("snapshot_interval = 1e-3\nmax_bytes = 5e8\nformat = \"vtk_ascii\"\n")), "");
  EXPECT_EQ(what_of(gas("snapshot_interval = 1e-3\nmax_bytes = 8e8\nformat = \"vtk_ascii\"\n")), "");
  EXPECT_NE(what_of(gas("snapshot_interval = 1e-3\nmax_bytes = 1e9\nformat = [\"vtk\", \"xyz\"]\n")), "");
  // Events: Enskog's rate for this gas is about 2e4 per unit time, 264 bytes each.
  const std::string events = what_of(gas("events = true\nmax_bytes = 1e6\n"));
  EXPECT_NE(events.find("output.events"), std::string::npos) << events;
  EXPECT_NE(events.find("Enskog"), std::string::npos) << events;
  EXPECT_EQ(what_of(gas("events = true\nmax_bytes = 1e8\n")), "");
  // The checkpoint at the end: 2744 grains at 500 bytes (EDM) is 1.4 MB.
  const std::string ckpt = what_of(gas("max_bytes = 1e6\n"));
  EXPECT_NE(ckpt.find("output.checkpoint_interval"), std::string::npos) << ckpt;
  EXPECT_NE(ckpt.find("checkpoint.bin: 2744 grain slots"), std::string::npos) << ckpt;
  EXPECT_EQ(what_of(gas("max_bytes = 2e6\n")), "");
  expect_scene_error(gas("max_bytes = 0\n"), "s.toml", ".", {"output.max_bytes", "must be > 0"});
}

// ------------------------------------------------------------------ the binary, as a new user runs it

namespace {

fs::path scene_file(const std::string& name, const std::string& text) {
  const fs::path d = matep::test::fresh_dir("cli_limits_" + name);
  write_file(d / (name + ".toml"), text);
  return d;
}

void expect_one_line_refusal(const matep::test::ChildResult& r, const std::string& file, const std::string& part) {
  EXPECT_EQ(r.signal, 0) << "ended by signal " << r.signal << ": " << r.out.substr(0, 300);
  EXPECT_EQ(r.code, 2) << r.out.substr(0, 300);
  EXPECT_EQ(r.out.rfind("matep: error: " + file, 0), 0u) << r.out.substr(0, 300);
  EXPECT_EQ(r.out.find('\n'), r.out.size() - 1) << r.out.substr(0, 300);
  EXPECT_NE(r.out.find(part), std::string::npos) << r.out.substr(0, 300);
}

}  // namespace

// main: signal 11 in the TOML parser.
TEST(CliLimits, ADeeplyNestedKeyEndsWithOneLineNotACrash) {
  const fs::path d = scene_file("deep", deep_dotted_key(50000));
  const std::string f = (d / "deep.toml").string();
  expect_one_line_refusal(matep::test::run_cli_child({"check", f}, 60), f, "line 4: tables, arrays and dotted keys");
  fs::remove_all(d);
}

// main: `check` never returned.
TEST(CliLimits, ASubnormalRadiusEndsWithinTheTimeout) {
  const fs::path d = scene_file("subnormal", box2d("1e-321", "5e-324", "1"));
  const std::string f = (d / "subnormal.toml").string();
  expect_one_line_refusal(matep::test::run_cli_child({"check", f}, 30), f, "particles.g.radius");
  fs::remove_all(d);
}

// main: a run that wrote its files and then stopped "unstable" about a time step.
TEST(CliLimits, ATinyRadiusIsRefusedBeforeAnythingIsWritten) {
  std::string text = box2d("1.0", "1e-300", "1");
  text.insert(text.find("end_time"), "method = \"tdm\"\n");
  text.insert(text.find("density"), "stiffness = 1e5\n");
  const fs::path d = scene_file("tiny", text);
  const std::string f = (d / "tiny.toml").string();
  expect_one_line_refusal(matep::test::run_cli_child({"run", f, "--out", (d / "out").string()}, 60), f,
                          "particles.g.radius: radius 1e-300 is too small for the domain");
  EXPECT_FALSE(fs::exists(d / "out"));
  fs::remove_all(d);
}

// main: "std::bad_alloc".
TEST(CliLimits, AHugeCountNamesItsKey) {
  const fs::path d = scene_file("count", box2d("1e6", "0.5", "1000000000000"));
  const std::string f = (d / "count.toml").string();
  const auto r = matep::test::run_cli_child({"run", f, "--out", (d / "out").string()}, 60);
  expect_one_line_refusal(r, f, "particles.g.count");
  EXPECT_EQ(r.out.find("bad_alloc"), std::string::npos);
  EXPECT_FALSE(fs::exists(d / "out"));
  fs::remove_all(d);
}

// main: hundreds of MB a minute, no warning.
TEST(CliLimits, ATinyThermoIntervalIsRefusedBeforeWritingAndMaxBytesIsTheWayOut) {
  const fs::path d = scene_file("thermo", gas("thermo_interval = 1e-300\n"));
  const std::string f = (d / "thermo.toml").string();
  expect_one_line_refusal(matep::test::run_cli_child({"run", f, "--out", (d / "out").string()}, 60), f,
                          "output.thermo_interval");
  EXPECT_FALSE(fs::exists(d / "out"));
  const auto ok = matep::test::run_cli_child(
      {"check", f, "--set", "output.thermo_interval=1e-4", "--set", "output.max_bytes=1e7"}, 60);
  EXPECT_EQ(ok.code, 0) << ok.out;
  EXPECT_NE(ok.out.find("scene is valid"), std::string::npos);
  fs::remove_all(d);
}

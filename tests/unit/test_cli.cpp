// The matep command line end to end: outputs and their formats, --set, check, exit codes and
// messages for bad input and for runs that stop early.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

#include "io/output.hpp"
#include "tests/support/cli.hpp"
#include "tests/support/vtp.hpp"

namespace fs = std::filesystem;

namespace {

using Result = matep::test::CliResult;
Result sh(const std::string& args) { return matep::test::run_cli(args); }
using matep::test::slurp;
fs::path tmpdir(const std::string& name) { return matep::test::fresh_dir("cli_" + name); }
const std::string& kCases = matep::test::kCasesDir;

std::string first_line(const std::string& s) { return s.substr(0, s.find('\n')); }

}  // namespace

TEST(Cli, VersionAndHelp) {
  const Result v = sh("--version");
  EXPECT_EQ(v.code, 0);
  EXPECT_EQ(v.out.rfind("matep ", 0), 0u);
  const Result h = sh("--help");
  EXPECT_EQ(h.code, 0);
  EXPECT_NE(h.out.find("matep run SCENE.toml"), std::string::npos);
  const Result bad = sh("frobnicate");
  EXPECT_EQ(bad.code, 2);
  EXPECT_NE(bad.out.find("unknown command"), std::string::npos);
}

// Every shipped case is a valid scene (its files found relative to it).
TEST(Cli, EveryShippedCasePassesCheck) {
  int n = 0;
  for (const auto& e : fs::directory_iterator(kCases)) {
    if (e.path().extension() != ".toml") continue;
    const Result r = sh("check " + e.path().string());
    EXPECT_EQ(r.code, 0) << e.path() << "\n" << r.out;
    EXPECT_NE(r.out.find("scene is valid"), std::string::npos) << e.path();
    ++n;
  }
  EXPECT_GE(n, 17);
}

// The stirred bowl: a mesh from an STL file turning about an axis; a few steps write its turning
// picture into each snapshot and its loads into thermo.csv.
TEST(Cli, TheMixerCaseRunsWithItsTurningMeshPaddle) {
  const fs::path d = tmpdir("mixer");
  const Result r = sh("run " + kCases + "mixer.toml --set run.end_time=0.02 --set output.snapshot_interval=0.01 "
                      "--set output.thermo_interval=0.01 --out " + d.string());
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(slurp(d / "snapshots.pvd").find("paddle"), std::string::npos);
  EXPECT_NE(first_line(slurp(d / "thermo.csv")).find("paddle_tz"), std::string::npos);
  fs::remove_all(d);
}

TEST(Cli, RunWritesEveryOutputWithTheDocumentedHeaders) {
  const fs::path d = tmpdir("run");
  const Result r = sh("run " + kCases + "elastic_gas.toml --set run.end_time=1.0 --out " + d.string());
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find(d.string()), std::string::npos);  // says where the output went
  const std::string thermo = slurp(d / "thermo.csv");
  EXPECT_EQ(first_line(thermo),
            "time,kinetic_energy,rotational_energy,potential_energy,temperature,collisions,pressure,elastic_energy,soft");
  // One row at t = 0 and one per interval (0.5) up to end_time = 1: header + 3 rows.
  EXPECT_EQ(std::count(thermo.begin(), thermo.end(), '\n'), 4);
  EXPECT_EQ(first_line(slurp(d / "final_state.csv")), "id,x,y,z,vx,vy,vz,wx,wy,wz,radius,group,material");
  const std::string summary = slurp(d / "summary.json");
  EXPECT_NE(summary.find("\"status\": \"ok\""), std::string::npos);
  EXPECT_NE(summary.find("\"end_time\": 1,"), std::string::npos) << summary;  // --set took effect
  EXPECT_NE(summary.find("\"events_per_second\""), std::string::npos);
  EXPECT_NE(summary.find("\"max_overlap\""), std::string::npos);
  // The event log holds exactly the collisions the summary counts, each conserving momentum.
  matep::EventLogReader log((d / "events.bin").string());
  EXPECT_EQ(log.header().dimension, 3u);
  EXPECT_EQ(log.header().particles, 2744u);
  matep::EventRecord rec;
  std::uint64_t n = 0;
  double last_time = 0.0;
  while (log.next(rec)) {
    ++n;
    EXPECT_GE(rec.time, last_time);
    last_time = rec.time;
    for (int k = 0; k < 3; ++k)
      EXPECT_NEAR(rec.mi * (rec.vi_after[k] - rec.vi_before[k]) + rec.mj * (rec.vj_after[k] - rec.vj_before[k]), 0.0,
                  1e-12);
  }
  const auto pos = summary.find("\"pair_collisions\": ");
  ASSERT_NE(pos, std::string::npos);
  EXPECT_EQ(std::stoull(summary.substr(pos + 19)), n);
  fs::remove_all(d);
}

// The hybrid on neighbour lists: a small clustering gas whose clusters go soft. Its summary says
// lists and counts shell exits, and every hard collision of its log replays (momentum, -e, energy).
TEST(Cli, TheHybridOnNeighbourListsSaysSoAndItsLogReplays) {
  const fs::path d = tmpdir("hybrid_lists");
  const std::string scene = kCases + "cooling_clusters.toml --set 'run.neighbours=\"lists\"' --set run.end_time=8 "
                            "--set particles.gas.count=2000 --set 'domain.upper=[60.0,60.0]' "
                            "--set material.grain.restitution=0.2 --set output.events=true";
  const Result r = sh("run " + scene + " --out " + d.string());
  ASSERT_EQ(r.code, 0) << r.out;
  const std::string summary = slurp(d / "summary.json");
  EXPECT_NE(summary.find("\"neighbours\": \"lists\""), std::string::npos) << summary;
  EXPECT_NE(summary.find("\"shell_exits\""), std::string::npos) << summary;
  EXPECT_EQ(summary.find("\"to_soft\": 0,"), std::string::npos) << summary;  // clusters went soft
  const Result v = sh("log verify " + (d / "events.bin").string() + " --scene " + scene);
  EXPECT_EQ(v.code, 0) << v.out;
  // A switch's record names its grain twice, by the scene's id (i = j: README, events.bin).
  matep::EventLogReader log((d / "events.bin").string());
  matep::EventRecord rec;
  std::uint64_t switches = 0;
  while (log.next(rec))
    if (rec.kind == 4 || rec.kind == 5) {
      ++switches;
      ASSERT_EQ(rec.i, rec.j) << "switch at t = " << rec.time;
    }
  EXPECT_GT(switches, 100u);
  fs::remove_all(d);
}

TEST(Cli, TwoDimensionalFinalStateHeader) {
  const fs::path d = tmpdir("run2d");
  const Result r = sh("run " + kCases + "disks_in_a_box.toml --set run.end_time=0.2 --out " + d.string());
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(first_line(slurp(d / "final_state.csv")), "id,x,y,vx,vy,w,radius,group,material");
  fs::remove_all(d);
}

TEST(Cli, CollapseStopsWithStatusMessageAndKeepsOutputs) {
  const fs::path d = tmpdir("collapse");
  const Result r = sh("run " + kCases + "bouncing_ball.toml --out " + d.string());
  EXPECT_EQ(r.code, 3) << r.out;
  EXPECT_NE(r.out.find("inelastic collapse: the collisions of particle 0 came ever faster"), std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("bouncing_ball.toml"), std::string::npos) << r.out;
  EXPECT_NE(slurp(d / "summary.json").find("\"status\": \"collapse\""), std::string::npos);
  // thermo rows up to the collapse (every 0.01 s until 4.06 s) were kept.
  const std::string thermo = slurp(d / "thermo.csv");
  EXPECT_GT(std::count(thermo.begin(), thermo.end(), '\n'), 400);
  EXPECT_TRUE(fs::exists(d / "final_state.csv"));
  EXPECT_TRUE(fs::exists(d / "events.bin"));
  // The TC model keeps it bouncing to the end.
  const Result tc = sh("run " + kCases + "bouncing_ball.toml --set run.tc=0.001 --out " + d.string());
  EXPECT_EQ(tc.code, 0) << tc.out;
  fs::remove_all(d);
}

TEST(Cli, CheckDescribesWhatWillBeModelled) {
  const Result r = sh("check " + kCases + "default.toml");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("particles    8000"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("no rotation modelled"), std::string::npos);
  EXPECT_NE(r.out.find("collisions per unit time"), std::string::npos);
}

// check says how the hard grains find their partners and whether their storage is re-sorted, by
// the engine's own rules ("auto": lists from packing 0.45 without gravity; the hybrid re-sorts only
// when given a number).
TEST(Cli, CheckSaysHowTheHardGrainsFindTheirPartners) {
  const std::string gas = kCases + "elastic_gas.toml --set 'run.neighbours=\"auto\"'";
  const Result a = sh("check " + gas);  // packing 0.31
  ASSERT_EQ(a.code, 0) << a.out;
  EXPECT_NE(a.out.find("pair search  cells (auto"), std::string::npos) << a.out;
  const Result b = sh("check " + gas + " --set 'domain.upper=[14.5,14.5,14.5]'");  // packing 0.47
  ASSERT_EQ(b.code, 0) << b.out;
  EXPECT_NE(b.out.find("pair search  neighbour lists, shells of 0.125 largest diameters (auto"), std::string::npos)
      << b.out;
  EXPECT_NE(b.out.find("storage      in its first order"), std::string::npos) << b.out;
  const Result c = sh("check " + kCases + "cooling_clusters.toml --set run.resort=4");
  EXPECT_NE(c.out.find("storage      re-sorted in space every 4 particle events per particle while no grain is soft"),
            std::string::npos)
      << c.out;
  const Result d = sh("check " + kCases + "cooling_clusters.toml");
  EXPECT_NE(d.out.find("pair search  cells\n"), std::string::npos) << d.out;
  EXPECT_NE(d.out.find("storage      in its first order"), std::string::npos) << d.out;
}

TEST(Cli, BadInputGetsOneClearMessageAndExitStatus2) {
  const fs::path d = tmpdir("bad");
  const fs::path scene = d / "bad.toml";
  {
    std::ofstream f(scene);
    f << "[run]\ndimension = 3\nend_time = 1.0\ncolour = \"red\"\n"
         "[domain]\nlower = [0,0,0]\nupper = [10,10,10]\nperiodic = [true,true,true]\n";
  }
  const Result r = sh("run " + scene.string() + " --out " + (d / "o").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.out.find("bad.toml"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("run.colour"), std::string::npos) << r.out;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;  // one line
  EXPECT_FALSE(fs::exists(d / "o"));                                   // nothing half-written
  const Result s = sh("check " + kCases + "default.toml --set material.grain.restitution=1.5");
  EXPECT_EQ(s.code, 2);
  EXPECT_NE(s.out.find("material.grain.restitution"), std::string::npos) << s.out;
  EXPECT_NE(s.out.find("1.5"), std::string::npos) << s.out;
  const Result m = sh("run " + (d / "missing.toml").string());
  EXPECT_EQ(m.code, 2);
  EXPECT_NE(m.out.find("missing.toml"), std::string::npos) << m.out;
  fs::remove_all(d);
}

// The rough-sphere key `tangential`: an unknown law, and two colliding materials with different
// laws, end with one line naming the file, the key and the value, exit status 2, nothing written.
TEST(Cli, BadTangentialRuleGetsExitStatus2) {
  const fs::path d = tmpdir("tangential");
  const std::string scene = kCases + "rough_gas.toml";
  const Result u = sh("run " + scene + " --set material.grain.tangential=coulomb --out " + (d / "u").string());
  EXPECT_EQ(u.code, 2);
  EXPECT_NE(u.out.find("rough_gas.toml"), std::string::npos) << u.out;
  EXPECT_NE(u.out.find("material.grain.tangential"), std::string::npos) << u.out;
  EXPECT_NE(u.out.find("coulomb"), std::string::npos) << u.out;
  EXPECT_EQ(std::count(u.out.begin(), u.out.end(), '\n'), 1) << u.out;
  EXPECT_FALSE(fs::exists(d / "u"));
  // A wall material with another law than the particles'.
  const fs::path two = d / "two.toml";
  {
    std::ofstream f(two);
    f << "[run]\ndimension = 2\nend_time = 1.0\n[domain]\nlower = [0,0]\nupper = [10,10]\nperiodic = [true,false]\n"
         "[material.a]\ndensity = 1\nfriction = 0.3\ntangential = \"walton\"\n"
         "[material.b]\ndensity = 1\ntangential = \"constant\"\n"
         "[particles.p]\nmaterial = \"a\"\nradius = 0.5\ncount = 4\narrangement = \"lattice\"\ntemperature = 1\n"
         "[wall.floor]\ntype = \"plane\"\npoint = [0,0]\nnormal = [0,1]\nmaterial = \"b\"\n"
         "[wall.roof]\ntype = \"plane\"\npoint = [0,10]\nnormal = [0,-1]\nmaterial = \"b\"\n";
  }
  for (const std::string& cmd : {"run " + two.string() + " --out " + (d / "t").string(), "check " + two.string()}) {
    const Result t = sh(cmd);
    EXPECT_EQ(t.code, 2) << t.out;
    EXPECT_NE(t.out.find("two.toml"), std::string::npos) << t.out;
    EXPECT_NE(t.out.find("material.a.tangential"), std::string::npos) << t.out;
    EXPECT_NE(t.out.find("\"constant\""), std::string::npos) << t.out;
    EXPECT_FALSE(fs::exists(d / "t"));
  }
  // The shipped rough case: check describes the rough rule.
  const Result c = sh("check " + scene);
  EXPECT_EQ(c.code, 0) << c.out;
  EXPECT_NE(c.out.find("rough: tangential Walton, friction 0.3, beta0 0.4"), std::string::npos) << c.out;
  fs::remove_all(d);
}

TEST(Cli, TruncatedEventLogIsReportedWithItsByteOffset) {
  const fs::path d = tmpdir("trunc");
  ASSERT_EQ(sh("run " + kCases + "elastic_gas.toml --set run.end_time=0.05 --out " + d.string()).code, 0);
  const fs::path log = d / "events.bin";
  const auto size = fs::file_size(log);
  ASSERT_GT(size, matep::kEventLogHeaderSize + 2 * matep::kEventRecordSize);
  const matep::EventLogHeader h = matep::EventLogReader(log.string()).header();
  EXPECT_EQ(h.version, matep::kEventLogVersionIdentity);
  // The identity section: magic and counts (16 bytes), the names "gas" and "hard" (2 + 3, 2 + 4), four
  // bytes for each of the 2744 ids, padded to 8, then its checksum record (8).
  EXPECT_EQ(h.data_offset, matep::kEventLogHeaderSize + (16 + 5 + 6 + 4 * 2744 + 7) / 8 * 8 + 8);
  fs::resize_file(log, size - 10);
  try {
    matep::EventLogReader reader(log.string());  // the size does not fit the layout
    matep::EventRecord rec;
    while (reader.next(rec)) {
    }
    FAIL() << "truncation not detected";
  } catch (const matep::IoError& e) {
    const std::string msg = e.what();
    // The cut is in the last block, whose checksum record ended the file.
    const std::uint64_t block = h.block_records * matep::kEventRecordSize + matep::kEventBlockTrailerSize;
    const std::uint64_t last = h.data_offset + (size - 10 - h.data_offset) / block * block;
    EXPECT_NE(msg.find(log.string() + ": truncated event log: the last block, at byte offset " + std::to_string(last)),
              std::string::npos)
        << msg;
  }
  fs::remove_all(d);
}

TEST(Cli, PeriodicAxisTooShortIsRefusedBeforeAnythingIsWritten) {
  const fs::path d = tmpdir("short");
  const fs::path scene = d / "short.toml";
  {
    std::ofstream f(scene);
    f << "[run]\ndimension = 2\nend_time = 1.0\n[domain]\nlower = [0.0, 0.0]\nupper = [2.5, 10.0]\n"
         "periodic = [true, false]\n[material.m]\ndensity = 1.0\n[particles.p]\nmaterial = \"m\"\n"
         "radius = 0.5\ncount = 1\nvelocity = [1.0, 0.0]\nregion = {lower = [0.0, 4.0], upper = [2.5, 6.0]}\n";
  }
  const Result r = sh("run " + scene.string() + " --out " + (d / "o").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.out.find("short.toml: domain.upper: periodic axis x is 2.5 long"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(d / "o"));
  fs::remove_all(d);
}

using matep::test::vtp_array;

TEST(Cli, VtkSnapshotsAndTheirTimeSeriesReadBack) {
  const fs::path d = tmpdir("vtk");
  const Result r = sh("run " + kCases + "elastic_gas.toml --set run.end_time=1.0 --set output.snapshot_interval=0.25 --out " +
                      d.string());
  ASSERT_EQ(r.code, 0) << r.out;
  // Snapshots at t = 0, 0.25, 0.5, 0.75 and 1, listed in order in the collection.
  const std::string pvd = slurp(d / "snapshots.pvd");
  const char* times[] = {"0", "0.25", "0.5", "0.75", "1"};
  for (int k = 0; k < 5; ++k) {
    const std::string file = "snapshots/snap_00000" + std::to_string(k) + ".vtp";
    EXPECT_NE(pvd.find("timestep=\"" + std::string(times[k]) + "\" group=\"\" part=\"0\" file=\"" + file + "\""),
              std::string::npos)
        << pvd;
    EXPECT_TRUE(fs::exists(d / file));
  }
  EXPECT_FALSE(fs::exists(d / "snapshots/snap_000005.vtp"));
  // The last snapshot is the final state: positions, velocities and radii read back exactly.
  const std::string vtp = slurp(d / "snapshots/snap_000004.vtp");
  const auto pos = vtp_array(vtp, "position"), vel = vtp_array(vtp, "velocity"), rad = vtp_array(vtp, "radius");
  const auto mode = vtp_array(vtp, "mode"), ids = vtp_array(vtp, "id");
  ASSERT_EQ(pos.size(), 3u * 2744u);
  ASSERT_EQ(rad.size(), 2744u);
  ASSERT_EQ(mode.size(), 2744u);
  EXPECT_EQ(ids[100], 100.0);
  std::istringstream fin(slurp(d / "final_state.csv"));
  std::string line;
  std::getline(fin, line);  // header id,x,y,z,vx,vy,vz,wx,wy,wz,radius,group,material
  for (std::size_t i = 0; std::getline(fin, line); ++i) {
    std::vector<double> f;
    std::istringstream ls(line);
    std::string cell;
    while (f.size() < 11 && std::getline(ls, cell, ',')) f.push_back(std::stod(cell));
    ASSERT_EQ(f.size(), 11u);
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(pos[3 * i + k], f[1 + k]) << "particle " << i;
      EXPECT_EQ(vel[3 * i + k], f[4 + k]) << "particle " << i;
    }
    EXPECT_EQ(rad[i], f[10]);
    EXPECT_EQ(mode[i], 0.0);  // hard
  }
  fs::remove_all(d);
}

// The snapshots show the walls: the vibrated bed's floor oscillates, p(t) = (0, 0.006 sin(2 pi 20 t)),
// and gets a file per snapshot whose segment spans the domain (x from 0 to 0.2) at the floor's
// height at that time; the side walls are at rest and written once, listed at every time.
TEST(Cli, SnapshotsShowTheWallsMovingWithTheirSurface) {
  const fs::path d = tmpdir("wall_vtk");
  const Result r = sh("run " + kCases + "vibrated_bed.toml --set run.end_time=0.02 --set output.snapshot_interval=0.0125 "
                      "--out " + d.string());
  ASSERT_EQ(r.code, 0) << r.out;
  const std::string pvd = slurp(d / "snapshots.pvd");
  const double times[] = {0.0, 0.0125, 0.02};
  for (int k = 0; k < 3; ++k) {
    const std::string file = "snapshots/wall_floor_00000" + std::to_string(k) + ".vtp";
    EXPECT_NE(pvd.find("part=\"1\" file=\"" + file + "\""), std::string::npos) << pvd;
    const auto pts = vtp_array(slurp(d / file), "");  // the first DataArray: the points
    ASSERT_EQ(pts.size(), 6u) << file;
    const double y = 0.006 * std::sin(2.0 * std::numbers::pi * 20.0 * times[k]);
    EXPECT_NEAR(std::min(pts[0], pts[3]), 0.0, 1e-15);
    EXPECT_NEAR(std::max(pts[0], pts[3]), 0.2, 1e-15);
    EXPECT_NEAR(pts[1], y, 1e-15) << file;
    EXPECT_NEAR(pts[4], y, 1e-15) << file;
  }
  EXPECT_TRUE(fs::exists(d / "snapshots/wall_left.vtp"));
  EXPECT_FALSE(fs::exists(d / "snapshots/wall_left_000001.vtp"));
  std::size_t listed = 0;
  for (auto at = pvd.find("wall_right.vtp"); at != std::string::npos; at = pvd.find("wall_right.vtp", at + 1)) ++listed;
  EXPECT_EQ(listed, 3u);
  const auto x = vtp_array(slurp(d / "snapshots/wall_right.vtp"), "");
  ASSERT_EQ(x.size(), 6u);
  EXPECT_EQ(x[0], 0.2);  // the line x = 0.2 from y = -0.01 to 1
  EXPECT_EQ(x[3], 0.2);
  EXPECT_NEAR(std::min(x[1], x[4]), -0.01, 1e-15);
  EXPECT_NEAR(std::max(x[1], x[4]), 1.0, 1e-15);
  fs::remove_all(d);
}

// A hybrid run's snapshots carry each particle's mode and soft cluster: the vibrated bed has soft
// disks (mode 1) in clusters (ids >= 0) and hard ones (mode 0, cluster -1), each snapshot's soft
// count matching thermo.csv's at the same time. (The bed is all hard while it flies above the
// floor and can be all soft on it, so twenty snapshots are checked and at least one must hold
// both kinds.)
TEST(Cli, HybridSnapshotsCarryModeAndCluster) {
  const fs::path d = tmpdir("hybrid_vtk");
  const Result r = sh("run " + kCases + "vibrated_bed.toml --set run.end_time=1.0 --set output.snapshot_interval=0.05 "
                      "--set output.thermo_interval=0.05 --out " + d.string());
  ASSERT_EQ(r.code, 0) << r.out;
  // thermo.csv's rows at t = 0, 0.05, ..., 1: the soft count is the last column.
  std::istringstream th(slurp(d / "thermo.csv"));
  std::string line;
  std::vector<std::size_t> thermo_soft;
  std::getline(th, line);  // header
  while (std::getline(th, line))
    if (!line.empty()) thermo_soft.push_back(std::stoul(line.substr(line.rfind(',') + 1)));
  ASSERT_EQ(thermo_soft.size(), 21u);
  int mixed = 0;
  for (int k = 1; k <= 20; ++k) {
    const std::string vtp = slurp(d / fmt::format("snapshots/snap_{:06d}.vtp", k));
    const auto mode = vtp_array(vtp, "mode"), cluster = vtp_array(vtp, "cluster");
    ASSERT_EQ(mode.size(), 200u) << k;
    ASSERT_EQ(cluster.size(), 200u) << k;
    std::size_t soft = 0;
    for (std::size_t i = 0; i < mode.size(); ++i) {
      EXPECT_TRUE(mode[i] == 0.0 || mode[i] == 1.0 || mode[i] == 3.0) << k << " " << i;
      if (mode[i] != 0.0) {
        ++soft;
        EXPECT_GE(cluster[i], 0.0) << k << " " << i;
      } else {
        EXPECT_EQ(cluster[i], -1.0) << k << " " << i;
      }
    }
    EXPECT_EQ(thermo_soft[static_cast<std::size_t>(k)], soft) << "snapshot " << k;
    if (soft > 0 && soft < 200) ++mixed;
  }
  EXPECT_GE(mixed, 1);
  fs::remove_all(d);
}

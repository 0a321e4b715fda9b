// run.start_time: a scene's state at a later time. A run restarted from a final_state.csv at the time
// it was written follows the run that went on (walls move in absolute time, so a vibrating floor
// keeps its phase), its rows start there, and a start at or after the end is refused.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "tests/support/cli.hpp"

namespace fs = std::filesystem;

namespace {

using matep::test::run_cli;
using matep::test::slurp;

// (time, kinetic energy, potential energy) of each thermo.csv row.
std::vector<std::array<double, 3>> rows(const fs::path& thermo) {
  std::vector<std::array<double, 3>> out;
  std::istringstream in(slurp(thermo));
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    std::array<double, 5> v{};
    std::istringstream l(line);
    for (double& x : v) {
      std::string cell;
      std::getline(l, cell, ',');
      x = std::stod(cell);
    }
    out.push_back({v[0], v[1], v[3]});
  }
  return out;
}

// A steel ball bouncing on a floor that vibrates (z = A sin 2 pi f t), in each method.
std::string scene(const std::string& method, const std::string& particles) {
  std::ostringstream s;
  s << "[run]\ndimension = 3\nmethod = \"" << method << "\"\nend_time = 1.0\ngravity = [0.0, 0.0, -9.81]\n"
    << "[domain]\nlower = [-0.05, -0.05, -0.01]\nupper = [0.05, 0.05, 0.3]\nperiodic = [true, true, false]\n"
    << "[material.steel]\ndensity = 7800.0\nrestitution = 0.9\ncontact = \"linear\"\nstiffness = 1.0e6\n"
    << "[particles.ball]\nmaterial = \"steel\"\n"
    << particles << "\n"
    << "[wall.floor]\ntype = \"plane\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\nmaterial = \"steel\"\n"
    << "oscillation = {amplitude = [0.0, 0.0, 0.004], frequency = 7.3}\n"
    << "[output]\nthermo_interval = 0.02\n";
  return s.str();
}

TEST(StartTime, ARunRestartedFromItsFinalStateAtThatTimeFollowsTheRunThatWentOn) {
  const fs::path root = matep::test::fresh_dir("start_time");
  for (const std::string method : {"edm", "tdm", "hybrid"}) {
    SCOPED_TRACE(method);
    const fs::path d = root / method;
    fs::create_directories(d);
    std::ofstream(d / "ball.csv") << "x,y,z,vx,vy,vz,radius\n0,0,0.1,0,0,0,0.005\n";
    std::ofstream(d / "whole.toml") << scene(method, "file = \"ball.csv\"");
    auto r = run_cli("run " + (d / "whole.toml").string() + " --quiet --out " + (d / "whole").string());
    ASSERT_EQ(r.code, 0) << r.out;
    r = run_cli("run " + (d / "whole.toml").string() + " --set run.end_time=0.5 --quiet --out " +
                (d / "half").string());
    ASSERT_EQ(r.code, 0) << r.out;
    // The second half, from the state at t = 0.5: at run.start_time = 0.5, and (wrongly) at 0.
    std::ofstream(d / "rest.toml") << scene(method, "file = \"half/final_state.csv\"");
    r = run_cli("run " + (d / "rest.toml").string() + " --set run.start_time=0.5 --quiet --out " +
                (d / "rest").string());
    ASSERT_EQ(r.code, 0) << r.out;
    r = run_cli("run " + (d / "rest.toml").string() + " --set run.end_time=0.5 --quiet --out " +
                (d / "shifted").string());
    ASSERT_EQ(r.code, 0) << r.out;
    const auto whole = rows(d / "whole" / "thermo.csv");
    const auto rest = rows(d / "rest" / "thermo.csv");
    const auto shifted = rows(d / "shifted" / "thermo.csv");
    ASSERT_EQ(whole.size(), 51u);
    ASSERT_EQ(rest.size(), 26u);  // t = 0.5, 0.52, ..., 1.0
    EXPECT_DOUBLE_EQ(rest.front()[0], 0.5);
    EXPECT_DOUBLE_EQ(rest.back()[0], 1.0);
    double worst = 0.0, worst_shifted = 0.0;
    for (std::size_t k = 0; k < rest.size(); ++k) {
      const auto& w = whole[25 + k];
      EXPECT_NEAR(rest[k][0], w[0], 1e-12);
      const double e = w[1] + w[2];
      worst = std::max(worst, std::abs(rest[k][1] + rest[k][2] - e) / std::abs(e));
      worst_shifted = std::max(worst_shifted, std::abs(shifted[k][1] + shifted[k][2] - e) / std::abs(e));
    }
    // The same flight and bounces (restarted from 17 significant digits); the floor started at the
    // wrong phase sends the ball elsewhere.
    EXPECT_LT(worst, 1e-6);
    EXPECT_GT(worst_shifted, 1e-2);
  }
  // A start at or after the end: one line naming the key and the value.
  const auto bad = run_cli("check " + (root / "edm" / "whole.toml").string() + " --set run.start_time=1.0");
  EXPECT_EQ(bad.code, 2) << bad.out;
  EXPECT_NE(bad.out.find("run.start_time: must be before run.end_time = 1 (got 1)"), std::string::npos) << bad.out;
  fs::remove_all(root);
}

}  // namespace

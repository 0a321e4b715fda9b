// final_state.csv as a restart: its group and material columns (io/output.cpp write_final_state)
// read back by the particle-file reader (io/scene.cpp read_file). A two-group, two-material scene
// with an inlet runs in EDM and TDM; its final state, read back one table per group (file_group) or
// as one table without a material, keeps every grain's group and material; a file whose material
// disagrees with the table or names no material, or a file_group the file lacks, is refused with
// one line naming the file, the key and the value.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <variant>
#include <vector>

#include "io/run.hpp"
#include "io/scene.hpp"
#include "tests/support/scene_errors.hpp"

namespace fs = std::filesystem;

namespace {

using matep::Scene;
using matep::System;

const std::string kHead = R"([run]
dimension = 2
method = "METHOD"
end_time = 0.3
seed = 3
[domain]
lower = [0.0, 0.0]
upper = [10.0, 10.0]
periodic = [true, true]
[material.glass]
density = 1.0
restitution = 1.0
contact = "linear"
stiffness = 1.0e4
[material.steel]
density = 3.0
restitution = 1.0
contact = "linear"
stiffness = 1.0e4
)";

const std::string kGroups = R"([particles.gas]
material = "glass"
radius = 0.2
count = 20
temperature = 1.0
[particles.heavy]
material = "steel"
radius = 0.3
count = 10
temperature = 1.0
[inlet.feed]
type = "box"
lower = [1.0, 8.0]
upper = [9.0, 9.5]
material = "steel"
grain_radius = 0.15
rate = 20
count = 4
)";

std::string with_method(const std::string& method) {
  std::string s = kHead;
  s.replace(s.find("METHOD"), 6, method);
  return s;
}

struct Row {
  double x, y, radius;
  std::string group, material;
};

std::vector<Row> read_state(const fs::path& p, std::string& header) {
  std::ifstream f(p);
  std::getline(f, header);
  std::vector<Row> rows;
  for (std::string line; std::getline(f, line);) {
    std::vector<std::string> c;
    std::stringstream ss(line);
    for (std::string cell; std::getline(ss, cell, ',');) c.push_back(cell);
    if (c.size() != 9u) {
      ADD_FAILURE() << line;
      continue;
    }
    rows.push_back({std::stod(c[1]), std::stod(c[2]), std::stod(c[6]), c[7], c[8]});
  }
  return rows;
}

TEST(FinalState, GroupsAndMaterialsSurviveARestart) {
  const fs::path dir = fs::temp_directory_path() / "matep_final_state_restart";
  fs::remove_all(dir);
  fs::create_directories(dir);
  for (const std::string method : {"edm", "tdm"}) {
    SCOPED_TRACE(method);
    const Scene first = matep::load_scene_string(with_method(method) + kGroups, "first.toml", dir.string());
    const fs::path out = dir / ("out_" + method);
    const matep::RunOutcome r = matep::run_scene(first, out.string());
    ASSERT_EQ(r.status, "ok") << r.message;
    std::string header;
    const std::vector<Row> rows = read_state(out / "final_state.csv", header);
    EXPECT_EQ(header, "id,x,y,vx,vy,w,radius,group,material");
    ASSERT_EQ(rows.size(), 34u);  // 30 at the start and the inlet's 4
    std::map<std::string, int> per_group;
    for (const Row& row : rows) {
      ++per_group[row.group];
      EXPECT_EQ(row.material, row.group == "gas" ? "glass" : "steel") << row.group;
    }
    EXPECT_EQ(per_group, (std::map<std::string, int>{{"gas", 20}, {"heavy", 10}, {"inlet.feed", 4}}));
    fs::copy_file(out / "final_state.csv", dir / "state.csv", fs::copy_options::overwrite_existing);

    // One table per group: the same groups, each grain with its material (the table's, which the
    // file agrees with, or the file's when the table names none).
    const Scene again = matep::load_scene_string(
        with_method(method) +
            "[particles.gas]\nmaterial = \"glass\"\nfile = \"state.csv\"\nfile_group = \"gas\"\n"
            "[particles.heavy]\nfile = \"state.csv\"\nfile_group = \"heavy\"\n"
            "[particles.fed]\nmaterial = \"steel\"\nfile = \"state.csv\"\nfile_group = \"inlet.feed\"\n",
        "again.toml", dir.string());
    EXPECT_EQ(again.group_names, (std::vector<std::string>{"gas", "heavy", "fed"}));
    const auto& sys = std::get<System<2>>(again.system);
    ASSERT_EQ(sys.size(), 34u);
    std::map<std::string, int> restarted;
    for (std::size_t i = 0; i < sys.size(); ++i) {
      const std::string& g = again.group_names[static_cast<std::size_t>(again.group[i])];
      ++restarted[g];
      EXPECT_EQ(sys.materials[static_cast<std::size_t>(sys.material[i])].name, g == "gas" ? "glass" : "steel");
    }
    EXPECT_EQ(restarted, (std::map<std::string, int>{{"gas", 20}, {"heavy", 10}, {"fed", 4}}));

    // One table without a material: every grain keeps its material, in file order.
    const Scene one = matep::load_scene_string(with_method(method) + "[particles.all]\nfile = \"state.csv\"\n",
                                               "one.toml", dir.string());
    const auto& s1 = std::get<System<2>>(one.system);
    ASSERT_EQ(s1.size(), rows.size());
    for (std::size_t i = 0; i < rows.size(); ++i) {
      EXPECT_EQ(s1.materials[static_cast<std::size_t>(s1.material[i])].name, rows[i].material) << i;
      EXPECT_EQ(s1.x[i][0], rows[i].x) << i;
      EXPECT_EQ(s1.radius[i], rows[i].radius) << i;
    }
    // ... and the restarted scene runs.
    const matep::RunOutcome r2 = matep::run_scene(one, (dir / ("again_" + method)).string());
    EXPECT_EQ(r2.status, "ok") << r2.message;
  }

  // Refusals: one line naming the file, the key and the value.
  const std::string head = with_method("edm");
  // The table's material and the file's disagree (the heavy grains are steel).
  matep::test::expect_scene_error(head + "[particles.all]\nmaterial = \"glass\"\nfile = \"state.csv\"\n", "bad.toml",
                                  dir.string(),
                                  {"particles.all.file", "\"state.csv\"", "material 'steel'",
                                   "particles.all.material is 'glass'", "line "});
  // A material the scene does not define.
  std::ofstream(dir / "brass.csv") << "id,x,y,vx,vy,w,radius,group,material\n"
                                   << "0,5,5,0,0,0,0.2,gas,glass\n1,2,2,0,0,0,0.2,gas,brass\n";
  matep::test::expect_scene_error(head + "[particles.p]\nfile = \"brass.csv\"\n", "bad.toml", dir.string(),
                                  {"particles.p.file", "\"brass.csv\"", "particles.p[1]", "line 3",
                                   "material 'brass'", "no such material (defined: glass, steel)"});
  // A group the file lacks; a file_group without a group column, or without a file.
  matep::test::expect_scene_error(
      head + "[particles.p]\nmaterial = \"glass\"\nfile = \"state.csv\"\nfile_group = \"beads\"\n", "bad.toml",
      dir.string(), {"particles.p.file_group", "\"beads\"", "no row of state.csv", "gas, heavy, inlet.feed"});
  std::ofstream(dir / "plain.csv") << "x,y,vx,vy,radius\n5,5,0,0,0.2\n";
  matep::test::expect_scene_error(
      head + "[particles.p]\nmaterial = \"glass\"\nfile = \"plain.csv\"\nfile_group = \"gas\"\n", "bad.toml",
      dir.string(), {"particles.p.file_group", "\"gas\"", "no group column"});
  matep::test::expect_scene_error(
      head + "[particles.p]\nmaterial = \"glass\"\nradius = 0.2\ncount = 3\nfile_group = \"gas\"\n", "bad.toml",
      dir.string(), {"particles.p.file_group", "\"gas\"", "needs file"});
  // Without a material column the table must name the material.
  matep::test::expect_scene_error(head + "[particles.p]\nfile = \"plain.csv\"\n", "bad.toml", dir.string(),
                                  {"particles.p.material"});
  fs::remove_all(dir);
}

}  // namespace

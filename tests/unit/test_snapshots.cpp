// Snapshot formats (io/snapshots.hpp): the binary VTK, ASCII VTK, extended XYZ and LAMMPS dump
// frames of one run hold the same grains as final_state.csv (the last snapshot is the final
// state), with each grain's id, group, material and mode; float32 keeps float(x); bad
// output.format / output.precision values are refused naming the key.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "tests/support/cli.hpp"
#include "tests/support/vtp.hpp"

namespace fs = std::filesystem;
using matep::test::fresh_dir;
using matep::test::kCasesDir;
using matep::test::run_cli;
using matep::test::slurp;
using matep::test::vtp_array;

namespace {

// final_state.csv as rows of fields (header dropped), keyed by id.
std::map<long, std::vector<std::string>> final_rows(const fs::path& csv) {
  std::istringstream in(slurp(csv));
  std::string line;
  std::getline(in, line);
  std::map<long, std::vector<std::string>> rows;
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::stringstream ls(line);
    std::string x;
    while (std::getline(ls, x, ',')) f.push_back(x);
    rows[std::stol(f[0])] = f;
  }
  return rows;
}

std::vector<std::vector<std::string>> text_rows(const std::string& text, std::size_t skip) {
  std::istringstream in(text);
  std::string line;
  for (std::size_t k = 0; k < skip; ++k) std::getline(in, line);
  std::vector<std::vector<std::string>> rows;
  while (std::getline(in, line)) {
    std::istringstream ls(line);
    std::vector<std::string> f;
    std::string x;
    while (ls >> x) f.push_back(x);
    if (!f.empty()) rows.push_back(f);
  }
  return rows;
}

}  // namespace

// A 2D TDM heap with a fixed plate and an inlet: two groups ("plate" fixed, "inlet.pour"), all four
// formats at once. Each format's last frame gives every grain of final_state.csv exactly.
TEST(Snapshots, EveryFormatHoldsTheFinalStateWithIdGroupMaterialAndMode) {
  const fs::path d = fresh_dir("snap_formats");
  const auto r = run_cli("run " + kCasesDir + "heap.toml --set run.end_time=0.1 --set output.snapshot_interval=0.05 "
                         "--set 'output.format=[\"vtk\", \"xyz\", \"lammps\"]' --out " + d.string());
  ASSERT_EQ(r.code, 0) << r.out;
  const auto rows = final_rows(d / "final_state.csv");  // id,x,y,vx,vy,w,radius,group,material
  ASSERT_GT(rows.size(), 60u);                          // the plate and some poured grains
  const std::string vtp = slurp(d / "snapshots/snap_000002.vtp");
  EXPECT_NE(vtp.find("format=\"appended\""), std::string::npos);
  EXPECT_NE(vtp.find("group: 0 plate, 1 inlet.pour; material: 0 glass"), std::string::npos);
  const auto pos = vtp_array(vtp, "position"), rad = vtp_array(vtp, "radius"), vel = vtp_array(vtp, "velocity");
  const auto ids = vtp_array(vtp, "id"), group = vtp_array(vtp, "group"), material = vtp_array(vtp, "material");
  const auto mode = vtp_array(vtp, "mode");
  ASSERT_EQ(ids.size(), rows.size());
  ASSERT_EQ(pos.size(), 3 * rows.size());
  ASSERT_EQ(mode.size(), rows.size());
  const std::vector<std::string> groups{"plate", "inlet.pour"};
  for (std::size_t i = 0; i < ids.size(); ++i) {
    const auto& f = rows.at(static_cast<long>(ids[i]));
    EXPECT_EQ(pos[3 * i], std::stod(f[1])) << i;
    EXPECT_EQ(pos[3 * i + 1], std::stod(f[2])) << i;
    EXPECT_EQ(pos[3 * i + 2], 0.0);
    EXPECT_EQ(vel[3 * i], std::stod(f[3])) << i;
    EXPECT_EQ(rad[i], std::stod(f[6])) << i;
    EXPECT_EQ(groups.at(static_cast<std::size_t>(group[i])), f[7]) << i;
    EXPECT_EQ(material[i], 0.0);
    EXPECT_EQ(mode[i], f[7] == "plate" ? 4.0 : 1.0) << i;  // TDM: soft, or fixed
  }
  // Extended XYZ: species pos(3) radius velocity(3) angular_velocity(3) id group material mode.
  const std::string xyz = slurp(d / "snapshots/snap_000002.xyz");
  EXPECT_NE(xyz.find("Properties=species:S:1:pos:R:3:radius:R:1:velocity:R:3:angular_velocity:R:3:id:I:1:group:S:1:"
                     "material:S:1:mode:I:1"),
            std::string::npos);
  EXPECT_NE(xyz.find("Lattice=\"0.20000000000000001 0 0 0 0.14999999999999999 0 0 0 1\""), std::string::npos) << xyz.substr(0, 300);
  const auto xr = text_rows(xyz, 2);
  ASSERT_EQ(xr.size(), rows.size());
  for (const auto& x : xr) {
    const auto& f = rows.at(std::stol(x[11]));
    EXPECT_EQ(x[0], "X");
    EXPECT_EQ(std::stod(x[1]), std::stod(f[1]));
    EXPECT_EQ(std::stod(x[2]), std::stod(f[2]));
    EXPECT_EQ(std::stod(x[4]), std::stod(f[6]));
    EXPECT_EQ(std::stod(x[10]), std::stod(f[5]));  // the disk's spin as its z component
    EXPECT_EQ(x[12], f[7]);
    EXPECT_EQ(x[13], f[8]);
  }
  // LAMMPS dump: id type x y z vx vy vz omegax omegay omegaz radius material mode; type = group + 1.
  const std::string dump = slurp(d / "snapshots/snap_000002.lammpstrj");
  EXPECT_EQ(dump.rfind("ITEM: TIMESTEP\n2\nITEM: TIME\n0.10000000000000001\nITEM: NUMBER OF ATOMS\n", 0), 0u)
      << dump.substr(0, 200);
  EXPECT_NE(dump.find("ITEM: BOX BOUNDS ff ff ff\n0 0.20000000000000001\n0 0.14999999999999999\n-0.5 0.5\n"),
            std::string::npos);
  const auto lr = text_rows(dump, 11);
  ASSERT_EQ(lr.size(), rows.size());
  for (const auto& x : lr) {
    const auto& f = rows.at(std::stol(x[0]));
    EXPECT_EQ(groups.at(std::stoul(x[1]) - 1), f[7]);
    EXPECT_EQ(std::stod(x[2]), std::stod(f[1]));
    EXPECT_EQ(std::stod(x[6]), std::stod(f[4]));
    EXPECT_EQ(std::stod(x[11]), std::stod(f[6]));
  }
  // The .pvd lists only the VTK files; summary.json carries the legend.
  const std::string pvd = slurp(d / "snapshots.pvd");
  EXPECT_EQ(pvd.find(".xyz"), std::string::npos);
  EXPECT_NE(pvd.find("file=\"snapshots/snap_000002.vtp\""), std::string::npos);
  const std::string summary = slurp(d / "summary.json");
  EXPECT_NE(summary.find("\"groups\": [\"plate\", \"inlet.pour\"]"), std::string::npos) << summary;
  EXPECT_NE(summary.find("\"materials\": [\"glass\"]"), std::string::npos);
  fs::remove_all(d);
}

// ASCII and binary VTK hold the same numbers; float32 holds float(x) of them. Pure EDM grains are
// hard (mode 0).
TEST(Snapshots, AsciiBinaryAndSinglePrecisionAgree) {
  const fs::path d = fresh_dir("snap_precision");
  const std::string base =
      "run " + kCasesDir + "elastic_gas.toml --set run.end_time=0.2 --set output.snapshot_interval=0.1 ";
  ASSERT_EQ(run_cli(base + "--out " + (d / "bin").string()).code, 0);
  ASSERT_EQ(run_cli(base + "--set output.format=vtk_ascii --out " + (d / "asc").string()).code, 0);
  ASSERT_EQ(run_cli(base + "--set output.precision=single --out " + (d / "f32").string()).code, 0);
  const std::string b = slurp(d / "bin/snapshots/snap_000002.vtp"), a = slurp(d / "asc/snapshots/snap_000002.vtp"),
                    s = slurp(d / "f32/snapshots/snap_000002.vtp");
  EXPECT_EQ(a.find("<AppendedData"), std::string::npos);
  EXPECT_NE(s.find("type=\"Float32\" Name=\"position\""), std::string::npos);
  for (const char* name : {"position", "velocity", "radius", "id", "mode", "group", "material"}) {
    const auto vb = vtp_array(b, name), va = vtp_array(a, name), vs = vtp_array(s, name);
    ASSERT_FALSE(vb.empty()) << name;
    EXPECT_EQ(vb, va) << name;
    ASSERT_EQ(vs.size(), vb.size()) << name;
    for (std::size_t i = 0; i < vb.size(); ++i) EXPECT_EQ(vs[i], static_cast<double>(static_cast<float>(vb[i]))) << name;
  }
  for (double m : vtp_array(b, "mode")) EXPECT_EQ(m, 0.0);
  // Smooth spheres never turn: no angular_velocity array.
  EXPECT_EQ(b.find("angular_velocity"), std::string::npos);
  // Binary float32 is at most a third of the ASCII file, float64 (8 bytes for 17 digits) at most half.
  EXPECT_LE(3 * s.size(), a.size()) << s.size() << " vs " << a.size();
  EXPECT_LE(2 * b.size(), a.size()) << b.size() << " vs " << a.size();
  fs::remove_all(d);
}

TEST(Snapshots, BadFormatOrPrecisionIsRefusedNamingTheKey) {
  const fs::path d = fresh_dir("snap_bad");
  const std::string base = "check " + kCasesDir + "elastic_gas.toml ";
  struct Case {
    std::string set, says;
  } cases[] = {
      {"output.format=pdf", "output.format: must be \"vtk\", \"vtk_ascii\", \"xyz\" or \"lammps\", or a list of them (got \"pdf\")"},
      {"'output.format=[\"xyz\", \"xyz\"]'", "output.format: names \"xyz\" twice"},
      {"'output.format=[\"vtk\", \"vtk_ascii\"]'", "output.format: \"vtk\" and \"vtk_ascii\" write the same files"},
      {"'output.format=[]'", "output.format: names no format"},
      {"output.format=3", "output.format: must be"},
      {"output.precision=half", "output.precision: must be one of \"double\", \"single\" (got \"half\")"},
      {"output.contacts=1", "output.contacts: expected a boolean but found an integer (got 1)"},
      {"output.contacts=true", "output.contacts: the contacts are written with the snapshots: set "
                               "output.snapshot_interval too"},
  };
  for (const auto& c : cases) {
    const auto r = run_cli(base + "--set " + c.set);
    EXPECT_EQ(r.code, 2) << c.set << "\n" << r.out;
    EXPECT_NE(r.out.find(c.says), std::string::npos) << c.set << "\n" << r.out;
  }
  fs::remove_all(d);
}

namespace {

// A contacts_NNNNNN.csv: its time line, header and rows of numbers.
struct ContactsFile {
  double time = -1.0;
  std::vector<std::string> header;
  std::vector<std::vector<double>> rows;
};

ContactsFile read_contacts(const fs::path& path) {
  ContactsFile c;
  std::istringstream in(slurp(path));
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line.rfind("# time = ", 0), 0u) << line;
  c.time = std::stod(line.substr(9));
  std::getline(in, line);
  std::stringstream hs(line);
  for (std::string x; std::getline(hs, x, ',');) c.header.push_back(x);
  while (std::getline(in, line)) {
    std::vector<double> r;
    std::stringstream ls(line);
    for (std::string x; std::getline(ls, x, ',');) r.push_back(std::stod(x));
    EXPECT_EQ(r.size(), c.header.size()) << line;
    c.rows.push_back(r);
  }
  return c;
}

}  // namespace

// output.contacts: one CSV per snapshot. A 2D TDM heap (a fixed plate, an inlet, walls) in single
// precision: soft rows (kind 1) between grains present at that time, pairs with i < j, walls with
// j = -1; a 3D EDM gas: hard rows (kind 0) with the number of collisions. The physics of the rows
// is checked in tests/analytic/test_contact_output.cpp.
TEST(Snapshots, ContactsAreWrittenWithEverySnapshot) {
  const fs::path d = fresh_dir("snap_contacts");
  auto r = run_cli("run " + kCasesDir + "heap.toml --set run.end_time=0.5 --set output.snapshot_interval=0.25 "
                   "--set output.contacts=true --set output.precision=single --out " + d.string());
  ASSERT_EQ(r.code, 0) << r.out;
  for (int k = 0; k < 3; ++k)
    EXPECT_TRUE(fs::exists(d / fmt::format("snapshots/contacts_{:06d}.csv", k))) << k;
  const ContactsFile c = read_contacts(d / "snapshots/contacts_000002.csv");
  EXPECT_DOUBLE_EQ(c.time, 0.5);
  const std::vector<std::string> h2{"kind", "i", "j", "wall", "x", "y", "fn_x", "fn_y", "ft_x", "ft_y", "overlap",
                                    "collisions"};
  EXPECT_EQ(c.header, h2);
  const auto rows = final_rows(d / "final_state.csv");
  ASSERT_GT(c.rows.size(), 50u);  // the plate's neighbours touch, and the landed grains
  int walls = 0;
  for (const auto& row : c.rows) {
    EXPECT_EQ(row[0], 1.0);
    EXPECT_TRUE(rows.count(static_cast<long>(row[1]))) << row[1];
    if (row[3] >= 0.0) {
      ++walls;
      EXPECT_EQ(row[2], -1.0);
    } else {
      EXPECT_LT(row[1], row[2]);
      EXPECT_TRUE(rows.count(static_cast<long>(row[2]))) << row[2];
    }
    EXPECT_GT(row[10], 0.0);  // overlap
    EXPECT_EQ(row[11], 0.0);
    EXPECT_EQ(std::stod(fmt::format("{:.9g}", static_cast<float>(row[4]))), row[4]);  // float32 digits
  }
  (void)walls;

  const fs::path e = fresh_dir("snap_contacts_edm");
  r = run_cli("run " + kCasesDir + "elastic_gas.toml --set run.end_time=0.2 --set output.snapshot_interval=0.1 "
              "--set output.contacts=true --set output.events=false --out " + e.string());
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(read_contacts(e / "snapshots/contacts_000000.csv").rows.size(), 0u);  // t = 0: no interval yet
  const ContactsFile g = read_contacts(e / "snapshots/contacts_000002.csv");
  EXPECT_EQ(g.header.size(), 15u);
  EXPECT_EQ(g.header[6], "z");
  ASSERT_GT(g.rows.size(), 100u);
  for (const auto& row : g.rows) {
    EXPECT_EQ(row[0], 0.0);
    EXPECT_GE(row[14], 1.0);  // collisions in the interval
    EXPECT_EQ(row[13], 0.0);  // no overlap
  }
  fs::remove_all(d);
  fs::remove_all(e);
}

// `matep log` (io/log_tools): stats, filter, verify and export over events.bin, through the library
// and the CLI: counts against summary.json, filters against a manual scan, verify on the log of every
// shipped case and on a corrupted copy, bad logs with exit status 2, and streaming (the peak RSS of
// `matep log stats` does not grow with the number of records).
#include <fmt/format.h>
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "io/log_tools.hpp"
#include "io/output.hpp"
#include "io/scene.hpp"
#include "tests/support/cli.hpp"
#include "tests/support/event_log.hpp"

namespace fs = std::filesystem;

namespace {

using Result = matep::test::CliResult;
Result sh(const std::string& args) { return matep::test::run_cli(args); }
using matep::test::slurp;
fs::path tmpdir(const std::string& name) { return matep::test::fresh_dir("log_" + name); }
const std::string& kCases = matep::test::kCasesDir;

std::uint64_t summary_count(const fs::path& summary, const std::string& key) {
  const std::string s = slurp(summary);
  const std::string k = "\"" + key + "\": ";
  const auto pos = s.find(k);
  if (pos == std::string::npos) return ~std::uint64_t{0};
  return std::stoull(s.substr(pos + k.size()));
}

std::vector<matep::EventRecord> read_all(const fs::path& log) {
  matep::EventLogReader reader(log.string());
  std::vector<matep::EventRecord> v;
  matep::EventRecord r;
  while (reader.next(r)) v.push_back(r);
  return v;
}

std::string encode(const matep::EventRecord& r) {
  std::string s(matep::kEventRecordSize, '\0');
  matep::encode_event_record(r, reinterpret_cast<unsigned char*>(s.data()));
  return s;
}

// Overwrites the double at `offset` of a file (corrupts one field of one record).
void poke_double(const fs::path& file, std::uint64_t offset, double value) {
  std::fstream f(file, std::ios::in | std::ios::out | std::ios::binary);
  f.seekp(static_cast<std::streamoff>(offset));
  f.write(reinterpret_cast<const char*>(&value), sizeof value);
}
double peek_double(const fs::path& file, std::uint64_t offset) {
  std::ifstream f(file, std::ios::binary);
  f.seekg(static_cast<std::streamoff>(offset));
  double v = 0.0;
  f.read(reinterpret_cast<char*>(&v), sizeof v);
  return v;
}
constexpr std::uint64_t kOffViAfter = 120;  // vi_after.x within a record (io/output.cpp)

std::size_t count_lines(const std::string& s) { return static_cast<std::size_t>(std::count(s.begin(), s.end(), '\n')); }

// Synthetic logs written directly: valid smooth collisions (pair, e = 0.9, and every tenth a wall
// collision), times increasing, `particles` particles.
class SyntheticLog {
 public:
  SyntheticLog(const fs::path& path, std::uint64_t particles, std::uint32_t version = matep::kEventLogVersion)
      : particles_(particles) {
    f_ = std::fopen(path.c_str(), "wb");
    buf_.resize(1 << 20);
    std::setvbuf(f_, buf_.data(), _IOFBF, buf_.size());
    unsigned char h[matep::kEventLogHeaderSize] = {};
    std::memcpy(h, matep::kEventLogMagic, 8);
    const std::uint32_t dim = 3, size = static_cast<std::uint32_t>(matep::kEventRecordSize);
    std::memcpy(h + 8, &version, 4);
    std::memcpy(h + 12, &dim, 4);
    std::memcpy(h + 16, &size, 4);
    std::memcpy(h + 24, &particles, 8);
    std::fwrite(h, 1, sizeof h, f_);
  }
  ~SyntheticLog() { close(); }
  void close() {
    if (f_) std::fclose(f_);
    f_ = nullptr;
  }
  matep::EventRecord next() {
    matep::EventRecord r;
    t_ += 1e-3;
    r.time = t_;
    const bool wall = (n_++ % 10) == 9;
    r.kind = wall ? 2 : 1;
    std::uniform_int_distribution<std::uint32_t> pick(0, static_cast<std::uint32_t>(particles_ - 1));
    std::normal_distribution<double> g;
    r.i = pick(rng_);
    r.j = wall ? pick(rng_) % 4 : static_cast<std::uint32_t>((r.i + 1 + pick(rng_) % (particles_ - 1)) % particles_);
    r.mi = 1.0 + 0.1 * (r.i % 7);
    r.mj = wall ? 0.0 : 1.0 + 0.1 * (r.j % 7);
    r.e = 0.9;
    double n[3] = {g(rng_), g(rng_), g(rng_)};
    const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    for (double& c : n) c /= len;
    for (int c = 0; c < 3; ++c) {
      r.vi_before[c] = g(rng_);
      r.vj_before[c] = wall ? 0.0 : g(rng_);
    }
    double u = 0.0;
    for (int c = 0; c < 3; ++c) u += (r.vi_before[c] - r.vj_before[c]) * n[c];
    if (u > 0.0) {  // make it approach
      for (double& c : n) c = -c;
      u = -u;
    }
    std::copy(n, n + 3, r.normal);
    const double mstar = wall ? r.mi : r.mi * r.mj / (r.mi + r.mj);
    const double J = -(1.0 + r.e) * mstar * u;
    for (int c = 0; c < 3; ++c) {
      r.vi_after[c] = r.vi_before[c] + J / r.mi * n[c];
      r.vj_after[c] = wall ? 0.0 : r.vj_before[c] - J / r.mj * n[c];
    }
    return r;
  }
  void write(const matep::EventRecord& r) {
    unsigned char b[matep::kEventRecordSize];
    matep::encode_event_record(r, b);
    std::fwrite(b, 1, sizeof b, f_);
  }
  void write_many(std::uint64_t count) {
    for (std::uint64_t k = 0; k < count; ++k) write(next());
  }

 private:
  std::uint64_t particles_;
  std::FILE* f_ = nullptr;
  std::vector<char> buf_;
  std::mt19937_64 rng_{12345};
  double t_ = 0.0;
  std::uint64_t n_ = 0;
};

// Runs the CLI as a child (fork + exec, stdout to `out`) and returns its exit status and peak
// resident set size (ru_maxrss, KiB) from wait4.
std::pair<int, long> run_measured(const std::vector<std::string>& args, const fs::path& out) {
  std::vector<std::string> all{MATEP_CLI};
  all.insert(all.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& a : all) argv.push_back(a.data());
  argv.push_back(nullptr);
  std::fflush(nullptr);
  const pid_t pid = fork();
  if (pid == 0) {
    std::FILE* o = std::freopen(out.c_str(), "w", stdout);
    if (!o) _exit(126);
    execv(MATEP_CLI, argv.data());
    _exit(127);
  }
  int status = 0;
  rusage ru{};
  if (pid < 0 || wait4(pid, &status, 0, &ru) != pid) return {-1, -1};
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, ru.ru_maxrss};
}

// Logs of two shipped cases, run once for the suite.
class LogTools : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new fs::path(tmpdir("suite"));
    gas_ok_ = sh("run " + kCases + "elastic_gas.toml --set run.end_time=0.3 --quiet --out " + (*dir_ / "gas").string()).code == 0;
    box_ok_ = sh("run " + kCases + "disks_in_a_box.toml --set run.end_time=0.3 --set output.events=true --quiet --out " +
                 (*dir_ / "box").string())
                  .code == 0;
  }
  static void TearDownTestSuite() {
    fs::remove_all(*dir_);
    delete dir_;
    dir_ = nullptr;
  }
  void SetUp() override {
    ASSERT_TRUE(gas_ok_);
    ASSERT_TRUE(box_ok_);
  }
  static fs::path gas() { return *dir_ / "gas"; }
  static fs::path box() { return *dir_ / "box"; }  // 2D: pair and wall collisions
  static fs::path dir() { return *dir_; }

  static fs::path* dir_;
  static bool gas_ok_, box_ok_;
};
fs::path* LogTools::dir_ = nullptr;
bool LogTools::gas_ok_ = false;
bool LogTools::box_ok_ = false;

}  // namespace

TEST_F(LogTools, StatsCountsEqualTheSummary) {
  for (const fs::path& d : {gas(), box()}) {
    const std::uint64_t pair = summary_count(d / "summary.json", "pair_collisions");
    const std::uint64_t wall = summary_count(d / "summary.json", "wall_collisions");
    const matep::LogStats s = matep::compute_log_stats((d / "events.bin").string(), 7);
    EXPECT_EQ(s.by_kind[1], pair);
    EXPECT_EQ(s.by_kind[2], wall);
    EXPECT_EQ(s.file.records, pair + wall);
    EXPECT_EQ(s.collisions, pair + wall);
    // Bins cover every collision, from the first record's time to the last one's.
    ASSERT_EQ(s.bins.size(), 7u);
    std::uint64_t binned = 0;
    for (const auto& b : s.bins) binned += b.pair + b.wall;
    EXPECT_EQ(binned, pair + wall);
    // Against a manual scan.
    const auto recs = read_all(d / "events.bin");
    ASSERT_FALSE(recs.empty());
    EXPECT_EQ(s.t_first, recs.front().time);
    EXPECT_EQ(s.t_last, recs.back().time);
    EXPECT_EQ(s.bins.front().t0, recs.front().time);
    EXPECT_EQ(s.bins.back().t1, recs.back().time);
    std::vector<std::uint64_t> per(s.file.header.particles, 0);
    double umax = 0.0, emin = 2.0, emax = -1.0, esum = 0.0;
    for (const auto& r : recs) {
      ++per[r.i];
      if (r.kind == 1) ++per[r.j];
      double u = 0.0;
      for (int c = 0; c < 3; ++c) u += (r.vi_before[c] - r.vj_before[c]) * r.normal[c];
      umax = std::max(umax, std::abs(u));
      emin = std::min(emin, r.e);
      emax = std::max(emax, r.e);
      esum += r.e;
    }
    EXPECT_EQ(s.busiest_count, *std::max_element(per.begin(), per.end()));
    EXPECT_EQ(per[s.busiest], s.busiest_count);
    EXPECT_EQ(s.max_impact, umax);
    EXPECT_EQ(s.e_min, emin);
    EXPECT_EQ(s.e_max, emax);
    EXPECT_NEAR(s.e_mean, esum / recs.size(), 1e-12);

    // The CLI prints the same counts.
    const Result r = sh("log stats " + (d / "events.bin").string() + " --bins 7");
    ASSERT_EQ(r.code, 0) << r.out;
    const auto line = [&](const std::string& label) {
      const auto pos = r.out.find(label);
      return pos == std::string::npos ? std::string() : r.out.substr(pos, r.out.find('\n', pos) - pos);
    };
    EXPECT_EQ(line("pair collisions").substr(line("pair collisions").find_last_of(' ') + 1), std::to_string(pair))
        << r.out;
    EXPECT_EQ(line("wall collisions").substr(line("wall collisions").find_last_of(' ') + 1), std::to_string(wall))
        << r.out;
    EXPECT_NE(r.out.find("most collisions"), std::string::npos);
    EXPECT_NE(r.out.find("largest impact"), std::string::npos);
    EXPECT_NE(r.out.find("restitution e"), std::string::npos);
  }
}

TEST_F(LogTools, FilterWritesExactlyTheMatchingRecords) {
  const fs::path log = box() / "events.bin";
  const auto recs = read_all(log);
  ASSERT_GT(recs.size(), 100u);
  const double t0 = recs.front().time, t1 = recs.back().time;
  const double from = t0 + (t1 - t0) / 3, to = t0 + 2 * (t1 - t0) / 3;
  // Ids: the i of one pair record, the j of another, the particle of a wall record.
  std::uint32_t id_i = 0, id_j = 0, id_w = 0;
  for (const auto& r : recs)
    if (r.kind == 1) {
      id_i = r.i;
      break;
    }
  for (auto it = recs.rbegin(); it != recs.rend(); ++it)
    if (it->kind == 1) {
      id_j = it->j;
      break;
    }
  for (const auto& r : recs)
    if (r.kind == 2) {
      id_w = r.i;
      break;
    }
  const std::vector<std::uint32_t> ids{id_i, id_j, id_w};
  auto in_ids = [&](const matep::EventRecord& r) {
    for (std::uint32_t id : ids)
      if (r.i == id || (r.kind == 1 && r.j == id)) return true;
    return false;
  };
  const std::string idlist = std::to_string(id_i) + "," + std::to_string(id_j) + "," + std::to_string(id_w);
  const std::string ft = fmt::format("--from {:.17g} --to {:.17g}", from, to);

  struct Case {
    std::string args;
    std::function<bool(const matep::EventRecord&)> keep;
  };
  const std::vector<Case> cases = {
      {ft, [&](const matep::EventRecord& r) { return r.time >= from && r.time <= to; }},
      {"--ids " + idlist, in_ids},
      {"--kind wall", [](const matep::EventRecord& r) { return r.kind == 2; }},
      {"--kind pair --kind wall", [](const matep::EventRecord&) { return true; }},
      {"--kind soft", [](const matep::EventRecord&) { return false; }},
      {ft + " --kind pair --ids " + idlist,
       [&](const matep::EventRecord& r) { return r.time >= from && r.time <= to && r.kind == 1 && in_ids(r); }},
  };
  const std::string input = slurp(log);
  const matep::EventLogHeader in_header = matep::inspect_log(log.string()).header;
  for (const auto& c : cases) {
    std::string expected;
    std::size_t n = 0;
    for (const auto& r : recs)
      if (c.keep(r)) {
        expected += encode(r);
        ++n;
      }
    const fs::path out = dir() / "filtered.bin";
    const Result res = sh("log filter " + log.string() + " --out " + out.string() + " " + c.args);
    ASSERT_EQ(res.code, 0) << c.args << "\n" << res.out;
    // A version-3 log with the input's dimension and particle count, holding exactly these records.
    const matep::LogFile lf = matep::inspect_log(out.string());
    EXPECT_EQ(lf.header.version, matep::kEventLogVersionChecked);
    EXPECT_EQ(lf.header.dimension, in_header.dimension);
    EXPECT_EQ(lf.header.particles, in_header.particles);
    EXPECT_EQ(lf.records, n);
    std::string got;
    for (const auto& r : read_all(out)) got += encode(r);
    EXPECT_EQ(got, expected) << c.args;
    EXPECT_NE(res.out.find(std::to_string(n) + " of " + std::to_string(recs.size())), std::string::npos) << res.out;
    // The same selection as CSV (by --csv and by the .csv extension).
    const fs::path csv = dir() / "filtered.csv";
    ASSERT_EQ(sh("log filter " + log.string() + " --out " + csv.string() + " " + c.args).code, 0);
    const std::string text = slurp(csv);
    EXPECT_EQ(count_lines(text), n + 1) << c.args;
    EXPECT_EQ(text.substr(0, text.find('\n')), matep::csv_header());
    const fs::path csv2 = dir() / "filtered.txt";
    ASSERT_EQ(sh("log filter " + log.string() + " --csv --out " + csv2.string() + " " + c.args).code, 0);
    EXPECT_EQ(slurp(csv2), text);
  }
  // The library's predicate agrees with the manual one.
  matep::LogFilter f;
  f.from = from;
  f.to = to;
  f.ids = matep::parse_id_list(idlist);
  f.kinds = {matep::parse_event_kind("pair")};
  const matep::FilterResult fr = matep::filter_log(log.string(), (dir() / "lib.bin").string(), f, false);
  EXPECT_EQ(fr.read, recs.size());
  EXPECT_EQ(fr.written, static_cast<std::uint64_t>(std::count_if(recs.begin(), recs.end(), [&](const auto& r) {
              return r.time >= from && r.time <= to && r.kind == 1 && in_ids(r);
            })));
  // Bad options: exit 2, one line, no output written.
  const fs::path none = dir() / "bad.bin";
  for (const std::string& bad : std::vector<std::string>{"--out " + none.string() + " --kind bogus",
                                                         "--out " + none.string() + " --ids 1,x",
                                                         "--from 1", "--out " + log.string()}) {
    const Result r = sh("log filter " + log.string() + " " + bad);
    EXPECT_EQ(r.code, 2) << bad << ": " << r.out;
    EXPECT_EQ(count_lines(r.out), 1u) << r.out;
    EXPECT_FALSE(fs::exists(none));
  }
  EXPECT_EQ(slurp(log), input);  // the input is untouched
}

TEST_F(LogTools, ExportHasOneRowPerRecord) {
  const fs::path log = box() / "events.bin";
  const auto recs = read_all(log);
  const Result r = sh("log export " + log.string());
  ASSERT_EQ(r.code, 0);
  EXPECT_EQ(count_lines(r.out), recs.size() + 1);
  const std::string header = r.out.substr(0, r.out.find('\n'));
  EXPECT_EQ(header,
            "time,kind,i,j,mi,mj,e,nx,ny,nz,vi_bx,vi_by,vi_bz,vj_bx,vj_by,vj_bz,vi_ax,vi_ay,vi_az,"
            "vj_ax,vj_ay,vj_az,wi_bx,wi_by,wi_bz,wj_bx,wj_by,wj_bz,wi_ax,wi_ay,wi_az,wj_ax,wj_ay,wj_az");
  // Every row: 34 fields, the kind as a word, values that read back exactly.
  std::istringstream in(r.out);
  std::string row;
  std::getline(in, row);
  for (const auto& rec : recs) {
    ASSERT_TRUE(std::getline(in, row));
    std::vector<std::string> fields;
    std::stringstream ss(row);
    std::string f;
    while (std::getline(ss, f, ',')) fields.push_back(f);
    ASSERT_EQ(fields.size(), 34u) << row;
    EXPECT_EQ(std::stod(fields[0]), rec.time);
    EXPECT_EQ(fields[1], rec.kind == 1 ? "pair" : "wall");
    EXPECT_EQ(std::stoul(fields[2]), rec.i);
    EXPECT_EQ(std::stoul(fields[3]), rec.j);
    EXPECT_EQ(std::stod(fields[6]), rec.e);
    EXPECT_EQ(std::stod(fields[16]), rec.vi_after[0]);
  }
  const fs::path out = dir() / "export.csv";
  const Result f = sh("log export " + log.string() + " --out " + out.string());
  ASSERT_EQ(f.code, 0) << f.out;
  EXPECT_EQ(slurp(out), r.out);
}

TEST(LogVerify, PassesOnTheLogOfEveryShippedCase) {
  const fs::path d = tmpdir("cases");
  std::vector<fs::path> scenes;
  for (const auto& e : fs::directory_iterator(kCases))
    if (e.path().extension() == ".toml") scenes.push_back(e.path());
  std::sort(scenes.begin(), scenes.end());
  ASSERT_GE(scenes.size(), 4u);
  for (const fs::path& scene : scenes) {
    const std::string name = scene.stem().string();
    // The event log records instantaneous collisions: soft-sphere (tdm) cases have none and
    // refuse output.events (tested in test_tdm_input.cpp).
    if (matep::load_scene(scene.string()).method == matep::Method::Tdm) continue;
    // Short runs; the bouncing ball runs to its collapse (exit 3), which still writes the log, and
    // the hybrid ball to its end (its first bounce is at 0.45 s; the switch record is skipped).
    const bool collapse = name == "bouncing_ball";
    const bool whole = collapse || name == "ball_to_rest";
    const std::string sets = std::string(whole ? "" : " --set run.end_time=0.3") + " --set output.events=true";
    const fs::path out = d / name;
    const Result run = sh("run " + scene.string() + sets + " --quiet --out " + out.string());
    ASSERT_EQ(run.code, collapse ? 3 : 0) << name << ": " << run.out;
    const std::uint64_t collisions = summary_count(out / "summary.json", "pair_collisions") +
                                     summary_count(out / "summary.json", "wall_collisions");
    ASSERT_GT(collisions, 0u) << name;
    const std::string log = (out / "events.bin").string();
    const Result v = sh("log verify " + log);
    EXPECT_EQ(v.code, 0) << name << ": " << v.out;
    EXPECT_EQ(v.out.rfind("verified " + std::to_string(collisions) + " records: momentum, restitution, energy OK", 0),
              0u)
        << name << ": " << v.out;
    // With the scene: e against the materials' restitution models (disks_in_a_box: Schwager-Poschel,
    // velocity-dependent, mixed with the steel walls).
    const Result vs = sh("log verify " + log + " --scene " + scene.string() + sets);
    EXPECT_EQ(vs.code, 0) << name << ": " << vs.out;
    EXPECT_NE(vs.out.find("restitution models"), std::string::npos) << vs.out;
    // Library: the same, and a tighter tolerance still passes (the engine is exact to round-off).
    const matep::Scene sc = matep::load_scene(scene.string(), {"output.events=true"});
    const matep::VerifyResult r = matep::verify_log(log, &sc, 1e-12);
    EXPECT_TRUE(r.ok) << r.message;
    EXPECT_EQ(r.pair + r.wall, collisions);
    EXPECT_TRUE(r.model_checked);
  }
  // A scene whose restitution differs from the one that was run: the model check names the record.
  const Result wrong = sh("log verify " + (d / "disks_in_a_box" / "events.bin").string() + " --scene " + kCases +
                          "disks_in_a_box.toml --set material.disk.restitution=0.5");
  EXPECT_EQ(wrong.code, 1) << wrong.out;
  EXPECT_NE(wrong.out.find("restitution model check"), std::string::npos) << wrong.out;
  // The TC model: e = 1 is accepted only when the scene has tc > 0.
  const fs::path tc = d / "tc";
  ASSERT_EQ(sh("run " + kCases + "bouncing_ball.toml --set run.tc=0.001 --set run.end_time=4.5 --quiet --out " +
               tc.string())
                .code,
            0);
  const std::string tclog = (tc / "events.bin").string();
  const Result with_tc = sh("log verify " + tclog + " --scene " + kCases + "bouncing_ball.toml --set run.tc=0.001");
  EXPECT_EQ(with_tc.code, 0) << with_tc.out;
  const Result without_tc = sh("log verify " + tclog + " --scene " + kCases + "bouncing_ball.toml");
  EXPECT_EQ(without_tc.code, 1) << without_tc.out;
  EXPECT_NE(without_tc.out.find("e = 1 "), std::string::npos) << without_tc.out;
  // A scene that does not match the log is bad input.
  const Result mismatch = sh("log verify " + tclog + " --scene " + kCases + "disks_in_a_box.toml");
  EXPECT_EQ(mismatch.code, 2) << mismatch.out;
  // A wall record is checked against the wall's shape: with the floor tilted in the scene, the
  // first floor bounce has a normal the plane does not have anywhere.
  const matep::Scene tilted =
      matep::load_scene(kCases + "bouncing_ball.toml", {"run.tc=0.001", "wall.floor.normal=[0.1, 0.0, 1.0]"});
  const matep::VerifyResult r = matep::verify_log(tclog, &tilted, 1e-9);
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.check, "wall normal") << r.message;
  EXPECT_EQ(r.index, 0u) << r.message;
  EXPECT_NE(r.message.find("plane through"), std::string::npos) << r.message;
  fs::remove_all(d);
}

TEST_F(LogTools, VerifyFailsOnAnAlteredRecordAndNamesIt) {
  const fs::path good = gas() / "events.bin";
  const std::uint64_t n = matep::inspect_log(good.string()).records;
  ASSERT_GT(n, 10u);
  const std::uint64_t k = n / 2;
  const fs::path bad = dir() / "altered.bin";
  fs::copy_file(good, bad, fs::copy_options::overwrite_existing);
  const std::uint64_t off = matep::record_offset(matep::inspect_log(good.string()).header, k);
  const double v = peek_double(bad, off + kOffViAfter);
  poke_double(bad, off + kOffViAfter, v + 1e-6 * (std::abs(v) + 1.0));
  matep::test::reseal_event_log(bad);  // past the checksums, to the physics

  const Result r = sh("log verify " + bad.string());
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_EQ(count_lines(r.out), 1u) << r.out;
  EXPECT_NE(r.out.find("record " + std::to_string(k) + " at byte offset " + std::to_string(off)), std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("momentum"), std::string::npos) << r.out;
  const matep::VerifyResult res = matep::verify_log(bad.string(), nullptr, 1e-9);
  EXPECT_FALSE(res.ok);
  EXPECT_EQ(res.index, k);
  EXPECT_EQ(res.offset, off);
  EXPECT_EQ(res.check, "momentum");
  EXPECT_EQ(res.records, k + 1);  // stopped at the first violation
  // The untouched log passes.
  EXPECT_TRUE(matep::verify_log(good.string(), nullptr, 1e-9).ok);
  // A NaN is refused by the reader (bad input, exit 2), naming the record, its offset and the field.
  poke_double(bad, off + kOffViAfter, std::nan(""));
  matep::test::reseal_event_log(bad);
  const Result nan = sh("log verify " + bad.string());
  EXPECT_EQ(nan.code, 2) << nan.out;
  EXPECT_NE(nan.out.find("corrupt event record " + std::to_string(k) + " at byte offset " + std::to_string(off) +
                         ": vi_after.x = nan"),
            std::string::npos)
      << nan.out;
}

TEST_F(LogTools, BadLogsGiveExitStatus2AndTheByteOffset) {
  const fs::path good = gas() / "events.bin";
  const auto size = fs::file_size(good);
  const fs::path t = dir() / "truncated.bin";
  fs::copy_file(good, t, fs::copy_options::overwrite_existing);
  fs::resize_file(t, size - 10);
  // The cut falls in the last block (its checksum record is the file's last 32 bytes).
  const matep::LogFile glf = matep::inspect_log(good.string());
  const std::string where = "the last block, at byte offset " + std::to_string(matep::block_offset(glf.header, glf.records));
  for (const std::string& cmd : std::vector<std::string>{"stats", "verify", "export", "filter"}) {
    const fs::path out = dir() / "from_truncated.bin";
    const Result r = sh("log " + cmd + " " + t.string() + (cmd == "filter" ? " --out " + out.string() : ""));
    EXPECT_EQ(r.code, 2) << cmd << ": " << r.out;
    EXPECT_NE(r.out.find("byte offset"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find(where), std::string::npos) << r.out;
    EXPECT_NE(r.out.find(t.string()), std::string::npos) << r.out;
    if (cmd != "export") {
      EXPECT_EQ(count_lines(r.out), 1u) << r.out;
    }
    EXPECT_FALSE(fs::exists(out));  // nothing half-written
  }
  // Unknown kind in a record (checksums resealed), bad magic, wrong version, a header cut short.
  const fs::path k = dir() / "kind.bin";
  fs::copy_file(good, k, fs::copy_options::overwrite_existing);
  {
    std::fstream f(k, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(static_cast<std::streamoff>(matep::record_offset(glf.header, 3) + 8));
    f.put(9);
  }
  matep::test::reseal_event_log(k);
  const Result rk = sh("log stats " + k.string());
  EXPECT_EQ(rk.code, 2);
  EXPECT_NE(rk.out.find("corrupt event record 3 at byte offset " + std::to_string(matep::record_offset(glf.header, 3)) +
                        ": kind 9"),
            std::string::npos)
      << rk.out;
  const fs::path m = dir() / "magic.bin";
  fs::copy_file(good, m, fs::copy_options::overwrite_existing);
  {
    std::fstream f(m, std::ios::in | std::ios::out | std::ios::binary);
    f.put('X');
  }
  const Result rm = sh("log verify " + m.string());
  EXPECT_EQ(rm.code, 2);
  EXPECT_NE(rm.out.find("byte offset 0"), std::string::npos) << rm.out;
  const fs::path h = dir() / "short.bin";
  {
    std::ofstream f(h, std::ios::binary);
    f << slurp(good).substr(0, 40);
  }
  const Result rh = sh("log export " + h.string());
  EXPECT_EQ(rh.code, 2);
  EXPECT_NE(rh.out.find("byte offset"), std::string::npos) << rh.out;
  // A record naming a particle beyond the header's count is corrupt: every tool refuses it (exit 2),
  // naming the record and its byte offset.
  const fs::path idx = dir() / "index.bin";
  {
    SyntheticLog s(idx, 10);
    s.write_many(5);
    matep::EventRecord r = s.next();
    r.i = 50;
    s.write(r);
  }
  const std::string at5 = "corrupt event record 5 at byte offset " +
                          std::to_string(matep::record_offset(matep::test::v1_header(), 5)) + ": i = 50";
  for (const std::string cmd : {"stats", "verify", "export"}) {
    const Result si = sh("log " + cmd + " " + idx.string());
    EXPECT_EQ(si.code, 2) << si.out;
    EXPECT_NE(si.out.find(at5), std::string::npos) << si.out;
  }
  const Result missing = sh("log stats " + (dir() / "missing.bin").string());
  EXPECT_EQ(missing.code, 2);
  EXPECT_EQ(sh("log").code, 2);
  EXPECT_EQ(sh("log frobnicate " + good.string()).code, 2);
  EXPECT_EQ(sh("log stats " + good.string() + " --bins 0").code, 2);
  EXPECT_EQ(sh("log verify " + good.string() + " --tol -1").code, 2);
}

TEST(LogStreaming, PeakMemoryDoesNotGrowWithTheLog) {
  const fs::path d = tmpdir("rss");
  const std::uint64_t big_n = fs::space(d).available > (std::uint64_t{2} << 30) ? 1000000 : 300000;
  const std::uint64_t small_n = 10000;
  {
    SyntheticLog s(d / "small.bin", 1000);
    s.write_many(small_n);
    SyntheticLog b(d / "big.bin", 1000);
    b.write_many(big_n);
  }
  ASSERT_EQ(fs::file_size(d / "big.bin"), matep::record_offset(matep::test::v1_header(), big_n));
  // A forked child starts with the test process's anonymous pages mapped until it execs, so
  // ru_maxrss has that floor; `matep --version` shows it. Both stats runs share it.
  const auto [code_f, rss_f] = run_measured({"--version"}, d / "version.txt");
  ASSERT_EQ(code_f, 0);
  const auto [code_s, rss_s] = run_measured({"log", "stats", (d / "small.bin").string()}, d / "small.txt");
  const auto [code_b, rss_b] = run_measured({"log", "stats", (d / "big.bin").string()}, d / "big.txt");
  ASSERT_EQ(code_s, 0) << slurp(d / "small.txt");
  ASSERT_EQ(code_b, 0) << slurp(d / "big.txt");
  EXPECT_NE(slurp(d / "big.txt").find("records     " + std::to_string(big_n)), std::string::npos);
  // The synthetic records are valid collisions: verify streams the big log too.
  const auto [code_v, rss_v] = run_measured({"log", "verify", (d / "big.bin").string()}, d / "verify.txt");
  EXPECT_EQ(code_v, 0) << slurp(d / "verify.txt");
  std::printf("peak RSS of matep log stats: %ld KiB (%llu records), %ld KiB (%llu records, %.0f MB); "
              "verify %ld KiB; matep --version %ld KiB\n",
              rss_s, static_cast<unsigned long long>(small_n), rss_b, static_cast<unsigned long long>(big_n),
              static_cast<double>(fs::file_size(d / "big.bin")) / 1e6, rss_v, rss_f);
  RecordProperty("rss_small_kib", static_cast<int>(rss_s));
  RecordProperty("rss_big_kib", static_cast<int>(rss_b));
  EXPECT_GT(rss_s, 0);
  EXPECT_LT(std::abs(rss_b - rss_s), 8 * 1024) << "stats holds records in memory";
  EXPECT_LT(std::abs(rss_v - rss_s), 8 * 1024) << "verify holds records in memory";
  fs::remove_all(d);
}

// A rough gas (cases/rough_gas.toml: friction, Walton's rule): every record passes with and without
// the scene (the scene gives the radii and the tangential rule; without it the radii the records
// imply), and a spin altered in one record fails the angular-momentum balance about the contact
// point, naming that record.
TEST_F(LogTools, VerifyRoughLogAndAlteredSpin) {
  const fs::path d = dir() / "rough";
  const std::string scene = kCases + "rough_gas.toml";
  ASSERT_EQ(sh("run " + scene + " --set run.end_time=3 --set output.events=true --quiet --out " + d.string()).code, 0);
  const fs::path good = d / "events.bin";
  const std::uint64_t n = matep::inspect_log(good.string()).records;
  ASSERT_GT(n, 100u);
  const matep::Scene sc = matep::load_scene(scene, {"run.end_time=3", "output.events=true"});
  {
    const matep::VerifyResult with = matep::verify_log(good.string(), &sc, 1e-12);
    EXPECT_TRUE(with.ok) << with.message;
    EXPECT_EQ(with.rough, n);
    const matep::VerifyResult without = matep::verify_log(good.string(), nullptr, 1e-9);
    EXPECT_TRUE(without.ok) << without.message;
    // Records with no spin before (the gas starts without spin) still change spins: all rough.
    EXPECT_EQ(without.rough, n);
    const Result v = sh("log verify " + good.string() + " --scene " + scene);
    EXPECT_EQ(v.code, 0) << v.out;
    EXPECT_NE(v.out.find("rough"), std::string::npos) << v.out;
  }
  constexpr std::uint64_t kOffWiAfter = 216;  // wi_after.x within a record (io/output.cpp)
  const std::uint64_t k = n / 2;
  const std::uint64_t off = matep::record_offset(matep::inspect_log(good.string()).header, k);
  for (const int c : {0, 1, 2}) {
    const fs::path bad = d / "altered.bin";
    fs::copy_file(good, bad, fs::copy_options::overwrite_existing);
    const double w = peek_double(bad, off + kOffWiAfter + 8 * c);
    poke_double(bad, off + kOffWiAfter + 8 * c, w + 1e-6 * (std::abs(w) + 1.0));
    matep::test::reseal_event_log(bad);
    const Result r = sh("log verify " + bad.string() + " --scene " + scene);
    EXPECT_EQ(r.code, 1) << r.out;
    EXPECT_NE(r.out.find("record " + std::to_string(k) + " at byte offset " + std::to_string(off)), std::string::npos)
        << r.out;
    const matep::VerifyResult res = matep::verify_log(bad.string(), &sc, 1e-9);
    EXPECT_FALSE(res.ok);
    EXPECT_EQ(res.index, k);
    EXPECT_EQ(res.check, "angular momentum") << res.message;
    // Without the scene the implied radius no longer fits the rest of the record.
    const matep::VerifyResult blind = matep::verify_log(bad.string(), nullptr, 1e-9);
    EXPECT_FALSE(blind.ok) << "component " << c;
    EXPECT_EQ(blind.index, k) << blind.message;
  }
  // A scene with another tangential rule: the tangential-restitution check names the first record.
  const matep::Scene other = matep::load_scene(scene, {"material.grain.tangential_restitution=0.2"});
  const matep::VerifyResult wrong = matep::verify_log(good.string(), &other, 1e-9);
  EXPECT_FALSE(wrong.ok);
  EXPECT_EQ(wrong.check, "tangential restitution") << wrong.message;
}


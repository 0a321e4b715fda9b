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
    // A version-4 log (as its input) with the input's dimension, particle count and identity,
    // holding exactly these records.
    const matep::LogFile lf = matep::inspect_log(out.string());
    EXPECT_EQ(lf.header.version, matep::kEventLogVersionIdentity);
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

// ---- issue 17: tools that never destroy, readers that check everything -----------------------

namespace {

// The names in a folder, sorted (to see that no temporary file is left behind).
std::vector<std::string> names_in(const fs::path& d) {
  std::vector<std::string> v;
  for (const auto& e : fs::directory_iterator(d)) v.push_back(e.path().filename().string());
  std::sort(v.begin(), v.end());
  return v;
}

// A copy of `from` with the byte at `offset` XOR-ed with `mask` (checksums left as they were).
void flip_copy(const fs::path& from, const fs::path& to, std::uint64_t offset, unsigned char mask) {
  fs::copy_file(from, to, fs::copy_options::overwrite_existing);
  std::fstream f(to, std::ios::in | std::ios::out | std::ios::binary);
  f.seekg(static_cast<std::streamoff>(offset));
  const int c = f.get();
  f.seekp(static_cast<std::streamoff>(offset));
  f.put(static_cast<char>(c ^ mask));
}

void write_text(const fs::path& p, const std::string& text) {
  std::ofstream f(p, std::ios::binary | std::ios::trunc);
  f << text;
}

// A valid smooth collision of particle 1 with a partner at rest that is fixed (mj = +infinity,
// versions 2 and 3): the reflection off a plane with normal n.
matep::EventRecord fixed_partner_record(double t) {
  matep::EventRecord r;
  r.time = t;
  r.kind = 1;
  r.i = 1;
  r.j = 0;
  r.mi = 2.0;
  r.mj = std::numeric_limits<double>::infinity();
  r.e = 0.8;
  const double n[3] = {0.6, 0.0, 0.8}, v[3] = {-1.0, 0.5, -2.0};
  const double un = v[0] * n[0] + v[1] * n[1] + v[2] * n[2];
  for (int c = 0; c < 3; ++c) {
    r.normal[c] = n[c];
    r.vi_before[c] = v[c];
    r.vi_after[c] = v[c] - (1.0 + r.e) * un * n[c];
  }
  return r;
}

}  // namespace

// A failed filter or export (a corrupt block after a good one: output already started) leaves the
// file that was at --out as it was, and leaves no temporary behind; a successful one replaces it
// and keeps its permissions.
TEST_F(LogTools, FailedFilterOrExportKeepsTheExistingOutput) {
  const fs::path good = gas() / "events.bin";
  const matep::LogFile lf = matep::inspect_log(good.string());
  const std::uint32_t k = lf.header.block_records;
  ASSERT_GT(lf.records, std::uint64_t{2} * k);
  const fs::path d = dir() / "keep";
  fs::create_directories(d);
  const fs::path bad = d / "bad.bin";
  flip_copy(good, bad, matep::record_offset(lf.header, k + 5) + kOffViAfter + 3, 0x40);
  const std::string where = "corrupt block at byte offset " + std::to_string(matep::block_offset(lf.header, k));
  const std::string precious = "an earlier result that must survive\n";
  for (const std::string cmd : {"filter", "filter --csv", "export"}) {
    const fs::path out = d / "result.out";
    write_text(out, precious);
    fs::permissions(out, fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read);
    const Result r = sh("log " + cmd + " " + bad.string() + " --out " + out.string());
    EXPECT_EQ(r.code, 2) << cmd << ": " << r.out;
    EXPECT_EQ(count_lines(r.out), 1u) << r.out;
    EXPECT_NE(r.out.find(bad.string() + ": " + where), std::string::npos) << r.out;
    EXPECT_EQ(slurp(out), precious) << cmd;
    EXPECT_EQ(names_in(d), (std::vector<std::string>{"bad.bin", "result.out"})) << cmd;
    // The same from the good log replaces the file (permissions kept).
    const Result ok = sh("log " + cmd + " " + good.string() + " --out " + out.string());
    ASSERT_EQ(ok.code, 0) << cmd << ": " << ok.out;
    EXPECT_NE(slurp(out), precious);
    if (cmd == "filter") {
      EXPECT_EQ(matep::inspect_log(out.string()).records, lf.records);
    }
    EXPECT_EQ(fs::status(out).permissions(), fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read);
    EXPECT_EQ(names_in(d), (std::vector<std::string>{"bad.bin", "result.out"})) << cmd;
    fs::remove(out);
  }
  // A folder that does not exist: one line, nothing created.
  const Result nodir = sh("log filter " + good.string() + " --out " + (d / "no" / "x.bin").string());
  EXPECT_EQ(nodir.code, 2) << nodir.out;
  EXPECT_NE(nodir.out.find("cannot create a temporary file in " + (d / "no").string()), std::string::npos) << nodir.out;
  EXPECT_FALSE(fs::exists(d / "no"));
}

// --out that is a FIFO, a device, a directory, or the input itself (the same path, another path to
// it, a hard link, a symbolic link) is refused with one line before anything is written.
TEST_F(LogTools, OutputThatIsNotARegularFileOrIsTheInputIsRefused) {
  const fs::path d = dir() / "refuse";
  fs::create_directories(d);
  const fs::path log = d / "events.bin";
  fs::copy_file(gas() / "events.bin", log, fs::copy_options::overwrite_existing);
  const std::string input = slurp(log);
  const fs::path fifo = d / "fifo", sub = d / "folder", hard = d / "hard.bin", soft = d / "soft.bin";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  fs::create_directories(sub);
  write_text(sub / "inside.txt", "x");
  fs::create_hard_link(log, hard);
  fs::create_symlink(log, soft);
  const std::vector<std::string> before = names_in(d);
  // Hold the FIFO's read end open: a tool that wrote to it would not block, and its bytes would show.
  const int rd = ::open(fifo.c_str(), O_RDONLY | O_NONBLOCK);
  ASSERT_GE(rd, 0);
  struct Case {
    std::string out, says;
  };
  const std::vector<Case> cases = {
      {fifo.string(), "is a FIFO, not a regular file"},
      {"/dev/null", "is a character device, not a regular file"},
      {sub.string(), "is a directory, not a regular file"},
      {log.string(), "is the input log"},
      {(sub / ".." / "events.bin").string(), "is the input log"},
      {hard.string(), "is the input log"},
      {soft.string(), "is the input log"},
  };
  for (const auto& c : cases)
    for (const std::string cmd : {"filter", "filter --csv", "export"}) {
      const Result r = sh("log " + cmd + " " + log.string() + " --out " + c.out);
      EXPECT_EQ(r.code, 2) << cmd << " --out " << c.out << ": " << r.out;
      EXPECT_EQ(count_lines(r.out), 1u) << r.out;
      EXPECT_NE(r.out.find(c.out + ": " + c.says), std::string::npos) << r.out;
    }
  char byte;
  EXPECT_LE(::read(rd, &byte, 1), 0) << "something was written to the FIFO";
  ::close(rd);
  struct stat st {};
  ASSERT_EQ(::lstat(fifo.c_str(), &st), 0);
  EXPECT_TRUE(S_ISFIFO(st.st_mode));
  ASSERT_EQ(::stat("/dev/null", &st), 0);
  EXPECT_TRUE(S_ISCHR(st.st_mode));
  EXPECT_EQ(slurp(sub / "inside.txt"), "x");
  EXPECT_EQ(slurp(log), input);
  EXPECT_TRUE(fs::is_symlink(soft));
  EXPECT_EQ(names_in(d), before);
}

// The header's particle count sizes nothing: a flipped byte that makes it 3e9 (the old reader
// allocated 24 GB for it) costs no memory, and a count no 32-bit id can reach is refused at once.
// In a version-3 log the header checksum catches the flip.
TEST(LogToolsLimits, TheHeaderParticleCountSizesNothing) {
  const fs::path d = tmpdir("count");
  {
    SyntheticLog s(d / "log.bin", 10);
    s.write_many(2000);
  }
  auto set_count = [&](const std::string& name, std::uint64_t count) {
    fs::copy_file(d / "log.bin", d / name, fs::copy_options::overwrite_existing);
    std::fstream f(d / name, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(24);
    f.write(reinterpret_cast<const char*>(&count), 8);
    return (d / name).string();
  };
  const std::string big = set_count("big.bin", 3000000000ull), huge = set_count("huge.bin", std::uint64_t{1} << 40);
  const auto [code_f, rss_f] = run_measured({"--version"}, d / "version.txt");
  ASSERT_EQ(code_f, 0);
  const auto [code_n, rss_n] = run_measured({"log", "stats", (d / "log.bin").string()}, d / "normal.txt");
  const auto [code_b, rss_b] = run_measured({"log", "stats", big}, d / "big.txt");
  ASSERT_EQ(code_n, 0) << slurp(d / "normal.txt");
  ASSERT_EQ(code_b, 0) << slurp(d / "big.txt");
  EXPECT_NE(slurp(d / "big.txt").find("10 of 3000000000"), std::string::npos) << slurp(d / "big.txt");
  std::printf("peak RSS of matep log stats: %ld KiB (header: 10 particles), %ld KiB (header: 3e9); --version %ld KiB\n",
              rss_n, rss_b, rss_f);
  EXPECT_LT(std::abs(rss_b - rss_n), 8 * 1024) << "stats sized memory from the header's count";
  const Result h = sh("log stats " + huge);
  EXPECT_EQ(h.code, 2) << h.out;
  EXPECT_NE(h.out.find(huge + ": corrupt event log header: particle count 1099511627776 at byte offset 24"),
            std::string::npos)
      << h.out;
  // Version 3: the flip breaks the header's checksum.
  const fs::path run = d / "run";
  ASSERT_EQ(sh("run " + kCases + "elastic_gas.toml --set run.end_time=0.02 --quiet --out " + run.string()).code, 0);
  flip_copy(run / "events.bin", d / "v3.bin", 28, 0x08);
  for (const std::string cmd : {"stats", "verify", "export"}) {
    const Result r = sh("log " + cmd + " " + (d / "v3.bin").string());
    EXPECT_EQ(r.code, 2) << r.out;
    EXPECT_NE(r.out.find("corrupt event log header: checksum at byte offset 60"), std::string::npos) << r.out;
  }
  fs::remove_all(d);
}

// Velocities of 1e200: |v|^2 overflows, and the relative comparisons against an infinite scale
// used to pass. Such a record now fails the "range" check; a consistent collision at 1e100 (every
// scale finite) still passes.
TEST(LogToolsVerify, OverflowingVelocitiesFailInsteadOfPassing) {
  const fs::path d = tmpdir("overflow");
  matep::EventRecord base;
  {
    SyntheticLog s(d / "ok.bin", 10);
    base = s.next();
    s.write(base);
  }
  auto one = [&](const std::string& name, const matep::EventRecord& r) {
    SyntheticLog s(d / name, 10);
    s.write(base);
    s.write(r);
    return (d / name).string();
  };
  // A wall collision whose tangential velocity (1e200) vanishes: momentum, tangential velocity and
  // energy are all violated, each relative to an infinite scale.
  matep::EventRecord w;
  w.time = base.time + 1.0;
  w.kind = 2;
  w.i = 3;
  w.mi = 1.0;
  w.e = 0.9;
  w.normal[2] = 1.0;
  w.vi_before[0] = w.vi_before[1] = 1e200;
  w.vi_before[2] = -1.0;
  w.vi_after[2] = 0.9;
  // The valid base collision with every velocity scaled.
  auto scaled = [&](double f) {
    matep::EventRecord r = base;
    r.time = base.time + 1.0;
    for (double* v : {r.vi_before, r.vj_before, r.vi_after, r.vj_after})
      for (int c = 0; c < 3; ++c) v[c] *= f;
    return r;
  };
  const std::string tangential = one("tangential.bin", w), big = one("big.bin", scaled(1e200)),
                    fine = one("fine.bin", scaled(1e100));
  const std::string at1 =
      "record 1 at byte offset " + std::to_string(matep::record_offset(matep::test::v1_header(), 1));
  for (const std::string& log : {tangential, big}) {
    const Result r = sh("log verify " + log);
    EXPECT_EQ(r.code, 1) << r.out;
    EXPECT_NE(r.out.find(at1), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("fails the range check"), std::string::npos) << r.out;
    const matep::VerifyResult v = matep::verify_log(log, nullptr, 1e-9);
    EXPECT_FALSE(v.ok);
    EXPECT_EQ(v.index, 1u);
    EXPECT_EQ(v.check, "range");
  }
  const Result ok = sh("log verify " + fine);
  EXPECT_EQ(ok.code, 0) << ok.out;
  fs::remove_all(d);
}

// Every record is checked when read, by every tool: an unknown kind, a non-finite field, a mass
// that is not positive, an infinite mj outside a log with fixed grains. The message names the
// file, the record's byte offset and the field.
TEST(LogToolsRecords, EveryToolRefusesARecordThatFailsItsChecks) {
  const fs::path d = tmpdir("records");
  struct Case {
    std::string name, says;
    std::function<void(matep::EventRecord&)> spoil;
  };
  const std::vector<Case> cases = {
      {"kind0", "kind 0 (known kinds are 1 to 7)", [](matep::EventRecord& r) { r.kind = 0; }},
      {"kind8", "kind 8 (known kinds are 1 to 7)", [](matep::EventRecord& r) { r.kind = 8; }},
      {"kind255", "kind 255 (known kinds are 1 to 7)", [](matep::EventRecord& r) { r.kind = 255; }},
      {"time", "time = inf", [](matep::EventRecord& r) { r.time = std::numeric_limits<double>::infinity(); }},
      {"normal", "normal.y = nan", [](matep::EventRecord& r) { r.normal[1] = std::nan(""); }},
      {"spin", "wj_after.z = -inf", [](matep::EventRecord& r) { r.wj_after[2] = -std::numeric_limits<double>::infinity(); }},
      {"mass", "mi = 0 (a mass must be > 0)", [](matep::EventRecord& r) { r.mi = 0.0; }},
      {"mj", "mj = -1 (a mass must be > 0)", [](matep::EventRecord& r) { r.kind = 1; r.mj = -1.0; }},
      {"fixed", "mj = inf", [](matep::EventRecord& r) { r.kind = 1; r.mj = std::numeric_limits<double>::infinity(); }},
      {"switch", "mi = -2 (a mass must be > 0)", [](matep::EventRecord& r) { r.kind = 4; r.mi = -2.0; }},
      {"inflow", "mj = 0 (an inflow's radius must be > 0)", [](matep::EventRecord& r) { r.kind = 7; r.mj = 0.0; }},
  };
  const std::string at3 = "corrupt event record 3 at byte offset " +
                          std::to_string(matep::record_offset(matep::test::v1_header(), 3)) + ": ";
  for (const auto& c : cases) {
    const fs::path log = d / (c.name + ".bin");
    {
      SyntheticLog s(log, 10);
      s.write_many(3);
      matep::EventRecord r = s.next();
      c.spoil(r);
      s.write(r);
      s.write_many(3);
    }
    for (const std::string cmd : {"stats", "verify", "export", "filter"}) {
      const fs::path out = d / "out.bin";
      const Result r = sh("log " + cmd + " " + log.string() + (cmd == "filter" ? " --out " + out.string() : ""));
      EXPECT_EQ(r.code, 2) << c.name << " " << cmd << ": " << r.out;
      EXPECT_NE(r.out.find(log.string() + ": " + at3 + c.says), std::string::npos) << c.name << " " << cmd << ": " << r.out;
      EXPECT_FALSE(fs::exists(out));
    }
  }
  fs::remove_all(d);
}

// A flipped byte in a float field of a run's (version-4) log: one ulp of a velocity, which no physics check
// can see, is caught by its block's checksum; every tool reports that block by byte offset, and
// the records before it were read. The same with the flip resealed passes verify (so it was the
// checksum that saw it); a flip in a checksum record and a log cut at a block boundary are caught.
TEST_F(LogTools, AFlippedByteIsCaughtByItsBlockChecksum) {
  const fs::path good = gas() / "events.bin";
  const matep::LogFile lf = matep::inspect_log(good.string());
  const matep::EventLogHeader& h = lf.header;
  ASSERT_EQ(h.version, matep::kEventLogVersionIdentity);
  const std::uint32_t k = h.block_records;
  ASSERT_EQ(k, matep::kEventLogBlockRecords);
  ASSERT_GT(lf.records, std::uint64_t{2} * k + 1);
  const std::uint64_t rec = k + k / 2;  // in the second block
  const fs::path d = dir() / "flip";
  fs::create_directories(d);
  const fs::path bad = d / "flipped.bin";
  flip_copy(good, bad, matep::record_offset(h, rec) + kOffViAfter + 8, 0x01);  // vi_after.y, lowest byte
  EXPECT_NE(peek_double(bad, matep::record_offset(h, rec) + kOffViAfter + 8),
            peek_double(good, matep::record_offset(h, rec) + kOffViAfter + 8));
  const std::string says = bad.string() + ": corrupt block at byte offset " + std::to_string(matep::block_offset(h, rec)) +
                           " (records " + std::to_string(k) + " to " + std::to_string(2 * k - 1) + "): checksum";
  for (const std::string cmd : {"stats", "verify", "export", "filter"}) {
    const fs::path out = d / "out.bin";
    const Result r = sh("log " + cmd + " " + bad.string() + (cmd == "filter" ? " --out " + out.string() : ""));
    EXPECT_EQ(r.code, 2) << cmd << ": " << r.out;
    EXPECT_NE(r.out.find(says), std::string::npos) << cmd << ": " << r.out;
    EXPECT_FALSE(fs::exists(out));
  }
  {
    matep::EventLogReader reader(bad.string());
    matep::EventRecord r;
    std::uint64_t n = 0;
    try {
      while (reader.next(r)) ++n;
      ADD_FAILURE() << "the flip was not seen";
    } catch (const matep::IoError& e) {
      EXPECT_NE(std::string(e.what()).find(says), std::string::npos) << e.what();
    }
    EXPECT_EQ(n, k);  // the first block, whole
    EXPECT_THROW(reader.record_at(rec), matep::IoError);
    EXPECT_EQ(reader.record_at(k - 1).time, matep::EventLogReader(good.string()).record_at(k - 1).time);
  }
  matep::test::reseal_event_log(bad);
  EXPECT_TRUE(matep::verify_log(bad.string(), nullptr, 1e-9).ok);
  // A flip in the first block's checksum record, then the log cut after its last full block.
  const std::uint64_t trailer = matep::record_offset(h, k - 1) + matep::kEventRecordSize;
  flip_copy(good, bad, trailer + 26, 0x80);
  const Result t = sh("log verify " + bad.string());
  EXPECT_EQ(t.code, 2) << t.out;
  EXPECT_NE(t.out.find("corrupt block at byte offset " + std::to_string(h.data_offset) + " (records 0 to " +
                       std::to_string(k - 1) + ")"),
            std::string::npos)
      << t.out;
  fs::copy_file(good, bad, fs::copy_options::overwrite_existing);
  const std::uint64_t cut = matep::block_offset(h, lf.records);  // the last block's start: whole blocks remain
  fs::resize_file(bad, cut);
  const Result c = sh("log stats " + bad.string());
  EXPECT_EQ(c.code, 2) << c.out;
  EXPECT_NE(c.out.find("truncated event log: the last block, at byte offset " + std::to_string(cut) + ", has 0 bytes"),
            std::string::npos)
      << c.out;
}

// CRC-32C: the standard check value, the table-driven and the accelerated code agree, and values
// chain. The block layout round-trips for every record count around a block length (K = 3 here).
TEST(LogToolsFormat, Crc32cAndTheBlockLayoutRoundTrip) {
  EXPECT_EQ(matep::crc32c("123456789", 9), 0xE3069283u);
  EXPECT_EQ(matep::crc32c_portable("123456789", 9), 0xE3069283u);
  EXPECT_EQ(matep::crc32c("", 0), 0u);
  std::mt19937_64 rng(7);
  std::vector<unsigned char> data(1000);
  for (auto& b : data) b = static_cast<unsigned char>(rng());
  for (const std::size_t n : {1u, 7u, 8u, 9u, 263u, 264u, 1000u}) {
    EXPECT_EQ(matep::crc32c(data.data(), n), matep::crc32c_portable(data.data(), n)) << n;
    EXPECT_EQ(matep::crc32c(data.data() + n / 2, n - n / 2, matep::crc32c(data.data(), n / 2)),
              matep::crc32c(data.data(), n))
        << n;
  }
  const fs::path d = tmpdir("blocks");
  for (std::uint64_t n = 0; n <= 7; ++n) {
    const fs::path log = d / ("k3_" + std::to_string(n) + ".bin");
    std::vector<matep::EventRecord> recs;
    {
      SyntheticLog gen(d / "unused.bin", 10);
      for (std::uint64_t i = 0; i < n; ++i) recs.push_back(gen.next());
      std::FILE* f = std::fopen(log.c_str(), "wb");
      ASSERT_NE(f, nullptr);
      matep::EventLogEncoder enc(f, log.string(), 3, 10, false, 3);
      for (const auto& r : recs) enc.add(r);
      enc.finish();
      std::fclose(f);
    }
    const std::uint64_t blocks = n / 3 + 1;  // the last holds n % 3 records (0..2)
    EXPECT_EQ(fs::file_size(log), matep::kEventLogHeaderSize + n * matep::kEventRecordSize +
                                      blocks * matep::kEventBlockTrailerSize);
    matep::EventLogReader reader(log.string());
    EXPECT_EQ(reader.header().block_records, 3u);
    EXPECT_EQ(reader.records(), n);
    matep::EventRecord r;
    std::uint64_t i = 0;
    while (reader.next(r)) {
      ASSERT_LT(i, n);
      EXPECT_EQ(encode(r), encode(recs[i])) << n << " " << i;
      EXPECT_EQ(slurp(log).substr(matep::record_offset(reader.header(), i), matep::kEventRecordSize), encode(recs[i]));
      ++i;
    }
    EXPECT_EQ(i, n);
    EXPECT_TRUE(matep::verify_log(log.string(), nullptr, 1e-9).ok);
  }
  fs::remove_all(d);
}

// Logs of versions 1 and 2, written by hand with their own layout (no blocks, no checksums), still
// read with every tool; filter writes them as version 3 with the same records (and the fixed-grain
// flag for version 2). A version-2 record with a fixed partner is refused when labelled version 1.
TEST(LogToolsFormat, VersionOneAndTwoLogsStillRead) {
  const fs::path d = tmpdir("old");
  std::vector<matep::EventRecord> recs;
  {
    SyntheticLog s(d / "v1.bin", 10);
    for (int k = 0; k < 20; ++k) {
      recs.push_back(s.next());
      s.write(recs.back());
    }
    SyntheticLog f(d / "v2.bin", 10, matep::kEventLogVersionFixed);
    for (const auto& r : recs) f.write(r);
    f.write(fixed_partner_record(recs.back().time + 1.0));
    SyntheticLog g(d / "v2_as_v1.bin", 10);
    for (const auto& r : recs) g.write(r);
    g.write(fixed_partner_record(recs.back().time + 1.0));
  }
  EXPECT_EQ(fs::file_size(d / "v1.bin"), matep::kEventLogHeaderSize + 20 * matep::kEventRecordSize);
  for (const std::string v : {"v1", "v2"}) {
    const std::string log = (d / (v + ".bin")).string();
    const std::uint64_t n = v == "v1" ? 20 : 21;
    matep::EventLogReader reader(log);
    EXPECT_EQ(reader.header().version, v == "v1" ? 1u : 2u);
    EXPECT_EQ(reader.header().fixed_grains(), v == "v2");
    EXPECT_EQ(reader.records(), n);
    matep::EventRecord r;
    std::uint64_t i = 0;
    while (reader.next(r)) {
      if (i < recs.size()) {
        EXPECT_EQ(encode(r), encode(recs[i])) << v << " " << i;
      }
      ++i;
    }
    EXPECT_EQ(i, n);
    const Result st = sh("log stats " + log);
    EXPECT_EQ(st.code, 0) << st.out;
    EXPECT_NE(st.out.find("version " + v.substr(1)), std::string::npos) << st.out;
    const Result ve = sh("log verify " + log);
    EXPECT_EQ(ve.code, 0) << ve.out;
    const Result ex = sh("log export " + log);
    EXPECT_EQ(ex.code, 0) << ex.out;
    EXPECT_EQ(count_lines(ex.out), n + 1);
    const fs::path out = d / (v + "_filtered.bin");
    ASSERT_EQ(sh("log filter " + log + " --out " + out.string()).code, 0);
    matep::EventLogReader back(out.string());
    EXPECT_EQ(back.header().version, matep::kEventLogVersionChecked);
    EXPECT_EQ(back.header().fixed_grains(), v == "v2");
    matep::EventLogReader again(log);
    matep::EventRecord a, b;
    std::uint64_t same = 0;
    while (again.next(a) && back.next(b)) same += encode(a) == encode(b);
    EXPECT_EQ(same, n);
    EXPECT_TRUE(matep::verify_log(out.string(), nullptr, 1e-9).ok);
  }
  const Result bad = sh("log verify " + (d / "v2_as_v1.bin").string());
  EXPECT_EQ(bad.code, 2) << bad.out;
  EXPECT_NE(bad.out.find("corrupt event record 20 at byte offset " +
                         std::to_string(matep::record_offset(matep::test::v1_header(), 20)) + ": mj = inf"),
            std::string::npos)
      << bad.out;
  fs::remove_all(d);
}

// Version 4: each particle's group and material after the header. It reads back, survives `log
// filter`, shifts the records by its length, and a flipped byte, an index beyond the names or a
// length beyond the file is refused with its byte offset.
TEST(LogToolsFormat, VersionFourCarriesEachParticlesGroupAndMaterial) {
  const fs::path d = tmpdir("identity");
  matep::EventLogIdentity id;
  id.groups = {"bed", "inlet.feed"};
  id.materials = {"glass", "steel"};
  for (std::uint16_t i = 0; i < 10; ++i) {
    id.group.push_back(i < 6 ? 0 : 1);
    id.material.push_back(i % 2);
  }
  const fs::path log = d / "v4.bin";
  std::vector<matep::EventRecord> recs;
  {
    SyntheticLog gen(d / "unused.bin", 10);
    for (int k = 0; k < 5; ++k) recs.push_back(gen.next());
    std::FILE* f = std::fopen(log.c_str(), "wb");
    ASSERT_NE(f, nullptr);
    matep::EventLogEncoder enc(f, log.string(), 3, 10, false, 3, &id);
    for (const auto& r : recs) enc.add(r);
    enc.finish();
    std::fclose(f);
  }
  // 16 + names (2+3, 2+10, 2+5, 2+5) + 40 = 87 bytes, padded to 88, and the 8-byte checksum record.
  const std::uint64_t section = 96;
  EXPECT_EQ(fs::file_size(log), matep::kEventLogHeaderSize + section + 5 * matep::kEventRecordSize +
                                    2 * matep::kEventBlockTrailerSize);
  {
    matep::EventLogReader reader(log.string());
    EXPECT_EQ(reader.header().version, matep::kEventLogVersionIdentity);
    EXPECT_EQ(reader.header().data_offset, matep::kEventLogHeaderSize + section);
    EXPECT_EQ(reader.identity().groups, id.groups);
    EXPECT_EQ(reader.identity().materials, id.materials);
    EXPECT_EQ(reader.identity().group, id.group);
    EXPECT_EQ(reader.identity().material, id.material);
    matep::EventRecord r;
    for (const auto& want : recs) {
      ASSERT_TRUE(reader.next(r));
      EXPECT_EQ(encode(r), encode(want));
    }
    EXPECT_FALSE(reader.next(r));
  }
  EXPECT_TRUE(matep::verify_log(log.string(), nullptr, 1e-9).ok);
  const fs::path out = d / "filtered.bin";
  ASSERT_EQ(sh("log filter " + log.string() + " --out " + out.string()).code, 0);
  {
    matep::EventLogReader back(out.string());
    EXPECT_EQ(back.header().version, matep::kEventLogVersionIdentity);
    EXPECT_EQ(back.identity().group, id.group);
    EXPECT_EQ(back.records(), 5u);
  }
  // A flipped byte in a name: the section's checksum.
  flip_copy(log, d / "flipped.bin", matep::kEventLogHeaderSize + 18, 0x01);
  Result r = sh("log stats " + (d / "flipped.bin").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.out.find("corrupt event log identity section at byte offset " +
                       std::to_string(matep::kEventLogHeaderSize + section - 8) + ": checksum"),
            std::string::npos)
      << r.out;
  // A group index beyond the names, its checksum made right: named with the particle.
  {
    std::string bytes = slurp(log);
    const std::size_t at = matep::kEventLogHeaderSize + 16 + 5 + 12 + 7 + 7 + 4 * 3;  // particle 3's group
    bytes[at] = 2;
    const std::uint32_t crc = matep::crc32c(bytes.data() + matep::kEventLogHeaderSize, section - 8);
    std::memcpy(bytes.data() + matep::kEventLogHeaderSize + section - 8, &crc, 4);
    write_text(d / "index.bin", bytes);
    r = sh("log verify " + (d / "index.bin").string());
    EXPECT_EQ(r.code, 2);
    EXPECT_NE(r.out.find("particle 3 has group 2 and material 1 (of 2 and 2)"), std::string::npos) << r.out;
  }
  // A section length beyond the file (header checksum made right).
  {
    std::string bytes = slurp(log);
    const std::uint32_t huge = 1u << 30;
    std::memcpy(bytes.data() + 36, &huge, 4);
    const std::uint32_t crc = matep::crc32c(bytes.data(), 60);
    std::memcpy(bytes.data() + 60, &crc, 4);
    write_text(d / "long.bin", bytes);
    r = sh("log stats " + (d / "long.bin").string());
    EXPECT_EQ(r.code, 2);
    EXPECT_NE(r.out.find("truncated event log: the identity section at byte offset 64 has 1073741824 bytes"),
              std::string::npos)
        << r.out;
  }
  fs::remove_all(d);
}

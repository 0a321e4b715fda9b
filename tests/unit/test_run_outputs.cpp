// A run's outputs as a set (io/run_folder.hpp, io/checked_file.hpp, io/interrupt.hpp): checked
// writes, a folder replaced only by a complete new set, the lock against a second run, and
// SIGINT / SIGTERM stopping each method at a whole step with every output written.
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "io/checked_file.hpp"
#include "io/run_folder.hpp"
#include "tests/support/cli.hpp"

namespace fs = std::filesystem;

namespace {

using matep::test::run_cli;
using matep::test::spawn_cli;
using matep::test::wait_exit;
using matep::test::wait_for;
using matep::test::slurp;
const std::string& kCases = matep::test::kCasesDir;

// The value of a top-level number or string key of summary.json ("" when absent).
std::string summary_value(const std::string& json, const std::string& key) {
  const std::string tag = "\"" + key + "\": ";
  const auto at = json.find(tag);
  if (at == std::string::npos) return "";
  const auto from = at + tag.size();
  const auto to = json.find_first_of(",\n", from);
  std::string v = json.substr(from, to - from);
  if (!v.empty() && v.front() == '"') v = v.substr(1, v.size() - 2);
  return v;
}

std::vector<std::string> lines_of(const std::string& s) {
  std::vector<std::string> out;
  std::istringstream in(s);
  for (std::string l; std::getline(in, l);) out.push_back(l);
  return out;
}

// The folder holds one run's complete set: the summary's time is the last thermo row's, the final
// state has a row per grain, the event log is whole and every block checks. Returns the summary's end_time.
double expect_one_complete_set(const fs::path& d, bool staging_may_remain = false) {
  const std::string summary = slurp(d / "summary.json");
  EXPECT_FALSE(summary.empty()) << d;
  const double reached = std::stod(summary_value(summary, "time_reached"));
  const auto thermo = lines_of(slurp(d / "thermo.csv"));
  EXPECT_GE(thermo.size(), 2u);
  if (thermo.size() >= 2) {
    EXPECT_EQ(std::stod(thermo.back().substr(0, thermo.back().find(','))), reached) << d;
  }
  const auto state = lines_of(slurp(d / "final_state.csv"));
  EXPECT_EQ(state.size(), std::stoul(summary_value(summary, "grains_at_end")) + 1) << d;
  if (fs::exists(d / "events.bin")) {  // whole, every block's checksum right
    const auto stats = run_cli("log stats " + (d / "events.bin").string());
    EXPECT_EQ(stats.code, 0) << stats.out;
  }
  if (!staging_may_remain) {
    EXPECT_FALSE(fs::exists(d.string() + ".running")) << d;
  }
  return std::stod(summary_value(summary, "end_time"));
}

// A fresh folder ROOT/NAME holding a previous run's complete set (EDM, end_time 0.1); returns
// the folder and that run's summary.json.
std::pair<fs::path, std::string> previous_set(const fs::path& root, const std::string& name) {
  const fs::path d = root / name;
  const auto r = run_cli("run " + kCases + "elastic_gas.toml --set run.end_time=0.1 --quiet --out " + d.string());
  EXPECT_EQ(r.code, 0) << r.out;
  return {d, slurp(d / "summary.json")};
}

}  // namespace

TEST(CheckedFile, AFullDiskIsAnErrorNamingTheFileAndTheOsReason) {
  // /dev/full accepts an open and fails every write with ENOSPC: stdio buffers the rows, so the
  // failure surfaces at the flush or at close, and both are checked.
  matep::CheckedFile f("/dev/full", "w");
  f.print("{},{}\n", 1.5, 2);
  try {
    f.close();
    FAIL() << "close did not report the full disk";
  } catch (const matep::WriteError& e) {
    EXPECT_NE(std::string(e.what()).find("/dev/full: write failed: No space left on device"), std::string::npos)
        << e.what();
  }
  matep::CheckedFile g("/dev/full", "w");
  g.puts("row\n");
  EXPECT_THROW(g.flush(), matep::WriteError);
}

TEST(RunOutputs, ANewRunReplacesThePreviousSetWholeAndKeepsTheUsersFiles) {
  const fs::path root = matep::test::fresh_dir("outputs_replace");
  const fs::path d = root / "gas";
  // First run: an event log and snapshots.
  auto r = run_cli("run " + kCases + "elastic_gas.toml --set run.end_time=0.2 --set output.snapshot_interval=0.1 --out " +
                   d.string());
  ASSERT_EQ(r.code, 0) << r.out;
  ASSERT_TRUE(fs::exists(d / "events.bin"));
  ASSERT_TRUE(fs::exists(d / "snapshots.pvd"));
  { std::ofstream(d / "notes.txt") << "mine\n"; }
  fs::create_directories(d / "plots");
  { std::ofstream(d / "plots" / "a.png") << "png"; }
  // Second run: no log, no snapshots. None of the first run's files may remain beside its own.
  r = run_cli("run " + kCases + "elastic_gas.toml --set run.end_time=0.3 --set output.events=false --quiet --out " +
              d.string());
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(expect_one_complete_set(d), 0.3);
  EXPECT_FALSE(fs::exists(d / "events.bin"));
  EXPECT_FALSE(fs::exists(d / "snapshots.pvd"));
  EXPECT_FALSE(fs::exists(d / "snapshots"));
  EXPECT_EQ(slurp(d / "notes.txt"), "mine\n");
  EXPECT_EQ(slurp(d / "plots" / "a.png"), "png");
  // Nothing of the run's machinery is left behind.
  for (const auto& e : fs::directory_iterator(root)) EXPECT_EQ(e.path().filename(), "gas");
  EXPECT_TRUE(matep::is_run_output("thermo.csv"));
  EXPECT_FALSE(matep::is_run_output("notes.txt"));
  fs::remove_all(root);
}

TEST(RunOutputs, AFileSizeLimitEndsWithExitStatus4AndKeepsThePreviousSet) {
  const fs::path root = matep::test::fresh_dir("outputs_fsize");
  const auto [d, before] = previous_set(root, "gas");
  // The event log of a 2 s run is ~80 MB; a 256 KiB file-size limit stops its writer.
  const std::string cmd = "bash -c 'ulimit -f 256; exec " + std::string(MATEP_CLI) + " run " + kCases +
                          "elastic_gas.toml --set run.end_time=2 --quiet --out " + d.string() + "' 2>&1";
  FILE* p = popen(cmd.c_str(), "r");
  std::string out;
  char buf[4096];
  while (p && std::fgets(buf, sizeof buf, p)) out += buf;
  const int st = p ? pclose(p) : -1;
  ASSERT_TRUE(WIFEXITED(st)) << out;
  EXPECT_EQ(WEXITSTATUS(st), 4) << out;
  EXPECT_NE(out.find("events.bin: write failed: File too large"), std::string::npos) << out;
  EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << out;
  // The previous set is untouched and the incomplete one is gone.
  EXPECT_EQ(slurp(d / "summary.json"), before);
  EXPECT_EQ(expect_one_complete_set(d), 0.1);
  EXPECT_FALSE(fs::exists(d.string() + ".running"));
  fs::remove_all(root);
}

TEST(RunOutputs, AFolderThatIsNotOneOrIsTheWorkingFolderIsRefused) {
  const fs::path root = matep::test::fresh_dir("outputs_refuse");
  { std::ofstream(root / "file") << "x"; }
  auto r = run_cli("run " + kCases + "elastic_gas.toml --out " + (root / "file").string());
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("exists and is not a folder"), std::string::npos) << r.out;
  EXPECT_EQ(slurp(root / "file"), "x");
  r = run_cli("run " + kCases + "elastic_gas.toml --out .");
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("working folder"), std::string::npos) << r.out;
  fs::remove_all(root);
}

// Each method, stopped by SIGINT or SIGTERM well before its end: exit 130 / 143, and the folder
// holds a complete set whose summary says "interrupted" at the time of the last thermo row.
TEST(RunOutputs, SigintAndSigtermStopEachMethodWithEveryOutputWritten) {
  struct Case {
    const char* scene;
    int sig;
  };
  const Case cases[] = {{"elastic_gas.toml", SIGINT}, {"soft_gas.toml", SIGTERM}, {"cooling_clusters.toml", SIGINT}};
  for (const Case& c : cases) {
    SCOPED_TRACE(c.scene);
    const fs::path root = matep::test::fresh_dir("outputs_signal");
    const fs::path d = root / "out";
    const pid_t pid = spawn_cli({"run", kCases + c.scene, "--set", "run.end_time=1000", "--set",
                                 "output.snapshot_interval=0", "--quiet", "--out", d.string()},
                                root / "log.txt");
    ASSERT_GT(pid, 0);
    ASSERT_TRUE(wait_for(d.string() + ".running/thermo.csv"));
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
    ::kill(pid, c.sig);
    const int code = wait_exit(pid);
    const std::string log = slurp(root / "log.txt");
    EXPECT_EQ(code, 128 + c.sig) << log;
    EXPECT_NE(log.find(c.sig == SIGINT ? "stopped by SIGINT at t = " : "stopped by SIGTERM at t = "),
              std::string::npos)
        << log;
    EXPECT_EQ(expect_one_complete_set(d), 1000.0);
    const std::string summary = slurp(d / "summary.json");
    EXPECT_EQ(summary_value(summary, "status"), "interrupted");
    const double reached = std::stod(summary_value(summary, "time_reached"));
    EXPECT_GT(reached, 0.0);
    EXPECT_LT(reached, 1000.0);
    if (std::string(c.scene) == "soft_gas.toml") {  // TDM stops at a whole step
      const double dt = std::stod(summary.substr(summary.find("\"dt\": ") + 6));
      EXPECT_NEAR(reached / dt, std::round(reached / dt), 1e-6);
    }
    fs::remove_all(root);
  }
}

TEST(RunOutputs, ASecondRunIntoAFolderALiveRunHoldsIsRefused) {
  const fs::path root = matep::test::fresh_dir("outputs_lock");
  const fs::path d = root / "out";
  const pid_t pid = spawn_cli({"run", kCases + "elastic_gas.toml", "--set", "run.end_time=1000", "--quiet", "--out",
                               d.string()},
                              root / "log.txt");
  ASSERT_GT(pid, 0);
  ASSERT_TRUE(wait_for(d.string() + ".running/thermo.csv"));
  const auto r = run_cli("run " + kCases + "elastic_gas.toml --set run.end_time=0.1 --out " + d.string());
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("another matep run (pid " + std::to_string(pid) + ") is writing into this folder"),
            std::string::npos)
      << r.out;
  ::kill(pid, SIGINT);
  EXPECT_EQ(wait_exit(pid), 130);
  EXPECT_EQ(expect_one_complete_set(d), 1000.0);  // the refused run touched nothing
  // Once the first has ended, the folder is free again.
  const auto again = run_cli("run " + kCases + "elastic_gas.toml --set run.end_time=0.1 --quiet --out " + d.string());
  EXPECT_EQ(again.code, 0) << again.out;
  EXPECT_EQ(expect_one_complete_set(d), 0.1);
  fs::remove_all(root);
}

// A run killed outright (SIGKILL, or a second Ctrl-C) leaves the previous set in place; the next
// run clears the staging folder it left.
TEST(RunOutputs, AKilledRunLeavesThePreviousSetAndTheNextRunClearsItsStaging) {
  const fs::path root = matep::test::fresh_dir("outputs_kill");
  const auto [d, before] = previous_set(root, "out");
  // The killed run's staging is still there when the second run starts. A marker left among its
  // outputs (which the next run deletes) tells the second run's own thermo.csv from the killed
  // one's: a signal sent before the second run has cleared the staging could come before it has
  // installed its handlers (seen under the sanitizers, whose start-up is slow).
  const fs::path staging = d.string() + ".running";
  for (int sig : {SIGKILL, SIGINT}) {
    const pid_t pid = spawn_cli({"run", kCases + "elastic_gas.toml", "--set", "run.end_time=1000", "--quiet",
                                 "--out", d.string()},
                                root / "log.txt");
    const auto t0 = std::chrono::steady_clock::now();
    while (fs::exists(staging / "snapshots/stale") || !fs::exists(staging / "thermo.csv")) {
      ASSERT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 60.0);
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    if (sig == SIGKILL) {
      ::kill(pid, SIGKILL);
      EXPECT_EQ(wait_exit(pid), -SIGKILL);
      EXPECT_EQ(slurp(d / "summary.json"), before);
      EXPECT_TRUE(fs::exists(d.string() + ".running/thermo.csv"));  // the partial files, for a look
      fs::create_directories(staging / "snapshots");  // an output folder: the next run deletes it
      std::ofstream(staging / "snapshots/stale") << "left by the killed run\n";
    } else {
      // Two signals at once: the second ends the process before it publishes anything.
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
      ::kill(pid, SIGINT);
      ::kill(pid, SIGINT);
      const int code = wait_exit(pid);
      EXPECT_EQ(code, 130);
      const std::string now = slurp(d / "summary.json");
      // Either the first signal's complete set made it out before the second, or the previous one stays.
      // (Two signals sent together usually arrive as one: the run stops and publishes. When they
      // arrive apart, the second stops it at once and its staging stays for the next run to clear.)
      if (now != before) {
        EXPECT_EQ(summary_value(now, "status"), "interrupted");
      }
      expect_one_complete_set(d, /*staging_may_remain=*/now == before);
    }
  }
  const auto r = run_cli("run " + kCases + "elastic_gas.toml --set run.end_time=0.2 --quiet --out " + d.string());
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(expect_one_complete_set(d), 0.2);
  fs::remove_all(root);
}

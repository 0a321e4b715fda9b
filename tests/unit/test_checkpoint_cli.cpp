// Checkpoints through `matep run` (io/checkpoint.hpp): a run stopped by a signal or killed outright
// and continued with --resume writes the same files, byte for byte, as the run that never stopped;
// a checkpoint of another scene, version or method, a corrupt or cut one, is refused naming what
// differs, and nothing already written is lost.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "io/checkpoint.hpp"
#include "tests/support/cli.hpp"

namespace fs = std::filesystem;

namespace {

using matep::test::run_cli;
using matep::test::spawn_cli;
using matep::test::wait_exit;
using matep::test::wait_for;
using matep::test::slurp;
const std::string& kCases = matep::test::kCasesDir;

std::vector<std::string> words(const std::string& s) {
  std::vector<std::string> out;
  std::size_t at = 0;
  while (at < s.size()) {
    const auto sp = s.find(' ', at);
    out.push_back(s.substr(at, sp == std::string::npos ? std::string::npos : sp - at));
    if (sp == std::string::npos) break;
    at = sp + 1;
  }
  return out;
}

// Every output but the summary (wall times) and the checkpoint itself, byte for byte.
void expect_same_outputs(const fs::path& a, const fs::path& b) {
  for (const char* f : {"thermo.csv", "final_state.csv", "events.bin", "outflow.csv", "snapshots.pvd"}) {
    ASSERT_EQ(fs::exists(a / f), fs::exists(b / f)) << f;
    if (fs::exists(a / f)) {
      EXPECT_TRUE(slurp(a / f) == slurp(b / f)) << f << " differs between " << a << " and " << b;
    }
  }
  if (fs::exists(a / "snapshots")) {
    for (const auto& e : fs::directory_iterator(a / "snapshots")) {
      EXPECT_TRUE(slurp(e.path()) == slurp(b / "snapshots" / e.path().filename())) << e.path();
    }
  }
}

struct Case {
  const char* scene;
  const char* sets;
};

// Each method, with every output a run can write (the contacts' impulse tally of the hard grains
// included): stopped by SIGINT at a random moment, resumed.
TEST(CheckpointCli, ResumedAfterASignalEachMethodWritesTheSameFiles) {
  const Case cases[] = {
      {"elastic_gas.toml", "--set run.end_time=40 --set output.thermo_interval=0.1 --set output.events=true "
                           "--set output.snapshot_interval=10 --set output.contacts=true"},
      {"heap.toml", "--set run.end_time=1.2 --set output.thermo_interval=0.01 --set output.snapshot_interval=0.4 "
                    "--set output.contacts=true"},
      {"pour_settle.toml", "--set run.end_time=0.8 --set particles.beads.count=600 --set output.thermo_interval=0.01 "
                           "--set output.events=true --set output.snapshot_interval=0.2 --set output.contacts=true"},
  };
  std::mt19937_64 rng(std::random_device{}());
  for (const Case& c : cases) {
    SCOPED_TRACE(c.scene);
    const fs::path root = matep::test::fresh_dir("checkpoint_signal");
    const std::string base = "run " + kCases + c.scene + " " + c.sets + " --quiet --out ";
    const auto t0 = std::chrono::steady_clock::now();
    const auto whole = run_cli(base + (root / "whole").string());
    ASSERT_EQ(whole.code, 0) << whole.out;
    const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    // Stopped somewhere in its middle half.
    std::vector<std::string> args = words(std::string("run ") + kCases + c.scene + " " + c.sets + " --quiet --out " +
                                          (root / "part").string());
    const pid_t pid = spawn_cli(args, root / "log.txt");
    ASSERT_TRUE(wait_for(root / "part.running" / "thermo.csv"));
    const double at = wall * (0.25 + 0.5 * std::uniform_real_distribution<double>()(rng));
    std::this_thread::sleep_for(std::chrono::duration<double>(at));
    ::kill(pid, SIGINT);
    const int code = wait_exit(pid);
    if (code == 0) continue;  // it ended first (a loaded machine): nothing to continue
    ASSERT_EQ(code, 130) << slurp(root / "log.txt");
    ASSERT_TRUE(fs::exists(root / "part" / "checkpoint.bin"));
    const auto resumed = run_cli(base + (root / "part").string() + " --resume " + (root / "part/checkpoint.bin").string());
    ASSERT_EQ(resumed.code, 0) << resumed.out;
    expect_same_outputs(root / "whole", root / "part");
    fs::remove_all(root);
  }
}

// Killed outright while it keeps checkpoints: the last one, with the outputs it continues, is
// kept as DIR.killed by the next run into DIR, and resuming it gives the uninterrupted files.
TEST(CheckpointCli, AKilledRunResumesFromItsLastCheckpoint) {
  const fs::path root = matep::test::fresh_dir("checkpoint_kill");
  const std::string sets = " --set run.end_time=60 --set output.thermo_interval=0.1 --set output.events=true "
                           "--set output.checkpoint_interval=2";
  const auto whole = run_cli("run " + kCases + "elastic_gas.toml" + sets + " --quiet --out " + (root / "whole").string());
  ASSERT_EQ(whole.code, 0) << whole.out;
  const fs::path d = root / "out";
  const pid_t pid = spawn_cli(words("run " + kCases + "elastic_gas.toml" + sets + " --quiet --out " + d.string()),
                              root / "log.txt");
  ASSERT_TRUE(wait_for(d.string() + ".running/checkpoint.bin"));
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  ::kill(pid, SIGKILL);
  ASSERT_EQ(wait_exit(pid), -SIGKILL);
  EXPECT_FALSE(fs::exists(d));  // nothing published
  // The checkpoint in the killed run's staging folder loads (whole, its checksum right).
  const matep::Checkpoint c = matep::read_checkpoint(d.string() + ".running/checkpoint.bin");
  EXPECT_GT(c.time, 0.0);
  EXPECT_TRUE(c.events.has_value());
  const auto resumed = run_cli("run " + kCases + "elastic_gas.toml" + sets + " --quiet --out " + d.string() +
                               " --resume " + d.string() + ".running/checkpoint.bin");
  ASSERT_EQ(resumed.code, 0) << resumed.out;
  EXPECT_TRUE(fs::exists(d.string() + ".killed/checkpoint.bin"));
  EXPECT_FALSE(fs::exists(d.string() + ".running"));
  expect_same_outputs(root / "whole", d);
  fs::remove_all(root);
}

// One refusal: exit status 2, one line naming the checkpoint and `what`, the folder untouched.
void expect_refused(const std::string& args, const fs::path& folder, const std::string& what) {
  const std::string before = slurp(folder / "summary.json");
  const auto r = run_cli(args);
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find(what), std::string::npos) << r.out;
  EXPECT_EQ(slurp(folder / "summary.json"), before);
  EXPECT_FALSE(fs::exists(folder.string() + ".running"));
}

TEST(CheckpointCli, AnotherSceneVersionMethodOrACorruptFileIsRefusedNamingWhatDiffers) {
  const fs::path root = matep::test::fresh_dir("checkpoint_refused");
  const fs::path d = root / "gas";
  const std::string scene = kCases + "elastic_gas.toml";
  const auto first = run_cli("run " + scene + " --set run.end_time=0.5 --quiet --out " + d.string());
  ASSERT_EQ(first.code, 0) << first.out;
  const fs::path ck = d / "checkpoint.bin";
  const std::string bytes = slurp(ck);
  ASSERT_GT(bytes.size(), 100u);
  const std::string resume = " --quiet --out " + d.string() + " --resume ";
  // A longer run continues it (what --resume is for at the end of a run).
  {
    const fs::path longer = root / "longer";
    fs::copy(d, longer, fs::copy_options::recursive);
    const auto r = run_cli("run " + scene + " --set run.end_time=0.7 --quiet --out " + longer.string() + " --resume " +
                           (longer / "checkpoint.bin").string());
    EXPECT_EQ(r.code, 0) << r.out;
    const auto full = run_cli("run " + scene + " --set run.end_time=0.7 --quiet --out " + (root / "full").string());
    ASSERT_EQ(full.code, 0);
    EXPECT_EQ(slurp(longer / "final_state.csv"), slurp(root / "full" / "final_state.csv"));
    // Its rows carry on at the same interval.
    auto times = [](const std::string& csv) {
      std::vector<std::string> t;
      std::size_t at = csv.find('\n') + 1;
      while (at < csv.size()) {
        t.push_back(csv.substr(at, csv.find(',', at) - at));
        at = csv.find('\n', at) + 1;
      }
      return t;
    };
    EXPECT_EQ(times(slurp(longer / "thermo.csv")), times(slurp(root / "full" / "thermo.csv")));
  }
  // matep check --resume: whole and for this scene, or not.
  {
    const auto ok = run_cli("check " + scene + " --set run.end_time=0.5 --resume " + ck.string());
    EXPECT_EQ(ok.code, 0) << ok.out;
    EXPECT_NE(ok.out.find("a \"edm\" run at t = 0.5; continues thermo.csv"), std::string::npos) << ok.out;
    EXPECT_NE(ok.out.find("scene is valid and the checkpoint continues it"), std::string::npos) << ok.out;
    const auto other = run_cli("check " + scene + " --set run.end_time=0.5 --set run.seed=3 --resume " + ck.string());
    EXPECT_EQ(other.code, 2) << other.out;
    EXPECT_NE(other.out.find("run.seed: checkpoint 7, this scene 3"), std::string::npos) << other.out;
  }
  // Another scene: the key that differs, both values.
  expect_refused("run " + scene + " --set run.end_time=0.5 --set material.hard.restitution=0.8" + resume + ck.string(),
                 d, "written for another scene than " + scene + ": material.hard.restitution: checkpoint 1.0, this scene 0.8");
  // Another method.
  expect_refused("run " + scene + " --set run.end_time=0.5 --set run.method=tdm --set material.hard.stiffness=1e5" +
                     resume + ck.string(),
                 d, "written by a \"edm\" run in 3D");
  auto write = [&](const std::string& name, const std::string& content) {
    const fs::path p = root / name;
    std::ofstream(p, std::ios::binary) << content;
    return p.string();
  };
  std::string flipped = bytes;
  flipped[bytes.size() / 2] ^= 0x10;
  expect_refused("run " + scene + " --set run.end_time=0.5" + resume + write("flipped.bin", flipped), d,
                 "the checksum does not match (the file is corrupt)");
  expect_refused("run " + scene + " --set run.end_time=0.5" + resume + write("cut.bin", bytes.substr(0, bytes.size() / 3)),
                 d, "(cut short or extended)");
  std::string later = bytes;  // a version this matep does not read: the next one
  later[8] = static_cast<char>(matep::kCheckpointVersion + 1);
  expect_refused("run " + scene + " --set run.end_time=0.5" + resume + write("later.bin", later), d,
                 fmt::format("checkpoint version {}, this matep reads version {}", matep::kCheckpointVersion + 1,
                             matep::kCheckpointVersion));
  expect_refused("run " + scene + " --set run.end_time=0.5" + resume + write("other.bin", "id,x,y\n"), d,
                 "not a matep checkpoint");
  expect_refused("run " + scene + " --set run.end_time=0.5" + resume + (root / "absent.bin").string(), d, "no such file");
  // The outputs it continues are gone or changed.
  {
    const fs::path lone = root / "lone";
    fs::create_directories(lone);
    fs::copy_file(ck, lone / "checkpoint.bin");
    expect_refused("run " + scene + " --set run.end_time=0.5" + resume + (lone / "checkpoint.bin").string(), d,
                   "thermo.csv: cannot continue thermo.csv: it is missing");
    std::ofstream(lone / "thermo.csv") << "time,kinetic_energy\n0,1\n";
    expect_refused("run " + scene + " --set run.end_time=0.5" + resume + (lone / "checkpoint.bin").string(), d,
                   "thermo.csv: does not begin with the");
  }
  fs::remove_all(root);
}

// A soft run resumes with the thread count it was saved with (its sums run in that order).
TEST(CheckpointCli, ATdmCheckpointNeedsItsThreadCount) {
  const fs::path root = matep::test::fresh_dir("checkpoint_threads");
  const fs::path d = root / "gas";
  const std::string scene = kCases + "soft_gas.toml --set run.end_time=0.05";
  const auto first = run_cli("run " + scene + " --set run.threads=2 --quiet --out " + d.string());
  ASSERT_EQ(first.code, 0) << first.out;
  expect_refused("run " + scene + " --set run.threads=1 --quiet --out " + d.string() + " --resume " +
                     (d / "checkpoint.bin").string(),
                 d, "");
  const auto r = run_cli("run " + scene + " --set run.threads=1 --quiet --out " + d.string() + " --resume " +
                         (d / "checkpoint.bin").string());
  EXPECT_NE(r.out.find("run.threads: checkpoint 2, this scene 1"), std::string::npos) << r.out;
  fs::remove_all(root);
}

}  // namespace

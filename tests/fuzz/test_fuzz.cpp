// The scene reader, the CSV particle reader, the event-log reader and the checkpoint reader under
// the mutation fuzzer (tests/fuzz/fuzz_driver.hpp): every input must load or be refused with
// SceneError / IoError / std::invalid_argument (CSV: CsvError; events.bin and checkpoints: IoError);
// never a crash, a hang (> 2 s) or more than 1 GiB. The corpus is tests/fuzz/corpus/ (small scenes
// from cases/ and tests/data, small event logs made by tests/fuzz/make_event_corpus.py, small
// checkpoints made by tests/fuzz/make_checkpoint_corpus.sh, and each input that once broke a reader).
//
// A short run by default; MATEP_FUZZ_EXECS=N (per target) and MATEP_FUZZ_SECONDS=S run longer,
// MATEP_FUZZ_SEED=K another sequence. Each run prints its executions per second. A failing input is
// written to MATEP_FUZZ_CRASH_DIR (default: the system's temporary folder) for the corpus.
#include <gtest/gtest.h>

#include <sys/mman.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>

#include "io/log_tools.hpp"
#include "io/checkpoint.hpp"
#include "io/output.hpp"
#include "io/scene.hpp"
#include "io/scene_csv.hpp"
#include "tests/fuzz/fuzz_driver.hpp"

namespace fs = std::filesystem;

namespace {

const fs::path kCorpus = fs::path(MATEP_SOURCE_DIR) / "tests/fuzz/corpus";

std::uint64_t env_or(const char* name, std::uint64_t def) {
  const char* v = std::getenv(name);
  return v && *v ? std::strtoull(v, nullptr, 10) : def;
}

#ifdef MATEP_SANITIZED
constexpr bool kLimitMemory = false;  // the sanitizers reserve terabytes of address space
constexpr std::uint64_t kShortRun = 1500;
// Seconds an input may take. Under the sanitizers a scene that places the most grains the memory check
// accepts (about 1.5 s in Release on a busy machine) takes over ten times longer.
constexpr unsigned kAlarm = 30;
#else
constexpr bool kLimitMemory = true;
constexpr std::uint64_t kShortRun = 60000;
constexpr unsigned kAlarm = 2;
#endif

void scene_target(const std::string& text) {
  try {
    matep::load_scene_string(text, "fuzz.toml", kCorpus.string(), {});
  } catch (const matep::SceneError&) {
  } catch (const matep::IoError&) {
  } catch (const std::invalid_argument&) {
  }
}

void csv_target(const std::string& text) {
  try {
    matep::scene_detail::parse_csv(text);
  } catch (const matep::scene_detail::CsvError&) {
  }
}

// The event-log reader reads from a file: each input is written to this one, an in-memory file
// (memfd; a file on disk costs milliseconds an input to truncate) that the forked workers inherit
// and open as /proc/self/fd/N, then read record by record, by random access, and by `matep log
// stats` and `verify`.
int g_events_fd = -1;
std::string g_events_path;

// Half of the inputs (by a bit of their CRC) get their header and block checksums recomputed, so
// that a mutation reaches the header and record checks instead of stopping at the first checksum.
void fix_checksums(std::string& s) {
  auto u32 = [&](std::size_t at) {
    std::uint32_t v;
    std::memcpy(&v, s.data() + at, 4);
    return v;
  };
  auto put = [&](std::size_t at, std::uint32_t v) { std::memcpy(s.data() + at, &v, 4); };
  if (s.size() < matep::kEventLogHeaderSize || s.compare(0, 8, matep::kEventLogMagic, 8) != 0 ||
      (u32(8) != 3 && u32(8) != 4))
    return;
  put(60, matep::crc32c(s.data(), 60));
  std::size_t start = matep::kEventLogHeaderSize;  // version 4: the identity section first
  if (u32(8) == 4) {
    const std::size_t n = u32(36);
    if (n < 8 || start + n > s.size()) return;
    put(start + n - 8, matep::crc32c(s.data() + start, n - 8));
    start += n;
  }
  const std::size_t k = u32(32), rec = matep::kEventRecordSize, tr = matep::kEventBlockTrailerSize;
  if (k == 0 || k > matep::kEventLogMaxBlockRecords) return;
  for (std::size_t off = start; off + tr <= s.size();) {
    std::size_t n = k;  // a full block, or the last one (what is left)
    if (off + k * rec + tr > s.size() || s.compare(off + k * rec, 8, matep::kEventBlockMagic, 8) != 0)
      n = (s.size() - off - tr) / rec;
    const std::size_t t = off + n * rec;
    put(t + 24, matep::crc32c(s.data() + t, 24, matep::crc32c(s.data() + off, n * rec)));
    off = t + tr;
  }
}

void events_target(const std::string& input) {
  std::string bytes = input;
  if (matep::crc32c(input.data(), input.size()) & 1) fix_checksums(bytes);
  if (::ftruncate(g_events_fd, 0) != 0 ||
      ::pwrite(g_events_fd, bytes.data(), bytes.size(), 0) != static_cast<ssize_t>(bytes.size()))
    throw std::logic_error("cannot write " + g_events_path);  // reported as a failure, not hidden
  try {
    matep::EventLogReader r(g_events_path);
    matep::EventRecord rec;
    while (r.next(rec)) {
    }
    if (r.records() > 0) {
      r.record_at(0);
      r.record_at(r.records() / 2);
      r.record_at(r.records() - 1);
    }
  } catch (const matep::IoError&) {
  }
  try {
    matep::compute_log_stats(g_events_path, 16);
  } catch (const matep::IoError&) {
  }
  try {
    matep::verify_log(g_events_path, nullptr);
  } catch (const matep::IoError&) {
  }
}

// The checkpoint reader (io/checkpoint.hpp) on bytes: half of the inputs get their length field
// and trailing CRC-32C recomputed so that a mutation reaches the body's parts (tags, lengths,
// optional outputs) instead of stopping at the checksum.
void checkpoint_target(const std::string& input) {
  std::vector<std::uint8_t> bytes(input.begin(), input.end());
  if ((matep::crc32c(input.data(), input.size()) & 1) && bytes.size() >= 28 &&
      std::memcmp(bytes.data(), matep::kCheckpointMagic, 8) == 0) {
    const std::uint64_t n = bytes.size() - 28;
    std::memcpy(bytes.data() + 16, &n, 8);
    const std::uint32_t crc = matep::crc32c(bytes.data(), bytes.size() - 4);
    std::memcpy(bytes.data() + bytes.size() - 4, &crc, 4);
  }
  try {
    const matep::Checkpoint c = matep::parse_checkpoint(bytes, "fuzz.ckpt");
    (void)matep::scene_difference(c.scene, "[run]\nend_time = 1.0\n", {"output.dir"});
  } catch (const matep::IoError&) {
  }
}

// Runs one target over its corpus and fails with each failing input's number, reason and file.
void fuzz(const std::string& name, std::string_view ext, const matep::fuzz::Target& target, std::uint64_t execs,
          std::uint64_t memory_bytes) {
  const auto corpus = matep::fuzz::read_corpus(kCorpus, ext);
  ASSERT_GE(corpus.size(), 5u) << "corpus " << kCorpus << " has too few " << ext << " files";
  const std::uint64_t seed = env_or("MATEP_FUZZ_SEED", 1);
  const std::uint64_t n = env_or("MATEP_FUZZ_EXECS", execs);
  const double seconds = static_cast<double>(env_or("MATEP_FUZZ_SECONDS", 25));
  const auto rep = matep::fuzz::run(corpus, seed, n, seconds, target, kLimitMemory, memory_bytes, kAlarm);
  std::printf("[ fuzz     ] %s: %llu executions in %.1f s, %.0f per second (seed %llu)\n", name.c_str(),
              static_cast<unsigned long long>(rep.executions), rep.seconds, rep.per_second(),
              static_cast<unsigned long long>(seed));
  ::testing::Test::RecordProperty("executions", std::to_string(rep.executions));
  ::testing::Test::RecordProperty("executions_per_second", std::to_string(rep.per_second()));
  // Every corpus file ran, and a good part of the mutated inputs (unless a long run was cut by time).
  EXPECT_GE(rep.executions, std::min<std::uint64_t>(n, corpus.size() + 100));
  const char* dir_env = std::getenv("MATEP_FUZZ_CRASH_DIR");
  const fs::path dir = dir_env && *dir_env ? fs::path(dir_env) : fs::temp_directory_path() / "matep_fuzz_crashes";
  for (const auto& f : rep.failures) {
    fs::create_directories(dir);
    const fs::path p = dir / (name + "_" + std::to_string(seed) + "_" + std::to_string(f.index) + std::string(ext));
    std::ofstream(p, std::ios::binary) << f.input;
    ADD_FAILURE() << name << " input " << f.index << " (seed " << seed << "): " << f.why << "; saved as " << p
                  << " (add it to tests/fuzz/corpus/ once fixed)";
  }
}

}  // namespace

TEST(Fuzz, SceneReaderNeverCrashesHangsOrOverallocates) {
  // 256 MiB: the scene reader then plans for that much memory (1024 bytes a grain), so a scene it
  // accepts holds at most about 250k grains and loads well within the 2 s (a million took 1.3 s).
  fuzz("scene", ".toml", scene_target, kShortRun, std::uint64_t{256} << 20);
}

TEST(Fuzz, CsvParticleReaderNeverCrashesHangsOrOverallocates) {
  fuzz("csv", ".csv", csv_target, 20 * kShortRun, std::uint64_t{1} << 30);
}

TEST(Fuzz, EventLogReaderNeverCrashesHangsOrOverallocates) {
  g_events_fd = ::memfd_create("matep_fuzz_events", 0);
  ASSERT_GE(g_events_fd, 0) << std::strerror(errno);
  g_events_path = "/proc/self/fd/" + std::to_string(g_events_fd);
  fuzz("events", ".bin", events_target, kShortRun / 2, std::uint64_t{1} << 30);
  ::close(g_events_fd);
}

TEST(Fuzz, CheckpointReaderNeverCrashesHangsOrOverallocates) {
  fuzz("checkpoint", ".ckpt", checkpoint_target, kShortRun / 2, std::uint64_t{1} << 30);
}

// The driver itself: an input is a function of (seed, index), the corpus comes first unchanged, and
// it reports a target that crashes, hangs or throws what it must not, with the input that did it.
TEST(Fuzz, DriverIsDeterministicAndCatchesCrashesHangsAndStrayExceptions) {
  const std::vector<std::string> corpus{"a = 1\n", "[b]\nc = 2.5\n"};
  EXPECT_EQ(matep::fuzz::make_input(corpus, 1, 0), corpus[0]);
  EXPECT_EQ(matep::fuzz::make_input(corpus, 1, 1), corpus[1]);
  EXPECT_EQ(matep::fuzz::make_input(corpus, 7, 40), matep::fuzz::make_input(corpus, 7, 40));
  int differ = 0;
  for (std::uint64_t i = 2; i < 50; ++i) differ += matep::fuzz::make_input(corpus, 1, i) != matep::fuzz::make_input(corpus, 2, i);
  EXPECT_GT(differ, 40);

  const auto bad = [](const std::string& s) {
    if (s == "a = 1\n") std::raise(SIGSEGV);
    if (s == "[b]\nc = 2.5\n") throw std::logic_error("stray");
  };
  const auto rep = matep::fuzz::run(corpus, 1, 10, 30.0, bad, kLimitMemory);
  ASSERT_EQ(rep.failures.size(), 2u);
  EXPECT_EQ(rep.failures[0].index, 0u);
#ifdef MATEP_SANITIZED
  // AddressSanitizer catches the SIGSEGV itself, prints its report and exits with status 1.
  EXPECT_TRUE(rep.failures[0].why == "signal 11" || rep.failures[0].why == "exit status 1") << rep.failures[0].why;
#else
  EXPECT_EQ(rep.failures[0].why, "signal 11");
#endif
  EXPECT_EQ(rep.failures[0].input, corpus[0]);
  EXPECT_EQ(rep.failures[1].index, 1u);
  EXPECT_EQ(rep.failures[1].why, "exception: stray");
  EXPECT_EQ(rep.executions, 10u);

  const auto hang = [](const std::string& s) {
    if (s == "a = 1\n") ::pause();  // waits for a signal: the alarm
  };
  const auto rh = matep::fuzz::run(corpus, 1, 3, 30.0, hang, kLimitMemory);
  ASSERT_EQ(rh.failures.size(), 1u);
  EXPECT_EQ(rh.failures[0].why, "timeout (> 2 s)");
  EXPECT_EQ(rh.executions, 3u);

  if (kLimitMemory) {
    const auto hog = [](const std::string& s) {
      if (s == "a = 1\n") {
        std::vector<char> big(std::size_t{3} << 30, 1);  // 3 GiB: past the limit
        if (big[12345] != 1) std::abort();
      }
    };
    const auto rm = matep::fuzz::run(corpus, 1, 2, 30.0, hog, kLimitMemory);
    ASSERT_EQ(rm.failures.size(), 1u);
    EXPECT_EQ(rm.failures[0].why, "exception: std::bad_alloc");
  }
}

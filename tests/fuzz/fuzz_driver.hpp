// A deterministic mutation fuzzer (no libFuzzer): inputs are corpus files mutated by a seed-fixed
// generator (byte flips, insertions, deletions, splices of two corpus files, and TOML-aware edits:
// duplicated lines, numbers replaced by extremes, runs of brackets and dots). Execution i is a pure
// function of (seed, i), so any input can be rebuilt from its number.
//
// The target runs in a forked worker under an address-space limit (at most 1 GiB above what the
// process holds; not under the sanitizers, which reserve far more) and an alarm per input (2 s; the
// sanitizer builds give more, their code being several times slower). A worker
// that dies (a crash, the alarm, an exception the target must not throw) is reported with its
// input, which is written to a file for the corpus, and a fresh worker continues after it.
#pragma once

#include <sys/mman.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

namespace matep::fuzz {

// splitmix64 (Steele, Lea & Flood 2014): small, fast, fixed across platforms.
class Prng {
 public:
  explicit Prng(std::uint64_t seed) : s_(seed) {}
  std::uint64_t next() {
    std::uint64_t z = (s_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  std::size_t below(std::size_t n) { return n == 0 ? 0 : static_cast<std::size_t>(next() % n); }

 private:
  std::uint64_t s_;
};

inline std::vector<std::string> read_corpus(const std::filesystem::path& dir, std::string_view ext) {
  std::vector<std::filesystem::path> paths;
  for (const auto& e : std::filesystem::directory_iterator(dir))
    if (e.path().extension() == ext) paths.push_back(e.path());
  std::sort(paths.begin(), paths.end());
  std::vector<std::string> out;
  for (const auto& p : paths) {
    std::ifstream f(p, std::ios::binary);
    std::stringstream s;
    s << f.rdbuf();
    out.push_back(s.str());
  }
  return out;
}

// Values that have broken readers: overflow, underflow to subnormals, signed zero, NaN, integer
// edges, huge counts.
inline constexpr std::string_view kExtremes[] = {
    "1e308", "-1e308", "1e-320", "5e-324", "-0", "-0.0", "nan", "inf", "-inf", "0", "1e-300", "1e300",
    "9223372036854775807", "9223372036854775808", "-9223372036854775808", "2147483648", "4294967296",
    "1000000000000", "18446744073709551615", "0x7fffffff", "1e12", "2.5e-308", "-1"};
inline constexpr std::string_view kTokens[] = {"[", "]", "{", "}", ".", "=", ",", "\"", "'", "#", "\n", "[[",
                                               "]]", "\"\"\"", "'''", "\\", "a.b", "x = 1\n", "true", "[run]\n"};

// One mutation of `s` in place (`other`: a corpus file to splice from).
inline void mutate_once(std::string& s, const std::string& other, Prng& r) {
  const std::size_t n = s.size();
  switch (r.below(9)) {
    case 0:  // flip a bit
      if (n) s[r.below(n)] ^= static_cast<char>(1u << r.below(8));
      break;
    case 1:  // insert a byte
      s.insert(s.begin() + static_cast<std::ptrdiff_t>(r.below(n + 1)), static_cast<char>(r.below(256)));
      break;
    case 2: {  // delete a range
      if (!n) break;
      const std::size_t at = r.below(n);
      s.erase(at, 1 + r.below(16));
      break;
    }
    case 3: {  // duplicate a line (a repeated key or table)
      if (!n) break;
      std::size_t b = s.rfind('\n', r.below(n));
      b = b == std::string::npos ? 0 : b + 1;
      std::size_t e = s.find('\n', b);
      e = e == std::string::npos ? n : e + 1;
      const std::string line = s.substr(b, e - b);
      s.insert(r.below(2) ? e : b, line + (line.empty() || line.back() != '\n' ? "\n" : ""));
      break;
    }
    case 4: {  // splice: this file's head, the other's tail
      if (other.empty()) break;
      s = s.substr(0, r.below(n + 1)) + other.substr(r.below(other.size()));
      break;
    }
    case 5:
    case 6: {  // a number becomes an extreme value
      if (!n) break;
      std::size_t b = r.below(n);
      while (b < n && !(s[b] >= '0' && s[b] <= '9')) ++b;
      if (b == n) break;
      while (b > 0 && std::string_view("0123456789.eE+-_").find(s[b - 1]) != std::string_view::npos) --b;
      std::size_t e = b;
      while (e < n && std::string_view("0123456789.eE+-_").find(s[e]) != std::string_view::npos) ++e;
      s.replace(b, e - b, kExtremes[r.below(std::size(kExtremes))]);
      break;
    }
    case 7: {  // a TOML token, sometimes repeated many times
      const std::string_view t = kTokens[r.below(std::size(kTokens))];
      const std::size_t reps = r.below(4) == 0 ? 1 + r.below(300) : 1;
      std::string run;
      for (std::size_t i = 0; i < reps; ++i) run += t;
      s.insert(r.below(n + 1), run);
      break;
    }
    default: {  // swap two lines' worth of bytes
      if (n < 2) break;
      const std::size_t a = r.below(n), b = r.below(n), len = 1 + r.below(40);
      const std::string x = s.substr(a, len), y = s.substr(b, len);
      if (a < b) {
        s.replace(b, y.size(), x);
        s.replace(a, x.size(), y);
      }
      break;
    }
  }
}

// Input number i: a corpus file (i < corpus size: unmutated) with 1 to 4 mutations.
inline std::string make_input(const std::vector<std::string>& corpus, std::uint64_t seed, std::uint64_t i) {
  Prng r(seed * 0x100000001B3ull ^ (i * 0x9E3779B97F4A7C15ull + 1));
  if (i < corpus.size()) return corpus[i];
  std::string s = corpus[r.below(corpus.size())];
  const std::size_t m = 1 + r.below(4);
  for (std::size_t k = 0; k < m; ++k) mutate_once(s, corpus[r.below(corpus.size())], r);
  return s;
}

struct Failure {
  std::uint64_t index = 0;
  std::string why;    // "signal 11", "timeout (> 2 s)", "exception: ...", "exit status N" (a sanitizer's report)
  std::string input;
};

struct Report {
  std::uint64_t executions = 0;
  double seconds = 0.0;
  std::vector<Failure> failures;
  double per_second() const { return seconds > 0.0 ? static_cast<double>(executions) / seconds : 0.0; }
};

// The target: returns normally or throws an accepted exception; anything else it throws is a failure
// (the worker writes its text to the shared page and exits 3).
using Target = std::function<void(const std::string& input)>;

namespace detail {
struct Shared {
  std::uint64_t current;  // the input being run
  std::uint64_t done;     // inputs finished
  char why[512];
};

inline std::uint64_t address_space_now() {
  std::ifstream f("/proc/self/statm");
  std::uint64_t pages = 0;
  f >> pages;
  return pages * static_cast<std::uint64_t>(::sysconf(_SC_PAGE_SIZE));
}
}  // namespace detail

// Runs inputs [0, max_execs) (or until max_seconds pass) of the corpus through `target`, with
// memory_bytes more address space than the process holds.
inline Report run(const std::vector<std::string>& corpus, std::uint64_t seed, std::uint64_t max_execs,
                  double max_seconds, const Target& target, bool limit_memory,
                  std::uint64_t memory_bytes = std::uint64_t{1} << 30, unsigned alarm_seconds = 2) {
  Report rep;
  auto* sh = static_cast<detail::Shared*>(
      ::mmap(nullptr, sizeof(detail::Shared), PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0));
  const auto start = std::chrono::steady_clock::now();
  const auto elapsed = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(); };
  std::uint64_t next = 0;
  while (next < max_execs && elapsed() < max_seconds) {
    sh->current = next;
    sh->done = next;
    sh->why[0] = 0;
    const pid_t pid = ::fork();
    if (pid == 0) {
      if (limit_memory) {
        const rlim_t cap = detail::address_space_now() + memory_bytes;
        const rlimit lim{cap, cap};
        ::setrlimit(RLIMIT_AS, &lim);
      }
      for (std::uint64_t i = next; i < max_execs; ++i) {
        if ((i & 63) == 0 && elapsed() >= max_seconds) break;
        sh->current = i;
        const std::string input = make_input(corpus, seed, i);
        ::alarm(alarm_seconds);
        try {
          target(input);
        } catch (const std::exception& e) {
          std::snprintf(sh->why, sizeof sh->why, "exception: %s", e.what());
          ::_exit(3);
        } catch (...) {
          std::snprintf(sh->why, sizeof sh->why, "exception of an unknown type");
          ::_exit(3);
        }
        ::alarm(0);
        sh->done = i + 1;
      }
      ::_exit(0);
    }
    int status = 0;
    ::waitpid(pid, &status, 0);
    if (WIFEXITED(status) && WEXITSTATUS(status) == 0) {
      next = sh->done;
      break;
    }
    Failure f;
    f.index = sh->current;
    if (WIFSIGNALED(status))
      f.why = WTERMSIG(status) == SIGALRM ? "timeout (> " + std::to_string(alarm_seconds) + " s)"
                                          : "signal " + std::to_string(WTERMSIG(status));
    else
      f.why = sh->why[0] ? std::string(sh->why) : "exit status " + std::to_string(WEXITSTATUS(status));
    f.input = make_input(corpus, seed, f.index);
    rep.failures.push_back(std::move(f));
    next = sh->current + 1;
  }
  rep.executions = next;
  rep.seconds = elapsed();
  ::munmap(sh, sizeof(detail::Shared));
  return rep;
}

}  // namespace matep::fuzz

// Test helpers for running the matep command line and reading what it wrote.
#pragma once

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

extern char** environ;

namespace matep::test {

struct CliResult {
  int code = -1;
  std::string out;  // stdout and stderr together
};

// Runs `matep ARGS` (the binary built with the tests) and captures its output and exit status.
inline CliResult run_cli(const std::string& args) {
  const std::string cmd = std::string(MATEP_CLI) + " " + args + " 2>&1";
  CliResult r;
  FILE* p = popen(cmd.c_str(), "r");
  std::array<char, 4096> buf;
  while (p && std::fgets(buf.data(), buf.size(), p)) r.out += buf.data();
  const int status = p ? pclose(p) : -1;
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

struct ChildResult {
  int code = -1;    // exit status, or -1 when a signal ended it
  int signal = 0;   // the signal that ended it (SIGALRM: it ran past the timeout)
  std::string out;  // stdout and stderr together
};

// Runs the matep binary as a child with `args` (no shell), killed by SIGALRM after timeout_s, so
// that a crash shows as a signal and a hang cannot stall the suite.
inline ChildResult run_cli_child(const std::vector<std::string>& args, unsigned timeout_s) {
  int fds[2];
  ChildResult r;
  if (::pipe(fds) != 0) return r;
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::dup2(fds[1], 1);
    ::dup2(fds[1], 2);
    ::close(fds[0]);
    ::close(fds[1]);
    std::vector<char*> argv{const_cast<char*>(MATEP_CLI)};
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    ::alarm(timeout_s);  // kept across exec; its default action ends the process
    ::execv(MATEP_CLI, argv.data());
    ::_exit(127);
  }
  ::close(fds[1]);
  std::array<char, 4096> buf;
  for (ssize_t n; (n = ::read(fds[0], buf.data(), buf.size())) > 0;) r.out.append(buf.data(), static_cast<std::size_t>(n));
  ::close(fds[0]);
  int status = 0;
  ::waitpid(pid, &status, 0);
  if (WIFEXITED(status)) r.code = WEXITSTATUS(status);
  if (WIFSIGNALED(status)) r.signal = WTERMSIG(status);
  return r;
}

inline std::string slurp(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

// The folders fresh_dir made, removed when the test process exits (MATEP_KEEP_TEST_DIRS set: kept,
// to look at what a failed test wrote).
struct ScratchDirs {
  std::vector<std::filesystem::path> dirs;
  ~ScratchDirs() {
    if (std::getenv("MATEP_KEEP_TEST_DIRS")) return;
    std::error_code ec;
    for (const auto& d : dirs) std::filesystem::remove_all(d, ec);
  }
};
inline ScratchDirs& scratch_dirs() {
  static ScratchDirs s;
  return s;
}

// A fresh, empty folder under the system's temporary directory, unique to this process, removed
// when the process exits.
inline std::filesystem::path fresh_dir(const std::string& name) {
  const std::filesystem::path d =
      std::filesystem::temp_directory_path() / ("matep_test_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(d);
  std::filesystem::create_directories(d);
  scratch_dirs().dirs.push_back(d);
  return d;
}

inline const std::string kCasesDir = std::string(MATEP_SOURCE_DIR) + "/cases/";

// `matep ARGS` started in the background, its stdout and stderr into `log`; its pid (-1: not started).
inline pid_t spawn_cli(const std::vector<std::string>& args, const std::filesystem::path& log) {
  std::vector<std::string> all{MATEP_CLI};
  all.insert(all.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& a : all) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&fa, 1, 2);
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, MATEP_CLI, &fa, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  return rc == 0 ? pid : -1;
}

// Waits for it; the exit status, or -signal when a signal ended it.
inline int wait_exit(pid_t pid) {
  int st = 0;
  if (waitpid(pid, &st, 0) != pid) return -1000;
  return WIFEXITED(st) ? WEXITSTATUS(st) : -WTERMSIG(st);
}

// Waits until `p` exists (at most `limit` seconds).
inline bool wait_for(const std::filesystem::path& p, double limit = 60.0) {
  const auto t0 = std::chrono::steady_clock::now();
  while (!std::filesystem::exists(p)) {
    if (std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() > limit) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return true;
}

}  // namespace matep::test

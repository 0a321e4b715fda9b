// Test helpers for running the matep command line and reading what it wrote.
#pragma once

#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

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

// A fresh, empty folder under the system's temporary directory, unique to this process.
inline std::filesystem::path fresh_dir(const std::string& name) {
  const std::filesystem::path d =
      std::filesystem::temp_directory_path() / ("matep_test_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(d);
  std::filesystem::create_directories(d);
  return d;
}

inline const std::string kCasesDir = std::string(MATEP_SOURCE_DIR) + "/cases/";

}  // namespace matep::test

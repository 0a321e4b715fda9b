// Test helpers for running the matep command line and reading what it wrote.
#pragma once

#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

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

#include "io/run_folder.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string_view>

#include "io/interrupt.hpp"
#include "io/io_error.hpp"

namespace matep {

namespace fs = std::filesystem;

bool is_run_output(const std::string& name) {
  static constexpr std::array<std::string_view, 10> kNames{
      "thermo.csv", "final_state.csv", "summary.json", "events.bin",
      "outflow.csv", "snapshots.pvd", "snapshots.pvd.tmp", "snapshots", "checkpoint.bin", "checkpoint.bin.tmp"};
  for (std::string_view n : kNames)
    if (name == n) return true;
  return false;
}

namespace {

// Empties `from` (an earlier run's staging folder, or the previous outputs after an exchange)
// into `into`: matep's outputs are deleted, anything else moves into `into` when that name is
// free there. Returns the first entry that had to stay (empty: `from` is gone).
std::string clear_into(const fs::path& from, const fs::path& into) {
  std::error_code ec;
  std::string kept;
  for (const auto& entry : fs::directory_iterator(from, ec)) {
    const std::string name = entry.path().filename().string();
    if (is_run_output(name)) {
      fs::remove_all(entry.path(), ec);
    } else if (!fs::exists(into / name, ec)) {
      fs::create_directories(into, ec);
      fs::rename(entry.path(), into / name, ec);
      if (ec && kept.empty()) kept = name;
    } else if (kept.empty()) {
      kept = name;
    }
  }
  if (kept.empty()) fs::remove(from, ec);
  return kept;
}

int try_lock(const std::string& path, const std::string& dir) {
  for (int attempt = 0; attempt < 8; ++attempt) {
    const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd < 0) throw WriteError(fmt::format("{}: cannot create the run lock: {}", path, std::strerror(errno)));
    if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
      char pid[32] = {};
      const ssize_t n = ::pread(fd, pid, sizeof pid - 1, 0);
      ::close(fd);
      std::string who(pid, n > 0 ? static_cast<std::size_t>(n) : 0);
      while (!who.empty() && (who.back() == '\n' || who.back() == ' ')) who.pop_back();
      throw IoError(fmt::format("{}: another matep run{} is writing into this folder (lock {}); wait for it to "
                                "end or give another --out",
                                dir, who.empty() ? std::string() : fmt::format(" (pid {})", who), path));
    }
    // The lock holds only if the file is still the one at `path` (an ending run unlinks it).
    struct stat held {}, now {};
    if (::fstat(fd, &held) == 0 && ::stat(path.c_str(), &now) == 0 && held.st_ino == now.st_ino &&
        held.st_dev == now.st_dev) {
      const std::string pid = fmt::format("{}\n", ::getpid());
      if (::ftruncate(fd, 0) == 0 && ::pwrite(fd, pid.data(), pid.size(), 0) < 0) {
        // The pid is only for the message of a refused second run.
      }
      return fd;
    }
    ::close(fd);
  }
  throw WriteError(fmt::format("{}: cannot hold the run lock (it keeps being replaced)", path));
}

}  // namespace

RunFolder::RunFolder(const std::string& dir) {
  fs::path p = fs::path(dir).lexically_normal();
  if (!p.empty() && !p.has_filename()) p = p.parent_path();  // "out/" -> "out"
  std::error_code ec;
  const fs::path abs = fs::weakly_canonical(fs::absolute(p, ec), ec);
  const fs::path cwd = fs::current_path(ec);
  if (p.empty() || abs == abs.root_path() || abs.filename() == "." || abs.filename() == "..")
    throw IoError(fmt::format("{}: not a usable output folder: a run replaces its folder's outputs as one set "
                              "and needs a folder of its own (e.g. out/NAME)",
                              dir));
  if (std::mismatch(abs.begin(), abs.end(), cwd.begin(), cwd.end()).first == abs.end())
    throw IoError(fmt::format("{}: the output folder is the working folder or holds it; a run replaces its "
                              "folder's outputs as one set and needs a folder of its own (e.g. out/NAME)",
                              dir));
  if (fs::exists(p, ec) && !fs::is_directory(p, ec))
    throw IoError(fmt::format("{}: the output folder exists and is not a folder", dir));
  dir_ = p.string();
  const fs::path parent = p.parent_path().empty() ? fs::path(".") : p.parent_path();
  fs::create_directories(parent, ec);
  if (ec) throw WriteError(fmt::format("{}: cannot create the folder: {}", parent.string(), ec.message()));
  const std::string name = p.filename().string();
  lock_path_ = (parent / ("." + name + ".lock")).string();
  staging_ = dir_ + ".running";
  lock_fd_ = try_lock(lock_path_, dir_);
  try {
    // What a killed run left: a fallback publish's previous outputs, then a staging folder.
    const std::string previous = dir_ + ".previous";
    if (fs::exists(previous, ec)) {
      if (!fs::exists(p, ec)) fs::rename(previous, p, ec);
      else if (const std::string kept = clear_into(previous, p); !kept.empty())
        throw IoError(fmt::format("{}: left by an interrupted run, it holds '{}', which {} holds too; move one away",
                                  previous, kept, dir_));
    }
    if (fs::exists(staging_, ec)) {
      if (!fs::is_directory(staging_, ec))
        throw IoError(fmt::format("{}: in the way of the run's staging folder (not a folder); move it away", staging_));
      // A killed run's checkpoint (and the outputs it continues) is kept for --resume.
      if (fs::exists(fs::path(staging_) / "checkpoint.bin", ec)) {
        killed_ = dir_ + ".killed";
        fs::remove_all(killed_, ec);
        fs::rename(staging_, killed_, ec);
        if (ec)
          throw WriteError(fmt::format("{}: cannot keep a killed run's checkpoint as {}: {}", staging_, killed_,
                                       ec.message()));
      } else if (const std::string kept = clear_into(staging_, p); !kept.empty())
        throw IoError(fmt::format("{}: left by an interrupted run, it holds '{}', which {} holds too; move one away",
                                  staging_, kept, dir_));
    }
    if (!fs::create_directory(staging_, ec) || ec)
      throw WriteError(fmt::format("{}: cannot create the staging folder: {}", staging_,
                                   ec ? ec.message() : std::string("it exists")));
  } catch (...) {
    ::unlink(lock_path_.c_str());
    ::close(lock_fd_);
    throw;
  }
}

RunFolder::~RunFolder() {
  std::error_code ec;
  if (!published_) fs::remove_all(staging_, ec);  // only this run's incomplete files
  ::unlink(lock_path_.c_str());
  ::close(lock_fd_);
}

void RunFolder::publish() {
  const PublishGuard guard;  // a second signal waits until the set is in place
  std::error_code ec;
  if (!fs::exists(dir_, ec)) {
    if (::rename(staging_.c_str(), dir_.c_str()) != 0)
      throw WriteError(fmt::format("{}: cannot publish the outputs from {}: {}", dir_, staging_, std::strerror(errno)));
    published_ = true;
    return;
  }
  std::string old = staging_;
  if (::renameat2(AT_FDCWD, staging_.c_str(), AT_FDCWD, dir_.c_str(), RENAME_EXCHANGE) != 0) {
    if (errno != EINVAL && errno != ENOSYS && errno != EOPNOTSUPP)
      throw WriteError(fmt::format("{}: cannot publish the outputs from {}: {}", dir_, staging_, std::strerror(errno)));
    // A file system without atomic exchange: two renames (a kill between them leaves the previous
    // outputs in DIR.previous, which the next run puts back).
    old = dir_ + ".previous";
    if (::rename(dir_.c_str(), old.c_str()) != 0 || ::rename(staging_.c_str(), dir_.c_str()) != 0)
      throw WriteError(fmt::format("{}: cannot publish the outputs from {}: {}", dir_, staging_, std::strerror(errno)));
  }
  published_ = true;
  // The previous outputs go; the user's files come along. What cannot move stays in `old` for the
  // next run into this folder to report.
  clear_into(old, dir_);
}

}  // namespace matep

// A file written through stdio whose every write, flush and close is checked. A failure (a full
// disk, a file-size limit, a folder removed under the run) throws IoError "PATH: write failed:
// OS error" (a WriteError: the CLI exits with status 4).
#pragma once

#include <fmt/format.h>

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <unistd.h>
#include <iterator>
#include <string>
#include <string_view>
#include <vector>

#include "io/io_error.hpp"

namespace matep {

std::uint32_t crc32c(const void* data, std::size_t n, std::uint32_t crc);  // io/output.cpp

// What a file held at a checkpoint (io/checkpoint.hpp): its length and the CRC-32C of those bytes.
struct FileMark {
  std::uint64_t bytes = 0;
  std::uint32_t crc = 0;
  template <class A>
  void archive(A& a) {
    a(bytes);
    a(crc);
  }
};

class CheckedFile {
 public:
  // mode: "w" or "wb" ("a"/"ab" with `from`: continues a file that holds the bytes of that mark).
  // buffer > 0: a stdio buffer of that many bytes (large sequential writers).
  CheckedFile(std::string path, const char* mode, std::size_t buffer = 0, const FileMark& from = {})
      : path_(std::move(path)), mark_(from) {
    f_ = std::fopen(path_.c_str(), mode);
    if (!f_) throw WriteError(fmt::format("{}: cannot open for writing: {}", path_, std::strerror(errno)));
    if (buffer > 0) {
      buffer_.resize(buffer);
      std::setvbuf(f_, buffer_.data(), _IOFBF, buffer_.size());
    }
  }
  // Unchecked: reached with a file still open only while an exception is already on its way.
  ~CheckedFile() {
    if (f_) std::fclose(f_);
  }
  CheckedFile(const CheckedFile&) = delete;
  CheckedFile& operator=(const CheckedFile&) = delete;

  const std::string& path() const { return path_; }

  void write(const void* p, std::size_t n) {
    if (n > 0 && std::fwrite(p, 1, n, f_) != n) fail();
    mark_.bytes += n;
    mark_.crc = crc32c(p, n, mark_.crc);
  }
  // Flushed, the file's length and checksum so far.
  FileMark mark() {
    flush();
    return mark_;
  }
  void puts(std::string_view s) { write(s.data(), s.size()); }
  template <class... A>
  void print(fmt::format_string<A...> format, A&&... args) {
    text_.clear();
    fmt::format_to(std::back_inserter(text_), format, std::forward<A>(args)...);
    write(text_.data(), text_.size());
  }
  void flush() {
    if (std::fflush(f_) != 0) fail();
  }
  // Flushed and on the disk (fsync): for a file renamed into place as whole.
  void sync() {
    flush();
    if (::fsync(::fileno(f_)) != 0) fail();
  }
  // Flushes and closes; throws on the first error the OS reports (also one held back by stdio).
  void close() {
    if (!f_) return;
    std::FILE* f = f_;
    f_ = nullptr;
    const bool bad = std::ferror(f) != 0;
    const int saved = errno;
    if (std::fclose(f) != 0 || bad) {
      if (bad && saved != 0) errno = saved;
      fail();
    }
  }

 private:
  [[noreturn]] void fail() {
    const int err = errno;
    throw WriteError(fmt::format("{}: write failed: {}", path_, err != 0 ? std::strerror(err) : "unknown error"));
  }
  std::string path_;
  FileMark mark_;
  std::FILE* f_ = nullptr;
  std::vector<char> buffer_;
  fmt::memory_buffer text_;
};

}  // namespace matep

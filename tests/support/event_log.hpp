// Test helpers for event logs: recompute the checksums of a version-3 log after a test altered it
// on purpose (so that the checks behind the checksum are reached), and a version-1 header.
#pragma once

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "io/output.hpp"

namespace matep::test {

inline std::uint32_t u32_at(const std::string& s, std::size_t off) {
  std::uint32_t v;
  std::memcpy(&v, s.data() + off, 4);
  return v;
}
inline void put_u32_at(std::string& s, std::size_t off, std::uint32_t v) { std::memcpy(s.data() + off, &v, 4); }

// Rewrites the header's and every block's CRC-32C of a version-3 log from its bytes (the layout
// of io/output.hpp); a version-1 or -2 log is left as it is.
inline void reseal_event_log(const std::filesystem::path& path) {
  std::string b;
  {
    std::ifstream f(path, std::ios::binary);
    b.assign(std::istreambuf_iterator<char>(f), {});
  }
  const std::uint32_t version = b.size() < kEventLogHeaderSize ? 0 : u32_at(b, 8);
  if (version != kEventLogVersionChecked && version != kEventLogVersionIdentity) return;
  put_u32_at(b, 60, crc32c(b.data(), 60));
  std::size_t start = kEventLogHeaderSize;  // version 4: after the identity section (resealed too)
  if (version == kEventLogVersionIdentity) {
    const std::size_t n = u32_at(b, 36);
    if (n >= 8 && start + n <= b.size()) put_u32_at(b, start + n - 8, crc32c(b.data() + start, n - 8));
    start += n;
  }
  const std::size_t k = u32_at(b, 32), block = k * kEventRecordSize + kEventBlockTrailerSize;
  const std::size_t body = b.size() - start, full = body / block;
  for (std::size_t blk = 0; blk <= full; ++blk) {
    const std::size_t off = start + blk * block;
    const std::size_t n = blk < full ? k : (body % block - kEventBlockTrailerSize) / kEventRecordSize;
    if (blk == full && body % block < kEventBlockTrailerSize) break;  // cut: nothing to seal
    const std::size_t t = off + n * kEventRecordSize;
    put_u32_at(b, t + 24, crc32c(b.data() + t, 24, crc32c(b.data() + off, n * kEventRecordSize)));
  }
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f.write(b.data(), static_cast<std::streamsize>(b.size()));
}

// The header of a version-1 log (no checksums, no blocks), for record_offset().
inline EventLogHeader v1_header(std::uint64_t particles = 0) {
  EventLogHeader h;
  h.version = kEventLogVersion;
  h.particles = particles;
  return h;
}

}  // namespace matep::test

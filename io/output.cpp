#include "io/output.hpp"

#include <fmt/format.h>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <utility>
#if defined(__SSE4_2__) && defined(__x86_64__)
#include <nmmintrin.h>
#endif

namespace matep {

namespace {

std::FILE* open_or_throw(const std::string& path, const char* mode) {
  std::FILE* f = std::fopen(path.c_str(), mode);
  if (!f) throw WriteError(fmt::format("{}: cannot open for writing: {}", path, std::strerror(errno)));
  return f;
}

void put_u32(unsigned char* p, std::uint32_t v) { std::memcpy(p, &v, 4); }
void put_u64(unsigned char* p, std::uint64_t v) { std::memcpy(p, &v, 8); }
void put_f64(unsigned char* p, double v) { std::memcpy(p, &v, 8); }
void put_v3(unsigned char* p, const double* v) { std::memcpy(p, v, 24); }
std::uint32_t get_u32(const unsigned char* p) {
  std::uint32_t v;
  std::memcpy(&v, p, 4);
  return v;
}
std::uint64_t get_u64(const unsigned char* p) {
  std::uint64_t v;
  std::memcpy(&v, p, 8);
  return v;
}
double get_f64(const unsigned char* p) {
  double v;
  std::memcpy(&v, p, 8);
  return v;
}
void get_v3(const unsigned char* p, double* v) { std::memcpy(v, p, 24); }

// Field offsets of the version-1 record (README: "Event log").
constexpr std::size_t kOffTime = 0, kOffKind = 8, kOffI = 12, kOffJ = 16, kOffMi = 24,
                      kOffMj = 32, kOffE = 40, kOffNormal = 48, kOffViB = 72, kOffVjB = 96,
                      kOffViA = 120, kOffVjA = 144, kOffWiB = 168, kOffWjB = 192, kOffWiA = 216,
                      kOffWjA = 240;
static_assert(kOffWjA + 24 == kEventRecordSize);

}  // namespace

void encode_event_record(const EventRecord& r, unsigned char* out) {
  std::memset(out, 0, kEventRecordSize);
  put_f64(out + kOffTime, r.time);
  out[kOffKind] = r.kind;
  put_u32(out + kOffI, r.i);
  put_u32(out + kOffJ, r.j);
  put_f64(out + kOffMi, r.mi);
  put_f64(out + kOffMj, r.mj);
  put_f64(out + kOffE, r.e);
  put_v3(out + kOffNormal, r.normal);
  put_v3(out + kOffViB, r.vi_before);
  put_v3(out + kOffVjB, r.vj_before);
  put_v3(out + kOffViA, r.vi_after);
  put_v3(out + kOffVjA, r.vj_after);
  put_v3(out + kOffWiB, r.wi_before);
  put_v3(out + kOffWjB, r.wj_before);
  put_v3(out + kOffWiA, r.wi_after);
  put_v3(out + kOffWjA, r.wj_after);
}

EventRecord decode_event_record(const unsigned char* in) {
  EventRecord r;
  r.time = get_f64(in + kOffTime);
  r.kind = in[kOffKind];
  r.i = get_u32(in + kOffI);
  r.j = get_u32(in + kOffJ);
  r.mi = get_f64(in + kOffMi);
  r.mj = get_f64(in + kOffMj);
  r.e = get_f64(in + kOffE);
  get_v3(in + kOffNormal, r.normal);
  get_v3(in + kOffViB, r.vi_before);
  get_v3(in + kOffVjB, r.vj_before);
  get_v3(in + kOffViA, r.vi_after);
  get_v3(in + kOffVjA, r.vj_after);
  get_v3(in + kOffWiB, r.wi_before);
  get_v3(in + kOffWjB, r.wj_before);
  get_v3(in + kOffWiA, r.wi_after);
  get_v3(in + kOffWjA, r.wj_after);
  return r;
}

// ---- CRC-32C -----------------------------------------------------------------------------------

namespace {

// Slicing-by-8 tables for the reflected Castagnoli polynomial.
struct Crc32cTables {
  std::uint32_t t[8][256];
  Crc32cTables() {
    for (std::uint32_t n = 0; n < 256; ++n) {
      std::uint32_t c = n;
      for (int k = 0; k < 8; ++k) c = (c & 1) ? (c >> 1) ^ 0x82F63B78u : c >> 1;
      t[0][n] = c;
    }
    for (std::uint32_t n = 0; n < 256; ++n)
      for (int s = 1; s < 8; ++s) t[s][n] = (t[s - 1][n] >> 8) ^ t[0][t[s - 1][n] & 0xFF];
  }
};
const Crc32cTables& crc_tables() {
  static const Crc32cTables tables;
  return tables;
}

}  // namespace

std::uint32_t crc32c_portable(const void* data, std::size_t n, std::uint32_t crc) {
  const auto& t = crc_tables().t;
  const auto* p = static_cast<const unsigned char*>(data);
  std::uint32_t c = ~crc;
  for (; n >= 8; n -= 8, p += 8) {
    std::uint32_t lo, hi;
    std::memcpy(&lo, p, 4);
    std::memcpy(&hi, p + 4, 4);
    lo ^= c;
    c = t[7][lo & 0xFF] ^ t[6][(lo >> 8) & 0xFF] ^ t[5][(lo >> 16) & 0xFF] ^ t[4][lo >> 24] ^ t[3][hi & 0xFF] ^
        t[2][(hi >> 8) & 0xFF] ^ t[1][(hi >> 16) & 0xFF] ^ t[0][hi >> 24];
  }
  for (; n; --n, ++p) c = (c >> 8) ^ t[0][(c ^ *p) & 0xFF];
  return ~c;
}

std::uint32_t crc32c(const void* data, std::size_t n, std::uint32_t crc) {
#if defined(__SSE4_2__) && defined(__x86_64__)
  const auto* p = static_cast<const unsigned char*>(data);
  std::uint64_t c = ~crc;
  for (; n >= 8; n -= 8, p += 8) {
    std::uint64_t v;
    std::memcpy(&v, p, 8);
    c = _mm_crc32_u64(c, v);
  }
  std::uint32_t c32 = static_cast<std::uint32_t>(c);
  for (; n; --n, ++p) c32 = _mm_crc32_u8(c32, *p);
  return ~c32;
#else
  return crc32c_portable(data, n, crc);
#endif
}

// ---- event log layout -------------------------------------------------------------------------

namespace {

std::uint64_t block_bytes(const EventLogHeader& h) {
  return std::uint64_t{h.block_records} * kEventRecordSize + kEventBlockTrailerSize;
}
bool has_blocks(const EventLogHeader& h) { return h.version >= kEventLogVersionChecked; }

}  // namespace

std::uint64_t record_offset(const EventLogHeader& h, std::uint64_t index) {
  if (!has_blocks(h)) return h.data_offset + index * kEventRecordSize;
  const std::uint64_t k = h.block_records;
  return h.data_offset + (index / k) * block_bytes(h) + (index % k) * kEventRecordSize;
}

std::uint64_t block_offset(const EventLogHeader& h, std::uint64_t index) {
  if (!has_blocks(h)) return record_offset(h, index);
  return h.data_offset + (index / h.block_records) * block_bytes(h);
}

std::string check_event_record(const EventRecord& r, const EventLogHeader& h) {
  if (r.kind < 1 || r.kind > 7) return fmt::format("kind {} (known kinds are 1 to 7)", static_cast<int>(r.kind));
  const bool pair = r.kind == static_cast<std::uint8_t>(EventKind::PairCollision);
  auto bad = [](double v) { return !std::isfinite(v); };
  if (bad(r.time)) return fmt::format("time = {}", r.time);
  if (bad(r.mi)) return fmt::format("mi = {}", r.mi);
  const bool fixed_mj = pair && h.fixed_grains() && r.mj == std::numeric_limits<double>::infinity();
  if (bad(r.mj) && !fixed_mj)
    return fmt::format("mj = {}{}", r.mj,
                       pair && r.mj > 0.0 ? " (+infinity marks a fixed partner only in a log with fixed grains)" : "");
  if (bad(r.e)) return fmt::format("e = {}", r.e);
  const std::pair<const char*, const double*> vecs[] = {
      {"normal", r.normal},       {"vi_before", r.vi_before}, {"vj_before", r.vj_before},
      {"vi_after", r.vi_after},   {"vj_after", r.vj_after},   {"wi_before", r.wi_before},
      {"wj_before", r.wj_before}, {"wi_after", r.wi_after},   {"wj_after", r.wj_after}};
  for (const auto& [name, v] : vecs)
    for (int c = 0; c < 3; ++c)
      if (bad(v[c])) return fmt::format("{}.{} = {}", name, "xyz"[c], v[c]);
  if (r.kind != static_cast<std::uint8_t>(EventKind::CellCrossing) && !(r.mi > 0.0))
    return fmt::format("mi = {} (a mass must be > 0)", r.mi);
  if (pair && !(r.mj > 0.0)) return fmt::format("mj = {} (a mass must be > 0)", r.mj);
  if (r.kind == static_cast<std::uint8_t>(EventKind::Inflow) && !(r.mj > 0.0))
    return fmt::format("mj = {} (an inflow's radius must be > 0)", r.mj);
  if (r.i >= h.particles) return fmt::format("i = {} (the log has {} particles)", r.i, h.particles);
  if (pair && r.j >= h.particles) return fmt::format("j = {} (the log has {} particles)", r.j, h.particles);
  return {};
}

// ---- event log identity (version 4) ----------------------------------------------------------

std::vector<unsigned char> encode_event_identity(const EventLogIdentity& id) {
  if (id.groups.size() > 65535 || id.materials.size() > 65535 || id.group.size() != id.material.size())
    throw std::invalid_argument("event log identity: more than 65535 groups or materials");
  std::vector<unsigned char> b(kEventIdentityMagic, kEventIdentityMagic + 8);
  auto u16 = [&](std::size_t v) {
    b.push_back(static_cast<unsigned char>(v & 0xff));
    b.push_back(static_cast<unsigned char>(v >> 8));
  };
  auto u32 = [&](std::uint32_t v) {
    for (int k = 0; k < 4; ++k) b.push_back(static_cast<unsigned char>(v >> (8 * k)));
  };
  u32(static_cast<std::uint32_t>(id.groups.size()));
  u32(static_cast<std::uint32_t>(id.materials.size()));
  for (const auto* names : {&id.groups, &id.materials})
    for (const std::string& n : *names) {
      if (n.size() > 65535) throw std::invalid_argument("event log identity: a name longer than 65535 bytes");
      u16(n.size());
      b.insert(b.end(), n.begin(), n.end());
    }
  for (std::size_t i = 0; i < id.group.size(); ++i) {
    u16(id.group[i]);
    u16(id.material[i]);
  }
  while (b.size() % 8 != 0) b.push_back(0);
  u32(crc32c(b.data(), b.size()));
  u32(0);
  return b;
}

EventLogIdentity decode_event_identity(const unsigned char* p, std::size_t n, std::uint64_t particles,
                                       const std::string& path) {
  auto fail = [&](std::size_t at, const std::string& why) {
    throw IoError(fmt::format("{}: corrupt event log identity section at byte offset {}: {}", path,
                              kEventLogHeaderSize + at, why));
  };
  if (n < 24 || n % 8 != 0) fail(0, fmt::format("length {} (expected a multiple of 8, at least 24)", n));
  if (std::memcmp(p, kEventIdentityMagic, 8) != 0) fail(0, "bad magic");
  if (const std::uint32_t stored = get_u32(p + n - 8), computed = crc32c(p, n - 8); stored != computed)
    fail(n - 8, fmt::format("checksum {:#010x}, the bytes give {:#010x}", stored, computed));
  EventLogIdentity id;
  std::size_t at = 16;
  const std::uint32_t G = get_u32(p + 8), M = get_u32(p + 12);
  if (G > 65535 || M > 65535) fail(8, fmt::format("{} groups and {} materials (at most 65535 each)", G, M));
  for (std::uint32_t k = 0; k < G + M; ++k) {
    if (at + 2 > n - 8) fail(at, "the names run past the section");
    const std::size_t len = p[at] | (std::size_t{p[at + 1]} << 8);
    if (at + 2 + len > n - 8) fail(at, fmt::format("a name of {} bytes runs past the section", len));
    (k < G ? id.groups : id.materials).emplace_back(reinterpret_cast<const char*>(p + at + 2), len);
    at += 2 + len;
  }
  if (particles > (n - 8 - at) / 4)
    fail(at, fmt::format("{} bytes left for the {} particles' group and material", n - 8 - at, particles));
  id.group.resize(particles);
  id.material.resize(particles);
  for (std::uint64_t i = 0; i < particles; ++i, at += 4) {
    id.group[i] = static_cast<std::uint16_t>(p[at] | (p[at + 1] << 8));
    id.material[i] = static_cast<std::uint16_t>(p[at + 2] | (p[at + 3] << 8));
    if (id.group[i] >= G || id.material[i] >= M)
      fail(at, fmt::format("particle {} has group {} and material {} (of {} and {})", i, id.group[i], id.material[i], G, M));
  }
  return id;
}

// ---- event log reader -----------------------------------------------------------------------

EventLogReader::EventLogReader(const std::string& path) : path_(path) {
  fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd_ < 0) throw IoError(fmt::format("{}: cannot open event log: {}", path, std::strerror(errno)));
  struct stat st {};
  if (::fstat(fd_, &st) != 0) {
    const int err = errno;
    ::close(fd_);
    throw IoError(fmt::format("{}: cannot read the event log's size: {}", path, std::strerror(err)));
  }
  if (!S_ISREG(st.st_mode)) {
    ::close(fd_);
    throw IoError(fmt::format("{}: is {}, not an event log", path,
                              S_ISDIR(st.st_mode) ? "a directory" : "not a regular file"));
  }
  size_ = static_cast<std::uint64_t>(st.st_size);
  unsigned char h[kEventLogHeaderSize];
  auto fail = [&](const std::string& msg) {
    ::close(fd_);
    fd_ = -1;
    throw IoError(msg);
  };
  if (size_ < kEventLogHeaderSize ||
      ::pread(fd_, h, kEventLogHeaderSize, 0) != static_cast<ssize_t>(kEventLogHeaderSize))
    fail(fmt::format("{}: truncated event log header at byte offset {} (file has {} bytes, header needs {})", path, 0,
                     size_, kEventLogHeaderSize));
  if (std::memcmp(h, kEventLogMagic, 8) != 0)
    fail(fmt::format("{}: not a matep event log (bad magic at byte offset 0)", path));
  header_.version = get_u32(h + 8);
  header_.dimension = get_u32(h + 12);
  header_.record_size = get_u32(h + 16);
  header_.particles = get_u64(h + 24);
  if (header_.version < kEventLogVersion || header_.version > kEventLogVersionIdentity)
    fail(fmt::format("{}: event log version {} at byte offset 8 is not supported (this build reads versions {} to {})",
                     path, header_.version, kEventLogVersion, kEventLogVersionIdentity));
  if (has_blocks(header_)) {
    const std::uint32_t stored = get_u32(h + 60), computed = crc32c(h, 60);
    if (stored != computed)
      fail(fmt::format("{}: corrupt event log header: checksum at byte offset 60 is {:#010x}, bytes 0..59 give "
                       "{:#010x}",
                       path, stored, computed));
    header_.flags = get_u32(h + 20);
    header_.block_records = get_u32(h + 32);
    if (header_.flags & ~kEventLogFlagFixed)
      fail(fmt::format("{}: corrupt event log header: unknown flags {:#x} at byte offset 20", path, header_.flags));
    if (header_.block_records < 1 || header_.block_records > kEventLogMaxBlockRecords)
      fail(fmt::format("{}: corrupt event log header: block length {} at byte offset 32 (expected 1 to {})", path,
                       header_.block_records, kEventLogMaxBlockRecords));
  }
  if (header_.record_size != kEventRecordSize)
    fail(fmt::format("{}: corrupt event log header: record size {} at byte offset 16 (expected {})", path,
                     header_.record_size, kEventRecordSize));
  if (header_.dimension != 2 && header_.dimension != 3)
    fail(fmt::format("{}: corrupt event log header: dimension {} at byte offset 12 (expected 2 or 3)", path,
                     header_.dimension));
  // Ids are 32-bit: a larger count cannot come from a run.
  if (header_.particles > (std::uint64_t{1} << 32))
    fail(fmt::format("{}: corrupt event log header: particle count {} at byte offset 24 (ids are 32-bit)", path,
                     header_.particles));
  if (header_.version >= kEventLogVersionIdentity) {
    const std::uint64_t n = get_u32(h + 36);
    if (n > size_ - kEventLogHeaderSize)
      fail(fmt::format("{}: truncated event log: the identity section at byte offset 64 has {} bytes, the file {} after "
                       "the header",
                       path, n, size_ - kEventLogHeaderSize));
    std::vector<unsigned char> sec(n);  // <= the file's size
    if (n > 0 && ::pread(fd_, sec.data(), n, kEventLogHeaderSize) != static_cast<ssize_t>(n))
      fail(fmt::format("{}: cannot read the identity section at byte offset 64", path));
    try {
      identity_ = decode_event_identity(sec.data(), sec.size(), header_.particles, path);
    } catch (const IoError& e) {
      fail(e.what());
    }
    header_.data_offset = kEventLogHeaderSize + n;
  }
  // The layout fixes the number of records; anything else is a cut (or padded) file.
  const std::uint64_t body = size_ - header_.data_offset;
  if (!has_blocks(header_)) {
    records_ = body / kEventRecordSize;
    if (body % kEventRecordSize != 0)
      fail(fmt::format("{}: truncated event record at byte offset {} ({} of {} bytes)", path,
                       record_offset(header_, records_), body % kEventRecordSize, kEventRecordSize));
  } else {
    const std::uint64_t full = body / block_bytes(header_), tail = body % block_bytes(header_);
    if (tail < kEventBlockTrailerSize || (tail - kEventBlockTrailerSize) % kEventRecordSize != 0)
      fail(fmt::format("{}: truncated event log: the last block, at byte offset {}, has {} bytes (not whole {}-byte "
                       "records and a {}-byte checksum record)",
                       path, header_.data_offset + full * block_bytes(header_), tail, kEventRecordSize,
                       kEventBlockTrailerSize));
    records_ = full * header_.block_records + (tail - kEventBlockTrailerSize) / kEventRecordSize;
  }
}

EventLogReader::~EventLogReader() {
  if (fd_ >= 0) ::close(fd_);
}

std::uint64_t EventLogReader::load_block(std::uint64_t index, std::vector<unsigned char>& buf) {
  // Versions 1 and 2 have no blocks: chunks of kEventLogBlockRecords records, unchecked.
  const std::uint64_t k = has_blocks(header_) ? header_.block_records : kEventLogBlockRecords;
  const std::uint64_t first = index - index % k;
  const std::uint64_t count = std::min<std::uint64_t>(k, records_ - first);
  const bool last = first + k > records_;  // the block holding records_ - 1, or the empty one after
  const std::uint64_t off = block_offset(header_, first);
  const std::uint64_t bytes = count * kEventRecordSize + (has_blocks(header_) ? kEventBlockTrailerSize : 0);
  buf.resize(bytes);  // <= the file's size (the layout was checked against it)
  std::uint64_t got = 0;
  while (got < bytes) {
    const ssize_t n = ::pread(fd_, buf.data() + got, bytes - got, static_cast<off_t>(off + got));
    if (n <= 0)
      throw IoError(fmt::format("{}: cannot read the block at byte offset {}: {}", path_, off,
                                n < 0 ? std::strerror(errno) : "the file got shorter"));
    got += static_cast<std::uint64_t>(n);
  }
  if (has_blocks(header_)) {
    const unsigned char* t = buf.data() + count * kEventRecordSize;
    const std::uint32_t stored = get_u32(t + 24);
    const std::uint32_t computed = crc32c(t, 24, crc32c(buf.data(), count * kEventRecordSize));
    std::string why;
    if (std::memcmp(t, kEventBlockMagic, 8) != 0)
      why = "no checksum record (bad magic)";
    else if (stored != computed)
      why = fmt::format("checksum {:#010x}, the bytes give {:#010x}", stored, computed);
    else if (get_u32(t + 8) != count || get_u64(t + 16) != first + count ||
             (get_u32(t + 12) & kEventBlockFlagLast) != (last ? kEventBlockFlagLast : 0u))
      why = fmt::format("its checksum record says {} records, {} in all{}, the file's layout {}, {}{}", get_u32(t + 8),
                        get_u64(t + 16), (get_u32(t + 12) & kEventBlockFlagLast) ? ", last" : "", count,
                        first + count, last ? ", last" : "");
    if (!why.empty())
      throw IoError(fmt::format("{}: corrupt block at byte offset {} ({}): {}", path_, off,
                                count ? fmt::format("records {} to {}", first, first + count - 1)
                                      : std::string("the empty last block"),
                                why));
  }
  return first;
}

EventRecord EventLogReader::decode_checked(const unsigned char* p, std::uint64_t index) const {
  EventRecord r = decode_event_record(p);
  const std::string why = check_event_record(r, header_);
  if (!why.empty())
    throw IoError(fmt::format("{}: corrupt event record {} at byte offset {}: {}", path_, index,
                              record_offset(header_, index), why));
  return r;
}

bool EventLogReader::next(EventRecord& rec) {
  if (index_ >= records_) {
    // A version-3 log whose records fill whole blocks ends with an empty last block: check it too.
    if (has_blocks(header_) && !end_checked_ && records_ % header_.block_records == 0) load_block(records_, block_);
    end_checked_ = true;
    block_.clear();
    return false;
  }
  if (block_.empty() || index_ >= block_first_ + block_count_) {
    block_first_ = load_block(index_, block_);
    block_count_ = (block_.size() - (has_blocks(header_) ? kEventBlockTrailerSize : 0)) / kEventRecordSize;
  }
  rec = decode_checked(block_.data() + (index_ - block_first_) * kEventRecordSize, index_);
  ++index_;
  return true;
}

EventRecord EventLogReader::record_at(std::uint64_t index) {
  if (index >= records_)
    throw IoError(fmt::format("{}: no record {} (the log has {})", path_, index, records_));
  std::vector<unsigned char> buf;
  const std::uint64_t first = load_block(index, buf);
  return decode_checked(buf.data() + (index - first) * kEventRecordSize, index);
}

// ---- event log encoder and writer ------------------------------------------------------------

EventLogEncoder::EventLogEncoder(std::FILE* f, std::string path, std::uint32_t dimension, std::uint64_t particles,
                                 bool fixed_grains, std::uint32_t block_records, const EventLogIdentity* identity)
    : f_(f), path_(std::move(path)), k_(block_records) {
  if (k_ < 1 || k_ > kEventLogMaxBlockRecords) throw std::invalid_argument("event log block length out of range");
  if (identity && identity->group.size() != particles)
    throw std::invalid_argument("event log identity: not one entry per particle");
  const std::vector<unsigned char> section = identity ? encode_event_identity(*identity) : std::vector<unsigned char>{};
  if (section.size() > 0xffffffffu) throw std::invalid_argument("event log identity: too many particles");
  block_.resize(std::size_t{k_} * kEventRecordSize + kEventBlockTrailerSize);
  unsigned char h[kEventLogHeaderSize] = {};
  std::memcpy(h, kEventLogMagic, 8);
  put_u32(h + 8, identity ? kEventLogVersionIdentity : kEventLogVersionChecked);
  put_u32(h + 36, static_cast<std::uint32_t>(section.size()));
  put_u32(h + 12, dimension);
  put_u32(h + 16, kEventRecordSize);
  put_u32(h + 20, fixed_grains ? kEventLogFlagFixed : 0u);
  put_u64(h + 24, particles);
  put_u32(h + 32, k_);
  put_u32(h + 60, crc32c(h, 60));
  put(h, kEventLogHeaderSize);
  if (!section.empty()) put(section.data(), section.size());
}

EventLogEncoder::EventLogEncoder(std::FILE* f, std::string path, const EventLogMark& from, std::uint32_t block_records)
    : f_(f), path_(std::move(path)), k_(block_records), file_(from.file), total_(from.total),
      in_block_(static_cast<std::size_t>(from.in_block)) {
  block_.resize(std::size_t{k_} * kEventRecordSize + kEventBlockTrailerSize);
  if (from.in_block >= k_ || from.pending.size() != in_block_ * kEventRecordSize)
    throw IoError(fmt::format("{}: the checkpoint's unfinished block does not fit this log", path_));
  std::copy(from.pending.begin(), from.pending.end(), block_.begin());
}

EventLogMark EventLogEncoder::mark() const {
  EventLogMark m;
  m.file = file_;
  m.total = total_;
  m.in_block = in_block_;
  m.pending.assign(block_.begin(), block_.begin() + static_cast<std::ptrdiff_t>(in_block_ * kEventRecordSize));
  return m;
}

void EventLogEncoder::put(const void* p, std::size_t n) {
  if (std::fwrite(p, 1, n, f_) != n) throw WriteError(fmt::format("{}: write failed: {}", path_, std::strerror(errno)));
  file_.bytes += n;
  file_.crc = crc32c(p, n, file_.crc);
}

void EventLogEncoder::add(const EventRecord& r) {
  if (finished_) throw std::logic_error("EventLogEncoder::add after finish");
  encode_event_record(r, block_.data() + in_block_ * kEventRecordSize);
  ++total_;
  if (++in_block_ == k_) flush_block(false);
}

void EventLogEncoder::flush_block(bool last) {
  unsigned char* t = block_.data() + in_block_ * kEventRecordSize;
  std::memcpy(t, kEventBlockMagic, 8);
  put_u32(t + 8, static_cast<std::uint32_t>(in_block_));
  put_u32(t + 12, last ? kEventBlockFlagLast : 0u);
  put_u64(t + 16, total_);
  put_u32(t + 24, crc32c(t, 24, crc32c(block_.data(), in_block_ * kEventRecordSize)));
  put_u32(t + 28, 0);
  const std::size_t n = in_block_ * kEventRecordSize + kEventBlockTrailerSize;
  in_block_ = 0;
  put(block_.data(), n);
}

void EventLogEncoder::finish() {
  if (finished_) return;
  finished_ = true;
  flush_block(true);
}

template <int D>
EventLogWriter<D>::EventLogWriter(const std::string& path, std::uint64_t particles, bool fixed_grains,
                                  const EventLogIdentity* identity)
    : path_(path) {
  f_ = open_or_throw(path, "wb");
  std::setvbuf(f_, nullptr, _IONBF, 0);  // the encoder writes whole blocks
  try {
    enc_ = std::make_unique<EventLogEncoder>(f_, path, D, particles, fixed_grains, kEventLogBlockRecords, identity);
  } catch (...) {
    std::fclose(f_);
    f_ = nullptr;
    throw;
  }
}

template <int D>
EventLogWriter<D>::EventLogWriter(const std::string& path, const EventLogMark& from) : path_(path) {
  f_ = open_or_throw(path, "ab");
  std::setvbuf(f_, nullptr, _IONBF, 0);
  try {
    enc_ = std::make_unique<EventLogEncoder>(f_, path, from);
  } catch (...) {
    std::fclose(f_);
    f_ = nullptr;
    throw;
  }
}

template <int D>
EventLogWriter<D>::~EventLogWriter() {
  try {
    close();
  } catch (const IoError&) {  // close() reports it when called; a destructor cannot
  }
}

template <int D>
void EventLogWriter<D>::close() {
  if (!f_) return;
  std::FILE* f = f_;
  f_ = nullptr;
  std::string err;
  try {
    enc_->finish();
  } catch (const IoError& e) {
    err = e.what();
  }
  if (std::fclose(f) != 0 && err.empty()) err = fmt::format("{}: write failed: {}", path_, std::strerror(errno));
  if (!err.empty()) throw WriteError(err);
}

template <int D>
void EventLogWriter<D>::on_collision(const CollisionRecord<D>& c) {
  if (!f_) return;
  EventRecord r;
  r.time = c.time;
  r.kind = static_cast<std::uint8_t>(c.kind);
  r.i = c.i;
  r.j = c.j;
  r.mi = c.mi;
  r.mj = c.mj;
  r.e = c.e;
  to3<D>(c.normal, r.normal);
  to3<D>(c.vi_before, r.vi_before);
  to3<D>(c.vj_before, r.vj_before);
  to3<D>(c.vi_after, r.vi_after);
  to3<D>(c.vj_after, r.vj_after);
  spin3<D>(c.wi_before, r.wi_before);
  spin3<D>(c.wj_before, r.wj_before);
  spin3<D>(c.wi_after, r.wi_after);
  spin3<D>(c.wj_after, r.wj_after);
  enc_->add(r);
}

// A grain leaving through an outlet: kind 6, i its id, j the outlet's index, mi its mass, its
// velocity and spin as vi_before = vi_after and wi_before = wi_after.
template <int D>
void EventLogWriter<D>::on_outflow(const OutflowRecord<D>& o) {
  CollisionRecord<D> c;
  c.time = o.time;
  c.kind = EventKind::Outflow;
  c.i = o.id;
  c.j = o.outlet;
  c.mi = o.mass;
  c.e = 0.0;
  c.vi_before = c.vi_after = o.v;
  c.wi_before = c.wi_after = o.w;
  on_collision(c);
}

// A grain inserted by an inlet: kind 7, i its id, j the inlet's index, mi its mass, mj its radius,
// its velocity as vi_before = vi_after.
template <int D>
void EventLogWriter<D>::on_inflow(const InflowRecord<D>& o) {
  CollisionRecord<D> c;
  c.time = o.time;
  c.kind = EventKind::Inflow;
  c.i = o.id;
  c.j = o.inlet;
  c.mi = o.mass;
  c.mj = o.radius;
  c.e = 0.0;
  c.vi_before = c.vi_after = o.v;
  on_collision(c);
}

template class EventLogWriter<2>;
template class EventLogWriter<3>;

// ---- outflow.csv ------------------------------------------------------------------------------

template <int D>
OutflowCsvWriter<D>::OutflowCsvWriter(const std::string& path, const std::vector<std::string>& outlets,
                                      const FileMark* resume)
    : outlets_(outlets), f_(std::make_unique<CheckedFile>(path, resume ? "a" : "w", 0, resume ? *resume : FileMark{})) {
  if (resume) return;
  f_->puts(D == 3 ? "time,id,outlet,mass,x,y,z,vx,vy,vz\n" : "time,id,outlet,mass,x,y,vx,vy\n");
}

template <int D>
OutflowCsvWriter<D>::~OutflowCsvWriter() = default;

template <int D>
void OutflowCsvWriter<D>::close() {
  f_->close();
}

template <int D>
void OutflowCsvWriter<D>::on_outflow(const OutflowRecord<D>& r) {
  f_->print("{:.17g},{},{},{:.17g}", r.time, r.id, outlets_.at(r.outlet), r.mass);
  for (int k = 0; k < D; ++k) f_->print(",{:.17g}", r.x[k]);
  for (int k = 0; k < D; ++k) f_->print(",{:.17g}", r.v[k]);
  f_->puts("\n");
}

template <int D>
void OutflowCsvWriter<D>::on_sample(const ThermoSample&) {
  f_->flush();  // complete up to the last thermo row if a run stops early
}

template class OutflowCsvWriter<2>;
template class OutflowCsvWriter<3>;

// ---- thermo.csv -------------------------------------------------------------------------------

ThermoCsvWriter::ThermoCsvWriter(const std::string& path, const std::vector<std::string>& walls, int dim, bool flows,
                                 const FileMark* resume)
    : walls_(walls.size()), dim_(dim), flows_(flows),
      f_(std::make_unique<CheckedFile>(path, resume ? "a" : "w", 0, resume ? *resume : FileMark{})) {
  if (resume) return;
  f_->puts("time,kinetic_energy,rotational_energy,potential_energy,temperature,collisions,pressure,elastic_energy,"
           "soft");
  if (flows_) f_->puts(",grains,grains_in,mass_in,grains_out,mass_out");
  for (const auto& w : walls) {
    if (dim_ == 2) f_->print(",{0}_fx,{0}_fy,{0}_tz", w);
    else f_->print(",{0}_fx,{0}_fy,{0}_fz,{0}_tx,{0}_ty,{0}_tz", w);
  }
  f_->puts("\n");
}

ThermoCsvWriter::~ThermoCsvWriter() = default;

void ThermoCsvWriter::close() { f_->close(); }

void ThermoCsvWriter::on_sample(const ThermoSample& s) {
  f_->print("{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{},{:.17g},{:.17g},{}", s.time, s.kinetic_energy,
            s.rotational_energy, s.potential_energy, s.temperature, s.collisions, s.pressure, s.elastic_energy, s.soft);
  if (flows_) f_->print(",{},{},{:.17g},{},{:.17g}", s.grains, s.grains_in, s.mass_in, s.grains_out, s.mass_out);
  // Six numbers per wall in the sample (2D: force x, y and torque z are the meaningful ones); none
  // at t = 0 (no interval yet): zeros.
  for (std::size_t w = 0; w < walls_; ++w) {
    const bool have = s.wall_loads.size() >= 6 * (w + 1);
    auto at = [&](int k) { return have ? s.wall_loads[6 * w + static_cast<std::size_t>(k)] : 0.0; };
    if (dim_ == 2) f_->print(",{:.17g},{:.17g},{:.17g}", at(0), at(1), at(5));
    else f_->print(",{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g}", at(0), at(1), at(2), at(3), at(4), at(5));
  }
  f_->puts("\n");
  f_->flush();  // a run that stops early keeps every row written so far
}

// ---- final_state.csv --------------------------------------------------------------------------

template <int D>
void write_final_state(const std::string& path, const RunResult<D>& res, const StateLabels& labels) {
  const auto& radius = res.radius;
  CheckedFile f(path, "w");
  if constexpr (D == 3)
    f.puts("id,x,y,z,vx,vy,vz,wx,wy,wz,radius,group,material\n");
  else
    f.puts("id,x,y,vx,vy,w,radius,group,material\n");
  for (std::size_t i = 0; i < res.x.size(); ++i) {
    const auto& x = res.x[i];
    const auto& v = res.v[i];
    const Spin<D> w = res.w.empty() ? Spin<D>::Zero() : res.w[i];
    const std::size_t id = res.id.empty() ? i : std::size_t{res.id[i]};
    const std::string& group = labels.group_names.at(static_cast<std::size_t>(labels.group.at(id)));
    const std::string& material = labels.materials.at(res.material.empty() ? 0 : static_cast<std::size_t>(res.material[i]));
    if constexpr (D == 3)
      f.print("{},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{},{}\n", id, x[0],
              x[1], x[2], v[0], v[1], v[2], w[0], w[1], w[2], radius[i], group, material);
    else
      f.print("{},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{},{}\n", id, x[0], x[1], v[0], v[1], w[0], radius[i],
              group, material);
  }
  f.close();
}

template void write_final_state<2>(const std::string&, const RunResult<2>&, const StateLabels&);
template void write_final_state<3>(const std::string&, const RunResult<3>&, const StateLabels&);

// ---- summary.json -----------------------------------------------------------------------------

namespace {
std::string json_string(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      case '\t': out += "\\t"; break;
      default:
        if (static_cast<unsigned char>(c) < 0x20)
          out += fmt::format("\\u{:04x}", static_cast<int>(c));
        else
          out += c;
    }
  }
  return out + "\"";
}
std::string json_number(double v) {
  if (!std::isfinite(v)) return "null";
  return fmt::format("{:.17g}", v);
}
}  // namespace

template <int D>
void write_summary(const std::string& path, const SummaryInfo& info, const RunResult<D>& r) {
  CheckedFile f(path, "w");
  const double wall = r.wall_seconds > 0.0 ? r.wall_seconds : 1e-9;
  f.print("{{\n");
  f.print("  \"scene\": {},\n", json_string(info.scene));
  f.print("  \"method\": {},\n", json_string(info.method));
  f.print("  \"queue\": {},\n", json_string(info.queue));
  f.print("  \"dimension\": {},\n", info.dimension);
  f.print("  \"particles\": {},\n", info.particles);
  f.print("  \"seed\": {},\n", info.seed);
  f.print("  \"end_time\": {},\n", json_number(info.end_time));
  f.print("  \"time_reached\": {},\n", json_number(r.time));
  f.print("  \"wall_seconds\": {},\n", json_number(r.wall_seconds));
  // With neighbour lists (EDM, the hybrid) the crossings are shell exits.
  f.print("  \"events\": {{\"pair_collisions\": {}, \"wall_collisions\": {}, \"{}\": {}, "
             "\"stale\": {}, \"thermo_samples\": {}, \"total\": {}}},\n",
             r.counts.pair, r.counts.wall, r.lists ? "shell_exits" : "cell_crossings", r.counts.cell, r.counts.stale,
             r.counts.samples, r.counts.total());
  if (r.method != Method::Tdm) f.print("  \"neighbours\": {},\n", json_string(r.lists ? "lists" : "cells"));
  if (r.method != Method::Tdm) f.print("  \"resorts\": {},\n", r.resorts);
  f.print("  \"events_per_second\": {},\n", json_number(r.counts.total() / wall));
  f.print("  \"collisions_per_second\": {},\n", json_number(r.counts.collisions() / wall));
  f.print("  \"max_overlap\": {},\n", json_number(r.max_overlap));
  f.print("  \"max_overlap_relative\": {},\n", json_number(r.max_overlap_relative));
  f.print("  \"grains_at_end\": {},\n", r.x.size());
  // The legend of the group and material indices in the snapshots (io/snapshots.hpp).
  auto names = [&](const char* key, const std::vector<std::string>& v) {
    f.print("  \"{}\": [", key);
    for (std::size_t k = 0; k < v.size(); ++k) f.print("{}{}", k ? ", " : "", json_string(v[k]));
    f.print("],\n");
  };
  names("groups", info.groups);
  names("materials", info.materials);
  if (info.flows) {
    f.print("  \"inflow\": {{\"grains\": {}, \"mass\": {}}},\n", r.grains_in, json_number(r.mass_in));
    f.print("  \"outflow\": {{\"grains\": {}, \"mass\": {}}},\n", r.grains_out, json_number(r.mass_out));
    f.print("  \"inlets\": [");
    for (std::size_t k = 0; k < r.inlets.size(); ++k)
      f.print("{}{{\"name\": {}, \"due\": {}, \"inserted\": {}, \"missed\": {}}}", k ? ", " : "",
                 json_string(r.inlets[k].name), r.inlets[k].due, r.inlets[k].inserted, r.inlets[k].missed);
    f.print("],\n");
  }
  if (r.method != Method::Edm) {
    const SoftStats& s = r.soft;
    f.print("  \"soft\": {{\"steps\": {}, \"dt\": {}, \"default_dt\": {}, \"max_stable_dt\": {}, "
               "\"contact_time\": {}, \"rayleigh_time\": {}, \"impact_speed\": {}, \"skin\": {}, "
               "\"rebuilds\": {}, \"contacts\": {}, \"threads\": {}, \"particle_steps_per_second\": {}}},\n",
               s.steps, json_number(s.dt), json_number(s.default_dt), json_number(s.max_stable_dt),
               json_number(s.contact_time), json_number(s.rayleigh_time), json_number(s.impact_speed),
               json_number(s.skin), s.rebuilds, s.contacts, s.threads, json_number(s.particle_steps_per_second));
  }
  if (r.method == Method::Hybrid) {
    const HybridStats& h = r.hybrid;
    f.print("  \"hybrid\": {{\"to_soft\": {}, \"by_stability\": {}, \"by_cost\": {}, \"by_cluster\": {}, "
               "\"by_capture\": {}, \"by_overlap\": {}, \"to_hard\": {}, \"released_by_cost\": {}, \"slept\": {}, \"woken\": {}, "
               "\"substeps\": {}, \"coasts\": {}, \"coasted_steps\": {}, \"soft_particle_steps\": {}, \"max_soft\": {}, \"soft_at_end\": {}, "
               "\"stability\": {}, \"hysteresis\": {}, \"skin\": {}, \"cost_ratio\": {}, \"rest_speed\": {}, "
               "\"rest_time\": {}, \"cost_measured\": {}, \"cost_ratio_measured\": {}, "
               "\"hard_ns_per_particle_collision\": {}, \"soft_ns_per_particle_step\": {}}},\n",
               h.to_soft, h.by_stability, h.by_cost, h.by_cluster, h.by_capture, h.by_overlap, h.to_hard, h.released_by_cost, h.slept,
               h.woken, h.substeps, h.coasts, h.coasted_steps, h.soft_particle_steps, h.max_soft, h.soft_at_end, json_number(h.stability),
               json_number(h.hysteresis), json_number(h.skin), json_number(h.cost_ratio), json_number(h.rest_speed),
               json_number(h.rest_time), r.hybrid_cost.followed, json_number(r.hybrid_cost.ratio),
               json_number(r.hybrid_cost.hard_ns_per_collision), json_number(r.hybrid_cost.soft_ns_per_step));
  }
  f.print("  \"status\": {},\n", json_string(r.status));
  f.print("  \"message\": {}\n", json_string(r.message));
  f.print("}}\n");
  f.close();
}

template void write_summary<2>(const std::string&, const SummaryInfo&, const RunResult<2>&);
template void write_summary<3>(const std::string&, const SummaryInfo&, const RunResult<3>&);

}  // namespace matep

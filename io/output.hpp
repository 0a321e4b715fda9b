// Run outputs: thermo.csv, final_state.csv, summary.json and the binary event log events.bin.
// Formats are documented in README.md ("Outputs").
#pragma once

#include <cstdint>
#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "engine/edm.hpp"
#include "engine/observer.hpp"
#include "io/checked_file.hpp"
#include "io/io_error.hpp"
#include "io/snapshots.hpp"
#include "io/vec3.hpp"

namespace matep {

// Event log layout, version 1 (little-endian). A 64-byte header: magic "MATEPLOG", u32 version,
// u32 dimension, u32 record size, u32 reserved, u64 particle count, zero padding. Then records
// of kEventRecordSize bytes (vectors always have 3 components; 2D leaves z = 0 and stores the
// disk spin in the z component).
// Version 2 is the same layout, written by runs with fixed grains: a pair record whose partner j is
// a fixed grain has mj = +infinity and vj, wj = 0 (version 1 never has an infinite mass).
// Version 3 (written since issue 17) adds checksums. Header: bytes 20..23 are flags (bit 0: fixed
// grains, the version-2 meaning of mj = +infinity; other bits 0), bytes 32..35 the block length K
// in records, bytes 60..63 the CRC-32C of bytes 0..59. The records come in blocks of K, each
// followed by a 32-byte checksum record: "MATEPBLK", u32 records in the block, u32 flags (bit 0:
// the last block), u64 records up to and including this block, u32 CRC-32C of the block's records
// and of bytes 0..23 of the checksum record, u32 zero. The last block (0..K-1 records) always ends
// the file, so a cut at a block boundary is seen too.
// Version 4 (written since issue 18) is version 3 with each particle's group and material: header
// bytes 36..39 give the length S of an identity section that follows the header (the records start
// at byte 64 + S): "MATEPIDS", u32 group count G, u32 material count M, the G group names then the
// M material names (each a u16 byte length and its UTF-8 bytes), then for every particle id a u16
// group index and a u16 material index, zero padding to a multiple of 8 bytes, and a final u32
// CRC-32C of the section's bytes before it and a u32 zero. Readers take all four versions.
inline constexpr char kEventLogMagic[8] = {'M', 'A', 'T', 'E', 'P', 'L', 'O', 'G'};
inline constexpr char kEventBlockMagic[8] = {'M', 'A', 'T', 'E', 'P', 'B', 'L', 'K'};
inline constexpr std::uint32_t kEventLogVersion = 1;
inline constexpr std::uint32_t kEventLogVersionFixed = 2;
inline constexpr std::uint32_t kEventLogVersionChecked = 3;
inline constexpr std::uint32_t kEventLogVersionIdentity = 4;  // the version runs write
inline constexpr char kEventIdentityMagic[8] = {'M', 'A', 'T', 'E', 'P', 'I', 'D', 'S'};
inline constexpr std::size_t kEventLogHeaderSize = 64;
inline constexpr std::size_t kEventRecordSize = 264;
inline constexpr std::size_t kEventBlockTrailerSize = 32;
inline constexpr std::uint32_t kEventLogBlockRecords = 1024;  // K of the logs this build writes
inline constexpr std::uint32_t kEventLogMaxBlockRecords = 65536;  // the largest K a reader takes
inline constexpr std::uint32_t kEventLogFlagFixed = 1;
inline constexpr std::uint32_t kEventBlockFlagLast = 1;

// CRC-32C (Castagnoli polynomial 0x1EDC6F41, reflected 0x82F63B78; RFC 3720, section 12.1 and
// appendix B.4): crc32c("123456789") = 0xE3069283. `crc` continues an earlier value.
std::uint32_t crc32c(const void* data, std::size_t n, std::uint32_t crc = 0);
// The same, table-driven on every machine (crc32c may use the SSE4.2 instruction).
std::uint32_t crc32c_portable(const void* data, std::size_t n, std::uint32_t crc = 0);

// The record as read back (3-component vectors regardless of dimension).
struct EventRecord {
  double time = 0.0;
  std::uint8_t kind = 0;
  std::uint32_t i = 0, j = 0;
  double mi = 0.0, mj = 0.0, e = 0.0;
  double normal[3]{}, vi_before[3]{}, vj_before[3]{}, vi_after[3]{}, vj_after[3]{};
  double wi_before[3]{}, wj_before[3]{}, wi_after[3]{}, wj_after[3]{};
};

void encode_event_record(const EventRecord& r, unsigned char* out);
EventRecord decode_event_record(const unsigned char* in);

struct EventLogHeader {
  std::uint32_t version = kEventLogVersionChecked;
  std::uint32_t dimension = 3;
  std::uint32_t record_size = kEventRecordSize;
  std::uint32_t flags = 0;              // version 3
  std::uint64_t particles = 0;
  std::uint32_t block_records = 0;      // version 3: K; 0 in versions 1 and 2 (no blocks)
  std::uint64_t data_offset = kEventLogHeaderSize;  // where the records begin (version 4: after the identity)
  // Pair records may have mj = +infinity (a fixed partner).
  bool fixed_grains() const {
    return version == kEventLogVersionFixed || (version >= kEventLogVersionChecked && (flags & kEventLogFlagFixed));
  }
};

// Version 4's identity section: each particle id's group and material (indices into the names).
struct EventLogIdentity {
  std::vector<std::string> groups, materials;
  std::vector<std::uint16_t> group, material;  // one per particle id
};
// The section's bytes (padded, with its checksum); throws std::invalid_argument for more than 65535
// names or a name longer than 65535 bytes.
std::vector<unsigned char> encode_event_identity(const EventLogIdentity& id);
// Decodes and checks a section of `particles` ids read at byte offset 64; throws IoError naming `path`.
EventLogIdentity decode_event_identity(const unsigned char* p, std::size_t n, std::uint64_t particles,
                                       const std::string& path);

// Byte offset of record `index` (0-based) and of the block holding it (version 3; versions 1 and
// 2: the record's own offset).
std::uint64_t record_offset(const EventLogHeader& h, std::uint64_t index);
std::uint64_t block_offset(const EventLogHeader& h, std::uint64_t index);

// The checks every record gets when read (known kind 1..7; time, masses, e and every vector
// finite, mj = +infinity only for a pair record of a log with fixed grains; mi > 0 for every
// kind but 3, mj > 0 for pairs, the radius mj > 0 for inflows; i < particles, and j < particles
// for pairs). Returns the failing field and why, or an empty string.
std::string check_event_record(const EventRecord& r, const EventLogHeader& h);

// Streams records from events.bin, one block at a time: memory is bounded by one block (at most
// kEventLogMaxBlockRecords records, and never more than the file holds), never by the header's
// counts. Throws IoError naming the file and the byte offset on a bad header, an unknown
// version, a file that is not a whole number of records (blocks), a block whose checksum does
// not match and a record that fails check_event_record.
class EventLogReader {
 public:
  explicit EventLogReader(const std::string& path);
  ~EventLogReader();
  EventLogReader(const EventLogReader&) = delete;
  EventLogReader& operator=(const EventLogReader&) = delete;
  const EventLogHeader& header() const { return header_; }
  std::uint64_t records() const { return records_; }      // from the file's size and layout
  std::uint64_t file_size() const { return size_; }
  bool next(EventRecord& rec);  // false at the end
  // Byte offset of the record last returned by next().
  std::uint64_t offset() const { return index_ ? record_offset(header_, index_ - 1) : header_.data_offset; }
  // Version 4: each particle's group and material (empty in older versions).
  const EventLogIdentity& identity() const { return identity_; }
  // Random access (the block holding it is read and checked); does not move next().
  EventRecord record_at(std::uint64_t index);

 private:
  // Reads and checks the block holding record `index` into buf; returns its first record's index.
  std::uint64_t load_block(std::uint64_t index, std::vector<unsigned char>& buf);
  EventRecord decode_checked(const unsigned char* p, std::uint64_t index) const;
  std::string path_;
  int fd_ = -1;
  EventLogHeader header_;
  EventLogIdentity identity_;
  std::uint64_t size_ = 0;
  std::uint64_t records_ = 0;
  std::uint64_t index_ = 0;        // next record to return
  std::uint64_t block_first_ = 0;  // index of the first record in block_
  std::uint64_t block_count_ = 0;  // records in block_
  bool end_checked_ = false;       // the empty last block (version 3) was read
  std::vector<unsigned char> block_;
};

// Writes the version-3 layout into an open file (the EventLogWriter's and `matep log filter`'s
// encoder). Every write is checked: IoError names `path` and the OS error.
// What an event log held at a checkpoint: the bytes written (the header and whole blocks), the
// records so far and those of the unfinished block.
struct EventLogMark {
  FileMark file;
  std::uint64_t total = 0;
  std::uint64_t in_block = 0;
  std::vector<unsigned char> pending;  // in_block records, encoded
  template <class A>
  void archive(A& a) {
    a(file);
    a(total);
    a(in_block);
    a(pending);
  }
};

class EventLogEncoder {
 public:
  // With an identity (one group and material per particle): version 4, else version 3.
  EventLogEncoder(std::FILE* f, std::string path, std::uint32_t dimension, std::uint64_t particles, bool fixed_grains,
                  std::uint32_t block_records = kEventLogBlockRecords, const EventLogIdentity* identity = nullptr);
  // Continues a log whose file holds the bytes of `from` (positioned at its end).
  EventLogEncoder(std::FILE* f, std::string path, const EventLogMark& from,
                  std::uint32_t block_records = kEventLogBlockRecords);
  void add(const EventRecord& r);
  void finish();  // the last block (0..K-1 records); then nothing more may be added
  EventLogMark mark() const;

 private:
  void flush_block(bool last);
  void put(const void* p, std::size_t n);
  std::FILE* f_;
  std::string path_;
  std::uint32_t k_;
  FileMark file_;
  std::uint64_t total_ = 0;
  std::size_t in_block_ = 0;
  bool finished_ = false;
  std::vector<unsigned char> block_;
};

template <int D>
class EventLogWriter final : public Observer<D> {
 public:
  // Writes version 4 (version 3 without an identity); fixed_grains sets the header flag (pair
  // records may have mj = +infinity).
  EventLogWriter(const std::string& path, std::uint64_t particles, bool fixed_grains,
                 const EventLogIdentity* identity = nullptr);
  // Continues the log at `path`, which holds the bytes of `from` (a checkpoint's).
  EventLogWriter(const std::string& path, const EventLogMark& from);
  ~EventLogWriter() override;
  EventLogMark mark() const { return enc_->mark(); }
  bool wants_collisions() const override { return true; }
  void on_collision(const CollisionRecord<D>& rec) override;
  void on_outflow(const OutflowRecord<D>& rec) override;
  void on_inflow(const InflowRecord<D>& rec) override;
  void close();  // writes the last block; throws WriteError when a write or the close fails

 private:
  std::string path_;
  std::FILE* f_ = nullptr;
  std::unique_ptr<EventLogEncoder> enc_;
};

class ThermoCsvWriter final : public Observer<2>, public Observer<3> {
 public:
  // With wall names, each row also gives every wall's mean force and torque over the interval
  // (ThermoSample::wall_loads): columns NAME_fx, NAME_fy[, NAME_fz], then NAME_tz (2D) or NAME_tx,
  // NAME_ty, NAME_tz (3D).
  // With flows (a scene with inlets or outlets), each row also gives the grains present, the grains
  // inserted and removed so far and their masses: columns grains, grains_in, mass_in, grains_out,
  // mass_out.
  // resume: continue a file that holds the bytes of that mark (a checkpoint's; no header).
  explicit ThermoCsvWriter(const std::string& path, const std::vector<std::string>& walls = {}, int dim = 3,
                           bool flows = false, const FileMark* resume = nullptr);
  ~ThermoCsvWriter() override;
  FileMark mark() { return f_->mark(); }
  void on_sample(const ThermoSample& s) override;
  void close();  // checked (WriteError); the destructor closes unchecked

 private:
  std::size_t walls_ = 0;
  int dim_ = 3;
  bool flows_ = false;
  std::unique_ptr<CheckedFile> f_;
};

// outflow.csv: one row per grain taken out by an outlet, in the order they left: time, id, the
// outlet's name, mass, position and velocity as it entered the outlet.
template <int D>
class OutflowCsvWriter final : public Observer<D> {
 public:
  OutflowCsvWriter(const std::string& path, const std::vector<std::string>& outlets, const FileMark* resume = nullptr);
  ~OutflowCsvWriter() override;
  FileMark mark() { return f_->mark(); }
  void on_outflow(const OutflowRecord<D>& r) override;
  void on_sample(const ThermoSample&) override;
  void close();  // checked (WriteError); the destructor closes unchecked

 private:
  std::vector<std::string> outlets_;
  std::unique_ptr<CheckedFile> f_;
};

// The words of final_state.csv's last two columns: io/snapshots.hpp StateLabels.
template <int D>
void write_final_state(const std::string& path, const RunResult<D>& result, const StateLabels& labels);

struct SummaryInfo {
  std::string scene;
  std::string method;
  std::string queue;
  int dimension = 3;
  std::uint64_t particles = 0;
  std::uint64_t seed = 0;
  double end_time = 0.0;
  bool flows = false;  // the scene has inlets or outlets
  std::vector<std::string> groups, materials;  // the names of the group and material indices
};

template <int D>
void write_summary(const std::string& path, const SummaryInfo& info, const RunResult<D>& result);

}  // namespace matep

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

namespace matep {

// Event log layout, version 1 (little-endian). A 64-byte header: magic "MATEPLOG", u32 version,
// u32 dimension, u32 record size, u32 reserved, u64 particle count, zero padding. Then records
// of kEventRecordSize bytes (vectors always have 3 components; 2D leaves z = 0 and stores the
// disk spin in the z component).
// Version 2 is the same layout, written by runs with fixed grains: a pair record whose partner j is
// a fixed grain has mj = +infinity and vj, wj = 0. A reader takes both versions (version 1 never
// has an infinite mass); runs without fixed grains still write version 1.
inline constexpr char kEventLogMagic[8] = {'M', 'A', 'T', 'E', 'P', 'L', 'O', 'G'};
inline constexpr std::uint32_t kEventLogVersion = 1;
inline constexpr std::uint32_t kEventLogVersionFixed = 2;
inline constexpr std::size_t kEventLogHeaderSize = 64;
inline constexpr std::size_t kEventRecordSize = 264;

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
  std::uint32_t version = kEventLogVersion;
  std::uint32_t dimension = 3;
  std::uint32_t record_size = kEventRecordSize;
  std::uint64_t particles = 0;
};

// Streams records from events.bin; throws IoError naming the file and byte offset on a bad
// header, a wrong version or a truncated record.
class EventLogReader {
 public:
  explicit EventLogReader(const std::string& path);
  ~EventLogReader();
  const EventLogHeader& header() const { return header_; }
  bool next(EventRecord& rec);  // false at a clean end of file
  std::uint64_t offset() const { return offset_; }

 private:
  std::string path_;
  std::FILE* f_ = nullptr;
  EventLogHeader header_;
  std::uint64_t offset_ = 0;
  std::uint64_t size_ = 0;
};

template <int D>
class EventLogWriter final : public Observer<D> {
 public:
  // version: kEventLogVersion, or kEventLogVersionFixed for a system with fixed grains.
  EventLogWriter(const std::string& path, std::uint64_t particles, std::uint32_t version = kEventLogVersion);
  ~EventLogWriter() override;
  bool wants_collisions() const override { return true; }
  void on_collision(const CollisionRecord<D>& rec) override;
  void on_outflow(const OutflowRecord<D>& rec) override;
  void on_inflow(const InflowRecord<D>& rec) override;
  void close();  // checked (WriteError); the destructor closes unchecked

 private:
  std::string path_;
  std::FILE* f_ = nullptr;
  std::vector<char> buffer_;
};

class ThermoCsvWriter final : public Observer<2>, public Observer<3> {
 public:
  // With wall names, each row also gives every wall's mean force and torque over the interval
  // (ThermoSample::wall_loads): columns NAME_fx, NAME_fy[, NAME_fz], then NAME_tz (2D) or NAME_tx,
  // NAME_ty, NAME_tz (3D).
  // With flows (a scene with inlets or outlets), each row also gives the grains present, the grains
  // inserted and removed so far and their masses: columns grains, grains_in, mass_in, grains_out,
  // mass_out.
  explicit ThermoCsvWriter(const std::string& path, const std::vector<std::string>& walls = {}, int dim = 3,
                           bool flows = false);
  ~ThermoCsvWriter() override;
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
  OutflowCsvWriter(const std::string& path, const std::vector<std::string>& outlets);
  ~OutflowCsvWriter() override;
  void on_outflow(const OutflowRecord<D>& r) override;
  void on_sample(const ThermoSample&) override;
  void close();  // checked (WriteError); the destructor closes unchecked

 private:
  std::vector<std::string> outlets_;
  std::unique_ptr<CheckedFile> f_;
};

// VTK XML PolyData snapshots for ParaView: DIR/snapshots/snap_NNNNNN.vtp (points with radius,
// velocity, angular_velocity, id, mode 0 = hard / 1 = soft, cluster -1 = none) and the time
// series DIR/snapshots.pvd, rewritten after every snapshot so that it is complete whenever a run
// stops.
template <int D>
class VtkSnapshotWriter final : public Observer<D> {
 public:
  // With walls (and the domain box that clips unbounded ones), every snapshot time of the series
  // also shows each wall's surface: DIR/snapshots/wall_NAME.vtp once for a wall at rest,
  // DIR/snapshots/wall_NAME_NNNNNN.vtp at every snapshot for a moving one; the .pvd lists the grains
  // as part 0 and wall k as part k + 1.
  explicit VtkSnapshotWriter(const std::string& dir, const std::vector<Wall<D>>& walls = {},
                             const Vec<D>& lower = Vec<D>::Zero(), const Vec<D>& upper = Vec<D>::Zero());
  bool wants_snapshots() const override { return true; }
  void on_snapshot(const Snapshot<D>& snap) override;

 private:
  std::string wall_file(std::size_t w, double t);  // writes it when needed; the relative path
  std::string dir_;
  std::vector<Wall<D>> walls_;
  Vec<D> lower_, upper_;
  std::vector<std::string> static_file_;  // per wall: its file once written (walls at rest)
  // (time, files relative to dir_: the grains', then each wall's)
  std::vector<std::pair<double, std::vector<std::string>>> written_;
};

template <int D>
void write_final_state(const std::string& path, const RunResult<D>& result);

struct SummaryInfo {
  std::string scene;
  std::string method;
  std::string queue;
  int dimension = 3;
  std::uint64_t particles = 0;
  std::uint64_t seed = 0;
  double end_time = 0.0;
  bool flows = false;  // the scene has inlets or outlets
};

template <int D>
void write_summary(const std::string& path, const SummaryInfo& info, const RunResult<D>& result);

}  // namespace matep

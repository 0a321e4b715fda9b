// `matep log`: streaming tools over the binary event log events.bin (README, "Inspecting event
// logs"). Every function reads the log block by block through EventLogReader, which checks every
// block and record: memory is one block plus, for stats, per-particle counts that grow with the
// ids seen (bounded by the log's size, never sized from the header). A truncated or corrupt log
// throws IoError naming the file and the byte offset.
#pragma once

#include <cstdint>
#include <cstdio>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "io/output.hpp"

namespace matep {

struct Scene;

// "pair", "wall", "cell", "soft", "hard" for kinds 1..5; "unknown" otherwise.
const char* event_kind_name(std::uint8_t kind);
// The inverse for the kinds a user may select: pair, wall, soft, hard. Throws
// std::invalid_argument naming the word and the accepted ones.
std::uint8_t parse_event_kind(std::string_view word);
// "3,17,42" -> {3, 17, 42} (sorted, duplicates removed); throws std::invalid_argument.
std::vector<std::uint32_t> parse_id_list(std::string_view list);

// A log's header, size and record count (EventLogReader checks the header and that the size fits
// the layout, so a truncated log is refused before any record is processed).
struct LogFile {
  EventLogHeader header;
  std::uint64_t file_size = 0;
  std::uint64_t records = 0;
};
LogFile inspect_log(const std::string& path);

// ---- stats ------------------------------------------------------------------------------------

struct LogStats {
  std::string path;
  LogFile file;
  std::uint64_t by_kind[8] = {};  // index = kind (1 pair, 2 wall, 3 cell, 4 soft, 5 hard, 6 outflow, 7 inflow)
  double t_first = 0.0, t_last = 0.0;  // times of the first and last record (0 if none)

  // Collision rate over time: `bins` equal bins from t_first to t_last (the last bin includes
  // t_last). rate = (pair + wall) / bin width (0 when the span is 0).
  struct Bin {
    double t0 = 0.0, t1 = 0.0;
    std::uint64_t pair = 0, wall = 0;
    double rate = 0.0;
  };
  std::vector<Bin> bins;

  // Per particle (pair collisions count for both partners, wall collisions for the particle).
  std::uint64_t particles_collided = 0;  // particles with at least one collision
  std::uint32_t busiest = 0;             // most collisions (lowest id on a tie)
  std::uint64_t busiest_count = 0;

  // Over pair and wall collisions: largest normal impact speed |(vi_before - vj_before).n|.
  std::uint64_t collisions = 0;
  double max_impact = 0.0;
  std::uint64_t max_impact_index = 0;
  double max_impact_time = 0.0;
  std::uint8_t max_impact_kind = 0;
  std::uint32_t max_impact_i = 0, max_impact_j = 0;
  // Applied restitution e.
  double e_min = 0.0, e_max = 0.0, e_mean = 0.0;
  std::uint64_t e_min_index = 0, e_max_index = 0;
};

// Reads the header, the first record and the last record (random access) to fix the time bins,
// then streams every record once. The per-particle counts grow with the ids the records name, so
// memory is bounded by the log's size, not by the header's particle count. Throws IoError on a bad
// log and std::invalid_argument when bins == 0.
LogStats compute_log_stats(const std::string& path, std::size_t bins);

// The readable table printed by `matep log stats`.
std::string format_log_stats(const LogStats& s);

// ---- filter / export --------------------------------------------------------------------------

struct LogFilter {
  std::optional<double> from, to;    // from <= time <= to
  std::vector<std::uint32_t> ids;    // sorted; empty = any. Matches i, or j of a pair collision
  std::vector<std::uint8_t> kinds;   // empty = any
  bool matches(const EventRecord& r) const;
};

struct FilterResult {
  std::uint64_t read = 0;
  std::uint64_t written = 0;
};

// Copies the records that match into `out`: an event log (version 3, with the input's dimension,
// particle count and fixed-grain flag, whatever the input's version) or, with csv, the CSV of
// export_csv. The output is written to a temporary file beside `out` and renamed onto it only on
// success; a failure removes only that temporary. An `out` that exists and is not a regular file,
// or is the input itself (same device and inode), is refused before anything is written.
FilterResult filter_log(const std::string& in, const std::string& out, const LogFilter& filter,
                        bool csv);

// The CSV header line (no newline) and one row per record.
std::string csv_header();
void append_csv_row(std::string& buf, const EventRecord& r);

// Every record as CSV into `out` (stdout when out_path is empty; a file path is written as
// filter_log writes). Returns the rows written.
std::uint64_t export_csv(const std::string& in, const std::string& out_path);
std::uint64_t export_csv(const std::string& in, std::FILE* out);

// ---- verify -----------------------------------------------------------------------------------

struct VerifyResult {
  bool ok = true;
  std::uint64_t records = 0;     // records read (up to and including a failing one)
  std::uint64_t pair = 0, wall = 0;  // collision records that passed every check
  std::uint64_t skipped = 0;     // records that are not collisions (switches to soft / hard)
  std::uint64_t rough = 0;       // of pair + wall: rough collisions (spins changed; see README)
  bool model_checked = false;    // restitution compared with the scene's materials

  // The first violation (when !ok).
  std::uint64_t index = 0;       // record index (0-based)
  std::uint64_t offset = 0;      // its byte offset
  double time = 0.0;
  std::uint8_t kind = 0;
  std::uint32_t i = 0, j = 0;
  std::string check;             // "momentum", "normal velocity", "energy", ...
  std::string detail;            // the numbers
  std::string message;           // one line naming all of the above
};

// Replays every collision record (see README for the checks). With a scene, also checks the
// stored e against the scene's restitution models (e = 1 accepted when the scene has tc > 0),
// masses, wall indices and wall normals; a scene whose dimension or particle count differs from
// the log's throws IoError. Rough collisions (a material pair with friction or a tangential rule;
// without a scene, a record whose spins change) are checked for angular momentum about the contact
// point, tangential restitution and energy with rotation, with the radii and the tangential rule of
// the scene (without one, the radii the records imply). Stops at the first violation. tol is relative to each record's
// momentum / velocity / energy scale (absolute for e).
VerifyResult verify_log(const std::string& path, const Scene* scene, double tol = 1e-9);

}  // namespace matep

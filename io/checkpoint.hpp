// Checkpoint files (checkpoint.bin): everything a run needs to continue bit for bit. A run writes
// one at the end, one when a signal stops it, and one every output.checkpoint_interval; `matep run
// SCENE --resume FILE` continues it (io/run.cpp).
//
// Layout (version 2, little-endian, the machine's doubles): "MATEPCKP", u32 version, u32 byte-order
// mark 0x01020304, u64 body length, the body, u32 CRC-32C of everything before it. The body lists
// (engine/state_archive.hpp's encoding): the method and dimension, the scene as canonical TOML,
// the time, what each output file held (length and CRC-32C), the event log's unfinished block,
// the snapshot series, and the engine's state.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "engine/state_archive.hpp"
#include "io/checked_file.hpp"
#include "io/output.hpp"

namespace matep {

inline constexpr char kCheckpointMagic[8] = {'M', 'A', 'T', 'E', 'P', 'C', 'K', 'P'};
inline constexpr std::uint32_t kCheckpointVersion = 14;  // 2: an EDM particle holds its collapse watch; 3: the hybrid's threads; 4: the switching rule's impact speeds; 5: the hybrid's grains in space order (engine/renumber.hpp); 6: the impact speed at the start of each rapid run (hybrid.speed_fall); 7: the EDM cells hold their first two particles; 8: arrays of equal elements saved as one (engine/state_archive.hpp); 9: the hybrid's coast counts; 10: the EDM particles' order (run.resort) and the map to the scene's ids; 11: the soft contacts' remembered springs without rolling torques unless the scene has them, the EDM lists' entries with their image shift; 12: the switching rule's history one record a grain; 13: the hybrid's last substep (a stop may precede a planned coast); 14: the soft set's free flight (the capture checks' times)
inline constexpr const char* kCheckpointName = "checkpoint.bin";

struct Checkpoint {
  std::uint32_t method = 0;  // Method
  std::uint32_t dimension = 3;
  std::string scene;         // the scene as canonical TOML (overrides applied)
  double time = 0.0;         // the simulated time it was saved at
  FileMark thermo;
  std::optional<FileMark> outflow;
  std::optional<EventLogMark> events;
  std::optional<SnapshotSeriesMark> snapshots;
  std::vector<std::uint8_t> engine;
  // Writing: when set, the engine's state comes from it instead of `engine` (the same bytes on
  // the disk, streamed into the file without a copy in memory).
  const std::function<void(StateWriter&)>* engine_source = nullptr;
  std::uint64_t engine_bytes = 0;  // what engine_source writes (write_checkpoint counts it once)

  template <class A>
  void archive(A& a);
};

// Writes `path` whole: a temporary beside it, flushed (and synced to the disk when `durable`),
// renamed onto it. Throws WriteError.
void write_checkpoint(const std::string& path, const Checkpoint& c, bool durable = true);
// Reads and checks a checkpoint; throws IoError "PATH: ..." naming what is wrong (not a checkpoint,
// another version or byte order, cut short, a checksum that does not match).
Checkpoint read_checkpoint(const std::string& path);
// The same from bytes already read (the fuzz target).
Checkpoint parse_checkpoint(const std::vector<std::uint8_t>& bytes, const std::string& path);

// The first difference between two canonical scenes, as "KEY: checkpoint VALUE, this scene VALUE"
// (nothing when they are the same); keys in `ignore` (dotted) are skipped.
std::optional<std::string> scene_difference(const std::string& saved, const std::string& now,
                                            const std::vector<std::string>& ignore);

}  // namespace matep

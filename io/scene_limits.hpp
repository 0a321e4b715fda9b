// Limits a scene must keep before any work is done (README.md, "Limits"): the size and nesting
// of its text (checked before the TOML parser sees it), the scale of radii against the domain,
// the particle count against memory and the size of the output plan. Internal to io/.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

namespace matep::scene_detail {

// A scene file is at most this many bytes (particles belong in a CSV file).
inline constexpr std::uint64_t kMaxSceneBytes = 16u << 20;
// Tables, arrays and dotted keys nest at most this deep (a scene needs about five levels).
inline constexpr int kMaxSceneNesting = 64;
// The widest axis of the domain is at most this many smallest diameters (the cell grids' bound).
inline constexpr double kMaxDomainToDiameter = 1e9;
// Particle ids are 32-bit in the engines.
inline constexpr std::uint64_t kMaxParticles = 2147483647;
// A generous estimate of the memory one grain costs while the scene is read and run (the engines
// hold 180-290 bytes a grain, DESIGN.md; the reader's copies and placement grid less than that).
inline constexpr double kBytesPerParticle = 1024.0;

// Throws SceneError "<file>: line N: ..." when the text is larger than kMaxSceneBytes or nests
// deeper than kMaxSceneNesting (brackets, braces, header and dotted-key levels, counted outside
// strings and comments: within a level or two of the tree the parser would build).
void check_scene_text(std::string_view text, const std::string& file);

// The memory a scene may plan for: the machine's physical memory (sysconf), or less under an
// address-space limit (ulimit -v); 0 when unknown.
double physical_memory_bytes();

// "1.5 GB", "12 MB", ... for messages.
std::string show_bytes(double bytes);

}  // namespace matep::scene_detail

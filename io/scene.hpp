// Scene files (TOML) -> a validated Scene. Every key is documented in README.md; unknown keys,
// wrong types, missing keys and impossible values throw SceneError with a message that names
// the file, the dotted key and the offending value.
#pragma once

#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <variant>
#include <vector>

#include "engine/result.hpp"
#include "engine/system.hpp"
#include "io/snapshots.hpp"

namespace matep {

// Particles read from a file may overlap by up to this fraction of their contact distance when
// run.method = "tdm" or "hybrid" (a soft-sphere state, e.g. a settled bed written by an earlier run); any
// overlap beyond round-off is an error for hard spheres.
inline constexpr double kSoftFileOverlap = 0.05;

class SceneError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct OutputSpec {
  std::string dir = "out";         // relative paths resolve against the current directory
  double thermo_interval = 0.0;    // 0 = rows at t = 0 and at the end only
  bool events = false;             // write events.bin
  double snapshot_interval = 0.0;  // VTK snapshots every interval (0 = none)
  bool wall_loads = false;         // thermo.csv gets each wall's mean force and torque
  double max_bytes = 10e9;         // a run whose planned outputs exceed this is refused (io/run.cpp)
  double checkpoint_interval = 0.0;  // checkpoint.bin every interval (0: at the end and on a signal only)
  SnapshotFormats formats;          // output.format and output.precision (io/snapshots.hpp)
};

// [hybrid]: the switching rule of run.method = "hybrid" (engine/hybrid.hpp); unset = default.
struct HybridSpec {
  std::optional<double> stability, speed_fall, lookahead, hysteresis, skin, cost_ratio, rest_speed, rest_time;
  bool coast = true;  // the soft set may skip substeps in free flight
  std::optional<int> repeats;
  bool cost_measured = false;  // cost_ratio = "measured"
};

struct Scene {
  std::string path;               // the scene file as given
  std::string canonical;          // the scene as canonical TOML, overrides applied (checkpoints)
  int dimension = 3;
  Method method = Method::Edm;    // run.method: "edm" | "tdm" | "hybrid"
  std::string queue = "calendar"; // "calendar" | "heap"
  double start_time = 0.0;        // run.start_time: the time of the scene's state
  double end_time = 1.0;
  std::uint64_t seed = 1;
  double tc = 0.0;                // run.tc, TC model; 0 = off
  double collapse_decades = EdmSettings{}.collapse_decades;  // run.collapse_decades (the engine's default)
  std::string neighbours = "cells";  // run.neighbours: "cells" | "lists" | "auto" (EDM pair candidates)
  double shell = EdmSettings{}.shell;  // run.shell: the shells' half-width in largest diameters
  double resort = EdmSettings{}.resort;  // run.resort: < 0 "auto", 0 "off", else particle events per particle between re-sorts
  std::uint64_t max_events = 0;   // run.max_events; 0 = unlimited
  std::optional<double> dt;       // run.dt (soft-sphere time step, > 0); unset = engine's choice
  std::optional<int> threads;     // run.threads (soft-sphere, >= 1); unset = engine's choice
  OutputSpec output;
  HybridSpec hybrid;
  std::vector<std::string> group_names;  // [particles.NAME] tables in file order
  std::vector<int> group;                // per particle: index into group_names
  std::vector<std::string> warnings;     // "<file>: <key>: <problem>" lines the CLI prints; the scene runs
  std::variant<System<2>, System<3>> system;
};

// Reads, overrides and validates a scene. `overrides` are "dotted.key=VALUE" strings from
// --set; VALUE is parsed as a TOML value (a bare word that is not valid TOML becomes a string).
Scene load_scene(const std::string& path, const std::vector<std::string>& overrides = {});

// Same from a string (tests); `name` stands in for the file name in messages and `base_dir`
// resolves relative particle files.
Scene load_scene_string(const std::string& toml_text, const std::string& name,
                        const std::string& base_dir, const std::vector<std::string>& overrides = {});

}  // namespace matep

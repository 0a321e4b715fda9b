// Runs a validated Scene with the chosen method and writes every output file into a folder.
#pragma once

#include <functional>
#include <string>

#include "io/scene.hpp"

namespace matep {

struct RunOutcome {
  std::string status;   // "ok" or the engine's stop reason
  std::string message;  // why it stopped early (empty when ok)
  std::string out_dir;
  double wall_seconds = 0.0;
  std::uint64_t collisions = 0;
};

// Progress callback: simulated time, fraction done, events so far.
using ProgressFn = std::function<void(double time, double fraction, std::uint64_t events)>;

// Throws SceneError / IoError / std::invalid_argument for problems found before the run starts.
RunOutcome run_scene(const Scene& scene, const std::string& out_dir, const ProgressFn& progress = {});

// The multi-line description printed by `matep check`.
std::string describe_scene(const Scene& scene);

}  // namespace matep

// Runs a validated Scene with the chosen method and writes every output file into a folder.
#pragma once

#include <functional>
#include <string>

#include "engine/hybrid.hpp"
#include "io/scene.hpp"

namespace matep {

struct RunOutcome {
  std::string status;   // "ok" or the engine's stop reason
  std::string message;  // why it stopped early (empty when ok)
  std::string out_dir;
  double wall_seconds = 0.0;
  std::uint64_t collisions = 0;  // EDM: collisions; TDM: contacts begun
  std::uint64_t steps = 0;       // TDM: time steps taken
  double dt = 0.0;               // TDM: time step
  double particle_steps_per_second = 0.0;
  // Hybrid: soft particle-steps, switches and the soft particles at the end.
  std::uint64_t soft_particle_steps = 0, to_soft = 0, to_hard = 0, soft_at_end = 0, slept = 0;
  // Per inlet: "inlet.NAME: ..." for each whose rate could not be met (grains found no free place).
  std::vector<std::string> warnings;
};

// The hybrid engine's settings of a scene (run.dt and the [hybrid] table).
HybridSettings hybrid_settings(const Scene& scene);

// Progress callback: simulated time, fraction done, events (EDM) or steps (TDM) so far.
using ProgressFn = std::function<void(double time, double fraction, std::uint64_t events)>;

// Throws SceneError / IoError / std::invalid_argument for problems found before the run starts.
// resume: a checkpoint.bin to continue (io/checkpoint.hpp), beside the outputs it continues.
RunOutcome run_scene(const Scene& scene, const std::string& out_dir, const ProgressFn& progress = {},
                     const std::string& resume = {});

// What `matep check SCENE --resume FILE` prints: the checkpoint read whole (its checksum right) and
// checked against the scene (io/checkpoint.hpp); throws IoError naming what is wrong.
std::string describe_checkpoint(const Scene& scene, const std::string& path);

// The multi-line description printed by `matep check`.
std::string describe_scene(const Scene& scene);

}  // namespace matep

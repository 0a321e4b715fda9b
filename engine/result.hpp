// What a run reports: its status, event counts, the final state and the figures of each method.
// Shared by the three engines (engine/edm.hpp, engine/tdm.hpp, engine/hybrid.hpp) and io/.
#pragma once

#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "contact/vec.hpp"
#include "engine/inlet.hpp"

namespace matep {

// The three methods a scene may ask for (run.method).
enum class Method : std::uint8_t { Edm, Tdm, Hybrid };

inline const char* method_name(Method m) {
  switch (m) {
    case Method::Edm: return "edm";
    case Method::Tdm: return "tdm";
    case Method::Hybrid: return "hybrid";
  }
  return "edm";
}
inline std::optional<Method> parse_method(std::string_view word) {
  if (word == "edm") return Method::Edm;
  if (word == "tdm") return Method::Tdm;
  if (word == "hybrid") return Method::Hybrid;
  return std::nullopt;
}

struct EventCounts {
  std::uint64_t pair = 0;      // pair collisions resolved
  std::uint64_t wall = 0;      // wall collisions resolved
  std::uint64_t cell = 0;      // cell crossings
  std::uint64_t stale = 0;     // popped events invalidated by a partner's collision
  std::uint64_t samples = 0;   // thermo samples
  std::uint64_t collisions() const { return pair + wall; }
  std::uint64_t total() const { return pair + wall + cell + stale + samples; }
};

// Soft-sphere (TDM) figures of a run; all zero for a pure event-driven run.
struct SoftStats {
  std::uint64_t steps = 0;          // time steps taken
  double dt = 0.0;                  // time step used
  double default_dt = 0.0;          // the engine's default step for this scene
  double max_stable_dt = 0.0;       // Verlet stability limit of the stiffest contact
  double contact_time = 0.0;        // shortest contact duration at impact_speed
  double rayleigh_time = 0.0;       // shortest Rayleigh time (inf: no elastic constants)
  double impact_speed = 0.0;        // largest expected impact speed
  double skin = 0.0;                // Verlet-list skin
  std::uint64_t rebuilds = 0;       // neighbour-list builds
  std::uint64_t contacts = 0;       // pair + wall contacts at the end
  int threads = 0;                  // threads of the force loop
  double particle_steps_per_second = 0.0;
};

// Hybrid figures of a run (all zero for pure EDM and TDM runs).
struct HybridStats {
  std::uint64_t to_soft = 0;          // switches hard -> soft, all reasons
  std::uint64_t by_stability = 0;     //   a collision within k t_c of the previous one
  std::uint64_t by_cost = 0;          //   collision interval below the cost crossover
  std::uint64_t by_cluster = 0;       //   recent collision partner of a particle that turned soft
  std::uint64_t by_capture = 0;       //   came within the skin of a soft particle
  std::uint64_t by_overlap = 0;       //   overlapping at t = 0
  std::uint64_t to_hard = 0;          // releases soft -> hard, all reasons
  std::uint64_t released_by_cost = 0; //   in a group whose collisions are cheaper as events
  std::uint64_t slept = 0;            // particles put to sleep (rest rule)
  std::uint64_t woken = 0;            // sleeping particles woken
  std::uint64_t substeps = 0;         // TDM substep events
  std::uint64_t coasts = 0;           // substeps followed by a coast (the soft set in free flight)
  std::uint64_t coasted_steps = 0;    // grid steps the coasts skipped
  std::uint64_t soft_particle_steps = 0;  // sum over substeps of the awake soft particles
  std::uint64_t max_soft = 0;         // largest soft set (awake + asleep)
  std::uint64_t soft_at_end = 0;      // soft particles (awake + asleep) at the end
  std::uint64_t rebuilds = 0;         // soft neighbour-list builds
  double stability = 0.0;             // k
  double hysteresis = 0.0;            // release hysteresis [s]
  double skin = 0.0;                  // least capture distance [m]
  double cost_ratio = 0.0;
  double rest_speed = 0.0, rest_time = 0.0;
};

// The hybrid's measured costs (engine/hybrid/cost.hpp), at the end of the run: NaN where a cost
// was never measured (no soft grain, or too few collisions).
struct HybridCost {
  double ratio = std::numeric_limits<double>::quiet_NaN();           // hard / soft
  double hard_ns_per_collision = std::numeric_limits<double>::quiet_NaN();  // per particle-collision
  double soft_ns_per_step = std::numeric_limits<double>::quiet_NaN();       // per soft particle-step
  bool followed = false;  // hybrid.cost_ratio = "measured": the rule used it
};

template <int D>
struct RunResult {
  Method method = Method::Edm;  // the engine that produced it
  std::string status = "ok";  // "ok" | "collapse" | "escaped" | "max_events" | "unstable" | "max_steps"
  std::string message;        // empty when ok
  double time = 0.0;          // simulated time reached
  EventCounts counts;
  bool lists = false;         // EDM: pair candidates from neighbour lists (counts.cell: shell exits)
  std::uint64_t resorts = 0;  // EDM: times the particles' storage was re-sorted in space (EdmSettings::resort)
  double wall_seconds = 0.0;
  double max_overlap = 0.0;           // EDM: largest overlap at the end; TDM: largest seen during the run
  double max_overlap_relative = 0.0;  // the same divided by the pair's contact distance
  // The final state: one row per grain present, in increasing id; id gives each row's particle id
  // once grains have left through an outlet (empty: row k is particle k).
  std::vector<std::uint32_t> id;
  std::vector<Vec<D>> x, v;
  std::vector<double> radius;
  std::vector<Spin<D>> w;             // empty when the system had no spins (all zero)
  std::vector<int> material;          // per row: index into System::materials
  SoftStats soft;                     // TDM and hybrid runs
  HybridStats hybrid;                 // hybrid runs
  HybridCost hybrid_cost;             // hybrid runs: the costs measured during the run
  std::vector<std::uint8_t> mode;     // hybrid: final mode per particle (0 hard, 1 soft, 3 asleep, 4 fixed)
  std::uint64_t grains_out = 0;       // grains removed by outlets
  double mass_out = 0.0;              // their mass
  std::uint64_t grains_in = 0;        // grains inserted by inlets
  double mass_in = 0.0;               // their mass
  std::vector<InletReport> inlets;    // per inlet: grains due, inserted and missed (no free place)
};

// Calls f on each per-row array of a per-particle state (a RunResult's final state, a Snapshot,
// with its material and cluster columns where it has them), in one fixed order.
template <class State, class F>
void for_each_row_array(State& s, F&& f) {
  f(s.x);
  f(s.v);
  f(s.w);
  f(s.radius);
  f(s.mode);
  if constexpr (requires { s.material; }) f(s.material);
  if constexpr (requires { s.cluster; }) f(s.cluster);
}

// Keeps the rows of a per-particle state (a RunResult's final state, a Snapshot) whose particle is
// present (gone[k] == 0 for particle k, in id order; gone empty: all present), filling its ids.
template <class State>
void keep_present(State& s, const std::vector<std::uint8_t>& gone) {
  if (gone.empty()) return;
  std::size_t m = 0;
  s.id.clear();
  for (std::size_t k = 0; k < s.x.size(); ++k) {
    if (gone[k]) continue;
    s.id.push_back(static_cast<std::uint32_t>(k));
    for_each_row_array(s, [&](auto& a) {
      if (!a.empty()) a[m] = a[k];
    });
    ++m;
  }
  for_each_row_array(s, [&](auto& a) {
    if (!a.empty()) a.resize(m);
  });
}

}  // namespace matep

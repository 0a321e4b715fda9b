// Event-driven dynamics (EDM) of smooth hard spheres (D = 3) and disks (D = 2).
//
// One event per particle lives in the queue (the earliest of its predicted pair collision, wall
// collision and cell crossing); stale events are recognised by per-particle collision counters
// (Smallenburg, Eur. Phys. J. E 45, 22 (2022), "Single" variant). Particles carry their own time
// and are advanced only when an event touches them; predictions use a neighbour's stored state
// without writing it (the lesson from DynamO's profile in DESIGN.md).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "engine/observer.hpp"
#include "engine/result.hpp"
#include "engine/system.hpp"

namespace matep {

struct RoughRules;

enum class QueueKind { Calendar, Heap };

// Runs the system from settings.start_time to settings.end_time (or until it stops early). The system is taken
// by value: move it in to let the engine release its particle arrays once copied (memory).
// Throws std::invalid_argument for systems the engine cannot represent (e.g. a periodic axis
// shorter than three largest diameters).
// `rough`: the rules of engine/rough_rules.hpp for system.materials when the caller has made them
// already (io/ checks a scene once and hands its plan on); null = made here.
template <int D>
RunResult<D> run_edm(System<D> system, const EdmSettings& settings, QueueKind queue,
                     const std::vector<Observer<D>*>& observers = {}, const RoughRules* rough = nullptr);

}  // namespace matep

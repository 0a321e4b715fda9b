// Hybrid dynamics: one event queue in which hard particles fly between predicted collisions (the
// EDM core of engine/edm/core.hpp) and a soft set, the particles of dense or collapsing clusters, is
// advanced by fixed TDM substeps (the scheme and contact laws of engine/tdm.hpp), each substep an
// event of the same queue. README "Hybrid dynamics" states the rule and its measured parameters:
//  * stability: a hard particle that collides again within `stability` * t_c of its previous
//    collision (t_c = the soft contact duration of that pair at that impact speed) turns soft,
//    with the particles it collided with in that window (its cluster); the collision is then
//    resolved by the soft contact law, which starts within the substep as in a pure TDM run;
//  * cost: the same when its smoothed interval between collisions falls below cost_ratio * dt
//    (the crossover where TDM substeps are cheaper than EDM events) and the mean rate of it and
//    its hard neighbours (whom it would draw in by capture) is above that crossover too;
//  * capture: a hard particle joins the soft set at the next substep when its gap to a soft one
//    falls below twice what the two can close in one substep at their current speeds (at least
//    `skin`), so no contact is missed and a grain joins only just before it touches;
//  * release: a soft particle without contact for `hysteresis` and without a particle within its
//    capture distance returns to EDM with its current velocity and spin;
//  * rest: a soft grain that stays slower than `rest_speed` for `rest_time` and whose contact
//    springs balance gravity falls asleep on its own: it is not integrated, its contacts with
//    sleepers are frozen with their springs, and awake neighbours meet it as an immovable body.
//    It wakes when a touching grain approaches it faster than rest_speed, when a contact opens, or
//    when its elastic load changes by more than rest_speed sqrt(m k) (k: its contact stiffness).
#pragma once

#include <cstdint>
#include <vector>

#include "engine/observer.hpp"
#include "engine/result.hpp"
#include "engine/soft_plan.hpp"
#include "engine/system.hpp"

namespace matep {

struct HybridSettings {
  double dt = 0.0;          // TDM substep; 0 = the soft plan's default step
  double stability = 2.0;   // k: a collision within k t_c of the previous one turns the cluster soft
  int repeats = 3;          // ... when it is the repeats-th such collision in a row
  double speed_fall = 100.0;  // ... and the impact speed has fallen by this factor since the first
                              // (not asked of a strongly inelastic impact, e <= 0.3)
  double lookahead = 20.0;  // L: a strongly inelastic collision soon after another whose outcome
                            // brings a grain back to its earlier partner within L t_c turns soft
                            // before it (engine/hybrid/hybrid.cpp lookahead_pair); 0 = off
  double hysteresis = 0.0;  // contact-free time before release; 0 = 10 k t_c (of the plan's t_c)
  double skin = 0.0;        // least capture distance, as a fraction of the smallest diameter; 0 = the
                            // scene's default (least_capture below)
  double cost_ratio = 10.0; // cost of one EDM collision per particle / cost of one TDM particle-step
  bool cost_measured = false;  // the crossover follows the costs measured during the run, starting
                               // from cost_ratio (engine/hybrid/cost.hpp; not reproducible run to run)
  double rest_speed = 0.0;  // sleeping threshold [m/s]; 0 = no sleeping
  double rest_time = 0.0;   // how long a grain must stay below rest_speed; 0 = 20 t_c
  bool coast = true;        // the soft set skips the substeps of a free flight (engine/hybrid/hybrid.cpp,
                            // coast_plan); false: a substep at every step, as before
  int threads = 1;          // the soft set's threads (0: all cores, OMP_NUM_THREADS respected); a run
                            // is deterministic for a given count
  int min_per_thread = 2048;  // awake soft grains per thread at least (fewer threads below; the
                              // fork and join of each substep's parallel loops cost more than they
                              // save on fewer, as in TDM)
};

// Strongly inelastic: the lookahead tries impacts at e <= kLookaheadMaxE (engine/hybrid/hybrid.cpp
// lookahead_pair). At e = 0.5 and above the hard sequences of the small systems measured end within
// 1 % of the soft ones; at 0.2 and below up to 25 times off. At 0.3 EDM ends within 25 % of
// converged TDM in every chain of three and four disks (tools/collapse_chains.py), the trial mended
// one five-disk line of 60 systems, and it fired 437 times a run in the stability map's e = 0.3,
// phi = 0.3 gas, where EDM is stable (14 x EDM).
inline constexpr double kLookaheadMaxE = 0.25;

// The least capture distance as a fraction of the smallest diameter: `settings.skin` when set,
// otherwise kWideSkin where grains come to rest or rapid sequences are strongly inelastic (gravity,
// or a material whose restitution is velocity dependent or at most kLookaheadMaxE), kNarrowSkin
// elsewhere (README "Hybrid dynamics", the capture row: there the floor serves round-off only, and
// at kWideSkin it held the clusters of a cooling gas soft).
inline constexpr double kWideSkin = 1e-3, kNarrowSkin = 1e-4;
template <int D>
double least_capture(const System<D>& system, const HybridSettings& settings) {
  if (settings.skin > 0.0) return settings.skin;
  bool wide = system.gravity.norm() > 0.0;
  for (const Material& m : system.materials)
    wide = wide || m.restitution.model != Restitution::Model::Constant ||
           m.restitution.e <= kLookaheadMaxE;
  return wide ? kWideSkin : kNarrowSkin;
}

// The checks run_hybrid makes before it starts (the soft plan, the substep against the stability
// limit). Throws std::invalid_argument naming the key.
template <int D>
SoftPlan hybrid_preflight(const System<D>& system, const HybridSettings& settings);

// Runs the system from edm.start_time to edm.end_time with the hybrid rule. Particles that overlap at
// t = 0 (a settled soft state) start soft; every other particle starts hard.
// `plan`: the result of hybrid_preflight for this system and settings when the caller has it (io/
// checks a scene once); null = planned here.
template <int D>
RunResult<D> run_hybrid(System<D> system, const EdmSettings& edm, const HybridSettings& hybrid,
                        const std::vector<Observer<D>*>& observers = {}, const SoftPlan* plan = nullptr);

}  // namespace matep

// Time-driven dynamics (TDM) of soft spheres (D = 3) and disks (D = 2): velocity Verlet with a
// fixed step, contact laws of contact/soft.hpp chosen per material pair (engine/soft_plan.hpp),
// a cell-built Verlet list with a skin that is rebuilt only when some particle has moved more
// than half the skin (docs/references.md §S.2.3), tangential contact history that survives
// rebuilds, plane walls, periodic axes, gravity and, when some contact has friction, rotation.
//
// Scheme (step h, a = F/m + g, and likewise for spins with the torque over I = q m R^2):
//   v(t + h/2) = v(t) + h/2 a(t);  x(t + h) = x(t) + h v(t + h/2);
//   forces at x(t + h), velocity-dependent terms (dashpots, the sliding direction) evaluated at
//   the predicted v(t) + h a(t) (second order; the half-step velocity would make the dissipation
//   first order), the tangential spring grown by the half-step contact velocity times h;
//   v(t + h) = v(t + h/2) + h/2 a(t + h).
// Threads (OpenMP) split the particles into fixed ranges; forces on particles of another range
// are queued and added after the loop in range order, so a run is deterministic for a given
// thread count.
#pragma once


#include <atomic>
#include <cstdint>
#include <limits>
#include <vector>

#include "engine/result.hpp"
#include "engine/observer.hpp"
#include "engine/soft_plan.hpp"
#include "engine/system.hpp"

namespace matep {

struct TdmSettings {
  double start_time = 0.0;  // the time of the system's state (run.start_time)
  double end_time = 1.0;
  double dt = 0.0;    // 0: the plan's default step. The step is then shortened so that a whole
                      // number of steps ends exactly at end_time (from start_time).
  double skin = 0.0;  // Verlet skin; 0: 0.1 of the largest diameter (LAMMPS' granular default)
  int threads = 0;    // 0: all cores (OMP_NUM_THREADS respected)
  double thermo_interval = 0.0;    // 0 = only t = 0 and the end
  double snapshot_interval = 0.0;  // 0 = none
  std::uint64_t max_steps = std::numeric_limits<std::uint64_t>::max();
  // Stop with status "unstable" when some overlap exceeds this fraction of the contact distance
  // (a time step too long for the contact stiffness) or a position stops being finite.
  double unstable_overlap = 0.5;
  // When set and it turns true (a signal handler may set it), the run stops at the next whole
  // step with status "interrupted" (every output written for that step).
  const std::atomic<bool>* stop = nullptr;
  // Checkpoints (engine/state_archive.hpp): where the run's states go, and one to resume from.
  const CheckpointHooks* checkpoint = nullptr;
};

// The checks run_tdm makes before it starts: the contact laws of every material pair, the time
// step against the stability limit and the periodic axes against the neighbour cut-off. Returns
// the plan; throws std::invalid_argument naming the key (material.NAME.KEY, run.dt, domain.upper).
template <int D>
SoftPlan tdm_preflight(const System<D>& system, const TdmSettings& settings);

// Runs the system from start_time to end_time. Throws std::invalid_argument for a system the soft
// contact laws cannot describe (see plan_soft) or a time step above the stability limit; the
// message names the material key or prints the limit.
// `plan`: the result of tdm_preflight for this system and settings when the caller has it (io/
// checks a scene once); null = planned here.
template <int D>
RunResult<D> run_tdm(System<D> system, const TdmSettings& settings,
                     const std::vector<Observer<D>*>& observers = {}, const SoftPlan* plan = nullptr);

extern template SoftPlan tdm_preflight<2>(const System<2>&, const TdmSettings&);
extern template SoftPlan tdm_preflight<3>(const System<3>&, const TdmSettings&);
extern template RunResult<2> run_tdm<2>(System<2>, const TdmSettings&, const std::vector<Observer<2>*>&,
                                        const SoftPlan*);
extern template RunResult<3> run_tdm<3>(System<3>, const TdmSettings&, const std::vector<Observer<3>*>&,
                                        const SoftPlan*);

}  // namespace matep

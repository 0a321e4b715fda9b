// Pure event-driven dynamics: the EDM core (engine/edm/core.hpp) with no extension.
#include "engine/edm.hpp"

#include <vector>

#include "engine/edm/core.hpp"
#include "engine/edm/neighbours.hpp"
#include "engine/renumber.hpp"
#include "scheduler/calendar_queue.hpp"
#include "scheduler/heap_queue.hpp"

namespace matep {

namespace {

template <int D, class Queue>
class EdmEngine final : public edm::EdmCore<D, Queue, EdmEngine<D, Queue>> {
 public:
  EdmEngine(System<D>&& system, const EdmSettings& set, const std::vector<Observer<D>*>& obs,
            const RoughRules* rough, IdMap* ids = nullptr)
      : edm::EdmCore<D, Queue, EdmEngine>(std::move(system), set, obs) {
    if (ids) this->track_ids(ids);
    this->init(rough);
  }
};

template <int D, class Queue>
RunResult<D> run_queue(System<D>&& system, const EdmSettings& settings, const std::vector<Observer<D>*>& observers,
                       const RoughRules* rough) {
  // A run that may re-sort its particles (engine/edm/core.hpp "re-sorting"; the engine decides,
  // by the grains' packing too) reports through a map to the scene's ids that the engine keeps up
  // to date.
  if (edm::resort_interval(settings.resort, system.size(), 0.0) <= 0.0)
    return EdmEngine<D, Queue>(std::move(system), settings, observers, rough).run();
  IdMap ids;
  const UserIdObservers<D> obs(observers, ids);
  EdmEngine<D, Queue> engine(std::move(system), settings, obs.list(), rough, &ids);
  RunResult<D> r = engine.run();
  to_user(r, ids);
  return r;
}

}  // namespace

template <int D>
RunResult<D> run_edm(System<D> system, const EdmSettings& settings, QueueKind queue,
                     const std::vector<Observer<D>*>& observers, const RoughRules* rough) {
  if (queue == QueueKind::Heap) return run_queue<D, HeapQueue>(std::move(system), settings, observers, rough);
  return run_queue<D, CalendarQueue>(std::move(system), settings, observers, rough);
}

template RunResult<2> run_edm<2>(System<2>, const EdmSettings&, QueueKind, const std::vector<Observer<2>*>&,
                                 const RoughRules*);
template RunResult<3> run_edm<3>(System<3>, const EdmSettings&, QueueKind, const std::vector<Observer<3>*>&,
                                 const RoughRules*);

}  // namespace matep

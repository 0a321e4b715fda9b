// Pure event-driven dynamics: the EDM core (engine/edm/core.hpp) with no extension.
#include "engine/edm.hpp"

#include "engine/edm/core.hpp"
#include "scheduler/calendar_queue.hpp"
#include "scheduler/heap_queue.hpp"

namespace matep {

namespace {

template <int D, class Queue>
class EdmEngine final : public edm::EdmCore<D, Queue, EdmEngine<D, Queue>> {
 public:
  EdmEngine(System<D>&& system, const EdmSettings& set, const std::vector<Observer<D>*>& obs,
            const RoughRules* rough)
      : edm::EdmCore<D, Queue, EdmEngine>(std::move(system), set, obs) {
    this->init(rough);
  }
};

}  // namespace

template <int D>
RunResult<D> run_edm(System<D> system, const EdmSettings& settings, QueueKind queue,
                     const std::vector<Observer<D>*>& observers, const RoughRules* rough) {
  if (queue == QueueKind::Heap) return EdmEngine<D, HeapQueue>(std::move(system), settings, observers, rough).run();
  return EdmEngine<D, CalendarQueue>(std::move(system), settings, observers, rough).run();
}

template RunResult<2> run_edm<2>(System<2>, const EdmSettings&, QueueKind, const std::vector<Observer<2>*>&,
                                 const RoughRules*);
template RunResult<3> run_edm<3>(System<3>, const EdmSettings&, QueueKind, const std::vector<Observer<3>*>&,
                                 const RoughRules*);

}  // namespace matep

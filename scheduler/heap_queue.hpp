#pragma once
// HeapQueue: the O(log N) reference event queue, a Boost.Heap heap with mutable handles and one
// handle per id.  Interface and ordering contract: see event_queue.hpp.
//
// The heap type is a template parameter so the benchmark can compare Boost.Heap variants
// (bench/bench_queues.cpp --matep_tune, hold workload): d_ary_heap with arity 2, 4 and 8 are within
// measurement noise of each other (arity 4 best at N <= 1e4, 8 slightly ahead at 1e6); pairing_heap
// is 1.6-2.7x slower.  HeapQueue uses arity 4.
#include <algorithm>
#include <cassert>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include <boost/heap/d_ary_heap.hpp>
#include <boost/heap/pairing_heap.hpp>

#include "scheduler/event_queue.hpp"

namespace matep {

namespace detail {
struct HeapEntry {
  double t;
  int id;
};
// Boost.Heap is a max-heap of its comparator: "a < b" must mean "a pops after b".
struct HeapEntryLater {
  bool operator()(const HeapEntry& a, const HeapEntry& b) const noexcept {
    return event_before(b.t, b.id, a.t, a.id);
  }
};
template <unsigned Arity>
using DaryHeap = boost::heap::d_ary_heap<HeapEntry, boost::heap::arity<Arity>, boost::heap::mutable_<true>,
                                         boost::heap::compare<HeapEntryLater>>;
using PairingHeap = boost::heap::pairing_heap<HeapEntry, boost::heap::compare<HeapEntryLater>>;
}  // namespace detail

template <class Heap>
class BasicHeapQueue {
 public:
  explicit BasicHeapQueue(std::size_t capacity) : handle_(capacity), present_(capacity, 0) {}

  void set(int id, double t) {
    assert(in_range(id));
    if (!(t < kInf)) [[unlikely]] {
      if (t != t) detail::throw_nan_time(id);
      erase(id);
      return;
    }
    const detail::HeapEntry e{t, id};
    if (present_[id]) {
      auto h = handle_[id];
      const detail::HeapEntry& old = *h;
      // Boost's "increase" = moves towards the top = earlier in (t, id).
      if (detail::event_before(t, id, old.t, old.id))
        heap_.increase(h, e);
      else
        heap_.decrease(h, e);
    } else {
      handle_[id] = heap_.push(e);
      present_[id] = 1;
    }
  }

  void erase(int id) {
    assert(in_range(id));
    if (!present_[id]) return;
    heap_.erase(handle_[id]);
    present_[id] = 0;
  }

  [[nodiscard]] bool contains(int id) const {
    assert(in_range(id));
    return present_[id] != 0;
  }
  // The time of id's entry (precondition: contains(id)); checkpoints list the entries with it.
  [[nodiscard]] double time_of(int id) const { return (*handle_[id]).t; }
  [[nodiscard]] bool empty() const { return heap_.empty(); }
  [[nodiscard]] std::size_t size() const { return heap_.size(); }
  [[nodiscard]] std::size_t capacity() const { return present_.size(); }

  [[nodiscard]] std::pair<int, double> top() const {
    assert(!empty());
    const detail::HeapEntry& e = heap_.top();
    return {e.id, e.t};
  }

  void pop() {
    assert(!empty());
    present_[heap_.top().id] = 0;
    heap_.pop();
  }

  void clear() {
    heap_.clear();
    std::fill(present_.begin(), present_.end(), std::uint8_t{0});
  }

 private:
  static constexpr double kInf = std::numeric_limits<double>::infinity();
  [[nodiscard]] bool in_range(int id) const {
    return id >= 0 && static_cast<std::size_t>(id) < present_.size();
  }

  Heap heap_;
  std::vector<typename Heap::handle_type> handle_;
  std::vector<std::uint8_t> present_;
};

using HeapQueue = BasicHeapQueue<detail::DaryHeap<4>>;
static_assert(EventQueue<HeapQueue>);

}  // namespace matep

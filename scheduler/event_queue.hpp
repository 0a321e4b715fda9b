#pragma once
// The event-queue interface shared by HeapQueue and CalendarQueue.
//
// The engine is templated on the queue type (static polymorphism); any type satisfying the
// `EventQueue` concept below can be dropped in.  A queue holds at most one entry per id, where ids are
// dense integers in [0, capacity) fixed at construction (one id per particle, or per wall/cell/system
// event slot: the engine decides).  An entry is a pair (t, id) with t a double.
//
// Contract (identical for every implementation):
//
//   explicit Q(std::size_t capacity)   ids are in [0, capacity); no entry present initially.
//   void set(int id, double t)         insert id with time t, or move it to t if present.
//                                      t = +inf means "no event": the entry is erased, never stored.
//                                      t may be negative, -inf, or as large as DBL_MAX.
//                                      t = NaN is rejected with std::invalid_argument (a NaN
//                                      prediction is a bug upstream, and silently dropping it would
//                                      lose an event).
//   void erase(int id)                 remove id; no-op if absent.
//   bool contains(int id) const        whether id has an entry.
//   bool empty() const, std::size_t size() const
//   std::pair<int, double> top()       (id, t) of the smallest entry.  Precondition: !empty().
//                                      May reorganise internal state (not const for the calendar).
//   void pop()                         remove the entry top() returns.  Precondition: !empty().
//   double time_of(int id) const       the time of id's entry.  Precondition: contains(id).
//   void clear()                       remove every entry (capacity unchanged).
//
// Order: the strict total order on (t, id), i.e. ties in t are broken by the smaller id.  Because the
// order is total, two conforming queues fed the same sequence of operations pop IDENTICAL sequences;
// the unit tests check this for HeapQueue against CalendarQueue.  (-0.0 and +0.0 compare equal, as
// doubles do; the stored t is returned unchanged.)
//
// Out-of-range ids are a precondition violation (checked with assert in debug builds only).
#include <concepts>
#include <cstddef>
#include <stdexcept>
#include <string>
#include <utility>

namespace matep {

template <class Q>
concept EventQueue = std::constructible_from<Q, std::size_t> &&
    requires(Q& q, const Q& cq, int id, double t) {
      { q.set(id, t) } -> std::same_as<void>;
      { q.erase(id) } -> std::same_as<void>;
      { cq.contains(id) } -> std::same_as<bool>;
      { cq.time_of(id) } -> std::same_as<double>;
      { cq.empty() } -> std::same_as<bool>;
      { cq.size() } -> std::same_as<std::size_t>;
      { q.top() } -> std::same_as<std::pair<int, double>>;
      { q.pop() } -> std::same_as<void>;
      { q.clear() } -> std::same_as<void>;
    };

namespace detail {
// The strict total order every queue uses: (t, id) lexicographic.
[[nodiscard]] constexpr bool event_before(double ta, int ia, double tb, int ib) noexcept {
  return ta < tb || (ta == tb && ia < ib);
}
[[noreturn, gnu::cold, gnu::noinline]] inline void throw_nan_time(int id) {
  throw std::invalid_argument("event queue: time of id " + std::to_string(id) + " is NaN");
}
}  // namespace detail

}  // namespace matep

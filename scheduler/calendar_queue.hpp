#pragma once
// CalendarQueue: the O(1) amortised event queue of G. Paul, J. Comput. Phys. 221, 615 (2007)
// (arXiv physics/0606226), with a rate-adaptive bin width.  Interface and ordering contract: see
// event_queue.hpp; it pops exactly the sequence HeapQueue pops.
//
// Structure.  Time is cut into bins of width 1/scale; an entry's absolute bin index is
//   idx(t) = floor((t - origin) * scale)            (clamped to [-1, 2^62]; monotone in t)
// and `cur` is the current bin.  Every live entry is in exactly one of three places:
//   * the small heap:  idx <= cur          an indexed binary heap ordered by (t, id); holds the
//                                          current bin plus "now" events set before it;
//   * the ring:        cur < idx < lim     nbins unsorted intrusive doubly linked lists, slot
//                                          idx & (nbins-1); lim - cur <= nbins, so one slot holds a
//                                          single idx;
//   * the overflow:    idx >= lim          an unsorted dense array (swap-remove).
// Because idx is monotone in t, everything outside the heap is strictly later in (t, id) than
// everything in it, so the heap's top is the global top.  When the heap runs empty, cur advances
// to the next non-empty slot and that slot's list is heapified.  When the ring is exhausted (or
// empty), cur jumps to the overflow's first bin, lim = cur + nbins, and the overflow is
// redistributed (O(size), once per ring pass).
//
// Adaptation.  The target is `events_per_bin` pops per bin width (Smallenburg: performance is flat
// over a wide range; the default was chosen by bench/bench_queues.cpp).  The pop rate is measured
// over epochs (time of popped events, at least kMinPops pops); at every ring wrap (cheap: the ring
// and heap are empty then, so re-framing costs the same O(size) as the wrap itself) and every
// nbins pops (full rebuild, O(capacity + nbins), amortised O(1)) the wanted scale is compared with
// the current one, and the queue is re-framed only if they differ by more than kAdaptFactor.  The
// periodic check also rebuilds when the small heap has grown far beyond its target size (e.g.
// after `cur` jumped to a huge time).  The very first top()/pop() calibrates from the spread of the
// stored times (scale = n / (events_per_bin * (mean - min))).
//
// Memory: 16 bytes per id (time + two links), 4 bytes per bin, 4 bytes per overflow slot (reserved
// for `capacity`), plus the small heap: about 24-28 bytes per id with the default nbins.
//
// No allocation per operation after construction (the overflow array is reserved up front; the
// small heap keeps its capacity).
#include <cassert>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "scheduler/event_queue.hpp"

namespace matep {

struct CalendarQueueOptions {
  // Target number of events popped per bin width.  Measured flat within ~20% between 0.5 and 16 up
  // to N = 1e5; at N = 1e6 (cache-missing) 0.5 is fastest: a short ring window keeps most entries
  // in the overflow, where a set() touches no list neighbours and the once-per-pass
  // redistribution is batched and prefetched.
  double events_per_bin = 0.5;
  // Number of ring bins per id of capacity (rounded up to a power of two, at least 16).
  double bins_per_id = 1.0;
};

class CalendarQueue {
 public:
  explicit CalendarQueue(std::size_t capacity) : CalendarQueue(capacity, CalendarQueueOptions{}) {}
  CalendarQueue(std::size_t capacity, const CalendarQueueOptions& options);

  void set(int id, double t);
  void erase(int id);
  [[nodiscard]] bool contains(int id) const {
    assert(in_range(id));
    return node_[id].b != kAbsent;
  }
  [[nodiscard]] bool empty() const { return size_ == 0; }
  [[nodiscard]] std::size_t size() const { return size_; }
  [[nodiscard]] std::size_t capacity() const { return node_.size(); }

  [[nodiscard]] std::pair<int, double> top() {
    assert(!empty());
    if (heap_.empty()) advance();
    return {heap_[0].id, heap_[0].t};
  }
  void pop();
  void clear();

  // The time of id's entry (precondition: contains(id)); checkpoints list the entries with it.
  [[nodiscard]] double time_of(int id) const { return node_[static_cast<std::size_t>(id)].t; }

  // Diagnostics (tests, benchmarks, logs).
  [[nodiscard]] double bin_width() const { return 1.0 / scale_; }
  [[nodiscard]] std::size_t bin_count() const { return nbins_; }
  [[nodiscard]] std::uint64_t reframe_count() const { return reframes_; }
  [[nodiscard]] std::size_t memory_bytes() const;

 private:
  struct Node {
    double t;
    // b >= 0: in a ring list, b = previous node; a = next node (or kNil).
    // b in [-nbins, -1]: head of ring slot -1-b; a = next node.
    // b == kHeap: in the small heap at position a.  b == kOver: in the overflow at position a.
    // b == kAbsent: no entry.
    std::int32_t a;
    std::int32_t b;
  };
  struct HeapEntry {
    double t;
    std::int32_t id;
  };

  static constexpr std::int32_t kNil = -1;
  static constexpr std::int32_t kHeap = std::numeric_limits<std::int32_t>::min();
  static constexpr std::int32_t kOver = kHeap + 1;
  static constexpr std::int32_t kAbsent = kHeap + 2;
  static constexpr double kInf = std::numeric_limits<double>::infinity();
  static constexpr std::int64_t kBinMax = std::int64_t{1} << 62;
  static constexpr std::int64_t kBinMin = -kBinMax;
  static constexpr double kBinMaxD = static_cast<double>(kBinMax);

  [[nodiscard]] bool in_range(int id) const {
    return id >= 0 && static_cast<std::size_t>(id) < node_.size();
  }
  [[nodiscard]] static bool before(const HeapEntry& x, const HeapEntry& y) noexcept {
    return detail::event_before(x.t, x.id, y.t, y.id);
  }
  // Monotone non-decreasing in t; never overflows.
  [[nodiscard]] std::int64_t bin(double t) const noexcept {
    const double x = (t - origin_) * scale_;
    if (x < kBinMaxD) return x < 0.0 ? -1 : static_cast<std::int64_t>(x);
    return kBinMax;
  }

  void place(int id, double t, std::int64_t b) {
    if (b <= cur_)
      heap_push(id, t);
    else if (b < lim_)
      ring_push(id, b);
    else
      over_push(id, t);
  }
  void ring_push(int id, std::int64_t b) {
    const auto s = static_cast<std::int32_t>(static_cast<std::uint64_t>(b) & mask_);
    Node& n = node_[id];
    const std::int32_t h = head_[s];
    n.a = h;
    n.b = -1 - s;
    if (h != kNil) node_[h].b = id;
    head_[s] = id;
    ++ring_count_;
  }
  void ring_unlink(const Node& n) {
    if (n.a != kNil) node_[n.a].b = n.b;
    if (n.b >= 0)
      node_[n.b].a = n.a;
    else
      head_[-1 - n.b] = n.a;
    --ring_count_;
  }
  void over_push(int id, double t) {
    Node& n = node_[id];
    n.a = static_cast<std::int32_t>(over_.size());
    n.b = kOver;
    over_.push_back(id);
    if (t < over_tmin_) over_tmin_ = t;
  }
  void over_remove(const Node& n) {
    const std::int32_t last = over_.back();
    over_[n.a] = last;
    node_[last].a = n.a;
    over_.pop_back();
  }

  // Indexed binary heap.
  void heap_set(std::size_t pos, const HeapEntry& e) {
    heap_[pos] = e;
    node_[e.id].a = static_cast<std::int32_t>(pos);
  }
  void sift_up(std::size_t pos, HeapEntry e) {
    while (pos > 0) {
      const std::size_t parent = (pos - 1) / 2;
      if (!before(e, heap_[parent])) break;
      heap_set(pos, heap_[parent]);
      pos = parent;
    }
    heap_set(pos, e);
  }
  void sift_down(std::size_t pos, HeapEntry e) {
    const std::size_t n = heap_.size();
    for (;;) {
      std::size_t child = 2 * pos + 1;
      if (child >= n) break;
      if (child + 1 < n && before(heap_[child + 1], heap_[child])) ++child;
      if (!before(heap_[child], e)) break;
      heap_set(pos, heap_[child]);
      pos = child;
    }
    heap_set(pos, e);
  }
  void heap_push(int id, double t) {
    node_[id].b = kHeap;
    heap_.push_back({t, id});
    sift_up(heap_.size() - 1, {t, id});
  }
  void heap_remove_at(std::size_t pos) {
    const HeapEntry last = heap_.back();
    heap_.pop_back();
    if (pos == heap_.size()) return;
    if (pos > 0 && before(last, heap_[(pos - 1) / 2]))
      sift_up(pos, last);
    else
      sift_down(pos, last);
  }
  void heap_move(std::size_t pos, double t) {  // entry at pos gets time t
    const HeapEntry e{t, heap_[pos].id};
    if (pos > 0 && before(e, heap_[(pos - 1) / 2]))
      sift_up(pos, e);
    else
      sift_down(pos, e);
  }
  void heapify();  // restore the heap property of heap_ (positions included)

  // Cold paths (calendar_queue.cpp).
  void advance();                  // precondition: heap empty, size > 0; makes the heap non-empty
  void wrap();                     // ring and heap empty: jump / re-frame / calibrate
  void distribute_overflow();      // re-place the overflow's entries for the current cur/lim
  void reframe();                  // ring and heap empty: new origin, cur = 0, distribute
  void full_rebuild();             // move everything to the overflow, then reframe()
  void calibrate();                // first top(): scale from the spread of stored times
  void periodic_check();           // every check_interval_ pops
  bool rate_says_rescale(double& want);

  std::vector<Node> node_;
  std::vector<std::int32_t> head_;
  std::vector<std::int32_t> over_;
  std::vector<HeapEntry> heap_;
  std::size_t nbins_ = 0;
  std::uint64_t mask_ = 0;
  std::size_t size_ = 0;
  std::size_t ring_count_ = 0;
  std::int64_t cur_ = kBinMin;  // uncalibrated: everything goes to the overflow
  std::int64_t lim_ = kBinMin;
  double origin_ = 0.0;
  double scale_ = 1.0;
  double over_tmin_ = kInf;  // lower bound of the overflow's times
  double events_per_bin_;
  bool calibrated_ = false;
  // Rate measurement.
  std::uint64_t pops_ = 0;
  std::uint64_t epoch_pops_ = 0;
  double epoch_t_ = 0.0;
  double last_t_ = 0.0;
  std::uint64_t next_check_ = 0;
  std::uint64_t check_interval_ = 0;
  std::size_t heap_limit_ = 0;
  std::uint64_t reframes_ = 0;
};

static_assert(EventQueue<CalendarQueue>);

// ---------------------------------------------------------------------------------------------
// Hot paths, inline.

inline void CalendarQueue::set(int id, double t) {
  assert(in_range(id));
  if (!(t < kInf)) [[unlikely]] {
    if (t != t) detail::throw_nan_time(id);
    erase(id);
    return;
  }
  Node& n = node_[id];
  const std::int64_t b = bin(t);
  const std::int32_t where = n.b;
  if (where == kAbsent) {
    ++size_;
  } else if (where == kHeap) {
    if (b <= cur_) {  // stays in the heap: move in place
      n.t = t;
      heap_move(static_cast<std::size_t>(n.a), t);
      return;
    }
    heap_remove_at(static_cast<std::size_t>(n.a));
  } else if (where == kOver) {
    if (b >= lim_) {  // stays in the overflow
      n.t = t;
      if (t < over_tmin_) over_tmin_ = t;
      return;
    }
    over_remove(n);
  } else {
    if (b < lim_ && b == bin(n.t)) {  // same ring slot
      n.t = t;
      return;
    }
    ring_unlink(n);
  }
  n.t = t;
  place(id, t, b);
}

inline void CalendarQueue::erase(int id) {
  assert(in_range(id));
  Node& n = node_[id];
  const std::int32_t where = n.b;
  if (where == kAbsent) return;
  if (where == kHeap)
    heap_remove_at(static_cast<std::size_t>(n.a));
  else if (where == kOver)
    over_remove(n);
  else
    ring_unlink(n);
  n.b = kAbsent;
  --size_;
}

inline void CalendarQueue::pop() {
  assert(!empty());
  if (heap_.empty()) advance();
  const HeapEntry e = heap_[0];
  heap_remove_at(0);
  node_[e.id].b = kAbsent;
  --size_;
  last_t_ = e.t;
  if (++pops_ >= next_check_) [[unlikely]]
    periodic_check();
}

}  // namespace matep

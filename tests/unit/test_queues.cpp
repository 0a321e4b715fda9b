// Event queues: HeapQueue and CalendarQueue against a std::set reference model, and against each
// other (identical pop sequences are an acceptance criterion of the EventQueue contract).
#include <gtest/gtest.h>

#include <cfloat>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <set>
#include <stdexcept>
#include <utility>
#include <vector>

#include "scheduler/calendar_queue.hpp"
#include "scheduler/event_queue.hpp"
#include "scheduler/heap_queue.hpp"

namespace matep {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Calendar variants that stress the ring: few bins (constant wrapping and overflow traffic) and
// extreme bin occupancies.
struct TinyRingCalendar : CalendarQueue {
  explicit TinyRingCalendar(std::size_t n) : CalendarQueue(n, CalendarQueueOptions{0.5, 0.001}) {}
};
struct FatBinCalendar : CalendarQueue {
  explicit FatBinCalendar(std::size_t n) : CalendarQueue(n, CalendarQueueOptions{200.0, 4.0}) {}
};
static_assert(EventQueue<TinyRingCalendar> && EventQueue<FatBinCalendar>);

// Reference model: the contract's order is exactly std::pair<double, int>'s.
class Reference {
 public:
  explicit Reference(std::size_t n) : t_(n, kInf) {}
  void set(int id, double t) {
    erase(id);
    if (t < kInf) {
      s_.insert({t, id});
      t_[id] = t;
    }
  }
  void erase(int id) {
    if (t_[id] < kInf) s_.erase({t_[id], id});
    t_[id] = kInf;
  }
  bool contains(int id) const { return t_[id] < kInf; }
  std::size_t size() const { return s_.size(); }
  bool empty() const { return s_.empty(); }
  std::pair<int, double> top() const { return {s_.begin()->second, s_.begin()->first}; }
  void pop() { erase(s_.begin()->second); }
  void clear() {
    s_.clear();
    std::fill(t_.begin(), t_.end(), kInf);
  }

 private:
  std::set<std::pair<double, int>> s_;
  std::vector<double> t_;
};

// Random times relative to "now" (the last popped time), covering the cases the calendar must
// survive: spreads, exact ties, "now" and earlier, far future, astronomically far, negative, -inf,
// +inf (= erase).
class TimeGen {
 public:
  explicit TimeGen(std::uint64_t seed, double window = 1.0) : rng_(seed), w_(window) {}
  double operator()(double now) {
    const int k = pick_(rng_);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    switch (k) {
      case 0: case 1: case 2: case 3: case 4: case 5: case 6: case 7: case 8: case 9:
      case 10: case 11: case 12: case 13: case 14: case 15: case 16: case 17: case 18: case 19:
        return now + w_ * u(rng_);
      case 20: case 21: case 22: case 23: case 24: case 25: case 26: case 27:
        return now + 0.25 * w_ * std::floor(4.0 * u(rng_));  // ties (including now itself)
      case 28: case 29:
        return now;
      case 30: case 31:
        return now - w_ * u(rng_);  // earlier than the current bin
      case 32: case 33:
        return now + 1e3 * w_ * (1.0 + u(rng_));  // beyond the ring
      case 34: return now + 1e12 * (1.0 + u(rng_));
      case 35: return 1e300 * (1.0 + u(rng_));
      case 36: return DBL_MAX;
      case 37: return -1e3 * u(rng_);
      case 38: return u(rng_) < 0.3 ? -kInf : 1e-310 * u(rng_);  // -inf, denormals
      default: return kInf;
    }
  }

 private:
  std::mt19937_64 rng_;
  std::uniform_int_distribution<int> pick_{0, 40};
  double w_;
};

template <class Q>
class QueueTest : public ::testing::Test {};
using QueueTypes = ::testing::Types<HeapQueue, CalendarQueue, TinyRingCalendar, FatBinCalendar>;
TYPED_TEST_SUITE(QueueTest, QueueTypes);

// Drives one queue and the reference with the same random operations; returns the popped sequence.
template <class Q>
std::vector<std::pair<int, double>> random_ops(std::size_t n, int ops, std::uint64_t seed, double window) {
  Q q(n);
  Reference ref(n);
  TimeGen gen(seed, window);
  std::mt19937_64 rng(seed ^ 0x9e3779b97f4a7c15ULL);
  std::uniform_int_distribution<int> pick_id(0, static_cast<int>(n) - 1);
  std::uniform_int_distribution<int> pick_op(0, 999);
  std::vector<std::pair<int, double>> popped;
  double now = 0.0;
  for (int step = 0; step < ops; ++step) {
    const int op = pick_op(rng);
    const int id = pick_id(rng);
    if (op < 450) {
      const double t = gen(now);
      q.set(id, t);
      ref.set(id, t);
    } else if (op < 550) {
      q.erase(id);
      ref.erase(id);
    } else if (op < 999) {
      if (!ref.empty()) {
        const auto e = q.top();
        EXPECT_EQ(e, ref.top()) << "step " << step;
        q.pop();
        ref.pop();
        popped.push_back(e);
        if (std::isfinite(e.second)) now = e.second;
      }
    } else {
      q.clear();
      ref.clear();
      now = 0.0;
    }
    EXPECT_EQ(q.size(), ref.size());
    EXPECT_EQ(q.empty(), ref.empty());
    EXPECT_EQ(q.contains(id), ref.contains(id));
    if (!ref.empty()) {
      EXPECT_EQ(q.top(), ref.top()) << "step " << step;
    }
    if (::testing::Test::HasFailure()) break;
  }
  for (int id = 0; id < static_cast<int>(n); ++id) EXPECT_EQ(q.contains(id), ref.contains(id));
  while (!ref.empty()) {  // drain
    EXPECT_EQ(q.top(), ref.top());
    popped.push_back(q.top());
    q.pop();
    ref.pop();
  }
  EXPECT_TRUE(q.empty());
  return popped;
}

TYPED_TEST(QueueTest, RandomOperationsMatchReference) {
  for (const std::size_t n : {1u, 2u, 7u, 64u, 1000u}) {
    for (std::uint64_t seed = 1; seed <= 3; ++seed) {
      SCOPED_TRACE(::testing::Message() << "n=" << n << " seed=" << seed);
      random_ops<TypeParam>(n, 20000, seed * 1000 + n, 1.0);
      if (this->HasFailure()) return;
    }
  }
}

TYPED_TEST(QueueTest, EdgeCases) {
  TypeParam q(4);
  EXPECT_TRUE(q.empty());
  q.erase(2);  // absent: no-op
  q.set(1, kInf);  // "no event" is never stored
  EXPECT_FALSE(q.contains(1));
  EXPECT_EQ(q.size(), 0u);
  q.set(3, 5.0);
  q.set(3, 5.0);  // same time twice
  q.set(0, 5.0);  // tie: smaller id first
  q.set(2, -0.0);
  q.set(1, 0.0);  // -0.0 == 0.0: a tie
  EXPECT_EQ(q.size(), 4u);
  EXPECT_EQ(q.top(), (std::pair<int, double>{1, 0.0}));
  q.pop();
  EXPECT_EQ(q.top().first, 2);
  q.set(2, kInf);  // erases
  EXPECT_FALSE(q.contains(2));
  EXPECT_EQ(q.top(), (std::pair<int, double>{0, 5.0}));
  EXPECT_THROW(q.set(1, std::nan("")), std::invalid_argument);
  q.pop();
  EXPECT_EQ(q.top(), (std::pair<int, double>{3, 5.0}));
  q.clear();
  EXPECT_TRUE(q.empty());
  q.set(3, 1.0);
  EXPECT_EQ(q.top(), (std::pair<int, double>{3, 1.0}));
  TypeParam none(0);
  EXPECT_TRUE(none.empty());
}

// Times whose bin index floor(t * scale) would overflow int64, mixed with ordinary ones.
TYPED_TEST(QueueTest, HugeTimesAndTinySpreads) {
  const std::vector<double> times = {1e-9, 2e-9, DBL_MAX, 1e300, 3e-9, 1e18, 1e19, -1e300, -kInf, 0.0, 5e-324};
  TypeParam q(times.size());
  Reference ref(times.size());
  for (std::size_t i = 0; i < times.size(); ++i) {
    q.set(static_cast<int>(i), times[i]);
    ref.set(static_cast<int>(i), times[i]);
  }
  while (!ref.empty()) {
    ASSERT_EQ(q.top(), ref.top());
    // re-insert the popped id a little later once, to exercise inserts right after huge jumps
    const auto [id, t] = ref.top();
    q.pop();
    ref.pop();
    if (id == 2 || id == 4) continue;
    if (t > 1e17 && t < 1e20) {
      q.set(id, t * 2.0);
      ref.set(id, t * 2.0);
      q.set(2, t + 1.0);
      ref.set(2, t + 1.0);
    }
  }
}

TEST(QueueAgreement, IdenticalPopSequences) {
  for (std::uint64_t seed = 11; seed <= 14; ++seed) {
    for (const double window : {1.0, 1e-6, 1e6}) {
      const auto h = random_ops<HeapQueue>(500, 30000, seed, window);
      const auto c = random_ops<CalendarQueue>(500, 30000, seed, window);
      const auto t = random_ops<TinyRingCalendar>(500, 30000, seed, window);
      ASSERT_GT(h.size(), 1000u);
      ASSERT_EQ(h, c) << "seed " << seed << " window " << window;
      ASSERT_EQ(h, t) << "seed " << seed << " window " << window;
    }
  }
}

// Hold workload: pop the minimum, re-insert it at t + Exp(mean), and re-predict one other id.
// `mean` changes by 1000x between phases; every pop is checked against HeapQueue.
template <class Q>
void hold_phase(Q& q, HeapQueue& ref, std::mt19937_64& rng, int ops, double mean, std::size_t n) {
  std::exponential_distribution<double> expo(1.0 / mean);
  std::uniform_int_distribution<int> pick(0, static_cast<int>(n) - 1);
  double last = -kInf;
  for (int i = 0; i < ops; ++i) {
    const auto e = ref.top();
    ASSERT_EQ(q.top(), e) << "op " << i;
    ASSERT_GE(e.second, last);
    last = e.second;
    q.pop();
    ref.pop();
    const double t1 = e.second + expo(rng);
    q.set(e.first, t1);
    ref.set(e.first, t1);
    const int other = pick(rng);
    const double t2 = e.second + expo(rng);
    q.set(other, t2);
    ref.set(other, t2);
  }
}

TEST(CalendarQueue, AdaptsToRateChangesAndStaysExact) {
  constexpr std::size_t n = 4000;
  CalendarQueue q(n);
  HeapQueue ref(n);
  std::mt19937_64 rng(7);
  std::exponential_distribution<double> expo(1.0);
  for (int id = 0; id < static_cast<int>(n); ++id) {
    const double t = expo(rng);
    q.set(id, t);
    ref.set(id, t);
  }
  hold_phase(q, ref, rng, 40000, 1.0, n);
  if (HasFatalFailure()) return;
  const double w1 = q.bin_width();
  const auto r1 = q.reframe_count();
  hold_phase(q, ref, rng, 60000, 1e-3, n);  // event rate up 1000x
  if (HasFatalFailure()) return;
  const double w2 = q.bin_width();
  EXPECT_GT(q.reframe_count(), r1);
  EXPECT_LT(w2, w1 * 4e-3);
  EXPECT_GT(w2, w1 * 2.5e-4);
  hold_phase(q, ref, rng, 60000, 1.0, n);  // and back down 1000x
  if (HasFatalFailure()) return;
  const double w3 = q.bin_width();
  EXPECT_LT(w3, w1 * 4.0);
  EXPECT_GT(w3, w1 * 0.25);
  // The bin width tracks the rate: ~events_per_bin pops per bin (default options).
  const double pops_per_bin = w3 * static_cast<double>(n) / 1.0;
  EXPECT_GT(pops_per_bin, CalendarQueueOptions{}.events_per_bin / 4.0);
  EXPECT_LT(pops_per_bin, CalendarQueueOptions{}.events_per_bin * 4.0);
}

TEST(CalendarQueue, LargeHoldWorkloadMatchesHeap) {
  constexpr std::size_t n = 100000;
  CalendarQueue q(n);
  HeapQueue ref(n);
  std::mt19937_64 rng(42);
  std::exponential_distribution<double> expo(1.0);
  for (int id = 0; id < static_cast<int>(n); ++id) {
    const double t = 1e4 + expo(rng);  // far from the origin: exercises the time origin
    q.set(id, t);
    ref.set(id, t);
  }
  hold_phase(q, ref, rng, 400000, 1.0, n);
  EXPECT_EQ(q.size(), n);
  EXPECT_LT(static_cast<double>(q.memory_bytes()) / static_cast<double>(n), 40.0);
}

TEST(CalendarQueue, ClearRecalibrates) {
  CalendarQueue q(1000);
  HeapQueue ref(1000);
  std::mt19937_64 rng(3);
  for (const double scale : {1.0, 1e-8, 1e8}) {
    q.clear();
    ref.clear();
    std::exponential_distribution<double> expo(1.0 / scale);
    for (int id = 0; id < 1000; ++id) {
      const double t = expo(rng);
      q.set(id, t);
      ref.set(id, t);
    }
    hold_phase(q, ref, rng, 5000, scale, 1000);
    if (HasFatalFailure()) return;
    // ~events_per_bin pops per bin at a pop rate of 1000 / scale
    const double expected = CalendarQueueOptions{}.events_per_bin * scale / 1000.0;
    EXPECT_GT(q.bin_width(), expected / 4.0);
    EXPECT_LT(q.bin_width(), expected * 4.0);
  }
}

}  // namespace
}  // namespace matep

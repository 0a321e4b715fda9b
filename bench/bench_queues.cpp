// Event-queue kernels: the "hold" workload of event-driven MD for HeapQueue and CalendarQueue.
//
// One hold operation = top() + pop() of the earliest event (id, t), set(id, t + Exp(1)) for the
// popped id, and set(other, t + Exp(1)) for a random other id (the partner's re-prediction).  N
// entries are live throughout, spread over ~ one mean free time.  Reported time per iteration = ns
// per hold operation; a summary table at the end gives heap/calendar ratios measured in the same run
// (medians when --benchmark_repetitions is given).
//
//   matep_bench --benchmark_filter=hold/ --benchmark_repetitions=5
//   matep_bench --matep_tune            also registers the tuning sweeps ("tune/...": Boost.Heap
//                                       variants, calendar events_per_bin and bins_per_id)
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <unistd.h>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "scheduler/calendar_queue.hpp"
#include "scheduler/heap_queue.hpp"

namespace {

using namespace matep;

// Deterministic, cheap randomness so the queue dominates the timing: xorshift64* ids and a table
// of exponential variates.
struct Rng {
  std::uint64_t s;
  std::uint64_t next() {
    s ^= s >> 12;
    s ^= s << 25;
    s ^= s >> 27;
    return s * 0x2545F4914F6CDD1DULL;
  }
  int below(std::size_t n) { return static_cast<int>(((next() >> 32) * n) >> 32); }
};

const std::vector<double>& exp_table() {
  static const std::vector<double> table = [] {
    std::vector<double> v(1u << 16);
    Rng rng{0x9E3779B97F4A7C15ULL};
    for (double& x : v) x = -std::log((static_cast<double>(rng.next() >> 11) + 0.5) * 0x1.0p-53);
    return v;
  }();
  return table;
}

template <class Q>
struct Hold {
  Q& q;
  std::size_t n;
  Rng rng{0xDEADBEEFCAFEULL};
  const double* ex = exp_table().data();
  std::uint32_t j = 0;
  double increment() { return ex[(j++) & 0xFFFFu]; }
  void fill() {
    for (std::size_t i = 0; i < n; ++i) q.set(static_cast<int>(i), increment());
  }
  void operator()() {
    const auto [id, t] = q.top();
    q.pop();
    q.set(id, t + increment());
    q.set(rng.below(n), t + increment());
  }
};

template <class Q, class... Args>
void bm_hold(benchmark::State& state, Args... args) {
  const auto n = static_cast<std::size_t>(state.range(0));
  Q q(n, args...);
  Hold<Q> hold{q, n};
  hold.fill();
  for (std::size_t i = 0; i < 2 * n + 20000; ++i) hold();  // steady state (and calibration)
  for (auto _ : state) hold();
  benchmark::DoNotOptimize(q.size());
  if constexpr (requires { q.memory_bytes(); })
  {
    state.counters["bytes_per_id"] = static_cast<double>(q.memory_bytes()) / static_cast<double>(n);
    state.counters["reframes"] = static_cast<double>(q.reframe_count());
  }
}

const std::vector<std::int64_t> kSizes = {1000, 10000, 100000, 1000000};

template <class F, class... Args>
void add(const std::string& name, F f, Args... args) {
  auto* b = benchmark::RegisterBenchmark(name.c_str(), f, args...);
  for (const auto n : kSizes) b->Arg(n);
  b->Unit(benchmark::kNanosecond);
}

void register_main() {
  add("hold/heap", bm_hold<HeapQueue>);
  add("hold/calendar", bm_hold<CalendarQueue>);
}

void register_tuning() {
  add("tune/heap_d2", bm_hold<BasicHeapQueue<detail::DaryHeap<2>>>);
  add("tune/heap_d8", bm_hold<BasicHeapQueue<detail::DaryHeap<8>>>);
  add("tune/heap_pairing", bm_hold<BasicHeapQueue<detail::PairingHeap>>);
  char name[64];
  for (const double epb : {0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 64.0}) {
    std::snprintf(name, sizeof name, "tune/calendar_epb%g", epb);
    add(name, bm_hold<CalendarQueue, CalendarQueueOptions>, CalendarQueueOptions{epb, 1.0});
  }
  for (const double bpi : {0.125, 0.25, 0.5, 2.0}) {
    std::snprintf(name, sizeof name, "tune/calendar_bpi%g", bpi);
    add(name, bm_hold<CalendarQueue, CalendarQueueOptions>,
        CalendarQueueOptions{CalendarQueueOptions{}.events_per_bin, bpi});
  }
}

// Console output as usual, plus a heap-vs-calendar table from the same run.
class RatioReporter : public benchmark::ConsoleReporter {
 public:
  RatioReporter() : ConsoleReporter(isatty(fileno(stdout)) ? OO_Defaults : OO_Tabular) {}
  void ReportRuns(const std::vector<Run>& runs) override {
    for (const Run& r : runs) {
      if (r.error_occurred) continue;
      const bool single = r.run_type == Run::RT_Iteration && r.repetitions <= 1;
      const bool median = r.run_type == Run::RT_Aggregate && r.aggregate_name == "median";
      if (single || median) ns_[r.run_name.function_name + "/" + r.run_name.args] = r.GetAdjustedRealTime();
    }
    ConsoleReporter::ReportRuns(runs);
  }
  void summary() const {
    if (ns_.empty()) return;
    std::fflush(stdout);
    std::printf("\n%-10s %14s %14s %10s\n", "N", "heap ns/hold", "calendar ns/hold", "speedup");
    for (const auto n : kSizes) {
      const auto h = ns_.find("hold/heap/" + std::to_string(n));
      const auto c = ns_.find("hold/calendar/" + std::to_string(n));
      if (h == ns_.end() || c == ns_.end()) continue;
      std::printf("%-10lld %14.1f %14.1f %10.2f\n", static_cast<long long>(n), h->second, c->second,
                  h->second / c->second);
    }
  }

 private:
  std::map<std::string, double> ns_;
};

}  // namespace

int main(int argc, char** argv) {
  bool tune = false;
  int kept = 1;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--matep_tune") == 0)
      tune = true;
    else
      argv[kept++] = argv[i];
  }
  argc = kept;
  register_main();
  if (tune) register_tuning();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  RatioReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  reporter.summary();
  benchmark::Shutdown();
  return 0;
}

// CalendarQueue cold paths: advancing the current bin, ring wraps, adaptation, rebuilds.
// Paul, J. Comput. Phys. 221, 615 (2007); see calendar_queue.hpp for the structure and invariants.
#include "scheduler/calendar_queue.hpp"

#include <algorithm>
#include <bit>
#include <cmath>

namespace matep {

namespace {
// Re-frame only when the wanted bin width is off by more than this factor (hysteresis; keeps the
// O(size) re-frames rare and amortised).
constexpr double kAdaptFactor = 2.0;
// A rate estimate needs at least this many pops.
constexpr std::uint64_t kMinPops = 32;
// Scales outside this range are clamped (any positive finite scale is correct, only slower).
constexpr double kScaleMin = 1e-250;
constexpr double kScaleMax = 1e250;

double clamp_scale(double s) { return std::clamp(s, kScaleMin, kScaleMax); }
}  // namespace

CalendarQueue::CalendarQueue(std::size_t capacity, const CalendarQueueOptions& options)
    : node_(capacity, Node{0.0, kNil, kAbsent}), events_per_bin_(options.events_per_bin) {
  if (capacity > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max() / 2))
    throw std::invalid_argument("CalendarQueue: capacity too large for 32-bit ids");
  if (!(options.events_per_bin > 0.0) || !(options.bins_per_id > 0.0))
    throw std::invalid_argument("CalendarQueue: events_per_bin and bins_per_id must be positive");
  const double want = std::ceil(static_cast<double>(capacity) * options.bins_per_id);
  nbins_ = std::bit_ceil(static_cast<std::size_t>(std::clamp(want, 16.0, 1073741824.0)));
  mask_ = nbins_ - 1;
  head_.assign(nbins_, kNil);
  over_.reserve(capacity);
  heap_.reserve(64);
  check_interval_ = std::max<std::uint64_t>(nbins_, 1024);
  next_check_ = check_interval_;
  heap_limit_ = 64 + static_cast<std::size_t>(16.0 * events_per_bin_);
}

std::size_t CalendarQueue::memory_bytes() const {
  return sizeof(*this) + node_.capacity() * sizeof(Node) + head_.capacity() * sizeof(std::int32_t) +
         over_.capacity() * sizeof(std::int32_t) + heap_.capacity() * sizeof(HeapEntry);
}

void CalendarQueue::clear() {
  for (Node& n : node_) n.b = kAbsent;
  std::fill(head_.begin(), head_.end(), kNil);
  over_.clear();
  heap_.clear();
  size_ = 0;
  ring_count_ = 0;
  cur_ = lim_ = kBinMin;
  over_tmin_ = kInf;
  calibrated_ = false;
}

void CalendarQueue::heapify() {
  const std::size_t n = heap_.size();
  for (std::size_t i = 0; i < n; ++i) node_[heap_[i].id].a = static_cast<std::int32_t>(i);
  for (std::size_t i = n / 2; i-- > 0;) sift_down(i, heap_[i]);
}

void CalendarQueue::advance() {
  assert(size_ > 0 && heap_.empty());
  for (;;) {
    if (ring_count_ == 0) {
      wrap();  // progress: a second wrap in a row uses the exact overflow minimum
      if (!heap_.empty()) return;
      continue;
    }
    while (++cur_ < lim_) {
      const auto s = static_cast<std::size_t>(static_cast<std::uint64_t>(cur_) & mask_);
      std::int32_t id = head_[s];
      if (id == kNil) continue;
      head_[s] = kNil;
      std::size_t moved = 0;
      do {  // the whole slot has idx == cur: it becomes the heap
        Node& n = node_[id];
        heap_.push_back({n.t, id});
        n.b = kHeap;
        id = n.a;
        ++moved;
      } while (id != kNil);
      ring_count_ -= moved;
      heapify();
      return;
    }
    assert(false && "ring_count_ says non-empty but no slot in (cur, lim) is");
    ring_count_ = 0;
  }
}

bool CalendarQueue::rate_says_rescale(double& want) {
  const std::uint64_t p = pops_ - epoch_pops_;
  if (p < kMinPops) return false;
  const double dt = last_t_ - epoch_t_;
  epoch_pops_ = pops_;
  epoch_t_ = last_t_;
  if (!(dt > 0.0) || !(dt < kInf)) return false;
  want = clamp_scale(static_cast<double>(p) / (dt * events_per_bin_));
  return want > kAdaptFactor * scale_ || want * kAdaptFactor < scale_;
}

void CalendarQueue::wrap() {
  assert(heap_.empty() && ring_count_ == 0 && over_.size() == size_);
  if (!calibrated_) {
    calibrate();
    return;
  }
  double want = scale_;
  if (rate_says_rescale(want)) {
    scale_ = want;
    reframe();
    return;
  }
  // Jump to the overflow's first bin (over_tmin_ is a lower bound; every overflow entry has
  // idx >= lim, so lim is one too).
  cur_ = std::max(bin(over_tmin_), lim_);
  lim_ = cur_ + static_cast<std::int64_t>(nbins_);
  distribute_overflow();
}

void CalendarQueue::distribute_overflow() {
  double keep_min = kInf;
  std::size_t j = 0;
  const std::size_t n = over_.size();
  constexpr std::size_t kAhead = 16;
  for (std::size_t i = 0; i < n; ++i) {
    if (i + kAhead < n) __builtin_prefetch(&node_[over_[i + kAhead]]);
    const std::int32_t id = over_[i];
    Node& nd = node_[id];
    const double t = nd.t;
    const std::int64_t b = bin(t);
    if (b <= cur_) {
      nd.b = kHeap;
      heap_.push_back({t, id});
    } else if (b < lim_) {
      ring_push(id, b);
    } else {
      nd.a = static_cast<std::int32_t>(j);  // stays, compacted (nd.b == kOver already)
      over_[j++] = id;
      keep_min = std::min(keep_min, t);
    }
  }
  over_.resize(j);
  over_tmin_ = keep_min;
  heapify();
}

void CalendarQueue::reframe() {
  assert(heap_.empty() && ring_count_ == 0 && over_.size() == size_);
  double tmin = kInf;
  for (const std::int32_t id : over_) {
    const double t = node_[id].t;
    if (t < tmin && t > -kInf) tmin = t;
  }
  origin_ = tmin < kInf ? tmin : 0.0;
  cur_ = 0;
  lim_ = static_cast<std::int64_t>(nbins_);
  distribute_overflow();
  ++reframes_;
}

void CalendarQueue::full_rebuild() {
  over_.clear();
  heap_.clear();
  std::fill(head_.begin(), head_.end(), kNil);
  ring_count_ = 0;
  const auto cap = static_cast<std::int32_t>(node_.size());
  for (std::int32_t id = 0; id < cap; ++id) {
    Node& n = node_[id];
    if (n.b == kAbsent) continue;
    n.b = kOver;
    n.a = static_cast<std::int32_t>(over_.size());
    over_.push_back(id);
  }
  reframe();
}

void CalendarQueue::calibrate() {
  // Everything is in the overflow.  Pop rate ~ n / (mean - min) for the usual spread of predicted
  // times (exact for an exponential spread, a factor 2 high for a uniform one).
  double tmin = kInf;
  double t0 = 0.0;
  double sum = 0.0;
  std::size_t n = 0;
  for (const std::int32_t id : over_) {
    const double t = node_[id].t;
    if (!(t > -kInf)) continue;
    if (n == 0) t0 = t;
    sum += t - t0;
    tmin = std::min(tmin, t);
    ++n;
  }
  if (n >= 2) {
    const double spread = (t0 + sum / static_cast<double>(n)) - tmin;
    if (spread > 0.0 && spread < kInf)
      scale_ = clamp_scale(static_cast<double>(n) / (events_per_bin_ * spread));
  }
  calibrated_ = true;
  reframe();
  epoch_pops_ = pops_;
  epoch_t_ = origin_;
  last_t_ = origin_;
}

void CalendarQueue::periodic_check() {
  next_check_ = pops_ + check_interval_;
  if (!calibrated_) return;
  double want = scale_;
  const bool rescale = rate_says_rescale(want);
  if (rescale || heap_.size() > heap_limit_) {
    scale_ = want;
    full_rebuild();
  }
}

}  // namespace matep

// The hybrid engine (engine/hybrid.hpp states the rule): the EDM core of engine/edm/core.hpp,
// extended through its hooks by a soft set advanced in TDM substeps (a system event of the same
// queue), the switching rule and the rest rule.
#include "engine/hybrid.hpp"

#include <fmt/format.h>

#include <omp.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <initializer_list>
#include <stdexcept>
#include <tuple>

#include "contact/soft.hpp"
#include "contact/timestep.hpp"
#include "engine/edm/core.hpp"
#include "engine/flatten.hpp"
#include "engine/hybrid/cost.hpp"
#include "engine/hybrid/meet.hpp"
#include "engine/hybrid/rest.hpp"
#include "engine/hybrid/switching.hpp"
#include "engine/renumber.hpp"
#include "engine/soft/batch.hpp"
#include "engine/soft/contact_rows.hpp"
#include "engine/soft/forces.hpp"
#include "engine/soft/pair_list.hpp"
#include "engine/soft/springs.hpp"
#include "engine/soft/verlet.hpp"
#include "engine/soft_plan.hpp"
#include "scheduler/calendar_queue.hpp"

namespace matep {

namespace {

using edm::Hot;
using hybrid::CostMeter;
using hybrid::RestRule;
using hybrid::Switch;
using hybrid::SwitchRule;

// The hybrid's substep (run.dt, or the plan's default); throws above the stability limit.
double hybrid_substep(const SoftPlan& plan, const HybridSettings& hs) {
  const double h = hs.dt > 0.0 ? hs.dt : plan.default_dt;
  if (!(h < plan.max_stable_dt))
    throw std::invalid_argument(fmt::format(
        "run.dt: {} is above the stability limit {:.6g} of the stiffest contact ({}); the default step is {:.6g}",
        h, plan.max_stable_dt, plan.limiting, plan.default_dt));
  return h;
}

// The hybrid's skins: the least and the largest capture distance (a hard particle this near a soft
// one joins the soft set; between the two the capture distance follows the speeds,
// HybridEngine::capture_gap; the largest widens the EDM cells) and the soft list's skin.
struct Skins {
  double capture = 0.0, capture_max = 0.0, list = 0.0;
};
constexpr double kListSkin = 0.1;  // soft neighbour-list skin, fraction of the smallest diameter
template <int D>
Skins hybrid_skins(const System<D>& sys, const SoftPlan& plan, const HybridSettings& hs, double h) {
  const double dmin = 2.0 * sys.radius_range().first;
  Skins s;
  s.capture = least_capture(sys, hs) * (dmin < kNever ? dmin : 0.0);
  // The capture distance of a pair at the largest expected impact speed (each grain at most that
  // fast): capture_gap's formula with speed = impact_speed and vsoft_max = impact_speed.
  s.capture_max = std::max(s.capture, 2.0 * h * (3.0 * plan.impact_speed + sys.gravity.norm() * h));
  // The Verlet list of the soft set takes the TDM engine's skin, 0.1 d, and at least the largest
  // capture distance (a captured grain's entries must reach its soft neighbours). A wider skin
  // (the EDM cells do not widen with it: ext_cell_margin) saves list builds where fast grains
  // join a bed, but gives every substep of a dense soft bed more entries to walk: at 0.4 d the
  // pour took 0.91 of its time and the stability map's dense cells 1.09-1.30 of theirs
  // (bench/README.md, fourteenth sitting).
  s.list = std::max(s.capture_max, kListSkin * dmin);
  return s;
}


template <int D>
class HybridEngine final : public edm::EdmCore<D, CalendarQueue, HybridEngine<D>> {
  using Base = edm::EdmCore<D, CalendarQueue, HybridEngine<D>>;
  friend Base;
  using Base::sys_;
  using Base::set_;
  using Base::N_;
  using Base::queue_;
  using Base::observers_;
  using Base::collision_observers_;
  using Base::snapshot_observers_;
  using Base::g_;
  using Base::lo_;
  using Base::hi_;
  using Base::L_;
  using Base::gravity_;
  using Base::all_elastic_;
  using Base::shapes_;
  using Base::anchors_;
  using Base::wall_loads_;
  using Base::bracketed_walls_;
  using Base::now_;
  using Base::hot_;
  using Base::mass_factor_;
  using Base::cold_;
  using Base::head_;
  using Base::grid_;
  using Base::next_;
  using Base::counts_;
  using Base::virial_;
  using Base::prev_ke_;
  using Base::status_;
  using Base::message_;
  using Base::rough_;
  using Base::rough_rules_;
  using Base::mass;
  using Base::is_fixed;
  using Base::ui;
  using Base::advance;
  using Base::predict;
  using Base::for_neighbours;
  using Base::cell_insert;
  using Base::cell_remove;
  using Base::linear;
  using Base::min_image;
  using Base::wall_checkpoint;
  using Base::kNone;
  using Base::kPair;
  using Base::kWall;

 public:
  HybridEngine(System<D>&& system, const EdmSettings& edm, const HybridSettings& hs, const SoftPlan* plan,
               const std::vector<Observer<D>*>& obs)
      : Base(std::move(system), edm, obs), given_settings_(hs), given_plan_(plan) {
    this->init(nullptr);
  }

 private:
  HybridSettings given_settings_;
  const SoftPlan* given_plan_ = nullptr;

  // Soft particles carry the TDM state of engine/soft/verlet.hpp's scheme: between substeps vh_ holds
  // v(t - h/2), acc_ a(t - h) (for the predicted velocity of the dashpots), f_/tq_ the force and
  // torque at t; hot_.x and hot_.t the position and time of the last substep, hot_.v and sys_.w the
  // full-step velocity and spin v(t) = v(t - h/2) + h/2 a(t) (for samples, snapshots and release).
  // A fixed grain (System::fixed) is kFixed for the whole run: an immovable sphere in the hard
  // collisions (the core) and a partner in the soft set's contact lists that is never integrated;
  // it never switches, sleeps or wakes, and a hard grain colliding with it is judged by the wall rule.
  // kGone: taken out by an outlet.
  enum : std::uint8_t { kHard = 0, kSoft = 1, kPending = 2, kAsleep = 3, kFixed = 4, kGone = 5 };

  // Whether i moves ballistically between its events (hard or pending), i.e. its stored state may
  // be extrapolated in time; a soft or sleeping particle is at its last substep.
  bool moved_by_events(int i) const { return mode_[i] == kHard || mode_[i] == kPending; }
  bool predicted(int i) const { return mode_[i] == kHard; }

  // ---- hooks of the EDM core ----
  void ext_setup() {
    hybrid_setup(given_settings_, given_plan_);
    set_.resort = edm::hybrid_resort(set_.resort);  // "auto": never
  }
  // With neighbour lists (run.neighbours) every grain keeps a shell and a list, soft and sleeping
  // ones too: a grain released hard then has its list, and a soft grain that leaves its shell gets
  // a new one at the substep (relocate). A hard grain lists every grain it may be captured by (the
  // largest capture distance as the lists' margin), so that its predictions mark it an interface
  // particle as the cells' walk would. The cells hold each grain by its shell's centre and are two
  // shells wider: the walks by position (captures, the soft set's entries) reach what they did.
  bool ext_lists() const { return true; }
  double ext_list_margin() const { return cskin_; }
  // Re-sorting (run.resort): only while no grain is soft, pending or asleep, when what the soft
  // set keeps by index is its per-grain arrays (permuted with the core's: ext_permute) and the
  // switching rule's memory of partners; its lists, springs, groups and sleepers are empty. A
  // re-sort due while grains are soft waits for the next one due.
  bool ext_can_resort() const {
    return soft_.empty() && pending_.empty() && asleep_ == 0 && asleep_list_.empty() && iface_.empty() &&
           pairs_.size() == 0 && we_.empty() && pe_sleep_.empty() && we_sleep_.empty() && watched_.empty() &&
           leaving_.empty() && unsupported_.empty() && !predrifted_;
  }
  template <class Permute>
  void ext_permute(Permute& permute, const std::vector<std::uint32_t>& to) {
    for (auto* v : {&vh_, &acc_, &f_, &x0_, &cblo_, &cbhi_, &fz_base_, &fz_mix_, &x_check_, &fz_step_}) permute(*v);
    for (auto* v : {&wh_, &alpha_, &tq_, &fz_tmix_, &fz_tbase_}) permute(*v);
    for (auto* v : {&minv_, &iinv_, &last_contact_, &iface_next_, &rate_t0_, &fz_scale_, &region_retry_, &cfree2_})
      permute(*v);
    for (auto* v : {&quiet_checks_, &slot_, &gslot_, &asleep_slot_}) permute(*v);
    for (auto* v : {&touching_, &near_, &mode_, &iface_flag_, &cand_, &joined_by_, &fz_cand_, &fz_lost_, &watch_flag_})
      permute(*v);
    permute(begun_n_);
    permute(region_seen_);
    switch_.permute(permute, to);
    // The fixed grains under their new indices, in index order as at the start.
    for (int& k : fixed_list_) k = static_cast<int>(to[static_cast<std::size_t>(k)]);
    std::sort(fixed_list_.begin(), fixed_list_.end());
    // Scratch of the substeps (made again before each use) and the threads' owners of rows.
    for (auto* v : {&region_, &early_, &group_, &freed_, &fresh_, &woken_}) v->clear();
    held_.clear();
    near_pairs_.clear();
    moved_.clear();
    moved_w_.clear();
    springs_.clear();
    for (const std::uint32_t k : own_set_) own_[k] = kUnowned;
    own_set_.clear();
    split_T_ = 0;
    dirty_ = true;  // the soft set's grid and lists are made anew at the next substep
  }
  // The soft set is at the run's time: not a step ahead (predrifted_), not behind (coasting).
  bool ext_can_stop() const { return !predrifted_ && !coasting(); }
  // The EDM cells reach every grain a capture may need (the largest capture distance), not the
  // soft list's skin: wider cells cost every hard prediction (a 500-grain gas at phi = 0.4 with no
  // soft grain: 1.3 x EDM's time with the list skin, 1.06 x with this margin). The few walks that
  // need the list's reach (a joining or waking grain's list entries) take two rings of cells
  // (for_neighbours_reach), so the cells are at least half that reach wide.
  // (dmax_: the radii are gone from sys_ by the time the core asks: it frees each input array once
  // copied. Read from the emptied array, dmax was 0 and the margin half the list's reach, 0.05 d
  // instead of the largest capture distance: in the stability map's 500-grain gases 7 cells a side
  // instead of 8, and 1.35-1.5 x EDM's time at phi = 0.5 with no grain soft.)
  double ext_cell_margin() const {
    return std::max(cskin_, 0.5 * (dmax_ + lskin_) - dmax_);
  }
  void ext_cells_ready(double rmax) {
    walls_.assign(shapes_);
    for (const WallShape<D>* w : shapes_) sweep_ = std::max(sweep_, w->sweep_speed());
    coast_scene_ = hset_.coast && sys_.outlets.empty() && sweep_ == 0.0;
    for (const WallShape<D>* w : shapes_) coast_scene_ = coast_scene_ && !w->moving();
    sg_w_ = 2.0 * rmax + lskin_;
    for (int k = 0; k < D; ++k) any_periodic_ = any_periodic_ || sys_.periodic[k];
    direct_cells_ = !grid_.hashed();
    for (int k = 0; k < D; ++k) direct_cells_ = direct_cells_ && (!grid_.periodic(k) || grid_.count(k) >= 3);
    hybrid_arrays();
    own_.assign(N_, kUnowned);
    spill_.resize(T_req_);
    loads_t_.resize(T_req_);
    for (auto& l : loads_t_) l.resize(shapes_.size());
    t_relocate_.resize(T_req_);
    t_leaving_.resize(T_req_);
    t_freed_.resize(T_req_);
    rb_.resize(T_req_);
    for (std::size_t sft = 0; sft < shifts_.size(); ++sft) {  // index sum_k (s_k + 1) 3^k, s_k in {-1, 0, 1}
      std::size_t r = sft;
      for (int k = 0; k < D; ++k) {
        shifts_[sft][k] = (static_cast<double>(r % 3) - 1.0) * L_[k];
        r /= 3;
      }
    }
    cblo_.assign(N_, Vec<D>::Constant(kNever));  // empty: the first substep relocates
    cbhi_.assign(N_, Vec<D>::Constant(-kNever));
    cfree2_.assign(N_, -1.0);
  }
  void ext_start() { hybrid_start(); }
  // Soft, pending and sleeping neighbours take no part in a hard particle's pair predictions (a
  // hard particle joins the soft set before it touches one); a soft or sleeping one makes it an
  // interface particle.
  // (While nothing is soft, pending or asleep, which is most of a gas's run, no mode is read.)
  bool ext_skip_neighbour(int i, int j) {
    if (all_hard() || mode_[j] == kHard) return false;
    if (mode_[j] != kPending) mark_interface(i);
    return true;
  }
  // Its course changed: an interface particle is checked for capture at the next substep (another
  // one's check time is set when it becomes one: mark_interface).
  void ext_on_predict(int i) {
    if (!iface_flag_[i]) return;
    iface_next_[i] = 0.0;
    due_now();
  }
  bool ext_divert_pair(int i, int j, double t) { return soft_rule_pair(i, j, t); }
  void ext_prefetch_pair(int i, int j) {
    switch_.prefetch(i);
    switch_.prefetch(j);
  }
  void ext_prefetch_next(int i) { switch_.prefetch(i); }
  bool ext_divert_wall(int i, int w, double t) { return soft_rule_wall(i, w, t); }
  // The EDM core's collapse watch fired for hard i at the collision just resolved: the group (i and
  // the partners of its collisions within the cluster window, this collision's among them) turns
  // soft instead of the run ending.
  bool ext_collapse(int i) {
    make_pending(i, now_, kByStability);
    return true;
  }
  void ext_snapshot(Snapshot<D>& snap) {
    snap.mode.resize(N_);
    for (int i = 0; i < N_; ++i) snap.mode[i] = mode_[i] == kPending ? std::uint8_t{kHard} : mode_[i];
    snap.cluster = soft_clusters();
    if (snap.with_contacts) soft_contact_rows(snap.contacts);
  }
  void ext_sample(ThermoSample& s) {
    s.elastic_energy = soft_elastic_energy();
    s.soft = soft_.size() + asleep_;
    s.collisions += hstats_soft_begun_;
  }
  void ext_result(RunResult<D>& res) { hybrid_result(res); }
  void ext_removed(int i) {
    set_mode(i, kGone);
    iface_flag_[i] = 0;
  }
  // A grain from an inlet enters hard, with its own mass; next to a soft grain it is an interface
  // particle (captured at the next substep if within the skin).
  void ext_inserted(int i, double) {
    set_mode(i, kHard);
    const double m = mass(i), R = hot_[i].R;
    minv_[i] = 1.0 / m;
    iinv_[i] = 1.0 / (inertia_factor<D>() * m * R * R);
    switch_.forget(i);
    region_retry_[i] = -kNever;
    last_contact_[i] = 0.0;
    quiet_checks_[i] = 0;
    for_neighbours(i, [&](int j, const Vec<D>&) {
      if (mode_[j] == kSoft || mode_[j] == kAsleep) mark_interface(i);
    });
  }

  using PairEntry = soft::PairEntry<D>;  // owner i, partner j, constants ctab_[c], image shift sh
  struct WallEntry {
    int i, w;
    std::uint32_t f;  // the wall's feature (contact/wall.hpp; 0 but for a mesh)
    std::uint32_t c;
    std::uint8_t touch;
    std::uint32_t r = 0;  // its rolling spring torque: wmr_[r] (Epsd rolling resistance; in the padding)
    Vec<D> xi;
  };
  // A new wall entry (with its rolling spring torque in wmr_ when the scene needs one).
  WallEntry new_wall_entry(int i, int w, std::uint32_t f) { return new_wall_entry_in(i, w, f, ctab_, wmr_); }
  WallEntry new_wall_entry_in(int i, int w, std::uint32_t f, std::vector<SoftContact>& tab,
                              std::vector<Spin<D>>& wmr) const {
    WallEntry e{i, w, f, wall_contact_in(w, i, tab), 0, 0, Vec<D>::Zero()};
    if (epsd_) {
      e.r = static_cast<std::uint32_t>(wmr.size());
      wmr.push_back(Spin<D>::Zero());
    }
    return e;
  }
  Spin<D>* wall_mr(const WallEntry& e) { return epsd_ ? &wmr_[e.r] : nullptr; }

  // ---- threads of the soft set ----
  // A force on a particle that the computing thread does not own, added after the parallel loop.
  struct Spill {
    std::uint32_t j;
    Vec<D> f;
    Spin<D> t;
  };
  static constexpr int kMaxThreads = 64;
  static constexpr std::uint8_t kUnowned = 255, kMulti = 254;  // own_: no thread owns the particle
  // The threads for n awake soft grains: at least HybridSettings::min_per_thread each.
  int threads_for(std::size_t n) {
    const int T = std::max(1, std::min<int>(T_req_, static_cast<int>(n / min_per_thread_)));
    threads_used_ = std::max(threads_used_, T);
    return T;
  }
  // body(t) for t = 0 .. T - 1, on T threads (fewer if OpenMP grants fewer: each runs several).
  template <class F>
  static void parallel(int T, F&& body) {
    if (T == 1) {
      body(0);
      return;
    }
#pragma omp parallel num_threads(T)
    for (int t = omp_get_thread_num(); t < T; t += omp_get_num_threads()) body(t);
  }
  // f(i) for the awake soft grains of thread th's part of the soft set (of T contiguous parts).
  template <class F>
  void for_soft_part(int th, int T, F&& f) const {
    const std::size_t n = soft_.size();
    for (std::size_t k = n * th / T, end = n * (th + 1) / T; k < end; ++k) f(soft_[k]);
  }
  // Flags and counters another thread may set at the same time (relaxed atomics).
  static void flag(std::uint8_t& b) { std::atomic_ref<std::uint8_t>(b).store(1, std::memory_order_relaxed); }
  static void bump(std::uint32_t& c) { std::atomic_ref<std::uint32_t>(c).fetch_add(1, std::memory_order_relaxed); }

  void hybrid_setup(const HybridSettings& hs, const SoftPlan* plan) {
    hset_ = hs;
    T_req_ = std::clamp(hs.threads > 0 ? hs.threads : omp_get_max_threads(), 1, kMaxThreads);
    min_per_thread_ = static_cast<std::size_t>(std::max(1, hs.min_per_thread));
    plan_ = plan ? *plan : plan_soft<D>(sys_);
    h_ = hybrid_substep(plan_, hs);
    hdt_ = 0.5 * h_;
    rot_ = plan_.friction;
    epsd_ = plan_.rolling_model == RollingModel::Epsd;
    springs_.set_rolling(epsd_);
    rolling_ = plan_.rolling;
    pairs_.set_rolling(epsd_);
    const Skins sk = hybrid_skins(sys_, plan_, hs, h_);
    dmax_ = 2.0 * sys_.radius_range().second;
    skin_ = sk.capture;
    cskin_ = sk.capture_max;
    lskin_ = sk.list;
    kstab_ = hs.stability;
    lookahead_ = hs.lookahead;
    hyst_ = hs.hysteresis > 0.0 ? hs.hysteresis : 10.0 * kstab_ * plan_.contact_time;
    rest_time_ = hs.rest_time > 0.0 ? hs.rest_time : 20.0 * plan_.contact_time;
    switch_params_ = {kstab_, hs.repeats, hs.speed_fall, hyst_, hs.cost_ratio * h_, kstab_ * plan_.contact_time};
    sleeping_ = hs.rest_speed > 0.0;
    rest_speed2_ = hs.rest_speed * hs.rest_speed;
    rest_.rest_speed2 = rest_speed2_;
    // Clusters are checked four times per rest time.
    sleep_every_ = std::max<std::uint64_t>(1, static_cast<std::uint64_t>(0.25 * rest_time_ / h_));
    // Release by cost: rates over at least k t_c, checked eight times as often while grains go,
    // down to once per k t_c while none can.
    cost_quiet_ = kstab_ * plan_.contact_time;
    cost_every_max_ = std::max<std::uint64_t>(1, static_cast<std::uint64_t>(cost_quiet_ / h_));
    cost_every_min_ = std::max<std::uint64_t>(1, cost_every_max_ / 8);
    cost_every_ = cost_every_min_;
    cost_ratio_ = hs.cost_ratio;
    substep_id_ = this->add_system_event("substep", [this](double t) {
      // The meter times one substep in kMeterStride and the gap after it: the clock's three reads
      // instead of two at every substep (about 50 ns each here: an eighth of the hybrid's own work
      // in the stability map's dilute gas at e = 0.1). Phase 0 starts a timed substep (no gap: the
      // last timed end is kMeterStride substeps back), phase 1 closes the gap after it.
      const std::uint64_t phase = meter_n_++ % kMeterStride;
      const std::uint64_t wrote = this->sample_k_ + this->snapshot_k_ + this->checkpoint_k_;
      if (phase <= 1) meter_.substep_begin(CostMeter::Clock::now(), particle_collisions(), phase == 0 || wrote != wrote_);
      wrote_ = wrote;
      const std::uint64_t steps_before = hstats_.soft_particle_steps;
      substep(t);
      if (phase == 0)
        meter_.substep_end(CostMeter::Clock::now(), static_cast<double>(hstats_.soft_particle_steps - steps_before),
                           particle_collisions());
      if (hset_.cost_measured && (hstats_.substeps & 0x3f) == 0) follow_measured_cost();
      // A stop request (a signal), after whole substeps: the soft set is then at t like the rest.
      if (status_.empty() && (hstats_.substeps & 0x3f) == 0 && !predrifted_ && set_.stop &&
          set_.stop->load(std::memory_order_relaxed)) {
        status_ = "interrupted";
        message_ = fmt::format("stopped on request at t = {:.17g}", t);
        this->save_checkpoint(t);  // the next substep is already scheduled
      }
      return status_.empty();
    });
    if (rot_ && sys_.w.empty()) sys_.w.assign(N_, Spin<D>::Zero());
    uniform_ = N_ > 0;
    for (int i = 1; i < N_ && uniform_; ++i)
      uniform_ = sys_.material[i] == sys_.material[0] && sys_.radius[i] == sys_.radius[0];
    for (const Inlet<D>& in : sys_.inlets) uniform_ = uniform_ && in.rmin == in.rmax;
    if (uniform_) {
      const int m = sys_.material[0];
      const double R = sys_.radius[0], M = sys_.mass(0);
      ctab_.push_back(pair_contact(plan_, m, R, M, m, R, M));
      for (std::size_t w = 0; w < sys_.walls.size(); ++w)
        ctab_.push_back(wall_contact(plan_, static_cast<int>(w), m, R, M));
      ctab_.push_back(pair_contact(plan_, m, R, M, m, R, kPlane));  // a moving and a fixed grain
    }
    for (int i = 0; i < N_; ++i)
      if (is_fixed(i)) fixed_list_.push_back(i);
    minv_.resize(N_);
    iinv_.resize(N_);
    for (int i = 0; i < N_; ++i) {
      const double m = sys_.mass(static_cast<std::size_t>(i));
      minv_[i] = 1.0 / m;
      iinv_[i] = 1.0 / (inertia_factor<D>() * m * sys_.radius[i] * sys_.radius[i]);
    }
  }

  void hybrid_arrays() {
    vh_.assign(N_, Vec<D>::Zero());
    acc_.assign(N_, Vec<D>::Zero());
    f_.assign(N_, Vec<D>::Zero());
    x0_.assign(N_, Vec<D>::Zero());
    if (rot_) {
      wh_.assign(N_, Spin<D>::Zero());
      alpha_.assign(N_, Spin<D>::Zero());
      tq_.assign(N_, Spin<D>::Zero());
    }
    last_contact_.assign(N_, set_.start_time);
    quiet_checks_.assign(N_, 0);
    begun_n_.assign(N_, 0);
    rate_t0_.assign(N_, set_.start_time);
    cand_.assign(N_, 0);
    region_seen_.assign(N_, 0u);
    region_retry_.assign(N_, -kNever);
    region_stamp_ = 0;
    gslot_.assign(N_, 0);
    joined_by_.assign(N_, kByOverlap);
    slot_.assign(N_, -1);
    touching_.assign(N_, 0);
    near_.assign(N_, 0);
    switch_.reset(N_, switch_params_);
    mode_.assign(N_, kHard);
    for (const int i : fixed_list_) mode_[i] = kFixed;  // (the interface list is empty yet)
    for (int i = 0; i < N_; ++i)
      if (this->is_removed(i)) mode_[i] = kGone;  // a slot an inlet fills later
    if (sleeping_) {
      fz_base_.assign(N_, Vec<D>::Zero());
      fz_mix_.assign(N_, Vec<D>::Zero());
      if (rot_) {
        fz_tbase_.assign(N_, Spin<D>::Zero());
        fz_tmix_.assign(N_, Spin<D>::Zero());
      }
      fz_scale_.assign(N_, 0.0);
      fz_step_.assign(N_, Vec<D>::Zero());
      x_check_.assign(N_, Vec<D>::Zero());
      fz_lost_.assign(N_, 0);
      fz_cand_.assign(N_, 0);
    }
    watch_flag_.assign(N_, 0);
    asleep_slot_.assign(N_, -1);
    iface_flag_.assign(N_, 0);
    iface_next_.assign(N_, 0.0);
  }

  double inv_mass(int i) const { return minv_[i]; }

  // No grain is soft, pending or asleep (fixed and gone grains aside): every grain moves by events.
  bool all_hard() const { return soft_.empty() && pending_.empty() && asleep_ == 0; }
  // Every change of a grain's mode goes through here: an interface grain that is no longer hard
  // leaves the interface list at the next capture scan.
  void set_mode(int i, std::uint8_t m) {
    mode_[i] = m;
    if (iface_flag_[i]) due_now();
  }

  // A capture check is due at the next grid point of the substeps (a coast ends there).
  void due_now() {
    iface_due_ = 0.0;
    pull_substep();
  }

  void mark_interface(int i) {
    iface_next_[i] = 0.0;  // check at the next substep
    due_now();
    if (iface_flag_[i]) return;
    iface_flag_[i] = 1;
    iface_.push_back(i);
    start_clock(now_);  // substeps check it against the soft set (they may have stopped: all asleep)
  }

  // Marks the hard neighbours of i as interface particles (i has just become soft or moved cell).
  // With lists, those of its list: a grain outside it cannot come within a capture distance of i
  // before one of the two gets a new list (its shell's exit predicts it over its new list; i's
  // marks again).
  void mark_neighbours(int i) {
    for_capture_range(i, [&](int j, const Vec<D>&) {
      if (mode_[j] == kHard) mark_interface(j);
    });
  }
  // f(j, shift) for the grains that may come within a capture distance of i before one of the two
  // moves to other cells or gets a new list: with lists, i's list (ext_list_margin); else the 3^D
  // cells around i.
  template <class F>
  void for_capture_range(int i, F&& f) const {
    if (this->lists_) {
      this->for_list(i, f);
    } else {
      for_neighbours(i, f);
    }
  }

  // The capture distance of a hard grain moving at `speed` (the gap to a soft grain below which it
  // joins the soft set): twice the most the gap can close in one substep (its speed and gravity's
  // gain, and twice the fastest soft grain's speed: a soft grain may speed up inside the
  // substep), so that the join comes a substep before the touch at the latest; at least
  // least_capture's distance (engine/hybrid.hpp: round-off, grains at rest under gravity and the
  // rapid sequences of strongly inelastic grains), at most the distance of a pair at the largest
  // expected impact speed (cskin_, the EDM cells' margin: their reach).
  // A fixed capture skin made a dense gas sticky: at phi = 0.5 each grain has on average 0.7
  // neighbours within 0.01 d, so a soft seed drew most of the gas in and held it there
  // (charts/README.md, stability map).
  double capture_gap(double speed) const {
    const double close = h_ * (speed + g_.norm() * h_ + 2.0 * vsoft_max_);
    return std::clamp(2.0 * close, skin_, cskin_);
  }

  void start_clock(double t) {
    if (clock_) return;
    clock_ = true;
    clock_t0_ = t;
    clock_n_ = 0;
    sub_last_n_ = -1;
    queue_->set(substep_id_, t);
  }

  // Contact duration of the soft law between i and j (w >= 0: i against wall w) at normal speed u.
  double contact_time_of(int i, int j, int w, double u) const {
    const int ma = cold_[i].mat;
    const double Ri = hot_[i].R;
    PairParams p;
    const SoftLaw* law;
    if (w >= 0) {
      law = &plan_.wall_laws[static_cast<std::size_t>(w) * plan_.materials + ma];
      p = wall_params(plan_.elastic[ma], Ri, mass(i), plan_.wall_elastic[w]);
    } else {
      const int mb = cold_[j].mat;
      law = &plan_.laws[static_cast<std::size_t>(ma) * plan_.materials + mb];
      p = pair_params(plan_.elastic[ma], Ri, mass(i), plan_.elastic[mb], hot_[j].R, is_fixed(j) ? kPlane : mass(j));
    }
    // The linear law's t_c depends on the law and m* alone: the last one is kept (in a gas of one
    // size every pair asks the same; its damping's logarithm was a third of the switching rule's
    // cost in the stability map's dilute gas).
    if (law->normal == NormalLaw::Linear) {
      if (law == tc_memo_law_ && p.mstar == tc_memo_mstar_) return tc_memo_;
      tc_memo_law_ = law;
      tc_memo_mstar_ = p.mstar;
      return tc_memo_ = soft_contact_time(*law, p, 1.0);
    }
    return soft_contact_time(*law, p, std::max(u, 1e-300));
  }
  mutable const SoftLaw* tc_memo_law_ = nullptr;
  mutable double tc_memo_mstar_ = 0.0, tc_memo_ = 0.0;

  // What the switching rule needs of a collision of materials mi and mj at normal impact speed u
  // (one restitution evaluated for both):
  //  * dissipative: it loses energy, inelastic (restitution below 1 at u) or rough (friction
  //    takes energy from the sliding);
  //  * ask_fall: a rapid run must show the fall of its impact speed (hybrid.speed_fall), unless
  //    the impact is strongly inelastic (e <= kNoFallMaxE), where the hard resolution of a
  //    rapid sequence departs from the soft one within a few collisions (README, the lookahead
  //    rule): in the stability map's beds at e = 0.1 and 0.3 the fall asked there too delayed the
  //    switch, and the bed of e = 0.1, phi = 0.3 settled 1.3 % lower than the reference (4.9
  //    floors; 0.6 % with the rule before).
  struct ImpactKind {
    bool dissipative, ask_fall;
  };
  ImpactKind impact_kind(int mi, int mj, double u) const {
    const double e = all_elastic_ ? 1.0 : this->restitution(mi, mj, u);
    return {e < 1.0 || (rough_ && rough_rules_.is_rough(mi, mj)), e > kNoFallMaxE};
  }

  // The switching rule (engine/hybrid/switching.hpp) at a pair collision of hard particles i and j,
  // both at time t and touching. Returns true when the pair (and its cluster) turned soft instead
  // of colliding.
  bool soft_rule_pair(int i, int j, double t) {
    if (mode_[j] == kFixed) return soft_rule_fixed(i, j, t);
    Vec<D> r = hot_[i].x - hot_[j].x;
    min_image(r);
    const double u = std::abs((hot_[i].v - hot_[j].v).dot(r)) / r.norm();  // impact speed
    double tc = -1.0;  // t_c of this impact, computed once when needed
    const auto contact_time = [&] {
      if (tc < 0.0) tc = contact_time_of(i, j, -1, u);
      return tc;
    };
    const double last_i = cold_[i].last, last_j = cold_[j].last;
    const ImpactKind k = impact_kind(cold_[i].mat, cold_[j].mat, u);
    Switch v = switch_.pair(i, j, t, last_i, last_j, contact_time, u, k.dissipative, k.ask_fall);
    if (v == Switch::Cost && !cost_switch(i, j, t)) v = Switch::Stay;
    if (v == Switch::Stay) return lookahead_pair(i, j, t, std::max(last_i, last_j), contact_time);
    const std::uint8_t reason = v == Switch::Stability ? kByStability : kByCost;
    make_pending(i, t, reason);
    make_pending(j, t, reason);
    return true;
  }

  // The cost rule over a region: a grain that turns soft draws hard grains in after it, so the
  // switch pays off only if the grains it draws in collide faster than the crossover. Turning i (and
  // j: -1 for none) soft costs one soft particle-step per substep for each grain of the region and
  // saves the region's collisions: soft is cheaper when the region's mean smoothed collision rate
  // (SwitchRule::rate) exceeds the crossover 1 / (cost_ratio h). The region is
  //  * i, j and the hard grains of their first coordination shell (centres closer than
  //    1.5 (R_i + R_k)), drawn in when they next come close;
  //  * and, through the region, every hard grain within the capture distance of one in it
  //    (capture_gap): captured at the first substep, and the grains within its capture distance
  //    at the next, and so on.
  // Grains already soft are paid for either way and not counted; the search stops at kMaxRegion
  // grains (the mean is then the nearest grains'). A rattler in a dense gas, whose own interval
  // is short while its cage's is not, stays hard: the single-grain test turned such grains soft,
  // and each drew about a hundred others in by capture (charts/README.md, stability map); so did
  // a region of nine grains of a cluster of cooling_clusters.toml rattling at 1.1 times the
  // crossover, whose seventy-six neighbours within the capture distance (rates 0.3-9 per unit time,
  // the crossover 820) joined at the next substep and held the soft set for 3 time units.
  // The region's verdict, remembered: a grain (or pair) whose region was not cheaper soft is not
  // priced again for the release hysteresis (10 k t_c). A hard bed's capture chain spans the bed,
  // and its fast grains ask at every collision: in the stability map's bed at e = 0.9, phi = 0.55
  // (seed 1) 34 678 searches of 430 grains on average took 8.9 s against 2.8 s before the region
  // had its chain.
  bool cost_switch(int i, int j, double t) {
    if (t < region_retry_[i] || (j >= 0 && t < region_retry_[j])) return false;
    if (region_cheaper_soft(i, j, t)) return true;
    region_retry_[i] = t + hyst_;
    if (j >= 0) region_retry_[j] = t + hyst_;
    return false;
  }
  bool region_cheaper_soft(int i, int j, double t) {
    region_.clear();
    if (++region_stamp_ == 0) {  // the stamps wrapped: clear them
      std::fill(region_seen_.begin(), region_seen_.end(), 0u);
      region_stamp_ = 1;
    }
    auto take = [&](int k) {
      if (region_seen_[k] == region_stamp_) return;
      region_seen_[k] = region_stamp_;
      region_.push_back(k);
    };
    take(i);
    if (j >= 0) take(j);
    for (const int c : {i, j}) {
      if (c < 0) continue;
      const Vec<D> xc = this->position_at(c, t);
      this->for_neighbours_reach(c, 1.5 * sg_w_, [&](int k, const Vec<D>& shift) {
        if (mode_[k] != kHard) return;
        const double cut = 1.5 * (hot_[c].R + hot_[k].R);
        if ((xc - this->position_at(k, t) - shift).squaredNorm() < cut * cut) take(k);
      });
    }
    // The capture's chain through the region (breadth first: the nearest grains come first).
    for (std::size_t q = 0; q < region_.size() && region_.size() < kMaxRegion; ++q) {
      const int c = region_[q];
      const Vec<D> xc = this->position_at(c, t);
      const double vc = hot_[c].v.norm();
      this->for_neighbours(c, [&](int k, const Vec<D>& shift) {
        if (mode_[k] != kHard || region_seen_[k] == region_stamp_) return;
        const Vec<D> xk = this->position_at(k, t);
        const double cut = hot_[c].R + hot_[k].R + capture_gap(std::max(vc, hot_[k].v.norm()));
        if ((xc - xk - shift).squaredNorm() < cut * cut) take(k);
      });
    }
    double sum = 0.0;
    for (const int k : region_) sum += switch_.rate(k);
    return sum > static_cast<double>(region_.size()) * switch_.crossover_rate();
  }
  static constexpr std::size_t kMaxRegion = 4096;

  // The lookahead of the stability rule (README "Hybrid dynamics"): a strongly inelastic collision
  // (e <= 0.25) of i and j that follows one of theirs within 5 L t_c (L = hybrid.lookahead) is
  // resolved on trial (smooth, the velocities only) and i's and j's next pair collisions predicted
  // from it. If either would meet the partner of its collision before this one again, within L t_c
  // and sooner than the interval just ended, and the sequence goes on past that return (a second
  // trial, sequence_goes_on), the collision continues a shrinking back-and-forth
  // sequence within a group (the motif of a collapsing line or cluster), whose hard resolution
  // departs from the soft one long before the contacts overlap (three grains in a line: a hard
  // collision 7 t_c before the next leaves relative velocities 40 % off the soft outcome). Then i,
  // j and that partner turn soft before it instead.
  template <class Tc>
  bool lookahead_pair(int i, int j, double t, double last, Tc&& contact_time) {
    if (!(lookahead_ > 0.0)) return false;
    const double since = t - last;
    if (!(since < kLookaheadSince * lookahead_ * plan_.contact_time * kLookaheadSpan)) return false;
    if (all_elastic_) return false;
    Vec<D> r = hot_[i].x - hot_[j].x;
    min_image(r);
    const Vec<D> n = r / r.norm();
    const Vec<D> vi = hot_[i].v, vj = hot_[j].v;
    const double u = (vi - vj).dot(n);
    if (!(u < 0.0)) return false;
    const double e = this->restitution(cold_[i].mat, cold_[j].mat, -u);
    if (e > kLookaheadMaxE) return false;
    const double window = lookahead_ * contact_time();
    if (!(since < kLookaheadSince * window)) return false;
    smooth_pair_collision(hot_[i].v, hot_[j].v, mass(i), mass(j), n, e);
    int next[2] = {-1, -1};
    double when[2] = {0.0, 0.0};
    for (int k = 0; k < 2; ++k) {
      const int c = k == 0 ? i : j;
      const int p = switch_.earlier_partner(c);
      double best = std::min(window, since);
      // Only a next collision with the earlier partner p counts, so p alone is tried first (the
      // arithmetic of the neighbour scan): the scan of every neighbour, to see whether another
      // comes first, runs only when p comes back within the bound. In the stability map's gas at
      // e = 0.1, phi = 0.05 the two scans of each trial were most of the hybrid's extra
      // predictions, and p rarely comes back.
      if (p < 0 || (mode_[p] != kHard && !this->is_fixed(p))) continue;  // never the scan's answer
      if (!this->is_fixed(p)) {
        Vec<D> d = hot_[c].x - hot_[p].x;
        min_image(d);
        double alone = best;
        std::uint8_t type = kNone;
        int q = -1;
        this->test_moving(d, hot_[c].v, hot_[c].R, p, t, alone, type, q);
        if (q < 0) continue;
      }
      std::uint8_t type = kNone;
      this->test_pairs(c, t, best, type, next[k]);
      when[k] = best;
      if (next[k] != p) next[k] = -1;
    }
    const Vec<D> vi1 = hot_[i].v, vj1 = hot_[j].v;
    hot_[i].v = vi;
    hot_[j].v = vj;
    // The sequence must go on past the partner's return (sequence_goes_on).
    if (next[0] >= 0 && !sequence_goes_on(i, j, next[0], vi1, vj1, t, when[0], window)) next[0] = -1;
    if (next[1] >= 0 && !sequence_goes_on(j, i, next[1], vj1, vi1, t, when[1], window)) next[1] = -1;
    if (next[0] < 0 && next[1] < 0) return false;
    make_pending(i, t, kByStability | kEarly);
    make_pending(j, t, kByStability | kEarly);
    for (int k : next)
      if (k >= 0 && mode_[k] == kHard) {
        advance(k, t);
        make_pending(k, t, kByCluster | kEarly);
      }
    return true;
  }

  // The lookahead's second trial: a, after its trial collision with b at t (velocities va, vb),
  // would meet p, its partner before b, after dt1. That collision is resolved on trial too (smooth,
  // the grains in free flight relative to each other: a uniform field cancels), and the sequence
  // goes on if a then meets b again, or p meets its own latest partner q (other than a and b),
  // within kLookaheadGoesOn dt1 and the window. A single return is common where three grains meet
  // in a gas; a collapsing line or cluster goes back and forth. In the stability map's gas at
  // e = 0.1, phi = 0.05 (EDM stable; seeds 0-2) the first trial alone fired 48-63 times a run, with
  // the second 9-15 times. On the small chains of tools/collapse_chains.py the second trial
  // passes 63 % of the first's verdicts with a horizon of 1 dt1, and the hybrid ends within 25 % of
  // converged TDM in 181 of 210 systems against 182 with the first trial alone (README, the
  // lookahead row); every test line ends as before. With a horizon of 1 dt1: 173, and one of the
  // four-grain test lines 98 % off; with 2 dt1: 181, that line 24 % off (17 % before); 3 and 5 dt1
  // end every test line as before.
  bool sequence_goes_on(int a, int b, int p, const Vec<D>& va, const Vec<D>& vb, double t, double dt1,
                        double window) {
    if (mode_[p] != kHard) return true;
    const auto sep = [&](int x, int y) {  // x's centre from y's at t, nearest image
      Vec<D> r = this->position_at(x, t) - this->position_at(y, t);
      min_image(r);
      return r;
    };
    const Vec<D> vp0 = this->velocity_at(p, t);
    const Vec<D> rap = sep(a, p) + (va - vp0) * dt1;
    const double dist = rap.norm();
    if (!(dist > 0.0)) return true;
    const Vec<D> n = rap / dist;
    const double u = (va - vp0).dot(n);
    if (!(u < 0.0)) return true;
    Vec<D> va2 = va, vp = vp0;
    smooth_pair_collision(va2, vp, mass(a), mass(p), n, this->restitution(cold_[a].mat, cold_[p].mat, -u));
    const double limit = std::min(window, kLookaheadGoesOn * dt1);
    const Vec<D> rab = sep(a, b) + (va - vb) * dt1;
    if (pair_collision_time(rab, Vec<D>(va2 - vb), hot_[a].R + hot_[b].R, limit) < limit) return true;
    // q: the latest of p's two recent partners that is hard and neither a nor b.
    const auto hard_other = [&](int c) { return c >= 0 && c != a && c != b && mode_[c] == kHard; };
    const int q = hard_other(switch_.recent(p, 0)) ? switch_.recent(p, 0) : switch_.recent(p, 1);
    if (!hard_other(q)) return false;
    const Vec<D> vq = this->velocity_at(q, t);
    const Vec<D> rpq = sep(p, q) + (vp0 - vq) * dt1;
    return pair_collision_time(rpq, Vec<D>(vp - vq), hot_[p].R + hot_[q].R, limit) < limit;
  }

  bool soft_rule_wall(int i, int w, double t) {
    const WallShape<D>& wall = *shapes_[w];
    const WallPoint<D> c = wall.at_impact(hot_[i].x, hot_[i].v, hot_[i].R, t);
    if (wall_checkpoint(i, wall, c)) return false;  // a checkpoint of the bracketing, not an impact
    const double un = (hot_[i].v - c.velocity).dot(c.normal);
    // Resting on the wall (no normal speed left) is the zero-time limit of a bouncing sequence.
    const ImpactKind k = impact_kind(cold_[i].mat, sys_.walls[w].material, std::max(-un, 0.0));
    Switch v = switch_.wall(i, t, cold_[i].last, !(un < 0.0), [&] { return contact_time_of(i, -1, w, -un); },
                            std::max(-un, 0.0), k.dissipative, k.ask_fall);
    if (v == Switch::Cost && !cost_switch(i, -1, t)) v = Switch::Stay;
    if (v == Switch::Stay) return false;
    make_pending(i, t, v == Switch::Stability ? kByStability : kByCost);
    return true;
  }

  // A hard collision of i with fixed grain j: the wall rule (j is immovable, as a wall; resting on it
  // counts as unstable), with the contact time of the pair (m* = i's mass). Only i turns soft.
  bool soft_rule_fixed(int i, int j, double t) {
    Vec<D> r = hot_[i].x - hot_[j].x;
    min_image(r);
    const double un = hot_[i].v.dot(r) / r.norm();
    const ImpactKind k = impact_kind(cold_[i].mat, cold_[j].mat, std::max(-un, 0.0));
    Switch v = switch_.wall(i, t, cold_[i].last, !(un < 0.0), [&] { return contact_time_of(i, j, -1, -un); },
                            std::max(-un, 0.0), k.dissipative, k.ask_fall);
    if (v == Switch::Cost && !cost_switch(i, -1, t)) v = Switch::Stay;
    if (v == Switch::Stay) return false;
    make_pending(i, t, v == Switch::Stability ? kByStability : kByCost);
    return true;
  }

  enum : std::uint8_t { kByStability = 0, kByCost = 1, kByCluster = 2, kByCapture = 3, kByOverlap = 4 };
  // Marks the grains the lookahead turned soft (with their cluster): their group may return hard
  // as soon as its sequence is over, before the release hysteresis (release_by_cost).
  static constexpr std::uint8_t kEarly = 0x80;

  // Hard i stops flying: it joins the soft set at the next substep, together with the particles it
  // collided with within the stability window (its cluster), recursively.
  void make_pending(int i, double t, std::uint8_t reason) {
    if (mode_[i] != kHard) return;
    set_mode(i, kPending);
    pending_reason_.push_back(reason);
    pending_.push_back(i);
    queue_->erase(i);
    ++cold_[i].counter;  // partners' predictions with i are stale
    start_clock(t);
    pull_substep();  // it joins at the next grid point
    // The cluster: partners of collisions within the stability window k t_c (t_c of the plan).
    switch_.cluster(i, t, [&](int j) {
      if (mode_[j] == kHard) make_pending(j, t, kByCluster | (reason & kEarly));
    });
  }

  void log_switch(int i, double t, EventKind kind) {
    if (collision_observers_.empty()) return;
    CollisionRecord<D> rec;
    rec.time = t;
    rec.kind = kind;
    rec.i = static_cast<std::uint32_t>(i);
    rec.j = static_cast<std::uint32_t>(i);
    rec.mi = mass(i);
    rec.vi_before = rec.vi_after = hot_[i].v;
    if (!sys_.w.empty()) rec.wi_before = rec.wi_after = sys_.w[i];
    for (auto* o : collision_observers_) o->on_collision(rec);
  }

  // i (hard or pending, flying ballistically) joins the soft set at substep time t.
  void join(int i, double t, std::uint8_t reason) {
    advance(i, t);
    if (mode_[i] == kHard) {
      queue_->erase(i);
      ++cold_[i].counter;
    }
    // A pending grain flew without events since it stopped being hard: it may have left its shell.
    if (this->lists_ && !in_shell(i)) this->relist(i);
    set_mode(i, kSoft);
    free_until_ = -kNever;  // the soft set's free flight was planned without i
    iface_flag_[i] = 0;
    cblo_[i].setConstant(kNever);  // relocate at the first substep (the box may be stale)
    cbhi_[i].setConstant(-kNever);
    cfree2_[i] = -1.0;
    slot_[i] = static_cast<int>(soft_.size());
    soft_.push_back(i);
    // Ballistic until now: v(t - h/2) = v(t) - h/2 g and a(t - h) = g, so that the predicted
    // velocity of the dashpots v(t - h/2) + h/2 a(t - h) is v(t).
    vh_[i] = hot_[i].v - hdt_ * g_;
    acc_[i] = g_;
    f_[i].setZero();
    x0_[i] = hot_[i].x;
    // The capture distances of this substep count the joining grain's speed (the bound of the
    // soft grains' speeds is otherwise the last full step's).
    vsoft_max_ = std::max(vsoft_max_, hot_[i].v.norm());
    if (rot_) {
      wh_[i] = sys_.w[i];
      alpha_[i].setZero();
      tq_[i].setZero();
    }
    last_contact_[i] = t;
    quiet_checks_[i] = 0;
    if (sleeping_) x_check_[i] = hot_[i].x;  // the rest rule's steps count from here
    begun_n_[i] = 0;
    rate_t0_[i] = t;
    joined_by_[i] = reason;
    reason &= static_cast<std::uint8_t>(~kEarly);
    switch_.forget_interval(i);
    cold_[i].watch = {};  // the collapse watch restarts when i returns hard
    ++hstats_.to_soft;
    switch (reason) {
      case kByStability: ++hstats_.by_stability; break;
      case kByCost: ++hstats_.by_cost; break;
      case kByCluster: ++hstats_.by_cluster; break;
      case kByCapture: ++hstats_.by_capture; break;
      default: ++hstats_.by_overlap; break;
    }
    log_switch(i, t, EventKind::ToSoft);
    if (!dirty_) add_entries(i, t);
    mark_neighbours(i);
  }

  // Soft i returns to EDM at substep time t with its full-step velocity and spin.
  void release(int i, double t) {
    set_mode(i, kHard);
    const int s = slot_[i];
    soft_[s] = soft_.back();
    slot_[soft_[s]] = s;
    soft_.pop_back();
    slot_[i] = -1;
    purge_ = true;  // its list entries go at the end of the substep's releases (purge_hard)
    hot_[i].t = t;
    cold_[i].last = -kNever;  // its collisions as a soft particle do not count for the rules
    switch_.forget(i);
    ++cold_[i].counter;
    ++hstats_.to_hard;
    log_switch(i, t, EventKind::ToHard);
    predict(i, t);
  }

  // Particle-collisions resolved hard so far (CostMeter): a pair collision changes two courses.
  double particle_collisions() const {
    return 2.0 * static_cast<double>(counts_.pair) + static_cast<double>(counts_.wall);
  }
  // hybrid.cost_ratio = "measured": the cost rule's crossover follows the meter's ratio (every 64
  // substeps, once it has both costs), kept within [kMinCostRatio, kMaxCostRatio]: below 1 a
  // collision would be cheaper than a particle-step, which no measurement has shown; above 1000 the
  // rule would turn soft a grain colliding once in a thousand substeps.
  void follow_measured_cost() {
    const double r = meter_.ratio();
    if (!std::isfinite(r)) return;
    cost_ratio_ = std::clamp(r, kMinCostRatio, kMaxCostRatio);
    switch_.set_cost_interval(cost_ratio_ * h_);
  }
  static constexpr double kMinCostRatio = 1.0, kMaxCostRatio = 1000.0;

  // Release by cost: soft grains whose collisions are cheaper as events return to EDM together.
  // A candidate is an awake soft grain that touches nothing (one that turned soft by the
  // stability rule: for the release hysteresis) and has begun contacts, over its recent window
  // (at least k t_c), at under half the cost crossover rate 1 / (cost_ratio h) that turns a hard
  // grain soft (the factor 2 is the rule's hysteresis). A hard grain may not lie within its
  // capture distance of a soft one, so a candidate with a soft or sleeping grain that is not a
  // candidate within that distance stays, and so on through the chain (fixed grains do not hold: hard
  // grains meet them in EDM); the rest go hard.
  // The single-grain release above is the case of a candidate with no soft grain within its
  // capture distance; this one frees a dense gas whose grains all lie close to each other. The window is halved
  // (count and span) once it exceeds 4 k t_c, so that it follows a cooling or thinning flow.
  void release_by_cost(double t) {
    const double rmax = 0.5 / (cost_ratio_ * h_);
    group_.clear();
    for (const int i : soft_) {
      double span = t - rate_t0_[i];
      if (span > 4.0 * cost_quiet_) {
        begun_n_[i] /= 2;
        span *= 0.5;
        rate_t0_[i] = t - span;
      }
      if (!(span >= cost_quiet_)) continue;
      // A grain that turned soft by the stability rule (or with its cluster) must first stay
      // contact-free for the release hysteresis (a bouncing sequence would otherwise come back at
      // once); the others may go as soon as they touch nothing.
      // A grain of the lookahead's sequence may go before that once the sequence is over (below).
      const std::uint8_t why = joined_by_[i] & static_cast<std::uint8_t>(~kEarly);
      const bool unstable = why == kByStability || why == kByCluster;
      const bool early = unstable && (joined_by_[i] & kEarly) && t - last_contact_[i] < hyst_;
      const bool quiet = unstable && !early ? t - last_contact_[i] >= hyst_ : last_contact_[i] < t;
      if (quiet && static_cast<double>(begun_n_[i]) < rmax * span) {
        cand_[i] = early ? 2 : 1;
        group_.push_back(i);
      }
    }
    if (group_.empty()) {
      cost_every_ = std::min(2 * cost_every_, cost_every_max_);  // nothing to release: look less often
      return;
    }
    // The candidates held: those within the skin of a grain that stays (held_, the queue), then
    // the chain through candidates within each other's skins (near_pairs_).
    auto holds = [&](std::uint32_t k) { return !cand_[k] && mode_[k] != kFixed; };
    near_pairs_.clear();
    held_.clear();
    pairs_.for_each([&](const PairEntry& e) {
      if (!cand_[e.i] && !cand_[e.j]) return;
      Vec<D> dx = hot_[e.i].x - hot_[e.j].x;
      min_image(dx);
      const double Rs = hot_[e.i].R + hot_[e.j].R, d2 = dx.squaredNorm();
      // Beyond the largest capture distance (capture_gap's bound) no pair's own can reach.
      if (d2 >= (Rs + cskin_) * (Rs + cskin_)) return;
      const double cut = Rs + capture_gap(std::sqrt(std::max(hot_[e.i].v.squaredNorm(), hot_[e.j].v.squaredNorm())));
      if (d2 >= cut * cut) return;
      // A fixed grain next to an early candidate holds it (under gravity a grain that leaves it
      // comes back).
      if ((cand_[e.i] == 2 || cand_[e.j] == 2) && (mode_[e.i] == kFixed || mode_[e.j] == kFixed)) {
        if (cand_[e.i] == 2) held_.push_back(e.i);
        if (cand_[e.j] == 2) held_.push_back(e.j);
      }
      if (cand_[e.i] && cand_[e.j]) {
        near_pairs_.push_back({e.i, e.j});
      } else if (cand_[e.i] && holds(e.j)) {
        held_.push_back(e.i);
      } else if (cand_[e.j] && holds(e.i)) {
        held_.push_back(e.j);
      }
    });
    // A wall near an early candidate holds it: under gravity a grain that leaves a floor comes back.
    for (const auto& e : we_)
      if (cand_[e.i] == 2) held_.push_back(e.i);
    hold_unfinished(t);
    if (!held_.empty()) {
      // Adjacency of the candidates (CSR over group_'s order) for the spread of the hold.
      for (std::size_t k = 0; k < group_.size(); ++k) gslot_[group_[k]] = static_cast<int>(k);
      gstart_.assign(group_.size() + 1, 0);
      for (const auto& [a, b] : near_pairs_) {
        ++gstart_[gslot_[a] + 1];
        ++gstart_[gslot_[b] + 1];
      }
      for (std::size_t k = 0; k < group_.size(); ++k) gstart_[k + 1] += gstart_[k];
      gadj_.resize(gstart_.back());
      gfill_.assign(gstart_.begin(), gstart_.end() - 1);
      for (const auto& [a, b] : near_pairs_) {
        gadj_[gfill_[gslot_[a]]++] = b;
        gadj_[gfill_[gslot_[b]]++] = a;
      }
      for (std::size_t q = 0; q < held_.size(); ++q) {
        const std::uint32_t k = held_[q];
        if (!cand_[k]) continue;
        cand_[k] = 0;
        for (int p = gstart_[gslot_[k]]; p < gstart_[gslot_[k] + 1]; ++p)
          if (cand_[gadj_[p]]) held_.push_back(gadj_[p]);
      }
    }
    std::size_t released = 0;
    for (const int i : group_) {
      if (cand_[i]) {
        release(i, t);
        ++released;
      }
      cand_[i] = 0;
    }
    hstats_.released_by_cost += released;
    cost_every_ = released > 0 ? cost_every_min_ : std::min(2 * cost_every_, cost_every_max_);
  }

  // The lookahead's sequence is over for an early candidate when no two candidates, one of them
  // early, would meet in free flight within the lookahead's window (below; their relative
  // velocity is constant: a uniform field moves both alike). Waiting out the hysteresis could then
  // change nothing between them, and the group may go now; otherwise both stay (held_). Releasing
  // a grain as soon as nothing near it approached (the first version) let a grain farther away,
  // still closing in, meet it hard: three grains in a line at r = 0.06 (tests/analytic/
  // test_collapse.cpp) ended 65 % off converged TDM instead of within 17 %. With more than
  // kMaxEarly early candidates every one stays for the hysteresis.
  void hold_unfinished(double t) {
    early_.clear();
    for (const int i : group_)
      if (cand_[i] == 2) early_.push_back(i);
    if (early_.empty()) return;
    if (early_.size() > kMaxEarly || early_.size() * group_.size() > kMaxEarlyPairs) {
      held_.insert(held_.end(), early_.begin(), early_.end());
      return;
    }
    // The lookahead's window, 5 L t_c: a grain's first collision after its release has no earlier
    // one for the lookahead to look back to, so a meeting within that window would be resolved
    // hard unseen (four grains in a line at r = 0.2: with the release hysteresis, 20 t_c, as the
    // horizon the middle grain went hard 2.6 hysteresis spans before a rapid hard sequence with
    // both neighbours, the end 99 % off converged TDM).
    const double horizon = kLookaheadSince * lookahead_ * plan_.contact_time;
    const auto test = [&](int a, int b) {
      if (b == a || (cand_[b] == 2 && b < a)) return;  // each pair once
      Vec<D> r = hot_[a].x - hot_[b].x;
      min_image(r);
      if (hybrid::meet_within<D>(r, Vec<D>(hot_[a].v - hot_[b].v), hot_[a].R + hot_[b].R, horizon)) {
        held_.push_back(a);
        held_.push_back(b);
      }
    };
    if (!group_cells(horizon)) {
      for (const int a : early_)
        for (const int b : group_) test(a, b);
    } else {
      for (const int a : early_)
        hgrid_.around(hgrid_.coords(group_pos(a)), [&](int l, const Vec<D>&) {
          for (int p = hg_start_[l], e = hg_start_[l + 1]; p < e; ++p) test(a, hg_items_[p]);
        });
    }
    // ... nor a hard grain of the candidate's neighbour cells: the hysteresis would capture it and
    // resolve that meeting soft (four grains in a line, the fourth hard and closing in: 27-53 % off
    // converged TDM when the three soft ones went before it arrived).
    for (const int a : early_) {
      bool meets = false;
      this->for_neighbours(a, [&](int k, const Vec<D>& shift) {
        if (meets || (mode_[k] != kHard && mode_[k] != kPending)) return;
        const Vec<D> r = hot_[a].x - this->position_at(k, t) - shift;
        const Vec<D> u = hot_[a].v - (hot_[k].v + (t - hot_[k].t) * g_);
        meets = hybrid::meet_within<D>(r, u, hot_[a].R + hot_[k].R, horizon);
      });
      if (meets) held_.push_back(a);
    }
  }
  // The candidates in cells at least as wide as two of them can be apart and still meet within
  // the window: the sum of their radii plus twice the fastest one's speed times the window
  // (hybrid::meet_cell_width, tested in tests/hybrid/test_meet.cpp). The pairs
  // of neighbouring cells are then every pair that can meet; hold_unfinished tests only those,
  // with the same test in the same arithmetic, so the hold is the one the test of every pair
  // gives (the held list is used as a set). In the stability map's dense gas at e = 0.1
  // (phi = 0.55, 500 spheres, about 400 soft) the test of every pair took 4.0 % of the run's
  // samples, 2.4 % with the cells (their making included). False where cells would not help (a
  // small group, a single block of cells, fewer than three cells across a periodic axis): every
  // pair is then tested.
  bool group_cells(double horizon) {
    if (group_.size() < kGroupCells) return false;
    double vmax = 0.0, rmax = 0.0;
    Vec<D> lo = Vec<D>::Constant(kNever), hi = Vec<D>::Constant(-kNever);
    for (const int b : group_) {
      vmax = std::max(vmax, hot_[b].v.norm());
      rmax = std::max(rmax, hot_[b].R);
      const Vec<D> x = group_pos(b);
      lo = lo.cwiseMin(x);
      hi = hi.cwiseMax(x);
    }
    const double cut = hybrid::meet_cell_width(rmax, vmax, horizon);
    if (!(cut < kNever)) return false;
    for (int k = 0; k < D; ++k) {
      if (sys_.periodic[k]) {
        lo[k] = lo_[k];
        hi[k] = hi_[k];
      } else {
        hi[k] = std::max(hi[k], lo[k] + cut);  // (one cell at least)
      }
    }
    if (CellGrid<D>::natural_cells(lo, hi, cut) < static_cast<double>(CellGrid<D>::kStencil) + 1.0) return false;
    if (!hgrid_.build(lo, hi, sys_.periodic, cut, 2.0 * static_cast<double>(group_.size()) + 27.0)) return false;
    cell_sort(static_cast<std::size_t>(hgrid_.cells()), {&group_},
              [&](int b) { return hgrid_.linear(hgrid_.coords(group_pos(b))); }, hg_start_, hg_items_);
    return true;
  }
  // A candidate's position for those cells: wrapped into the domain along periodic axes.
  Vec<D> group_pos(int b) const {
    Vec<D> x = hot_[b].x;
    for (int k = 0; k < D; ++k)
      if (sys_.periodic[k]) x[k] = wrap_periodic(x[k], lo_[k], hi_[k]);
    return x;
  }
  static constexpr std::size_t kGroupCells = 64;
  CellGrid<D> hgrid_;
  std::vector<int> hg_start_, hg_items_;

  static constexpr std::size_t kMaxEarly = 256, kMaxEarlyPairs = std::size_t{1} << 20;

  // The list entries of the grains released at this substep leave the lists (they touch nothing:
  // no spring is lost). A pass over the entries, where a rebuild would also search the grid and
  // carry every spring over.
  void purge_hard() {
    purge_ = false;
    pairs_.filter([&](const PairEntry& e) { return mode_[e.i] != kHard && mode_[e.j] != kHard; });
    std::size_t kw = 0;
    for (const auto& e : we_)
      if (mode_[e.i] != kHard) we_[kw++] = e;
    we_.resize(kw);
  }

  // Pair and wall entries of soft i with the soft particles (and walls) within the skin.
  void add_entries(int i, double t) {
    const Vec<D> xi = hot_[i].x;
    const double Ri = hot_[i].R;
    pairs_.begin_row(ui(i));
    this->for_neighbours_reach(i, sg_w_, [&](int j, const Vec<D>& shift) {
      if (mode_[j] != kSoft && mode_[j] != kAsleep && mode_[j] != kFixed) return;
      const double cut = Ri + hot_[j].R + lskin_;
      if ((xi - hot_[j].x - shift).squaredNorm() >= cut * cut) return;
      pairs_.add({ui(i), ui(j), pair_contact_of(i, j), image_of(shift), 0, Vec<D>::Zero()});
      if (mode_[j] == kAsleep) watch(j);
    });
    pairs_.end_row();
    add_walls_only(i, t);
  }

  // Index of the contact constants of a pair (a wall) in ctab_. One table for a uniform scene (one
  // material, one radius); otherwise one constant per entry, appended as the entry is made and the
  // table rebuilt for the live entries at each list build (rebuild_entries): a polydisperse scene
  // has a different constant for nearly every pair, and a table of every pair ever met grew
  // without bound and cost a tree search per entry (47 % of a 2D chute flow's time).
  std::uint32_t pair_contact_of(int a, int b) { return pair_contact_in(a, b, ctab_); }
  std::uint32_t wall_contact_of(int w, int i) { return wall_contact_in(w, i, ctab_); }
  // The same, appending a new constant to the table `tab` (a thread's during a list build).
  std::uint32_t pair_contact_in(int a, int b, std::vector<SoftContact>& tab) const {
    if (is_fixed(a) || is_fixed(b)) {  // m* = the moving grain's mass
      if (is_fixed(a)) std::swap(a, b);
      if (uniform_) return 1 + static_cast<std::uint32_t>(sys_.walls.size());
      return add_contact(tab, pair_contact(plan_, cold_[a].mat, hot_[a].R, mass(a), cold_[b].mat, hot_[b].R, kPlane));
    }
    if (uniform_) return 0;
    return add_contact(tab, pair_contact(plan_, cold_[a].mat, hot_[a].R, mass(a), cold_[b].mat, hot_[b].R, mass(b)));
  }
  std::uint32_t wall_contact_in(int w, int i, std::vector<SoftContact>& tab) const {
    if (uniform_) return 1 + static_cast<std::uint32_t>(w);
    return add_contact(tab, wall_contact(plan_, w, cold_[i].mat, hot_[i].R, mass(i)));
  }
  static std::uint32_t add_contact(std::vector<SoftContact>& tab, const SoftContact& c) {
    tab.push_back(c);
    return static_cast<std::uint32_t>(tab.size() - 1);
  }

  static std::uint64_t key(std::uint32_t a, std::uint32_t b) { return (std::uint64_t(a) << 32) | b; }
  // A pair's key whatever its orientation.
  static std::uint64_t pkey(std::uint32_t a, std::uint32_t b) { return a < b ? key(a, b) : key(b, a); }
  // The index of the image shift (shifts_) that brings j next to i, for the shift a neighbour walk
  // reports (x_j + shift is the image next to x_i; the list stores -shift).
  static std::uint8_t image_of(const Vec<D>& shift) {
    int s = 0;
    for (int k = 0, p = 1; k < D; ++k, p *= 3) s += ((shift[k] > 0.0) ? 0 : (shift[k] < 0.0) ? 2 : 1) * p;
    return static_cast<std::uint8_t>(s);
  }

  // All entries anew, the springs of touching contacts carried over by particle ids: every pair
  // (wall) within the list skin with an awake soft end. The touching pairs of two sleepers (walls
  // of a sleeper) stay in pe_sleep_/we_sleep_ (rest rule: freeze_quiet, wake_loaded). Sleepers
  // with an awake neighbour are watched.
  MATEP_FLATTEN void rebuild_entries(double t) {
    ++hstats_.rebuilds;
    build_t_ = t;
    // The soft set in id order (the arrays' order): each substep's passes (drift, rows, full step)
    // then walk the arrays forwards instead of in the order the grains joined.
    std::sort(soft_.begin(), soft_.end());
    for (std::size_t k = 0; k < soft_.size(); ++k) slot_[soft_[k]] = static_cast<int>(k);
    soft::SpringMemory<D>& mem = springs_;
    mem.clear();
    pairs_.for_each([&](const PairEntry& e) {
      if (e.touch) mem.remember_pair(e.i, e.j, e.xi, e.mr);
    });
    for (const auto& e : we_)
      if (e.touch)
        mem.remember_wall(ui(e.i), wall_slot(ui(e.w), e.f), e.xi, epsd_ ? wmr_[e.r] : Spin<D>(Spin<D>::Zero()));
    mem.sort();
    pairs_.clear();
    we_.clear();
    if (!uniform_) {  // the constants of the live entries only: the sleepers' now, the rest below
      ctab_.clear();
      for (auto& e : pe_sleep_) e.c = pair_contact_of(static_cast<int>(e.i), static_cast<int>(e.j));
      for (auto& e : we_sleep_) e.c = wall_contact_of(e.w, e.i);
    }
    if (epsd_) {  // the sleepers' wall entries keep their torques; the rest is rebuilt below
      std::vector<Spin<D>> kept;
      for (auto& e : we_sleep_) {
        kept.push_back(wmr_[e.r]);
        e.r = static_cast<std::uint32_t>(kept.size() - 1);
      }
      wmr_ = std::move(kept);
    }
    for (const int j : watched_) watch_flag_[j] = 0;
    watched_.clear();
    soft_grid_build();
    const int T = threads_for(soft_.size());
    if (T == 1) {
      BuildSink out{pairs_, we_, ctab_, wmr_, watch_new_, feats_};
      for (const int i : soft_) build_row(i, t, mem, out);
    } else {
      // Each thread builds the rows of a range of the soft set into its own lists; they are
      // appended in thread order (the same rows, in the same order, as one thread builds), their
      // contact-constant and rolling-torque indices shifted past the earlier threads'.
      parallel(T, [&](int th) {
        RowBuild& b = rb_[th];
        b.clear(epsd_);
        BuildSink out = b.sink();
        for_soft_part(th, T, [&](int i) { build_row(i, t, mem, out); });
      });
      for (int th = 0; th < T; ++th) {
        RowBuild& b = rb_[th];
        const std::uint32_t c0 = static_cast<std::uint32_t>(ctab_.size()), r0 = static_cast<std::uint32_t>(wmr_.size());
        ctab_.insert(ctab_.end(), b.ctab.begin(), b.ctab.end());
        wmr_.insert(wmr_.end(), b.wmr.begin(), b.wmr.end());
        const std::size_t e0 = pairs_.size();
        pairs_.append(b.pairs);
        if (!uniform_)
          for (std::size_t e = e0; e < pairs_.size(); ++e) pairs_.c[e] += c0;
        for (WallEntry w : b.walls) {
          if (!uniform_) w.c += c0;
          w.r += r0;
          we_.push_back(w);
        }
        watch_new_.insert(watch_new_.end(), b.watch.begin(), b.watch.end());
      }
    }
    for (const int j : watch_new_) watch(j);
    watch_new_.clear();
    dirty_ = false;
  }

  // Where a list build puts the rows it makes: the pair list, the wall entries, the contact
  // constants and rolling torques they index, the sleepers to watch, the walls' search scratch.
  struct BuildSink {
    soft::PairList<D>& pairs;
    std::vector<WallEntry>& walls;
    std::vector<SoftContact>& ctab;
    std::vector<Spin<D>>& wmr;
    std::vector<int>& watch;
    std::vector<std::uint32_t>& feats;
  };
  struct RowBuild {
    soft::PairList<D> pairs;
    std::vector<WallEntry> walls;
    std::vector<SoftContact> ctab;
    std::vector<Spin<D>> wmr;
    std::vector<int> watch;
    std::vector<std::uint32_t> feats;
    BuildSink sink() { return {pairs, walls, ctab, wmr, watch, feats}; }
    void clear(bool rolling) {
      pairs.clear();
      pairs.set_rolling(rolling);
      walls.clear();
      ctab.clear();
      wmr.clear();
      watch.clear();
    }
  };
  // The row of awake soft i at a list build (rebuild_entries): its pairs with the soft particles
  // of the cells after its own and the higher ids of its own, the sleepers and the fixed grains
  // within the list skin, and its walls, each with the spring it had (mem).
  void build_row(int i, double t, const soft::SpringMemory<D>& mem, BuildSink& out) {
    x0_[i] = hot_[i].x;
    set_free_reach(i);
    const Vec<D> xi = hot_[i].x;
    const double Ri = hot_[i].R;
    out.pairs.begin_row(ui(i));
    const auto entry = [&](int j, const Vec<D>& shift) {
      const double cut = Ri + hot_[j].R + lskin_;
      if ((xi - hot_[j].x - shift).squaredNorm() >= cut * cut) return;
      PairEntry e{ui(i), ui(j), pair_contact_in(i, j, out.ctab), image_of(shift), 0, Vec<D>::Zero()};
      if (mem.recall_pair(ui(i), ui(j), e.xi, &e.mr)) e.touch = 1;
      out.pairs.add(e);
      if (mode_[j] == kAsleep) out.watch.push_back(j);
    };
    // Soft pairs once each: in the row of the grain in the lower cell, or of the lower id in one cell
    // (a half stencil, as TDM's build; on hashed cells, every cell and the lower id).
    const std::array<int, D> ci = sgrid_.coords(xi);
    const int li = sgrid_.linear(ci);
    const bool half = sg_half_;
    sgrid_.around(ci, [&](int l, const Vec<D>& shift) {
      if (half && l < li) return;
      const bool own = !half || l == li;
      for (int p = sg_start_[l], e = sg_start_[l + 1]; p < e; ++p)
        if (const int j = sg_items_[p]; !own || j > i) entry(j, shift);
    });
    // The sleepers and fixed grains in every cell around.
    if (!ss_items_.empty())
      sgrid_.around(ci, [&](int l, const Vec<D>& shift) {
        for (int p = ss_start_[l], e = ss_start_[l + 1]; p < e; ++p) entry(ss_items_[p], shift);
      });
    out.pairs.end_row();
    soft::walls_in_reach<D>(shapes_, xi, Ri, lskin_, t, out.feats, [&](std::uint32_t w, std::uint32_t f) {
      WallEntry e = new_wall_entry_in(i, static_cast<int>(w), f, out.ctab, out.wmr);
      Spin<D>* mr = epsd_ ? &out.wmr[e.r] : nullptr;
      if (mem.recall_wall(ui(i), wall_slot(w, f), e.xi, mr)) e.touch = 1;
      out.walls.push_back(e);
    });
  }

  // The neighbour search of the list builds: the awake soft particles, and apart from them the
  // sleepers and fixed grains near them, counting-sorted into cells of width 2 rmax + lskin over
  // the awake particles' bounding box widened by one cell (the whole axis if periodic). The EDM
  // cells are coarser where the domain is mostly empty (a tall pour: their count is capped at 2 N).
  void soft_grid_build() {
    Vec<D> lo = Vec<D>::Constant(kNever), hi = Vec<D>::Constant(-kNever);
    for (const int i : soft_) {
      lo = lo.cwiseMin(hot_[i].x);
      hi = hi.cwiseMax(hot_[i].x);
    }
    const double w = sg_w_;
    for (int k = 0; k < D; ++k) {
      if (sys_.periodic[k]) {
        lo[k] = lo_[k];
        hi[k] = hi_[k];
      } else {
        lo[k] -= w;
        hi[k] += w;
      }
    }
    // At most about four cells per participant (periodic axes keep three).
    const double cap = 4.0 * static_cast<double>(soft_.size() + asleep_list_.size()) + 64.0;
    sgrid_.build(lo, hi, sys_.periodic, w, cap, 1e6, /*hash=*/true);
    // The half stencil needs each neighbour cell once: a linear layout, three cells or more on a
    // periodic axis (fewer would show a cell as two images).
    sg_half_ = !sgrid_.hashed();
    for (int k = 0; k < D; ++k) sg_half_ = sg_half_ && (!sys_.periodic[k] || sgrid_.count(k) >= 3);
    const std::size_t cells = static_cast<std::size_t>(sgrid_.cells());
    // Two counting sorts into the same cells: the awake soft grains, and the sleepers and fixed
    // grains within reach.
    const auto cell_of = [&](int i) {
      std::array<int, D> c{};
      for (int k = 0; k < D; ++k) {
        const double u = (hot_[i].x[k] - sgrid_.lower()[k]) / sgrid_.width(k);
        if (!sys_.periodic[k] && !(u >= 0.0 && u < sgrid_.count(k))) return -1;  // out of reach
        c[k] = std::clamp(static_cast<int>(u), 0, sgrid_.count(k) - 1);
      }
      return sgrid_.linear(c);
    };
    cell_sort(cells, {&soft_}, cell_of, sg_start_, sg_items_);
    if (asleep_list_.empty() && fixed_list_.empty())
      ss_items_.clear();
    else
      cell_sort(cells, {&asleep_list_, &fixed_list_}, cell_of, ss_start_, ss_items_);
  }
  // A stable counting sort of the grains of `lists` (in order) into `cells` cells: grain i goes
  // to cell cell_of(i) (negative: left out), cell l's grains are items[start[l] .. start[l + 1]).
  template <class CellOf>
  void cell_sort(std::size_t cells, std::initializer_list<const std::vector<int>*> lists, CellOf&& cell_of,
                 std::vector<int>& start, std::vector<int>& items) {
    start.assign(cells + 1, 0);
    sg_part_.clear();
    sg_cell_.clear();
    for (const std::vector<int>* list : lists)
      for (const int i : *list) {
        const int l = cell_of(i);
        if (l < 0) continue;
        sg_part_.push_back(i);
        sg_cell_.push_back(l);
        ++start[static_cast<std::size_t>(l) + 1];
      }
    for (std::size_t c = 0; c < cells; ++c) start[c + 1] += start[c];
    items.resize(sg_part_.size());
    sg_fill_.assign(start.begin(), start.end() - 1);
    for (std::size_t p = 0; p < sg_part_.size(); ++p) items[sg_fill_[sg_cell_[p]]++] = sg_part_[p];
  }

  void watch(int j) {
    if (watch_flag_[j]) return;
    watch_flag_[j] = 1;
    watched_.push_back(j);
  }

  // The elastic force of a contact (spring and tangential spring, no dashpots: both ends at rest):
  // force and torque on e.i, torque on e.j (walls: none), and the overlap (<= 0: no contact, all
  // zero).
  struct StaticForce {
    Vec<D> f = Vec<D>::Zero();
    Spin<D> ti = Spin<D>::Zero(), tj = Spin<D>::Zero();
    double delta = 0.0;
  };
  StaticForce static_pair_force(const PairEntry& e) const {
    StaticForce out;
    Vec<D> dx = hot_[e.i].x - hot_[e.j].x;
    min_image(dx);
    const double r = dx.norm();
    out.delta = hot_[e.i].R + hot_[e.j].R - r;
    if (!(out.delta > 0.0)) return out;
    ContactKinematics<D> k;
    k.delta = out.delta;
    k.n = dx / r;
    ContactHistory<D> hist{e.xi};
    const ContactForce<D> cf = soft_contact_force(ctab_[e.c], k, hist);
    out.f = cf.force;
    if (rot_) {
      const Spin<D> m = lever_moment<D>(k.n, cf.tangential);
      out.ti = -pair_lever_arm(hot_[e.i].R, k.delta) * m;
      out.tj = -pair_lever_arm(hot_[e.j].R, k.delta) * m;
    }
    return out;
  }
  StaticForce static_wall_force(const WallEntry& e, double t) const {
    StaticForce out;
    const WallPoint<D> c = shapes_[e.w]->at_feature(hot_[e.i].x, hot_[e.i].R, t, e.f);
    out.delta = -c.gap;
    if (!(out.delta > 0.0)) return out;
    ContactKinematics<D> k;
    k.delta = out.delta;
    k.n = c.normal;
    ContactHistory<D> hist{e.xi};
    const ContactForce<D> cf = soft_contact_force(ctab_[e.c], k, hist);
    out.f = cf.force;
    if (rot_) out.ti = contact_torque<D>(k.n, cf.tangential, wall_lever_arm(hot_[e.i].R, k.delta));
    return out;
  }
  // Adds s times the force and torque that pair e's static force sf puts on its end k to f[k],
  // tq[k] (a sleeper's balance at sleep, fz_base_, or its awake neighbours' share, fz_mix_).
  void add_share(std::vector<Vec<D>>& f, std::vector<Spin<D>>& tq, int k, const PairEntry& e,
                 const StaticForce& sf, double s) {
    const bool own = ui(k) == e.i;
    f[k] += own ? Vec<D>(s * sf.f) : Vec<D>(-s * sf.f);
    if (rot_) tq[k] += s * (own ? sf.ti : sf.tj);
  }
  void add_walls_only(int i, double t) {
    walls_in_reach(i, t, [&](int w, std::uint32_t f) {
      we_.push_back(new_wall_entry(i, w, f));
    });
  }
  // Calls fn(w, feature) for each wall (feature) within the list skin of i (engine/soft/forces.hpp).
  template <class Fn>
  void walls_in_reach(int i, double t, Fn&& fn) {
    soft::walls_in_reach<D>(shapes_, hot_[i].x, hot_[i].R, lskin_, t, feats_,
                            [&](std::uint32_t w, std::uint32_t f) { fn(static_cast<int>(w), f); });
  }

  // Moves soft i into its cell after a substep that took it out of its cell's box (cblo_, cbhi_;
  // periodic wrap; escape through an open face).
  void relocate(int i, double t) {
    Hot<D>& h = hot_[i];
    std::array<int, D> c{};
    const bool lists = this->lists_;
    for (int k = 0; k < D; ++k) {
      if (sys_.periodic[k]) {
        // A wrap changes the image shifts of its list entries: rebuild before the forces.
        if ((h.x[k] >= hi_[k] || h.x[k] < lo_[k]) && std::isfinite(h.x[k])) {
          h.x[k] = wrap_periodic(h.x[k], lo_[k], hi_[k]);
          dirty_ = true;
        }
      } else if (!(h.x[k] >= lo_[k] - h.R && h.x[k] <= hi_[k] + h.R) && status_.empty()) {
        status_ = std::isfinite(h.x[k]) ? "escaped" : "unstable";
        message_ = std::isfinite(h.x[k])
                       ? escape_message(this->ids_->user(static_cast<std::uint64_t>(i)), k, t, h.x[k])
                       : fmt::format("particle {} reached a non-finite position at t = {:.17g}: the substep {} is "
                                     "too long for the contacts (stability limit {:.6g})",
                                     this->ids_->user(static_cast<std::uint64_t>(i)), t, h_, plan_.max_stable_dt);
      }
      if (lists) continue;
      c[k] = std::isfinite(h.x[k]) ? grid_.coord(k, h.x[k]) : 0;
      const double cw = grid_.width(k);
      const int nk = grid_.count(k);
      const bool closed = !sys_.periodic[k];
      cblo_[i][k] = c[k] == 0 ? (closed ? lo_[k] - h.R : lo_[k]) : lo_[k] + c[k] * cw;
      cbhi_[i][k] = c[k] == nk - 1 ? (closed ? std::nextafter(hi_[k] + h.R, kNever) : hi_[k])
                                   : lo_[k] + (c[k] + 1) * cw;
    }
    if (lists) {
      fit_shell(i);
      shell_box(i);
      set_free_reach(i);
      return;
    }
    set_free_reach(i);
    if (c != cold_[i].cell) {
      cell_remove(i);
      cold_[i].cell = c;
      cell_insert(i);
      mark_neighbours(i);
    }
  }

  // With lists: whether grain i is inside its shell (engine/edm/core.hpp: a ball, under gravity a
  // cube; a soft grain's box is the cube inside the ball, shell_box).
  bool in_shell(int i) const {
    const Vec<D> d = hot_[i].x - this->shell_c_[i].c;
    const double s = this->shell_;
    if (this->sphere_) return d.squaredNorm() <= s * s;
    return (d.array().abs() <= s).all();
  }
  // A new shell, list and cell about i's centre when it has left its shell; the hard grains about
  // its new place then check it (mark_neighbours, as a soft grain's move to another cell does).
  void fit_shell(int i) {
    if (!std::isfinite(hot_[i].x.squaredNorm()) || in_shell(i)) return;
    this->relist(i);
    mark_neighbours(i);
  }
  // Soft i's box (cblo_, cbhi_) with lists: inside its shell (a ball's inner cube, shortened by
  // 1e-9 against round-off), inside the escape limits of closed axes and the domain along periodic
  // ones (a wrap relocates), as the cells' boxes are.
  void shell_box(int i) {
    const Hot<D>& h = hot_[i];
    const double hw = this->sphere_ ? (1.0 - 1e-9) * this->shell_ / std::sqrt(static_cast<double>(D)) : this->shell_;
    const Vec<D>& c = this->shell_c_[i].c;
    for (int k = 0; k < D; ++k) {
      const bool closed = !sys_.periodic[k];
      cblo_[i][k] = std::max(c[k] - hw, closed ? lo_[k] - h.R : lo_[k]);
      cbhi_[i][k] = std::min(c[k] + hw, closed ? std::nextafter(hi_[k] + h.R, kNever) : hi_[k]);
    }
  }

  // cfree2_[i]: the square of how far soft i may move from x0_[i] and stay inside its cell's box
  // (cblo_, cbhi_), -1 when x0_[i] is not inside it. The drift tests the box only beyond that
  // distance (kick_drift gives it): most substeps of a bed then read one number instead of the
  // box. The distance is shortened by 1e-9 of the box's coordinates, far more than the round-off
  // of x - x0 and of the distance itself, so that a grain within it is inside the box exactly as
  // the box test would find.
  void set_free_reach(int i) {
    double m = kNever, scale = 0.0;
    for (int k = 0; k < D; ++k) {
      m = std::min({m, x0_[i][k] - cblo_[i][k], cbhi_[i][k] - x0_[i][k]});
      scale = std::max({scale, std::abs(cblo_[i][k]), std::abs(cbhi_[i][k])});
    }
    m -= 1e-9 * (scale + m);
    cfree2_[i] = m > 0.0 ? m * m : -1.0;
  }

  // The drift of one soft grain (engine/soft/verlet.hpp) to the substep at time tn, with the
  // forces of the substep before: it returns whether the grain moved beyond half the list skin
  // and notes whether it entered an outlet (leave) or left its cell's box (reloc). A copy of the
  // engine's pointers, so that the loops keep them in registers (the flag is returned, not
  // stored: a byte store would make the compiler reload every pointer at each grain).
  struct Drift {
    Hot<D>* HOT;
    const Vec<D>* BLO;
    const Vec<D>* BHI;
    const double* FREE2;
    Vec<D>* FF;
    Vec<D>* AC;
    Vec<D>* VH;
    const Vec<D>* X0;
    const double* MINV;
    Spin<D>* TQ;
    Spin<D>* AL;
    Spin<D>* WH;
    const double* IINV;
    Vec<D> g;
    double h, lim2;
    bool rot, outlets;
    const System<D>* sys;

    [[gnu::always_inline]] bool operator()(int i, double tn, std::vector<int>& reloc,
                                           std::vector<std::pair<int, int>>& leave) const {
      double d2;
      const bool moved = soft::kick_drift<D>(FF[i], AC[i], VH[i], HOT[i].x, X0[i], MINV[i], g, h, lim2, d2);
      if (rot) soft::kick_spin(TQ[i], AL[i], WH[i], IINV[i], h);
      HOT[i].t = tn;
      const Vec<D>& x = HOT[i].x;
      if (outlets) [[unlikely]] {
        if (const int o = sys->outlet_at(x); o >= 0) {
          leave.emplace_back(i, o);
          return moved;
        }
      }
      // Still inside the box of its cell (edge cells of closed axes: up to the escape limit;
      // NaN fails the test): no cell update. Within cfree2_ of x0, it is (set_free_reach).
      if (!(d2 < FREE2[i]) && !((x.array() >= BLO[i].array()).all() && (x.array() < BHI[i].array()).all()))
        reloc.push_back(i);
      return moved;
    }
  };
  Drift drift_kernel() {
    return Drift{hot_.data(), cblo_.data(), cbhi_.data(), cfree2_.data(), f_.data(), acc_.data(), vh_.data(),
                 x0_.data(), minv_.data(), tq_.data(), alpha_.data(), wh_.data(), iinv_.data(), g_, h_,
                 0.25 * lskin_ * lskin_, rot_, !sys_.outlets.empty(), &sys_};
  }

  // One TDM substep at time t (README "Hybrid dynamics", "Substeps").
  void substep(double t) {
    if ((++hstats_.substeps & 0x3ff) == 0)  // progress: events so far, substeps included
      for (auto* o : observers_) o->on_progress(t, counts_.total() + hstats_.substeps);
    // 1. Drift the awake soft particles from t - h to t with the forces of t - h (engine/soft/verlet.hpp),
    // unless the last substep's closing pass did (predrifted_, see step 5): then only its notes
    // are handled here, in the order of the soft set as it is now, as the drift would have.
    // (Threads: each drifts a range of the soft set and lists the grains that left their cell box
    // or entered an outlet; those are handled after, in soft-set order, as one thread would.)
    const int T = threads_for(soft_.size());
    int notes = T;  // the threads whose notes (t_relocate_, t_leaving_) the drift left
    const std::int64_t steps = static_cast<std::int64_t>(clock_n_) - sub_last_n_;  // > 1: a coast
    sub_last_n_ = static_cast<std::int64_t>(clock_n_);
    if (steps > 1) {
      coast_drift(t, steps, T);
    } else if (predrifted_) {
      predrifted_ = false;
      notes = predrift_T_;
      if (predrift_moved_) dirty_ = true;
    } else {
      std::array<std::uint8_t, kMaxThreads> moved{};
      const int* const SOFT = soft_.data();
      const std::size_t nsoft = soft_.size();
      const Drift drift = drift_kernel();
      parallel(T, [&, drift, SOFT, nsoft, t](int th) {
        bool dirty = false;
        std::vector<int>& reloc = t_relocate_[th];
        std::vector<std::pair<int, int>>& leave = t_leaving_[th];
        reloc.clear();
        leave.clear();
        const Drift dr = drift;  // (a local copy: its pointers stay in registers)
        for (std::size_t k = nsoft * th / T, end = nsoft * (th + 1) / T; k < end; ++k)
          dirty |= dr(SOFT[k], t, reloc, leave);
        moved[th] = dirty;
      });
      for (int th = 0; th < T; ++th)
        if (moved[th]) dirty_ = true;
    }
    // The grains that left their cell box, in the soft set's present order (a closing pass drifted
    // them before the releases reordered it; the threads' parts are otherwise in that order).
    std::vector<int>& reloc = t_relocate_[0];
    for (int th = 1; th < notes; ++th) reloc.insert(reloc.end(), t_relocate_[th].begin(), t_relocate_[th].end());
    std::sort(reloc.begin(), reloc.end(), [&](int a, int b) { return slot_[a] < slot_[b]; });
    for (const int i : reloc) relocate(i, t);
    for (int th = 0; th < notes; ++th) leaving_.insert(leaving_.end(), t_leaving_[th].begin(), t_leaving_[th].end());
    hstats_.soft_particle_steps += soft_.size();
    if (!leaving_.empty()) remove_soft(t);
    if (!status_.empty()) return;
    // 2. Joins: pending particles, then hard particles within the skin of a soft one.
    for (std::size_t k = 0; k < pending_.size(); ++k)
      if (mode_[pending_[k]] == kPending) join(pending_[k], t, pending_reason_[k]);
    pending_.clear();
    pending_reason_.clear();
    capture(t);
    // 3. Entries, 4. forces at t.
    // A turning wall sweeps towards the grains too: with their half skin, half the skin.
    if (sweep_ > 0.0 && sweep_ * (t - build_t_) > 0.5 * lskin_) dirty_ = true;
    if (dirty_) rebuild_entries(t);
    for (const int k : unsupported_)  // sleepers that lost a touching grain to an outlet: wake test
      if (mode_[k] == kAsleep) watch(k);
    unsupported_.clear();
    soft_forces(t);
    if (t == 0.0) start_soft_state();
    if (asleep_ > 0 && !watched_.empty()) wake_loaded(t);
    // 5. Full-step velocities; release and rest. When nothing can happen before the next
    // substep but that substep (fuse_next), the same pass also drifts each grain that stays soft
    // to it (step 1 of the next substep, which then only handles the drift's notes): one pass
    // over the soft set instead of two, with the same arithmetic on the same values.
    double vmax2 = 0.0;
    const double hdt = hdt_, hyst = hyst_;
    const Vec<D>* const F5 = f_.data();
    const Vec<D>* const VH5 = vh_.data();
    const double* const MINV = minv_.data();
    Hot<D>* const HOT = hot_.data();
    const Vec<D> g = g_;
    const bool rot = rot_;
    std::uint8_t* const TOUCHING = touching_.data();
    std::uint8_t* const NEAR = near_.data();
    double* const LAST = last_contact_.data();
    freed_.clear();
    const int T5 = threads_for(soft_.size());
    // (Per-thread results: only the T5 slots in use are cleared, not kMaxThreads of them at every
    // substep.)
    std::array<double, kMaxThreads> vmax;
    std::fill_n(vmax.begin(), T5, 0.0);
    std::array<std::uint8_t, kMaxThreads> moved{};
    const int* const SOFT5 = soft_.data();  // the soft set has changed since the drift (joins)
    const std::size_t n5 = soft_.size();
    const double tn = clock_t0_ + static_cast<double>(clock_n_ + 1) * h_;  // the next substep's time
    std::int64_t coast = coast_plan(t);  // grid steps to the next substep
    const bool fuse = coast == 1 && fuse_next(tn);
    const Drift drift = drift_kernel();
    parallel(T5, [&, hdt, hyst, g, HOT, F5, VH5, MINV, TOUCHING, NEAR, LAST, SOFT5, n5, rot, t, tn, fuse,
                  drift](int th) {
      double vm2 = 0.0;
      bool dirty = false;
      std::vector<int>& freed = t_freed_[th];
      std::vector<int>& reloc = t_relocate_[th];
      std::vector<std::pair<int, int>>& leave = t_leaving_[th];
      freed.clear();
      reloc.clear();
      leave.clear();
      const Drift dr = drift;  // (a local copy: its pointers stay in registers)
      for (std::size_t k = n5 * th / T5, end = n5 * (th + 1) / T5; k < end; ++k) {
        const int i = SOFT5[k];
        const Vec<D> v = soft::full_step<D>(VH5[i], F5[i], MINV[i], g, hdt);
        HOT[i].v = v;
        vm2 = std::max(vm2, v.squaredNorm());
        if (rot) sys_.w[i] = wh_[i] + hdt * (tq_[i] * iinv_[i]);
        const bool touching = TOUCHING[i], near = NEAR[i];
        TOUCHING[i] = NEAR[i] = 0;
        if (touching) {
          LAST[i] = t;
        } else if (!near && t - LAST[i] >= hyst) {
          freed.push_back(i);  // released at t below: not drifted
          continue;
        }
        if (fuse) dirty |= dr(i, tn, reloc, leave);
      }
      vmax[th] = vm2;
      moved[th] = dirty;
    });
    for (int th = 0; th < T5; ++th) {
      vmax2 = std::max(vmax2, vmax[th]);
      freed_.insert(freed_.end(), t_freed_[th].begin(), t_freed_[th].end());
    }
    if (fuse) {
      predrifted_ = true;
      predrift_T_ = T5;
      predrift_moved_ = false;
      for (int th = 0; th < T5; ++th) predrift_moved_ = predrift_moved_ || moved[th];
    }
    for (const int i : freed_) release(i, t);
    if (++since_cost_check_ >= cost_every_) {
      since_cost_check_ = 0;
      release_by_cost(t);
    }
    if (purge_) purge_hard();
    vsoft_max_ = std::sqrt(vmax2);
    if (sleeping_ && ++since_sleep_check_ >= sleep_every_) {
      since_sleep_check_ = 0;
      freeze_quiet(t);
    }
    hstats_.max_soft = std::max<std::uint64_t>(hstats_.max_soft, soft_.size() + asleep_);
    // With nothing soft, asleep or pending no grain can be captured: the interface list empties
    // now instead of at each member's next check (in the stability map's gas at e = 0.1,
    // phi = 0.05, a fifth of the substeps had no soft grain).
    if (all_hard() && !iface_.empty()) {
      for (const int i : iface_) iface_flag_[i] = 0;
      iface_.clear();
    }
    // 6. The next substep while anything is soft, pending or next to a soft particle; a coast
    // ends earlier if what step 5 did (releases, their predictions) brought a capture check forward.
    if (!soft_.empty() || !pending_.empty() || !iface_.empty()) {
      if (coast > 1 && (!pending_.empty() || soft_.empty())) coast = 1;
      if (coast > 1 && iface_due_ < t + static_cast<double>(coast) * h_)
        coast = std::max<std::int64_t>(1, static_cast<std::int64_t>(std::floor((iface_due_ - t) / h_)));
      if (coast > 1) {
        ++hstats_.coasts;
        hstats_.coasted_steps += static_cast<std::uint64_t>(coast - 1);
        since_cost_check_ += static_cast<std::uint64_t>(coast - 1);
        if (sleeping_) since_sleep_check_ += static_cast<std::uint64_t>(coast - 1);
      }
      clock_n_ += static_cast<std::uint64_t>(coast);
      queue_->set(substep_id_, clock_t0_ + static_cast<double>(clock_n_) * h_);
    } else {
      clock_ = false;
      predrifted_ = false;  // nothing soft was drifted (every grain was released)
    }
  }

  // Whether the closing pass of the substep now ending may drift the soft set to the next one at
  // tn: nothing else may happen before it (the earliest event of the queue is later: no sample,
  // snapshot, checkpoint, inlet, end or hard collision sees the soft set a substep ahead), no rule
  // that reads the soft set at this time runs after the pass (the cost release, the rest rule's
  // check), and no stop has been asked for (a stopped run leaves with the soft set at its time).
  // The grains released after the pass are not drifted; their new courses, predicted from t, meet
  // no soft grain (hard courses skip soft neighbours).
  bool fuse_next(double tn) {
    if (!status_.empty() || t_relocate_.empty()) return false;
    if (since_cost_check_ + 1 >= cost_every_) return false;
    if (sleeping_ && since_sleep_check_ + 1 >= sleep_every_) return false;
    if (set_.stop && set_.stop->load(std::memory_order_relaxed)) return false;
    return queue_->empty() || queue_->top().second > tn;
  }

  // ---- Coasts: the soft set in free flight (README "Hybrid dynamics", "Substeps") ----
  // While no soft grain touches anything, every soft grain flies freely under gravity alone, and
  // the leapfrog's steps are exact for that flight: k steps from x, v(t - h/2) reach
  //   v += k h g,   x += k h v(t - h/2) + h^2 g k (k + 1) / 2,
  // which the next substep applies at once instead of k drifts (equal up to round-off). The run
  // skips the substeps between (a coast) while nothing could happen at them:
  //  * no pending join, no sleeper, no wall entry, no fixed grain in a soft pair, no outlet and
  //    no moving wall in the scene. A stop asked for does not end or forbid a coast (a run that
  //    coasts where the uninterrupted one would not ends a round-off apart from it, and its resumed
  //    run too): the stop comes at a substep (the soft set at its time), with the coast planned
  //    after it saved in the checkpoint (sub_last_n_);
  //  * it ends before any other timed event of the run (sample, snapshot, checkpoint, inlet,
  //    end), at the next capture check (iface_due_), at the earliest single-grain release, and at
  //    the next check of the cost release and of the rest rule (their cadences count the skipped
  //    steps);
  //  * at the last grid point before two soft grains of the list could touch: their relative
  //    velocity is constant in free flight (a uniform field moves both alike), so the time of
  //    touch is the root of |r + u s| = R_i + R_j;
  //  * before any grain could leave its cell's box (capture and the hard grains' walks find soft
  //    grains by their cells) or move half the list skin from its list position (the pairs not in
  //    the list stay farther apart than touch), bounded by |v| s + |g| s (s + h) / 2.
  // A hard event that brings a capture check or a join forward (due_now, make_pending) pulls the
  // coast's end in to the next grid point (pull_substep).
  bool coasting() const { return clock_ && static_cast<std::int64_t>(clock_n_) > sub_last_n_ + 1; }

  void pull_substep() {
    if (!coasting()) return;
    std::int64_t n = sub_last_n_ + 1;
    const double at = std::ceil((now_ - clock_t0_) / h_);
    if (at > static_cast<double>(n)) n = static_cast<std::int64_t>(at);
    while (clock_t0_ + static_cast<double>(n) * h_ < now_) ++n;
    if (n >= static_cast<std::int64_t>(clock_n_)) return;
    const std::uint64_t unskipped = clock_n_ - static_cast<std::uint64_t>(n);
    hstats_.coasted_steps -= unskipped;
    if (n == sub_last_n_ + 1) --hstats_.coasts;  // no step skipped after all
    since_cost_check_ -= std::min(since_cost_check_, unskipped);
    if (sleeping_) since_sleep_check_ -= std::min(since_sleep_check_, unskipped);
    clock_n_ = static_cast<std::uint64_t>(n);
    queue_->set(substep_id_, clock_t0_ + static_cast<double>(clock_n_) * h_);
  }

  // Grid steps from the substep at t to the next one: more than 1 for a coast. Called after the
  // forces of t (touching_ holds this substep's contacts), before the full-step pass.
  std::int64_t coast_plan(double t) {
    free_until_ = -kNever;
    if (!coast_scene_ || soft_.empty() || !pending_.empty() || asleep_ > 0 || !we_.empty() || !status_.empty())
      return 1;
    // Each soft grain: in contact (no coast), its release time, its reach (to the cell box's faces
    // and to half the skin from x0), and whether the cost release could free it. Checked first:
    // in a soft bed the first grain in contact ends the plan.
    const double gn = g_.norm();
    double s = static_cast<double>(kMaxCoast) * h_;  // the coast's longest span
    bool releasable = false;
    for (const int i : soft_) {
      if (touching_[i] || f_[i] != Vec<D>::Zero()) return 1;
      s = std::min(s, last_contact_[i] + hyst_ - t);
      const Vec<D>& x = hot_[i].x;
      double reach = 0.5 * lskin_ - (x - x0_[i]).norm();
      for (int k = 0; k < D; ++k) reach = std::min({reach, x[k] - cblo_[i][k], cbhi_[i][k] - x[k]});
      if (!(reach > 0.0)) return 1;
      // |v| s + |g| s (s + h) / 2 <= reach
      const double a = 0.5 * gn, b = vh_[i].norm() + 0.5 * gn * h_;
      const double smax = a > 0.0 ? 2.0 * reach / (b + std::sqrt(b * b + 4.0 * a * reach)) : b > 0.0 ? reach / b : kNever;
      s = std::min(s, smax);
      if (!(s >= 2.0 * h_)) return 1;
      const std::uint8_t why = joined_by_[i] & static_cast<std::uint8_t>(~kEarly);
      releasable = releasable || (joined_by_[i] & kEarly) || (why != kByStability && why != kByCluster);
    }
    // The cadences of the cost release and the rest rule, counted from this substep's check. The
    // cost release can free no grain that the stability rule turned soft (but the lookahead's)
    // before its hysteresis, which bounds the coast above: with only such grains soft its checks
    // would find nothing.
    if (releasable) {
      const std::uint64_t since = since_cost_check_ + 1 >= cost_every_ ? 0 : since_cost_check_ + 1;
      s = std::min(s, static_cast<double>(cost_every_ - since) * h_);
    }
    if (sleeping_) {
      const std::uint64_t since = since_sleep_check_ + 1 >= sleep_every_ ? 0 : since_sleep_check_ + 1;
      s = std::min(s, static_cast<double>(sleep_every_ - since) * h_);
    }
    for (int id = this->N_; id < this->N_ + static_cast<int>(this->system_.size()); ++id)
      if (id != substep_id_ && queue_->contains(id)) s = std::min(s, queue_->time_of(id) - t);
    if (!(s >= 2.0 * h_)) return 1;
    bool fixed = false;
    pairs_.for_each([&](const PairEntry& e) {
      if (fixed || !(s >= 2.0 * h_)) return;
      if (mode_[e.i] == kFixed || mode_[e.j] == kFixed) {
        fixed = true;
        return;
      }
      Vec<D> r = hot_[e.i].x - hot_[e.j].x;
      min_image(r);
      s = std::min(s, hybrid::meet_time<D>(r, Vec<D>(vh_[e.i] - vh_[e.j]), hot_[e.i].R + hot_[e.j].R));
    });
    if (fixed || !(s >= 2.0 * h_)) return 1;
    // No soft grain touches anything before t + s: s is at most the soft pairs' meets and the
    // reach to half the list skin (the other bounds only shorten it). Its last grid point strictly
    // before is the free flight's end for the capture checks (free_until_), whose own next check
    // (iface_due_) ends the coast; the plan is computed past it only where that check alone would
    // have cut the coast.
    free_until_ = t + (std::ceil(s / h_) - 1.0) * h_;
    s = std::min(s, iface_due_ - t);
    // The last grid point strictly before s.
    std::int64_t k = static_cast<std::int64_t>(std::floor(s / h_));
    if (static_cast<double>(k) * h_ >= s) --k;
    return k >= 2 ? k : 1;
  }

  // Step 1 of the substep at t after a coast of `steps` grid steps: the free flight in closed form
  // (coast_plan), with the drift's notes (half the skin passed, the cell's box left).
  void coast_drift(double t, std::int64_t steps, int T) {
    std::array<std::uint8_t, kMaxThreads> moved{};
    std::array<double, kMaxThreads> vmax;
    std::fill_n(vmax.begin(), T, 0.0);
    const double kh = static_cast<double>(steps) * h_;
    const Vec<D> dv = kh * g_;
    const Vec<D> dx = (0.5 * h_ * h_ * static_cast<double>(steps) * static_cast<double>(steps + 1)) * g_;
    const double lim2 = 0.25 * lskin_ * lskin_;
    const int* const SOFT = soft_.data();
    const std::size_t nsoft = soft_.size();
    parallel(T, [&, SOFT, nsoft, t](int th) {
      bool dirty = false;
      double vm2 = 0.0;
      std::vector<int>& reloc = t_relocate_[th];
      reloc.clear();
      t_leaving_[th].clear();
      for (std::size_t k = nsoft * th / T, end = nsoft * (th + 1) / T; k < end; ++k) {
        const int i = SOFT[k];
        Hot<D>& h = hot_[i];
        h.x += kh * vh_[i] + dx;
        vh_[i] += dv;
        acc_[i] = g_;
        if (rot_) alpha_[i].setZero();
        h.t = t;
        vm2 = std::max(vm2, (vh_[i] + hdt_ * g_).squaredNorm());
        dirty |= !((h.x - x0_[i]).squaredNorm() <= lim2);
        if (!((h.x.array() >= cblo_[i].array()).all() && (h.x.array() < cbhi_[i].array()).all())) reloc.push_back(i);
      }
      moved[th] = dirty;
      vmax[th] = vm2;
    });
    for (int th = 0; th < T; ++th) {
      if (moved[th]) dirty_ = true;
      vsoft_max_ = std::max(vsoft_max_, std::sqrt(vmax[th]));  // the capture distances at t
    }
  }
  static constexpr std::uint64_t kMaxCoast = 1024;

  // The soft grains that entered an outlet in this substep's drift (leaving_) leave the run with
  // their half-step velocity; a sleeper one of them touched has lost a support and is tested for
  // waking at this substep (fz_lost_).
  void remove_soft(double t) {
    std::sort(leaving_.begin(), leaving_.end());  // by id: the order does not depend on the soft set's
    if (sleeping_ && asleep_ > 0)
      pairs_.for_each([&](const PairEntry& e) {
        if (!e.touch) return;
        for (const auto& [i, o] : leaving_) {
          const std::uint32_t k = ui(i) == e.i ? e.j : ui(i) == e.j ? e.i : ui(-1);
          if (k != ui(-1) && mode_[k] == kAsleep) {
            fz_lost_[k] = 1;
            unsupported_.push_back(static_cast<int>(k));
          }
        }
      });
    for (const auto& [i, o] : leaving_) {
      const int s = slot_[i];
      soft_[s] = soft_.back();
      slot_[soft_[s]] = s;
      soft_.pop_back();
      slot_[i] = -1;
      hot_[i].v = vh_[i];
      if (rot_) sys_.w[i] = wh_[i];
      this->remove_particle(i, t, o);
    }
    leaving_.clear();
    dirty_ = true;
  }

  // f(j, shift) for the soft and sleeping grains j that for_neighbours(i) would visit (those in the
  // 3^D cells around i's), with the same image shifts (0 or a periodic axis's length, as the
  // grid's walk gives them), in the soft set's and then the sleepers' order. Only while
  // direct_cells_: a grid of linear cells with at least three along each periodic axis, so that
  // each neighbour cell is one cell and one image.
  template <class F>
  void for_soft_near(int i, F&& f) const {
    const std::array<int, D>& ci = cold_[i].cell;
    const auto visit = [&](int j) {
      const std::array<int, D>& cj = cold_[j].cell;
      Vec<D> shift = Vec<D>::Zero();
      for (int k = 0; k < D; ++k) {
        const int d = cj[k] - ci[k];
        if (d >= -1 && d <= 1) continue;
        const int n = grid_.count(k);
        if (!grid_.periodic(k)) return;
        if (ci[k] == 0 && cj[k] == n - 1) {
          shift[k] = -grid_.length(k);  // the cell below wraps to the top one: j's image below
        } else if (ci[k] == n - 1 && cj[k] == 0) {
          shift[k] = grid_.length(k);
        } else {
          return;
        }
      }
      f(j, shift);
    };
    for (const int j : soft_) visit(j);
    for (const int j : asleep_list_) visit(j);
  }
  static constexpr std::size_t kDirectSoft = 16;
  bool direct_cells_ = false;

  // Hard interface particles within the skin of a soft (or sleeping) one join the soft set.
  void capture(double t) {
    // Nothing due before iface_due_ (the earliest check of the list, brought forward by every
    // change to it): the scan would keep every entry as it is.
    if (t < iface_due_) return;
    iface_due_ = kNever;  // brought forward by what the joins below change
    // A few soft and sleeping grains: each check looks at them directly instead of walking the
    // 3^D cells around the hard grain (the same grains, images and arithmetic: for_soft_near).
    const bool direct = soft_.size() + asleep_list_.size() <= kDirectSoft && direct_cells_;
    double due = kNever;
    std::size_t keep = 0;
    const std::size_t n = iface_.size();
    for (std::size_t k = 0; k < n; ++k) {
      const int i = iface_[k];
      if (mode_[i] != kHard) {
        iface_flag_[i] = 0;
        continue;
      }
      if (t < iface_next_[i]) {  // too far from every soft particle to reach the skin yet
        due = std::min(due, iface_next_[i]);
        iface_[keep++] = i;
        continue;
      }
      const Hot<D>& hi = hot_[i];
      const double dt = t - hi.t;
      const Vec<D> xi = this->position_at(i, t);
      bool any = false, in = false;
      double gmin = kNever, smin = kNever;
      const Vec<D> vvi = hi.v + g_ * dt;
      const double vi = vvi.norm();
      const double reach = capture_gap(vi);
      // In the soft set's free flight (free_until_) each soft grain's course relative to i is a
      // straight line at the grid points, u = v_i - v_j(t - h/2) - g h / 2 (the leapfrog's
      // positions against i's parabola: the terms in g s^2 cancel), and i comes within its capture
      // distance of j no sooner than that line does. Its distance there is bounded by the speeds
      // gravity may add over the longest skip (i's, and twice the fastest soft grain's).
      const bool exact = t < free_until_;
      const double span = kMaxSkip * h_;
      const double reach_max = exact ? capture_gap(vi + 3.0 * g_.norm() * span) : 0.0;
      const Vec<D> ui = vvi - hdt_ * g_;
      const auto near = [&](int j, const Vec<D>& shift) {
        const std::uint8_t m = mode_[j];
        if (m != kSoft && m != kAsleep) return;
        any = true;
        const double cut = hi.R + hot_[j].R + reach;
        const Vec<D> r = xi - hot_[j].x - shift;
        const double d2 = r.squaredNorm();
        if (d2 < cut * cut) {
          in = true;
        } else {
          gmin = std::min(gmin, std::sqrt(d2) - cut);
          if (exact) smin = std::min(smin, hybrid::meet_time<D>(r, Vec<D>(ui - vh_[j]), hi.R + hot_[j].R + reach_max));
        }
      };
      if (direct) {
        for_soft_near(i, near);
      } else {
        for_capture_range(i, near);
      }
      if (in) {
        iface_flag_[i] = 0;
        join(i, t, kByCapture);
      } else if (any) {
        // The next check: the gap beyond the skin cannot close before gmin / (closing speed
        // bound): i's speed (plus what gravity adds over the longest skip) and twice the fastest
        // soft particle's. At most kMaxSkip substeps; a collision of i or a soft particle moving
        // next to it brings the check forward (predict, mark_interface).
        // In the soft set's free flight, the later of that bound and the time the straight courses
        // bring i within the largest capture distance of a soft grain (or the free flight's end).
        const double vb = vi + g_.norm() * span + 2.0 * vsoft_max_;
        double skip = vb > 0.0 ? gmin / vb : span;
        if (exact) skip = std::max(skip, std::min(smin, free_until_ - t));
        iface_next_[i] = t + std::min(span, skip);
        due = std::min(due, iface_next_[i]);
        iface_[keep++] = i;
      } else {
        iface_flag_[i] = 0;
      }
    }
    // Particles marked during the joins above were appended after n.
    if (iface_.size() > n) due = 0.0;
    for (std::size_t k = n; k < iface_.size(); ++k) iface_[keep++] = iface_[k];
    iface_.resize(keep);
    iface_due_ = std::min(iface_due_, due);
  }

  // Contact forces of the soft set at time t: the soft path's pair loop and wall contacts
  // (engine/soft/forces.hpp) with the hybrid's policy. A contact present at the run's first force
  // evaluation (t = 0: particles that start overlapping) began before the run: no onset weight.
  void soft_forces(double t) {
    wall_t_ = t;
    walls_.refresh(t, 0.5 * h_);
    switch (plan_.law) {
      case NormalLaw::Linear:
        rolling_ ? soft_forces_law<NormalLaw::Linear, true, true>()
        : rot_   ? soft_forces_law<NormalLaw::Linear, true>()
                 : soft_forces_law<NormalLaw::Linear, false>();
        break;
      case NormalLaw::Hertz:
        rolling_ ? soft_forces_law<NormalLaw::Hertz, true, true>()
        : rot_   ? soft_forces_law<NormalLaw::Hertz, true>()
                 : soft_forces_law<NormalLaw::Hertz, false>();
        break;
      case NormalLaw::Viscoelastic:
        rolling_ ? soft_forces_law<NormalLaw::Viscoelastic, true, true>()
        : rot_   ? soft_forces_law<NormalLaw::Viscoelastic, true>()
                 : soft_forces_law<NormalLaw::Viscoelastic, false>();
        break;
    }
  }

  // The run's first force evaluation (t = 0, particles that start overlapping) gives a(0) only, as in
  // TDM (engine/soft/verlet.hpp start_half_step): v(-h/2) = v(0) - h/2 a(0), springs unstretched.
  void start_soft_state() {
    for (const int i : soft_) {
      vh_[i] = hot_[i].v;
      soft::start_half_step(vh_[i], f_[i], minv_[i], g_, hdt_);
      if (rot_) {
        wh_[i] = sys_.w[i];
        soft::start_half_step_spin(wh_[i], tq_[i], iinv_[i], hdt_);
      }
    }
    for (auto& x : pairs_.xi) x.setZero();
    for (auto& m : pairs_.mr) m.setZero();
    for (auto& e : we_) e.xi.setZero();
    for (auto& m : wmr_) m.setZero();
  }

  // What the soft path's loop does differently here: rows are the soft particles' (any order),
  // touching and nearby particles are flagged for the release rule, a sleeping end (rest rule) is
  // pushed by the springs only and wakes when approached fast or when a contact opens, and the
  // virial of the contact forces adds to the hard collisions'.
  template <bool Rot, bool Periodic>
  struct SoftPolicy {
    static constexpr bool kSleepers = true, kNear = true, kVirial = true, kOwners = true, kShifts = Periodic,
                          kSparseRows = true;
    const SoftContact* C;
    const std::uint32_t* cidx;
    std::uint8_t* TOUCHING;
    std::uint8_t* NEAR;
    const std::uint8_t* MODE;
    std::uint8_t* LOST;
    double skin;
    RestRule rest;
    bool onset_ok, sleepers;
    std::uint64_t begun = 0;
    double vir = 0.0;
    bool fixed_j = false;  // the last partner() was a fixed grain
    // Threads (soft_forces_law): this thread's index; a force on a particle this thread does not
    // own (OWN, written before the loop) is spilled and added after it in thread order. The flags
    // and counters of a partner may be another thread's: relaxed atomic stores (a plain store
    // on x86) and, for the rare count of contacts begun, atomic increments.
    const std::uint8_t* OWN = nullptr;  // null: one thread, everything direct
    std::uint8_t tid = 0;
    std::vector<Spill>* spill = nullptr;

    bool mine(std::uint32_t k) const { return !OWN || OWN[k] == tid; }
    bool onset() const { return onset_ok; }
    const SoftContact& contact(std::uint32_t e, std::uint32_t, std::uint32_t, SoftContact&) const { return C[cidx[e]]; }
    // The batched loop's constants (engine/soft/batch.hpp): each entry's in the table; one law.
    static constexpr bool kTable = true;
    const SoftContact* table() const { return C; }
    std::uint32_t contact_index(std::uint32_t e) const { return cidx[e]; }
    bool clip() const { return clip_law; }
    bool clip_law = true;
    std::uint32_t* BEGUN = nullptr;  // contacts begun per particle since its last cost check
    void began(std::uint32_t i, std::uint32_t j) {
      ++begun;
      bump(BEGUN[i]);
      bump(BEGUN[j]);
    }
    void opened(std::uint32_t i, std::uint32_t j) {
      // A sleeper that loses a contact wakes (its support may be gone).
      if (sleepers) {
        if (MODE[i] == kAsleep) flag(LOST[i]);
        if (MODE[j] == kAsleep) flag(LOST[j]);
      }
    }
    void overlap(double, double) {}
    void touching(std::uint32_t i, std::uint32_t j) {
      flag(TOUCHING[i]);
      flag(TOUCHING[j]);
    }
    // Release needs no particle within the capture distance, save a fixed one (a hard grain meets it in
    // EDM without being captured).
    void near(std::uint32_t i, std::uint32_t j) {
      if (MODE[j] != kFixed) {
        flag(NEAR[i]);
        flag(NEAR[j]);
      }
    }
    double near_skin() const { return skin; }
    bool any_asleep() const { return sleepers; }
    bool asleep(std::uint32_t i) const { return MODE[i] == kAsleep; }
    bool approached(double un) const { return rest.approached(un); }
    void wake(std::uint32_t k) { flag(LOST[k]); }
    [[gnu::always_inline]] void own_force(Vec<D>* FF, std::uint32_t i, const Vec<D>& f) {
      if (mine(i)) FF[i] += f;
      else spill->push_back({i, f, Spin<D>::Zero()});
    }
    [[gnu::always_inline]] void own_torque(Spin<D>* TQ, std::uint32_t i, const Spin<D>& t) {
      if (mine(i)) TQ[i] += t;
      else spill->push_back({i, Vec<D>::Zero(), t});
    }
    [[gnu::always_inline]] void partner(Vec<D>* FF, Spin<D>* TQ, std::uint32_t j, const Vec<D>& f, const Spin<D>& t) {
      fixed_j = MODE[j] == kFixed;
      if (fixed_j) return;  // a fixed grain is never integrated
      if (!mine(j)) {
        spill->push_back({j, Vec<D>(-f), Rot ? t : Spin<D>(Spin<D>::Zero())});
        return;
      }
      FF[j] -= f;
      if constexpr (Rot) TQ[j] += t;
    }
    // (called after partner: a contact with a fixed grain is a boundary's, as a wall's: no virial)
    void virial(const Vec<D>& F, const Vec<D>& dx) {
      if (!fixed_j) vir += F.dot(dx);
    }
    void row_done(std::uint32_t) {}
  };

  template <NormalLaw Law, bool Rot, bool Roll = false>
  void soft_forces_law() {
    any_periodic_ ? soft_forces_law<Law, Rot, Roll, true>() : soft_forces_law<Law, Rot, Roll, false>();
  }
  // The pair rows split among T threads by their entries (rlo_), each thread then owning the
  // particles whose rows all lie in its range (own_; kShared: rows in several ranges, or none); a
  // thread computes its rows' pair forces and its own particles' wall contacts (thread 0 also
  // those of the particles no thread owns: kUnowned, kMulti), spilling forces on particles it does
  // not own; the spills are added after the loop in thread order, so a run is deterministic for a
  // given thread count. One thread: everything in row order, then the walls in list order.
  template <NormalLaw Law, bool Rot, bool Roll, bool Periodic>
  MATEP_FLATTEN void soft_forces_law() {
    const double h = h_;
    const bool onset_ok = wall_t_ > 0.0;
    const int T = threads_for(soft_.size());
    const std::uint32_t rows = static_cast<std::uint32_t>(pairs_.rows());
    // The split and the owners, made again when the rows or the thread count changed.
    if (T != split_T_ || pairs_.layout() != split_layout_) {
      split_T_ = T;
      split_layout_ = pairs_.layout();
      rlo_.assign(static_cast<std::size_t>(T) + 1, rows);
      rlo_[0] = 0;
      for (int t = 1; t < T; ++t) {
        const std::uint32_t target = static_cast<std::uint32_t>(pairs_.size() * static_cast<std::size_t>(t) / T);
        rlo_[t] = static_cast<std::uint32_t>(std::lower_bound(pairs_.off.begin(), pairs_.off.begin() + rows, target) -
                                             pairs_.off.begin());
      }
      for (const std::uint32_t k : own_set_) own_[k] = kUnowned;
      own_set_.clear();
      if (T > 1)
        for (int t = 0; t < T; ++t)
          for (std::uint32_t r = rlo_[t]; r < rlo_[t + 1]; ++r) {
            std::uint8_t& o = own_[pairs_.owner[r]];
            if (o == kUnowned) own_set_.push_back(pairs_.owner[r]);
            o = (o == kUnowned || o == t) ? static_cast<std::uint8_t>(t) : kMulti;
          }
    }
    std::array<std::uint64_t, kMaxThreads> begun;  // (only the T slots in use are cleared)
    std::fill_n(begun.begin(), T, std::uint64_t{0});
    // A soft grain is "near" another (the single release waits) within the capture distance.
    const double near_skin = capture_gap(vsoft_max_);
    std::array<double, kMaxThreads> vir;
    std::fill_n(vir.begin(), T, 0.0);
    auto body = [&](int th) {
      SoftPolicy<Rot, Periodic> pol{ctab_.data(), pairs_.c.data(), touching_.data(), near_.data(), mode_.data(),
                                    fz_lost_.data(), near_skin, rest_, onset_ok, asleep_ > 0};
      pol.BEGUN = begun_n_.data();
      pol.tid = static_cast<std::uint8_t>(th);
      if (T > 1) {
        pol.OWN = own_.data();
        spill_[th].clear();
        pol.spill = &spill_[th];
      }
      pol.clip_law = ctab_.empty() || ctab_[0].clip;
      const soft::Records<D, Hot<D>> pos{hot_.data()};
      const auto bodies = soft::bodies_of(vh_, acc_, f_, wh_, alpha_, tq_);
      const auto rows = pairs_.as_rows(shifts_.data());
      if constexpr (!Roll)
        soft::pair_rows_batched<D, Law, Rot>(pos, bodies, rows, rlo_[th], rlo_[th + 1], h, pol, batch_[th]);
      else
        soft::pair_rows<D, Law, Rot, Roll>(pos, bodies, rows, rlo_[th], rlo_[th + 1], h, pol);
      std::uint64_t b = pol.begun;
      const Spin<D> no_spin = Spin<D>::Zero();
      Spin<D> tq_none = Spin<D>::Zero();
      WallLoads<D>& loads = th == 0 ? wall_loads_ : loads_t_[th];
      for (auto& e : we_) {
        const int i = e.i;
        if (T > 1 && own_[i] != th && !(th == 0 && own_[i] >= T)) continue;
        bool began = false;
        const soft::WallContact<D> c = walls_.with_wall(e.w, e.f, [&](const auto& shape) {
          return soft::wall_contact<D, Law, Rot, Roll>(shape, wall_t_, h, onset_ok, hot_[i].x, hot_[i].R, vh_[i],
                                                       acc_[i], Rot ? wh_[i] : no_spin, Rot ? alpha_[i] : no_spin,
                                                       ctab_[e.c], e.touch, e.xi, began, f_[i],
                                                       Rot ? tq_[i] : tq_none, wall_mr(e));
        });
        if (began) {
          ++b;
          bump(begun_n_[i]);
        }
        if (c.delta > 0.0) {
          flag(touching_[i]);
          loads.add(static_cast<std::size_t>(e.w), anchors_[e.w], c.point, -h * c.force);
        }
      }
      begun[th] = b;
      vir[th] = pol.vir;
    };
    if (batch_.size() < static_cast<std::size_t>(T)) batch_.resize(static_cast<std::size_t>(T));
    parallel(T, body);
    std::uint64_t b = 0;
    double v = 0.0;
    for (int t = 0; t < T; ++t) {
      b += begun[t];
      v += vir[t];
    }
    if (T > 1) {
      for (int t = 0; t < T; ++t) {
        for (const Spill& sp : spill_[t]) {
          f_[sp.j] += sp.f;
          if constexpr (Rot) tq_[sp.j] += sp.t;
        }
        if (t > 0) {
          wall_loads_.add(loads_t_[t]);
          loads_t_[t].clear();
        }
      }
    }
    hstats_soft_begun_ += b;
    virial_ += v * h;  // impulse times distance over the substep, as the hard collisions
  }

  // Elastic energy stored in the soft contacts (engine/tdm/tdm.cpp sample()).
  // The soft set's touching contacts (Snapshot::contacts, kind 1; engine/soft/contact_rows.hpp), each
  // at its grains' last substep: pairs (sleepers' included), then walls.
  void soft_contact_rows(std::vector<ContactRow<D>>& rows) const {
    auto body = [&](int i) {
      const Spin<D> w = sys_.w.empty() ? Spin<D>(Spin<D>::Zero()) : sys_.w[i];
      return soft::RowBody<D>{static_cast<std::uint32_t>(i), hot_[i].x, hot_[i].R, hot_[i].v, w};
    };
    auto pair = [&](const PairEntry& e) {
      if (!e.touch) return;
      const int i = static_cast<int>(e.i), j = static_cast<int>(e.j);
      Vec<D> dx = hot_[i].x - hot_[j].x;
      min_image(dx);
      if (dx.squaredNorm() >= (hot_[i].R + hot_[j].R) * (hot_[i].R + hot_[j].R)) return;
      rows.push_back(soft::pair_row<D>(ctab_[e.c], body(i), body(j), dx, e.xi));
    };
    pairs_.for_each(pair);
    for (const auto& e : pe_sleep_) pair(e);
    for (const auto* list : {&we_, &we_sleep_})
      for (const auto& e : *list) {
        if (!e.touch) continue;
        const WallPoint<D> p = shapes_[e.w]->at_feature(hot_[e.i].x, hot_[e.i].R, hot_[e.i].t, e.f);
        if (p.gap < 0.0) rows.push_back(soft::wall_row<D>(ctab_[e.c], body(e.i), e.w, p, e.xi));
      }
  }

  double soft_elastic_energy() const {
    double el = 0.0;
    auto stored = [](const SoftContact& c, double delta, const Vec<D>& xi) { return stored_energy<D>(c, delta, xi); };
    auto pair = [&](const PairEntry& e) {
      if (!e.touch) return;
      Vec<D> dx = hot_[e.i].x - hot_[e.j].x;
      min_image(dx);
      const double delta = hot_[e.i].R + hot_[e.j].R - dx.norm();
      if (delta > 0.0) el += stored(ctab_[e.c], delta, e.xi);
    };
    pairs_.for_each(pair);
    for (const auto& e : pe_sleep_) pair(e);
    for (const auto* list : {&we_, &we_sleep_})
    for (const auto& e : *list) {
      if (!e.touch) continue;
      const double delta = -shapes_[e.w]->at_feature(hot_[e.i].x, hot_[e.i].R, hot_[e.i].t, e.f).gap;
      if (delta > 0.0) el += stored(ctab_[e.c], delta, e.xi);
    }
    return el;
  }

  // Soft cluster ids (connected by touching contacts; -1 for hard particles).
  std::vector<std::int32_t> soft_clusters() const {
    std::vector<std::int32_t> parent(N_);
    for (int i = 0; i < N_; ++i) parent[i] = i;
    auto find = [&](int a) {
      while (parent[a] != a) a = parent[a] = parent[parent[a]];
      return a;
    };
    auto pair = [&](const PairEntry& e) {
      if (!e.touch || mode_[e.j] == kFixed) return;  // fixed grains join no cluster
      const int a = find(static_cast<int>(e.i)), b = find(static_cast<int>(e.j));
      if (a != b) parent[std::max(a, b)] = std::min(a, b);
    };
    pairs_.for_each(pair);
    for (const auto& e : pe_sleep_) pair(e);
    std::vector<std::int32_t> id(N_, -1), label(N_, -1);
    std::int32_t next = 0;
    for (int i = 0; i < N_; ++i) {
      if (mode_[i] != kSoft && mode_[i] != kAsleep) continue;
      const int r = find(i);
      if (label[r] < 0) label[r] = next++;
      id[i] = label[r];
    }
    return id;
  }

  // Overlapping particles (and particles overlapping a wall) at t = 0 start soft.
  void hybrid_start() {
    for (int i = 0; i < N_; ++i) {
      if (mode_[i] == kFixed || mode_[i] == kGone) continue;  // never soft (a moving grain overlapping it is)
      bool over = false;
      for (const WallShape<D>* W : shapes_) over = over || W->at(hot_[i].x, hot_[i].R, set_.start_time).gap < 0.0;
      if (!over)
        for_neighbours(i, [&](int j, const Vec<D>& shift) {
          const double s = hot_[i].R + hot_[j].R;
          over = over || (hot_[i].x - hot_[j].x - shift).squaredNorm() < s * s;
        });
      if (over) {
        set_mode(i, kPending);
        pending_.push_back(i);
        pending_reason_.push_back(kByOverlap);
      }
    }
    if (!pending_.empty()) start_clock(set_.start_time);
  }

  // ---- rest rule: sleeping particles ----
  //
  // A sleeper i keeps, from the moment it fell asleep, its static net contact force and torque
  // B_i (springs only: it was at rest) and the wake threshold W_i. Its contacts with sleepers and
  // walls are frozen in pe_sleep_/we_sleep_ (constant: neither end moves); its contacts with awake
  // particles are evaluated at every substep in pairs_ (it is an immovable body for them), and their
  // sum is compared with M_i, the part of B_i they carried: M_i = B_i - (the frozen part), updated
  // whenever a contact moves between the two lists. The net force on i is then
  // f_mixed + B_i - M_i, and i wakes when it differs from B_i by more than W_i.

  // Puts to sleep every awake soft particle that has been quiet at the last four checks (a quarter
  // rest_time apart: speed, with the surface speed of its spin R w, below rest_speed), is in
  // static equilibrium (its contact springs and gravity cancel to within W_i), and has no
  // oscillating wall within the list skin.
  void freeze_quiet(double t) {
    if (soft_.empty()) return;
    for (const int i : soft_) {
      double s2 = hot_[i].v.squaredNorm();
      if (rot_) s2 += sys_.w[i].squaredNorm() * hot_[i].R * hot_[i].R;
      quiet_checks_[i] = rest_.quiet(quiet_checks_[i], s2);
      fz_step_[i] = hot_[i].x - x_check_[i];
      min_image(fz_step_[i]);  // (a grain that crossed a periodic face since)
      x_check_[i] = hot_[i].x;
    }
    for (const auto& e : we_)
      if (shapes_[e.w]->moving()) quiet_checks_[e.i] = 0;
    bool any = false;
    for (const int i : soft_) {
      const bool c = RestRule::candidate(quiet_checks_[i]);
      fz_cand_[i] = c;
      any |= c;
      if (c) {
        fz_base_[i].setZero();
        fz_mix_[i].setZero();
        if (rot_) {
          fz_tbase_[i].setZero();
          fz_tmix_[i].setZero();
        }
        fz_scale_[i] = 0.0;  // first the sum of its contact stiffnesses
      }
    }
    if (!any) return;
    // 1. The static net contact force of each candidate and its mean contact force.
    pairs_.for_each([&](const PairEntry& e) {
      if (!(fz_cand_[e.i] || fz_cand_[e.j])) return;
      if (!e.touch) {  // settled: a contact about to form keeps both ends awake
        Vec<D> dx = hot_[e.i].x - hot_[e.j].x;
        min_image(dx);
        const double r = dx.norm(), sig = hot_[e.i].R + hot_[e.j].R, gap = r - sig;
        if (!(gap > 0.0)) return;
        // The gap at the last check: a soft end has moved by its step since (every soft grain
        // was checked then; a sleeper or fixed grain has not moved).
        Vec<D> before = dx;
        if (mode_[e.i] == kSoft) before -= fz_step_[e.i];
        if (mode_[e.j] == kSoft) before += fz_step_[e.j];
        if (RestRule::closing(gap, (hot_[e.i].v - hot_[e.j].v).dot(dx) / r, rest_time_) ||
            RestRule::closing_trend(gap, before.norm() - sig))
          fz_cand_[e.i] = fz_cand_[e.j] = 0;
        return;
      }
      const StaticForce sf = static_pair_force(e);
      const double k_n = normal_stiffness(ctab_[e.c], sf.delta);
      for (const int k : {static_cast<int>(e.i), static_cast<int>(e.j)}) {
        if (!fz_cand_[k]) continue;
        add_share(fz_base_, fz_tbase_, k, e, sf, 1.0);
        fz_scale_[k] += k_n;
      }
    });
    for (const auto& e : we_) {
      if (!e.touch || !fz_cand_[e.i]) continue;
      const StaticForce sf = static_wall_force(e, t);
      fz_base_[e.i] += sf.f;
      if (rot_) fz_tbase_[e.i] += sf.ti;
      fz_scale_[e.i] += normal_stiffness(ctab_[e.c], sf.delta);
    }
    // 2. Candidates in equilibrium fall asleep.
    std::size_t keep = 0;
    const std::size_t n = soft_.size();
    for (std::size_t k = 0; k < n; ++k) {
      const int i = soft_[k];
      if (fz_cand_[i]) {
        fz_cand_[i] = 0;
        const double m = mass(i);
        // Wake threshold W (engine/hybrid/rest.hpp) from the sum of its contact stiffnesses.
        fz_scale_[i] = rest_.wake_threshold(m, fz_scale_[i]);
        if (RestRule::balanced(fz_base_[i], m, g_, fz_scale_[i])) {
          freeze(i);
          fz_cand_[i] = 1;  // now: fell asleep at this check
          fresh_.push_back(i);
          continue;
        }
      }
      slot_[i] = static_cast<int>(keep);
      soft_[keep++] = i;
    }
    if (keep == n) return;
    soft_.resize(keep);
    // 3. The new sleepers' entries: a pair of two sleepers is frozen (set aside if touching, with
    // its static force leaving the mixed part of an older sleeper's balance); a pair with an awake
    // particle stays, and its static force is the new sleeper's mixed part.
    pairs_.filter([&](const PairEntry& e) {
      const bool ni = fz_cand_[e.i], nj = fz_cand_[e.j];
      if (!ni && !nj) return true;
      const StaticForce sf = e.touch ? static_pair_force(e) : StaticForce{};
      // Both ends still (asleep or fixed): frozen; a fixed end keeps no balance.
      if (still(e.i) && still(e.j)) {
        if (!ni && mode_[e.i] == kAsleep) add_share(fz_mix_, fz_tmix_, static_cast<int>(e.i), e, sf, -1.0);
        if (!nj && mode_[e.j] == kAsleep) add_share(fz_mix_, fz_tmix_, static_cast<int>(e.j), e, sf, -1.0);
        if (e.touch) pe_sleep_.push_back(e);
        return false;
      }
      const int k = static_cast<int>(ni ? e.i : e.j);  // the new sleeper; the other end is awake
      add_share(fz_mix_, fz_tmix_, k, e, sf, 1.0);
      watch(k);
      return true;
    });
    std::size_t kw = 0;
    for (const auto& e : we_) {
      if (!fz_cand_[e.i]) {
        we_[kw++] = e;
      } else if (e.touch) {
        we_sleep_.push_back(e);
      }
    }
    we_.resize(kw);
    for (const int i : fresh_) fz_cand_[i] = 0;
    fresh_.clear();
  }

  bool still(std::uint32_t i) const { return mode_[i] == kAsleep || mode_[i] == kFixed; }

  void freeze(int i) {
    set_mode(i, kAsleep);
    free_until_ = -kNever;  // (a sleeper stops: no longer on its free course)
    slot_[i] = -1;
    quiet_checks_[i] = 0;
    hot_[i].v.setZero();
    vh_[i].setZero();
    acc_[i].setZero();
    f_[i].setZero();
    if (rot_) {
      sys_.w[i].setZero();
      wh_[i].setZero();
      alpha_[i].setZero();
      tq_[i].setZero();
    }
    ++asleep_;
    ++hstats_.slept;
    asleep_slot_[i] = static_cast<int>(asleep_list_.size());
    asleep_list_.push_back(i);
  }

  // The wake test of the watched sleepers after the forces of substep t (f_, tq_ hold the forces
  // of their awake neighbours). A sleeper whose net contact force has moved from its value at
  // sleep by more than its threshold wakes, at rest, with that force and torque; its frozen
  // contacts join pairs_ (the sleepers among their other ends are watched from now on) and its
  // sleeping neighbours within the list skin get entries.
  void wake_loaded(double t) {
    woken_.clear();
    for (const int j : watched_) {
      if (mode_[j] != kAsleep) continue;
      touching_[j] = near_[j] = 0;
      const Vec<D> dev = f_[j] - fz_mix_[j];
      const bool lost = fz_lost_[j];
      fz_lost_[j] = 0;
      if (lost || RestRule::loaded(dev, fz_scale_[j])) {
        f_[j] = dev + fz_base_[j];
        if (rot_) tq_[j] += fz_tbase_[j] - fz_tmix_[j];
        set_mode(j, kSoft);
        slot_[j] = static_cast<int>(soft_.size());
        soft_.push_back(j);
        x0_[j] = hot_[j].x;
        set_free_reach(j);
        hot_[j].t = t;
        last_contact_[j] = t;
        --asleep_;
        ++hstats_.woken;
        woken_.push_back(j);
        const int q = asleep_slot_[j];
        asleep_list_[q] = asleep_list_.back();
        asleep_slot_[asleep_list_[q]] = q;
        asleep_list_.pop_back();
        asleep_slot_[j] = -1;
      } else {
        f_[j].setZero();
        if (rot_) tq_[j].setZero();
      }
    }
    if (woken_.empty()) return;
    start_clock(t);
    // Frozen contacts with a woken end join pairs_; a sleeper at the other end gets them in its mixed
    // part.
    moved_.clear();
    std::size_t ks = 0;
    for (const auto& e : pe_sleep_) {
      const bool ai = mode_[e.i] == kAsleep, aj = mode_[e.j] == kAsleep;
      if (still(e.i) && still(e.j)) {
        pe_sleep_[ks++] = e;
        continue;
      }
      if (ai || aj) {
        const int k = static_cast<int>(ai ? e.i : e.j);
        add_share(fz_mix_, fz_tmix_, k, e, static_pair_force(e), 1.0);
        watch(k);
      }
      pairs_.push(e);
      moved_.push_back(pkey(e.i, e.j));
    }
    pe_sleep_.resize(ks);
    std::size_t kw = 0;
    moved_w_.clear();
    for (const auto& e : we_sleep_) {
      if (mode_[e.i] == kAsleep) {
        we_sleep_[kw++] = e;
      } else {
        we_.push_back(e);
        moved_w_.push_back(key(ui(e.i), wall_slot(ui(e.w), e.f)));
      }
    }
    we_sleep_.resize(kw);
    std::sort(moved_w_.begin(), moved_w_.end());
    // Sleeping neighbours within the list skin that it did not touch; walls it did not touch.
    std::sort(moved_.begin(), moved_.end());
    for (const int j : woken_) {
      const Vec<D> xj = hot_[j].x;
      const double Rj = hot_[j].R;
      this->for_neighbours_reach(j, sg_w_, [&](int k, const Vec<D>& shift) {
        if (!still(ui(k))) return;
        const double cut = Rj + hot_[k].R + lskin_;
        if ((xj - hot_[k].x - shift).squaredNorm() >= cut * cut) return;
        if (std::binary_search(moved_.begin(), moved_.end(), pkey(ui(j), ui(k)))) return;
        pairs_.push({ui(j), ui(k), pair_contact_of(j, k), image_of(shift), 0, Vec<D>::Zero()});
        if (mode_[k] == kAsleep) watch(k);
      });
      walls_in_reach(j, t, [&](int w, std::uint32_t f) {
        if (!std::binary_search(moved_w_.begin(), moved_w_.end(), key(ui(j), wall_slot(ui(w), f))))
          we_.push_back(new_wall_entry(j, w, f));
      });
    }
  }

  void hybrid_result(RunResult<D>& res) {
    res.method = Method::Hybrid;
    res.hybrid_cost = {meter_.ratio(), 1e9 * meter_.hard_seconds_per_collision(), 1e9 * meter_.soft_seconds_per_step(),
                       hset_.cost_measured};
    HybridStats& s = hstats_;
    s.stability = kstab_;
    s.hysteresis = hyst_;
    s.skin = skin_;
    s.cost_ratio = cost_ratio_;
    s.rest_speed = hset_.rest_speed;
    s.rest_time = rest_time_;
    s.soft_at_end = soft_.size() + asleep_;
    res.hybrid = s;
    res.mode.resize(N_);
    for (int i = 0; i < N_; ++i) res.mode[i] = mode_[i] == kPending ? std::uint8_t{kHard} : mode_[i];
    SoftStats& t = res.soft;
    t.steps = hstats_.substeps;
    t.dt = h_;
    record_plan(t, plan_);
    t.skin = skin_;
    t.rebuilds = hstats_.rebuilds;
    for (const auto f : pairs_.touch) t.contacts += f;
    for (const auto& e : we_) t.contacts += e.touch;
    t.contacts += pe_sleep_.size() + we_sleep_.size();
    t.threads = threads_used_;  // the most the soft set used (threads_for: fewer while it is small)
  }

  // Checkpoints (engine/state_archive.hpp): the core's state, then everything of the soft set,
  // the switching and rest rules and the substep clock (what setup makes from the scene and the
  // settings is made again; the walls are refreshed at every substep).
  template <class A>
  void archive(A& a) {
    Base::archive_core(a);
    a.tag("hybrid.clock");
    a.check(h_, "the substep");
    a.check(T_req_, "threads");  // the force sums' order (a run is deterministic for a given count)
    a(threads_used_);
    a(build_t_);
    a(clock_);
    a(clock_t0_);
    a(clock_n_);
    a(sub_last_n_);  // a stop at a substep may come with a coast planned after it
    a(dirty_);
    a(purge_);
    a(asleep_);
    a(hstats_soft_begun_);
    a(hstats_);
    a.tag("hybrid.soft");
    for (auto* v : {&vh_, &acc_, &f_, &x0_, &cblo_, &cbhi_, &fz_base_, &fz_mix_, &x_check_}) a(*v);
    for (auto* v : {&wh_, &alpha_, &tq_, &wmr_, &fz_tmix_, &fz_tbase_}) a(*v);
    for (auto* v : {&minv_, &iinv_, &last_contact_, &iface_next_, &rate_t0_, &fz_scale_, &region_retry_}) a(*v);
    for (auto* v : {&quiet_checks_, &slot_, &soft_, &pending_, &iface_, &group_, &gslot_, &gstart_, &gfill_, &woken_,
                    &fresh_, &asleep_list_, &asleep_slot_, &fixed_list_, &freed_, &unsupported_, &sg_start_,
                    &sg_items_, &sg_cell_, &sg_part_, &sg_fill_, &watched_})
      a(*v);
    for (auto* v : {&pending_reason_, &touching_, &near_, &mode_, &iface_flag_, &cand_, &joined_by_, &fz_cand_,
                    &fz_lost_, &watch_flag_})
      a(*v);
    for (auto* v : {&begun_n_, &held_, &gadj_}) a(*v);
    a(moved_);
    a(moved_w_);
    a(near_pairs_);
    a(leaving_);
    a(vsoft_max_);
    a(iface_due_);  // the coasts' ends depend on it: a resumed run coasts as the first one did
    a(free_until_);
    a.tag("hybrid.contacts");
    a(springs_);
    a(pairs_);
    a(pe_sleep_);
    a(we_);
    a(we_sleep_);
    a(wall_t_);
    a.tag("hybrid.rules");
    a(switch_);
    a(sleep_every_);
    a(since_sleep_check_);
    a(cost_every_);
    a(since_cost_check_);
    a(sg_w_);
    a(sgrid_);
    // (cfree2_ follows from x0_ and the boxes: made again, not stored)
    cfree2_.resize(x0_.size());
    for (std::size_t i = 0; i < x0_.size(); ++i) set_free_reach(static_cast<int>(i));
  }

  // Hybrid state.
  HybridSettings hset_;
  SoftPlan plan_;
  double lskin_ = 0.0;
  double cskin_ = 0.0;  // the largest capture distance (the EDM cells' margin)
  double dmax_ = 0.0;   // the largest diameter (inlets' grains included)
  double sweep_ = 0.0, build_t_ = 0.0;  // the walls' largest sweep speed, the time of the last rebuild
  double h_ = 0.0, hdt_ = 0.0, skin_ = 0.0, kstab_ = 0.0, hyst_ = 0.0, rest_time_ = 0.0;
  double lookahead_ = 0.0;  // hybrid.lookahead: L
  // The lookahead tries collisions within kLookaheadSince L t_c of a previous one; it computes the
  // impact's t_c only for those within kLookaheadSpan times that with the plan's (shortest) t_c: a
  // Hertz t_c grows as v^(-1/5), 10 times at impacts 1e5 times slower.
  static constexpr double kLookaheadSince = 5.0, kLookaheadSpan = 10.0;
  static constexpr double kLookaheadGoesOn = 3.0;  // sequence_goes_on: the second trial's horizon, in dt1
  // ... and only for strongly inelastic impacts, e <= kLookaheadMaxE (engine/hybrid.hpp).
  // A rapid run of impacts at e <= kNoFallMaxE turns soft without the fall of its impact speed.
  static constexpr double kNoFallMaxE = 0.3;
  SwitchRule::Params switch_params_;
  static constexpr int kMeterStride = 8;
  CostMeter meter_{kMeterStride};  // the two methods' costs in this run (engine/hybrid/cost.hpp)
  std::uint64_t meter_n_ = 0;      // substeps seen by the meter (its phase)
  double cost_ratio_ = 10.0; // the cost rule's crossover in use: hybrid.cost_ratio, or measured
  std::uint64_t wrote_ = 0;  // output events seen by the meter
  SwitchRule switch_;  // engine/hybrid/switching.hpp
  RestRule rest_;      // engine/hybrid/rest.hpp
  bool rot_ = false;
  bool rolling_ = false;  // some contact has rolling resistance (the force loops' Roll instantiation)
  bool epsd_ = false;  // Epsd rolling resistance: the contacts carry rolling spring torques
  std::vector<Spin<D>> wmr_;  // the wall entries' rolling spring torques (WallEntry::r), Epsd only
  int substep_id_ = -1;
  bool clock_ = false;
  double clock_t0_ = 0.0;
  std::uint64_t clock_n_ = 0;
  std::int64_t sub_last_n_ = -1;  // the grid index of the last substep (clock_n_ - 1 but in a coast; saved)
  bool coast_scene_ = false;      // no outlet, no moving wall: the soft set may coast
  bool dirty_ = true;
  bool purge_ = false;  // grains released at this substep still have list entries
  std::uint64_t asleep_ = 0;
  std::uint64_t hstats_soft_begun_ = 0;
  HybridStats hstats_;
  std::vector<Vec<D>> vh_, acc_, f_, x0_;  // x0_: position at the last list build (or join)
  std::vector<Spin<D>> wh_, alpha_, tq_;
  std::vector<double> minv_, iinv_, last_contact_;
  std::vector<int> quiet_checks_;
  std::vector<int> slot_, soft_, pending_, iface_;
  std::vector<std::uint8_t> pending_reason_, touching_, near_;
  // Per particle, one byte each (read for every neighbour of a prediction: kept compact).
  std::vector<std::uint8_t> mode_;        // kHard, kSoft, kPending, kAsleep
  std::vector<std::uint8_t> iface_flag_;  // a hard particle on the interface list
  std::vector<double> iface_next_;        // its next capture check (substep time)
  double iface_due_ = 0.0;                // the earliest iface_next_ of the list, or earlier
  double vsoft_max_ = 0.0;                // fastest awake soft particle at the last substep
  std::vector<int> region_;               // region_cheaper_soft's region
  std::vector<std::uint32_t> region_seen_;  // ... its members: region_stamp_ of the search
  std::uint32_t region_stamp_ = 0;
  std::vector<double> region_retry_;        // cost_switch: no region search for a grain before this time
  static constexpr double kMaxSkip = 64.0;
  // The last grid point up to which no soft grain touches anything (coast_plan): each flies freely.
  double free_until_ = -kNever;
  bool uniform_ = false;              // one material and one radius: ctab_ = {pair, wall 0, wall 1, ...}
  std::vector<SoftContact> ctab_;
  soft::SpringMemory<D> springs_;  // contacts remembered across a list build
  soft::PairList<D> pairs_;         // entries with an awake soft end (the soft path's loop)
  std::vector<PairEntry> pe_sleep_;  // touching pairs of two sleepers (frozen)
  std::array<Vec<D>, D == 3 ? 27 : 9> shifts_{};  // periodic image shifts by index (image_of)
  double wall_t_ = 0.0;             // the time of the soft forces being computed
  soft::WallsNow<D> walls_;  // shapes_, planes frozen at the soft forces' time
  std::vector<WallEntry> we_, we_sleep_;
  std::vector<std::uint32_t> feats_;  // walls_in_reach's scratch
  bool sleeping_ = false;                 // rest rule on
  double rest_speed2_ = 0.0;
  std::uint64_t sleep_every_ = 1, since_sleep_check_ = 0;
  double cost_quiet_ = 0.0;                            // release_by_cost: shortest rate window
  std::uint64_t cost_every_ = 1, since_cost_check_ = 0;  // ... and its cadence in substeps
  std::vector<std::uint32_t> begun_n_;  // contacts begun per soft particle since rate_t0_
  std::vector<double> rate_t0_;
  std::vector<std::uint8_t> cand_;      // release_by_cost's candidates
  std::vector<std::uint8_t> joined_by_; // why each soft grain turned soft (kByStability ...; kEarly)
  std::vector<int> early_;               // release_by_cost: the early candidates (hold_unfinished)
  std::vector<int> group_;
  std::uint64_t cost_every_min_ = 1, cost_every_max_ = 1;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> near_pairs_;  // candidates within the skin
  std::vector<std::uint32_t> held_;
  std::vector<int> gslot_, gstart_, gfill_;
  std::vector<std::uint32_t> gadj_;
  // Sleepers (rest rule): static net contact force at sleep and wake threshold; for the watched
  // ones (an awake neighbour in pairs_), the constant force and torque of their sleeping contacts.
  std::vector<Vec<D>> fz_base_, fz_mix_;
  std::vector<Spin<D>> fz_tbase_, fz_tmix_;
  std::vector<int> woken_;
  std::vector<int> fresh_, asleep_list_, asleep_slot_;
  std::vector<int> fixed_list_;  // the fixed grains (kFixed)
  // Soft grid (soft_grid_build): the one cell grid (engine/grid.hpp) over the soft set. Its width,
  // 2 rmax + lskin_, is the largest centre distance of a soft list entry.
  double sg_w_ = 0.0;
  CellGrid<D> sgrid_;
  bool any_periodic_ = false;
  std::vector<Vec<D>> cblo_, cbhi_;  // the box a soft particle may move in without relocating
  std::vector<double> cfree2_;       // how far (squared) from x0_ it stays inside it (set_free_reach)
  // The last substep's closing pass drifted the soft set to this one (substep, step 5): its
  // threads' notes are in t_relocate_, t_leaving_ (predrift_T_ of them), predrift_moved_.
  bool predrifted_ = false, predrift_moved_ = false;
  int predrift_T_ = 1;
  std::vector<int> freed_;           // soft particles released at this substep
  std::vector<std::pair<int, int>> leaving_;  // (soft particle, outlet) entered at this substep
  std::vector<int> unsupported_;     // sleepers that touched a grain that left
  std::vector<int> sg_start_, sg_items_, sg_cell_, sg_part_, sg_fill_;
  std::vector<int> ss_start_, ss_items_;  // the sleepers and fixed grains in the same cells
  bool sg_half_ = false;                  // the rows' walk takes the half stencil (soft_grid_build)
  std::vector<std::uint64_t> moved_, moved_w_;
  std::vector<double> fz_scale_;
  // The rest rule's gap trend: each soft grain's position at its last check (or join), and its
  // move since (scratch of one check, freeze_quiet).
  std::vector<Vec<D>> x_check_;
  std::vector<Vec<D>> fz_step_;
  std::vector<int> watched_;
  std::vector<std::uint8_t> fz_cand_, fz_lost_, watch_flag_;
  // Threads (threads_for): the count asked for; the force loop's row ranges, particle owners and
  // spills, the other threads' wall loads; the drift's and the full step's per-thread lists.
  int T_req_ = 1, threads_used_ = 1;
  std::size_t min_per_thread_ = 2048;
  std::vector<std::uint32_t> rlo_;
  std::vector<std::uint8_t> own_;
  std::vector<std::uint32_t> own_set_;  // the particles own_ names an owner for
  int split_T_ = 0;                     // rlo_ and own_ are for this thread count ...
  std::uint64_t split_layout_ = ~std::uint64_t{0};  // ... and this layout of the rows
  std::vector<std::vector<Spill>> spill_;
  std::vector<soft::ContactBatch<D>> batch_;  // each thread's scratch of the batched pair loop
  std::vector<WallLoads<D>> loads_t_;
  std::vector<std::vector<int>> t_relocate_, t_freed_;
  std::vector<std::vector<std::pair<int, int>>> t_leaving_;
  std::vector<RowBuild> rb_;     // the threads' rows of a list build
  std::vector<int> watch_new_;   // sleepers next to the rows of a list build

};

}  // namespace

template <int D>
SoftPlan hybrid_preflight(const System<D>& system, const HybridSettings& settings) {
  SoftPlan plan = plan_soft<D>(system);
  const double h = hybrid_substep(plan, settings);
  const double dmax = 2.0 * system.radius_range().second;
  check_periodic_axes<D>(system.lower, system.upper, system.periodic, dmax,
                         hybrid_skins(system, plan, settings, h).list);
  return plan;
}

template <int D>
RunResult<D> run_hybrid(System<D> system, const EdmSettings& edm, const HybridSettings& hybrid,
                        const std::vector<Observer<D>*>& observers, const SoftPlan* plan) {
  // The grains in space order (engine/renumber.hpp), everything reported in the scene's ids.
  return run_in_space_order<D>(std::move(system), observers,
                               [&](System<D>&& sys, const std::vector<Observer<D>*>& obs, IdMap& ids) {
                                 HybridEngine<D> engine(std::move(sys), edm, hybrid, plan, obs);
                                 engine.track_ids(&ids);
                                 return engine.run();
                               });
}

template SoftPlan hybrid_preflight<2>(const System<2>&, const HybridSettings&);
template SoftPlan hybrid_preflight<3>(const System<3>&, const HybridSettings&);
template RunResult<2> run_hybrid<2>(System<2>, const EdmSettings&, const HybridSettings&,
                                    const std::vector<Observer<2>*>&, const SoftPlan*);
template RunResult<3> run_hybrid<3>(System<3>, const EdmSettings&, const HybridSettings&,
                                    const std::vector<Observer<3>*>&, const SoftPlan*);

}  // namespace matep

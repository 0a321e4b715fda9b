#include "engine/tdm.hpp"

#include <fmt/format.h>
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>
#include <stdexcept>
#include <type_traits>

#include "contact/soft.hpp"
#include "engine/flatten.hpp"
#include "engine/grid.hpp"
#include "engine/soft/contact_rows.hpp"
#include "engine/soft/batch.hpp"
#include "engine/soft/forces.hpp"
#include "engine/soft/springs.hpp"
#include "engine/soft/verlet.hpp"
#include "engine/wall_loads.hpp"

namespace matep {

namespace {

using Clock = std::chrono::steady_clock;

constexpr std::size_t kMinPerThread = 2048;

// Force on a particle owned by another thread's range, added after the parallel loop.
template <int D>
struct Spill {
  std::uint32_t j;
  Vec<D> f;
  Spin<D> t;
};

template <int D>
class TdmEngine {
 public:
  TdmEngine(System<D>& sys, const TdmSettings& set, const std::vector<Observer<D>*>& obs, const SoftPlan* plan)
      : sys_(sys), set_(set), obs_(obs), given_plan_(plan) {}

  RunResult<D> run();

 private:
  // ---- setup ----
  void setup();
  // ---- neighbour lists ----
  void rebuild();
  // ---- forces ----
  struct alignas(64) Acc {
    std::uint64_t new_pair = 0, new_wall = 0;
    double max_rel = 0.0, max_abs = 0.0;
    bool moved = false;
  };
  void forces(bool fuse);
  template <bool Rot, bool Uniform, NormalLaw Law, bool Fuse, bool Roll>
  struct RangePolicy;
  template <bool Rot, bool Uniform, NormalLaw Law, bool Fuse, bool Roll>
  void pair_range(int t);
  template <bool Rot, bool Uniform, NormalLaw Law, bool Roll>
  void wall_contact_force(std::uint32_t e, Acc& acc, WallLoads<D>& loads);
  template <NormalLaw Law, bool Fuse>
  void force_body(int t);
  bool integrate_one(std::uint32_t i);
  void integrate(int t);
  // ---- outlets ----
  bool scan_outlets();
  void drop_gone();
  void release_working_arrays();
  void set_ranges();
  // ---- inlets ----
  bool insert_due();
  bool place_free(Vec<D>& x, double R, double t) const;
  // ---- diagnostics ----
  ThermoSample sample(double time);
  Snapshot<D> snapshot(double time) const;
  void add_contacts(Snapshot<D>& s, double time) const;  // Snapshot::contacts (engine/soft/contact_rows.hpp)
  // A fixed grain (System::fixed) is never integrated: zero velocity and spin, its position kept.
  bool is_fixed(std::size_t i) const { return n_fixed_ > 0 && fixed_[i] != 0; }
  Vec<D> v_full(std::size_t i) const {
    return is_fixed(i) ? Vec<D>::Zero() : soft::full_step<D>(v_[i], f_[i], minv_[i], g_, hdt_);
  }
  Spin<D> w_full(std::size_t i) const {
    if (is_fixed(i) || !spins_) return Spin<D>::Zero();
    return rot_ ? Spin<D>(w_[i] + hdt_ * (tq_[i] * iinv_[i])) : w_[i];
  }
  // The mass a contact sees: a fixed grain is infinitely heavy, so the pair's m* is the moving
  // grain's mass (contact/soft.hpp effective_mass with kPlane).
  double contact_mass(std::size_t i) const { return is_fixed(i) ? kPlane : m_[i]; }
  SoftContact pair_coeffs(std::size_t i, std::size_t j) const {
    if (uniform_) return is_fixed(i) || is_fixed(j) ? cfixed_ : cpair_;
    return pair_contact(plan_, mat_[i], R_[i], contact_mass(i), mat_[j], R_[j], contact_mass(j));
  }
  SoftContact wall_coeffs(int w, std::size_t i) const {
    return uniform_ ? cwall_[w] : wall_contact(plan_, w, mat_[i], R_[i], m_[i]);
  }

  System<D>& sys_;
  const TdmSettings& set_;
  const std::vector<Observer<D>*>& obs_;
  const SoftPlan* given_plan_;

  SoftPlan plan_;
  std::size_t N_ = 0;
  double dt_ = 0.0, hdt_ = 0.0, skin_ = 0.0, half_skin2_ = 0.0;
  int T_ = 1;
  bool rot_ = false, uniform_ = false;
  bool spins_ = true;  // w_ is held: rotation, or spins given by the scene (else every spin is zero)
  bool rolling_ = false;  // some contact has rolling resistance (the force loops' Roll instantiation)
  bool epsd_ = false;  // Epsd rolling resistance: the contacts carry rolling spring torques (mr_, wl_mr_)
  NormalLaw law_ = NormalLaw::Linear;  // one law for the whole run (plan_soft checks)
  SoftContact cpair_, cfixed_;  // uniform: a pair of moving grains, a moving and a fixed one
  std::vector<SoftContact> cwall_;
  std::size_t n_fixed_ = 0;
  std::vector<std::uint8_t> fixed_;  // per particle in storage order (empty: none fixed)
  Vec<D> g_ = Vec<D>::Zero(), L_ = Vec<D>::Zero();

  // Particle state in storage order (sorted by cell at every rebuild); id_ maps back.
  std::vector<Vec<D>> x_, v_, acc_, f_, x0_;
  std::vector<Spin<D>> w_, alpha_, tq_;
  std::vector<double> R_, m_, minv_, iinv_;
  std::vector<int> mat_;
  std::vector<std::uint32_t> id_;

  // Half Verlet list in CSR form: entries off_[i] .. off_[i+1] hold j, the periodic image, the
  // touching flag and (with rotation) the tangential spring.
  std::vector<std::uint32_t> off_, nb_;
  std::vector<std::vector<std::uint32_t>> nb_t_;  // each thread's rows at a list build, before they are joined
  std::vector<std::vector<std::uint8_t>> sh_t_;
  std::vector<std::uint8_t> sh_, touch_;
  std::vector<Vec<D>> xi_;
  std::vector<Spin<D>> mr_;     // rolling spring torques per entry (Epsd rolling resistance; else empty)
  std::array<Vec<D>, D == 3 ? 27 : 9> shifts_;
  // Wall list: (particle, wall) pairs within the skin, in particle order.
  std::vector<std::uint32_t> wl_i_, wl_w_, wl_f_;  // particle, wall, feature (contact/wall.hpp)
  std::vector<std::uint8_t> wl_touch_;
  std::vector<Vec<D>> wl_xi_;
  std::vector<Spin<D>> wl_mr_;  // the same per wall entry
  std::vector<const WallShape<D>*> shapes_;  // sys_.walls[w].shape
  soft::WallsNow<D> walls_;                  // the same, planes frozen at the step being computed
  double wall_t_ = 0.0;      // the time of the forces being computed

  // Cell grid used by rebuild().
  CellGrid<D> grid_;
  std::vector<std::uint32_t> cell_of_, cell_start_, order_;
  // Half stencil of each cell: neighbour cells of larger index (CSR) and the periodic image shift
  // to add to x_i.
  std::vector<std::uint32_t> st_off_, st_cell_;
  std::vector<std::uint8_t> st_shift_;
  std::uint8_t centre_shift_ = 0;
  bool initial_ = true;     // the force evaluation at t = 0 (contacts present then began before)

  // Threads: particle ranges and per-thread accumulators.
  std::vector<std::uint32_t> lo_, hi_, wlo_, whi_;
  std::vector<std::vector<Spill<D>>> spill_;
  std::vector<soft::ContactBatch<D>> batch_;  // each thread's scratch of the batched pair loop
  // boundary_[i]: i receives forces from a lower thread range (integrated after the spills).
  std::vector<std::uint8_t> boundary_;
  std::vector<std::uint32_t> boundary_list_;
  std::vector<Acc> acc_t_;
  std::vector<WallLoads<D>> loads_t_;  // each thread's wall impulses since the last sample
  std::vector<Vec<D>> anchors_;        // each wall's anchor (torque reference)
  double last_sample_t_ = 0.0;
  soft::SpringMemory<D> springs_;  // contacts remembered across a rebuild

  // Outlets (System::outlets): grains whose centre is inside one after a step are taken out
  // (scan_outlets) and dropped from the arrays at the rebuild that follows (drop_gone).
  std::vector<std::uint8_t> gone_;        // per particle in storage order: leaving at this step
  std::vector<std::uint8_t> removed_id_;  // per particle id: has left (empty until the first)
  std::size_t N0_ = 0;                    // particle ids: those at the start, then one per grain due from the inlets
  std::size_t n_built_ = 0;               // particles in the cells of the last rebuild (storage 0 .. n_built_ - 1)
  int T_req_ = 1;                         // threads asked for
  std::vector<InletClock<D>> clocks_;     // engine/inlet.hpp
  std::uint32_t next_id_ = 0;
  std::uint64_t grains_in_ = 0;
  double mass_in_ = 0.0;
  std::uint64_t grains_out_ = 0;
  double mass_out_ = 0.0;
  double particle_steps_ = 0.0;

  std::uint64_t steps_ = 0, rebuilds_ = 0, pair_begun_ = 0, wall_begun_ = 0;
  std::uint64_t build_step_ = 0;  // the step of the last rebuild
  double sweep_ = 0.0;            // the walls' largest sweep speed (contact/wall.hpp)
  double max_rel_ = 0.0, max_abs_ = 0.0;
  std::string status_ = "ok", message_;
  bool stopping_ = false;  // a stop was requested (TdmSettings::stop): end at the next whole step
  std::uint64_t k_sample_ = 1, k_snap_ = 1, k_check_ = 1;  // the next thermo row, snapshot, checkpoint
  double t0_ = 0.0;  // the time of step 0 (TdmSettings::start_time)
  double step_time(std::uint64_t n) const { return t0_ + static_cast<double>(n) * dt_; }

  // Checkpoints (engine/state_archive.hpp): everything a step reads that an earlier step wrote,
  // saved at a whole step after its forces (what setup makes from the scene is made again).
  template <class A>
  void archive(A& a) {
    a.tag("tdm.particles");
    a.check(dt_, "the time step");
    a.check(T_req_, "threads");
    a(N_);
    for (auto* v : {&x_, &v_, &acc_, &f_, &x0_}) a(*v);
    for (auto* v : {&w_, &alpha_, &tq_}) a(*v);
    for (auto* v : {&R_, &m_, &minv_, &iinv_}) a(*v);
    a(mat_);
    a(id_);
    a(fixed_);
    a.tag("tdm.lists");
    a(off_);
    a(nb_);
    a(sh_);
    a(touch_);
    a(xi_);
    a(mr_);
    a(wl_i_);
    a(wl_w_);
    a(wl_f_);
    a(wl_touch_);
    a(wl_xi_);
    a(wl_mr_);
    a(cell_of_);
    a(cell_start_);
    a(order_);
    a(initial_);
    a.tag("tdm.threads");
    a(T_);
    a(lo_);
    a(hi_);
    a(wlo_);
    a(whi_);
    a(boundary_);
    a(boundary_list_);
    a(acc_t_);
    a.same(loads_t_, "threads");
    a(last_sample_t_);
    a.tag("tdm.flows");
    a(gone_);
    a(removed_id_);
    a(n_built_);
    a.same(clocks_, "inlets");
    a(next_id_);
    a(grains_in_);
    a(mass_in_);
    a(grains_out_);
    a(mass_out_);
    a.tag("tdm.counters");
    a(particle_steps_);
    a(steps_);
    a(rebuilds_);
    a(pair_begun_);
    a(wall_begun_);
    a(build_step_);
    a(max_rel_);
    a(max_abs_);
    a(k_sample_);
    a(k_snap_);
    a(k_check_);
  }
  void save_checkpoint() {
    if (!set_.checkpoint || !set_.checkpoint->save) return;
    set_.checkpoint->save(step_time(steps_), [&](StateWriter& w) { archive(w); });
  }
};

// The largest diameter of the run: of the grains at the start and of those the inlets insert.
template <int D>
double largest_diameter(const System<D>& sys) {
  return 2.0 * sys.radius_range().second;
}

template <int D>
double skin_of(const System<D>& sys, const TdmSettings& set) {
  return set.skin > 0.0 ? set.skin : 0.1 * largest_diameter(sys);
}

template <int D>
SoftPlan preflight(const System<D>& sys, const TdmSettings& set) {
  if (!(set.end_time > set.start_time))
    throw std::invalid_argument(fmt::format("run.end_time: {} must be after run.start_time = {}", set.end_time,
                                            set.start_time));
  SoftPlan plan = plan_soft<D>(sys);
  if (set.dt > 0.0 && set.dt > plan.max_stable_dt)
    throw std::invalid_argument(fmt::format(
        "run.dt: {} is above the stability limit {:.6g} of velocity Verlet for the stiffest contact "
        "({}, at impact speed {:.4g}); use run.dt <= {:.6g} (the default is {:.6g})",
        set.dt, plan.max_stable_dt, plan.limiting, plan.impact_speed, plan.max_stable_dt, plan.default_dt));
  // The step count must fit a counter (and a run that long would never end anyway).
  const double dt = set.dt > 0.0 ? set.dt : plan.default_dt;
  if (dt > 0.0 && !((set.end_time - set.start_time) / dt < 1e15))
    throw std::invalid_argument(fmt::format("run.dt: {} gives {:.3g} steps to run.end_time = {}; at most 1e15 (use a "
                                            "longer step or a shorter run)",
                                            dt, (set.end_time - set.start_time) / dt, set.end_time));
  check_periodic_axes<D>(sys.lower, sys.upper, sys.periodic, largest_diameter(sys), skin_of(sys, set));
  return plan;
}

template <int D>
void TdmEngine<D>::setup() {
  N_ = sys_.size();
  N0_ = N_;
  next_id_ = static_cast<std::uint32_t>(N_);
  for (std::size_t k = 0; k < sys_.inlets.size(); ++k) {
    clocks_.emplace_back(sys_.inlets[k], k, set_.end_time);
    N0_ += clocks_.back().slots;
  }
  if (N0_ > N_) {  // the inlets' ids are absent until their grains come in
    removed_id_.assign(N0_, 1);
    std::fill(removed_id_.begin(), removed_id_.begin() + static_cast<std::ptrdiff_t>(N_), std::uint8_t{0});
  }
  sys_.check_fixed();
  n_fixed_ = sys_.fixed_count();
  plan_ = given_plan_ ? *given_plan_ : preflight(sys_, set_);
  t0_ = set_.start_time;
  const double span = set_.end_time - t0_;
  const double dt = set_.dt > 0.0 ? set_.dt : (plan_.default_dt > 0.0 ? plan_.default_dt : span);
  // A whole number of steps ends exactly at end_time (the step only shortens).
  const double n = std::ceil(span / dt * (1.0 - 1e-12));
  dt_ = span / std::max(1.0, n);
  hdt_ = 0.5 * dt_;
  last_sample_t_ = t0_;
  const double dmax = largest_diameter(sys_);
  skin_ = skin_of(sys_, set_);
  half_skin2_ = 0.25 * skin_ * skin_;
  L_ = sys_.upper - sys_.lower;
  g_ = sys_.gravity;
  for (const auto& w : sys_.walls) {
    shapes_.push_back(w.shape.get());
    sweep_ = std::max(sweep_, w.shape->sweep_speed());
  }
  walls_.assign(shapes_);
  rot_ = plan_.friction;
  epsd_ = plan_.rolling_model == RollingModel::Epsd;
  springs_.set_rolling(epsd_);
  rolling_ = plan_.rolling;
  law_ = plan_.law;

  // Take over the system's particle state (run_tdm owns its copy of the system, which keeps no
  // per-particle array after this). Angular accelerations and torques only with rotation; spins
  // only with rotation or when the scene gives some (they are then constant).
  m_.resize(N_);
  minv_.resize(N_);
  iinv_.resize(N_);
  id_.resize(N_);
  const double q = inertia_factor<D>();
  for (std::size_t i = 0; i < N_; ++i) {
    m_[i] = sys_.mass(i);
    minv_[i] = 1.0 / m_[i];
    const double R = sys_.radius[i];
    iinv_[i] = 1.0 / (q * m_[i] * R * R);  // I = q m R^2: 2/5 spheres, 1/2 disks
    id_[i] = static_cast<std::uint32_t>(i);
  }
  x_ = std::move(sys_.x);
  v_ = std::move(sys_.v);
  spins_ = rot_ || std::any_of(sys_.w.begin(), sys_.w.end(), [](const Spin<D>& w) { return !w.isZero(0.0); });
  if (spins_) w_ = sys_.w.empty() ? std::vector<Spin<D>>(N_, Spin<D>::Zero()) : std::move(sys_.w);
  std::vector<Spin<D>>().swap(sys_.w);
  R_ = std::move(sys_.radius);
  mat_ = std::move(sys_.material);
  if (n_fixed_ > 0) fixed_ = std::move(sys_.fixed);
  std::vector<std::uint8_t>().swap(sys_.fixed);
  acc_.assign(N_, Vec<D>::Zero());
  f_.assign(N_, Vec<D>::Zero());
  if (rot_) {
    alpha_.assign(N_, Spin<D>::Zero());
    tq_.assign(N_, Spin<D>::Zero());
  }

  uniform_ = N_ > 0;
  for (std::size_t i = 1; i < N_ && uniform_; ++i) uniform_ = R_[i] == R_[0] && mat_[i] == mat_[0];
  for (const Inlet<D>& in : sys_.inlets)
    uniform_ = uniform_ && in.rmin == in.rmax && in.rmin == R_[0] && in.material == mat_[0];
  if (uniform_) {
    cpair_ = pair_contact(plan_, mat_[0], R_[0], m_[0], mat_[0], R_[0], m_[0]);
    cfixed_ = pair_contact(plan_, mat_[0], R_[0], m_[0], mat_[0], R_[0], kPlane);
    for (int w = 0; w < static_cast<int>(sys_.walls.size()); ++w)
      cwall_.push_back(wall_contact(plan_, w, mat_[0], R_[0], m_[0]));
  }

  // Cell grid (engine/grid.hpp): cells at least one largest diameter plus the skin wide (at least
  // three on a periodic axis: the preflight's rule), with the half stencil of each cell and the
  // periodic image shifts by index.
  // A mostly empty domain (a pipe, a tall silo: more than CellGrid::kHashFactor times the cells it
  // may hold, about four per particle) hashes its cells instead (memory with the grains).
  const double max_cells = std::max(64.0, 4.0 * static_cast<double>(N_));
  if (CellGrid<D>::natural_cells(sys_.lower, sys_.upper, dmax + skin_) > CellGrid<D>::kHashFactor * max_cells)
    grid_.build(sys_.lower, sys_.upper, sys_.periodic, dmax + skin_, max_cells, 1 << 20, /*hash=*/true);
  else
    grid_.build(sys_.lower, sys_.upper, sys_.periodic, dmax + skin_, std::numeric_limits<double>::infinity());
  if (!grid_.hashed()) grid_.half_stencil(st_off_, st_cell_, st_shift_);
  shifts_ = grid_.shift_table();
  {
    int cs = 0;
    for (int k = 0, p = 1; k < D; ++k, p *= 3) cs += p;  // index of the zero shift
    centre_shift_ = static_cast<std::uint8_t>(cs);
  }

  // Threads: contiguous particle ranges of at least kMinPerThread particles (below that, the
  // fork-join of a parallel region each step costs more than it saves).
  T_req_ = set_.threads > 0 ? set_.threads : omp_get_max_threads();
  set_ranges();
  wlo_.resize(T_);
  whi_.resize(T_);
  spill_.resize(T_);
  acc_t_.resize(T_);
  loads_t_.resize(T_);
  for (auto& l : loads_t_) l.resize(shapes_.size());
  for (const WallShape<D>* w : shapes_) anchors_.push_back(w->anchor());
}

// The threads' particle ranges for N_ particles (fewer threads once grains have left: at least
// kMinPerThread particles each).
template <int D>
void TdmEngine<D>::set_ranges() {
  T_ = std::max(1, std::min<int>(T_req_, static_cast<int>(N_ / kMinPerThread)));
  lo_.resize(T_);
  hi_.resize(T_);
  if (batch_.size() < static_cast<std::size_t>(T_)) batch_.resize(T_);
  for (int t = 0; t < T_; ++t) {
    lo_[t] = static_cast<std::uint32_t>(N_ * t / T_);
    hi_[t] = static_cast<std::uint32_t>(N_ * (t + 1) / T_);
  }
}

// After a step: every moving grain whose centre is inside an outlet leaves (reported to the
// observers with its half-step velocity). Returns whether any did (the arrays then need a rebuild).
template <int D>
bool TdmEngine<D>::scan_outlets() {
  const double t = step_time(steps_);
  bool any = false;
  for (std::size_t i = 0; i < N_; ++i) {
    if (is_fixed(i)) continue;
    const int o = sys_.outlet_at(x_[i]);
    if (o < 0) continue;
    if (gone_.empty()) gone_.assign(N_, 0);
    if (removed_id_.empty()) removed_id_.assign(N0_, 0);  // (with inlets: allocated at the start)
    gone_[i] = 1;
    removed_id_[id_[i]] = 1;
    any = true;
    ++grains_out_;
    mass_out_ += m_[i];
    OutflowRecord<D> rec;
    rec.time = t;
    rec.id = id_[i];
    rec.outlet = static_cast<std::uint32_t>(o);
    rec.mass = m_[i];
    rec.x = sys_.wrapped(x_[i]);
    rec.v = v_[i];
    rec.w = spins_ ? w_[i] : Spin<D>(Spin<D>::Zero());
    for (auto* ob : obs_) ob->on_outflow(rec);
  }
  return any;
}

// Drops the grains marked in gone_ from every per-particle array (storage order kept).
template <int D>
void TdmEngine<D>::drop_gone() {
  std::size_t m = 0;
  for (std::size_t i = 0; i < N_; ++i) {
    if (gone_[i]) continue;
    if (m != i) {
      x_[m] = x_[i]; v_[m] = v_[i]; acc_[m] = acc_[i]; f_[m] = f_[i];
      if (spins_) w_[m] = w_[i];
      if (rot_) { alpha_[m] = alpha_[i]; tq_[m] = tq_[i]; }
      R_[m] = R_[i]; m_[m] = m_[i]; minv_[m] = minv_[i]; iinv_[m] = iinv_[i];
      mat_[m] = mat_[i]; id_[m] = id_[i];
      if (n_fixed_ > 0) fixed_[m] = fixed_[i];
    }
    ++m;
  }
  N_ = m;
  for (auto* a : {&x_, &v_, &acc_, &f_}) a->resize(N_);
  if (spins_) w_.resize(N_);
  if (rot_) for (auto* a : {&alpha_, &tq_}) a->resize(N_);
  for (auto* a : {&R_, &m_, &minv_, &iinv_}) a->resize(N_);
  mat_.resize(N_);
  id_.resize(N_);
  if (n_fixed_ > 0) fixed_.resize(N_);
  gone_.assign(N_, 0);
}

// At the end of the run: frees what the final state (snapshot()) does not read: the lists, the
// cells, the threads' scratch, the arrays only a step uses.
template <int D>
void TdmEngine<D>::release_working_arrays() {
  auto drop = [](auto& a) { std::decay_t<decltype(a)>().swap(a); };
  drop(acc_); drop(x0_); drop(alpha_); drop(m_);
  drop(off_); drop(nb_); drop(nb_t_); drop(sh_t_); drop(sh_); drop(touch_); drop(xi_); drop(mr_);
  drop(wl_i_); drop(wl_w_); drop(wl_f_); drop(wl_touch_); drop(wl_xi_); drop(wl_mr_);
  drop(cell_of_); drop(cell_start_); drop(order_);
  drop(spill_); drop(batch_); drop(boundary_); drop(boundary_list_); drop(gone_);
  springs_.release();
}

// After a step: the inlets' grains due by now enter (engine/inlet.hpp) where place_free finds room,
// in flight with the velocity drawn (between steps v holds v(t - h/2) = v - h/2 g, as for a grain
// that has flown freely). Returns whether any did (the lists then need a rebuild).
template <int D>
bool TdmEngine<D>::insert_due() {
  const double t = step_time(steps_);
  bool any = false;
  for (std::size_t k = 0; k < clocks_.size(); ++k) {
    InletClock<D>& c = clocks_[k];
    const Inlet<D>& in = sys_.inlets[k];
    while (c.pending() && c.next_time() <= t) {
      Vec<D> x, v;
      double R = 0.0;
      if (!c.draw([&](Vec<D>& y, double r) { return place_free(y, r, t); }, x, R, v)) continue;
      const double m = sys_.materials[static_cast<std::size_t>(in.material)].density * ball_volume<D>(R);
      x_.push_back(x);
      v_.push_back(v - hdt_ * g_);
      acc_.push_back(g_);
      f_.push_back(Vec<D>::Zero());
      if (spins_) w_.push_back(Spin<D>::Zero());
      if (rot_) {
        alpha_.push_back(Spin<D>::Zero());
        tq_.push_back(Spin<D>::Zero());
      }
      R_.push_back(R);
      m_.push_back(m);
      minv_.push_back(1.0 / m);
      iinv_.push_back(1.0 / (inertia_factor<D>() * m * R * R));
      mat_.push_back(in.material);
      id_.push_back(next_id_);
      if (n_fixed_ > 0) fixed_.push_back(0);
      if (!gone_.empty()) gone_.push_back(0);
      removed_id_[next_id_] = 0;
      ++N_;
      ++grains_in_;
      mass_in_ += m;
      any = true;
      InflowRecord<D> rec;
      rec.time = t;
      rec.id = next_id_++;
      rec.inlet = static_cast<std::uint32_t>(k);
      rec.mass = m;
      rec.radius = R;
      rec.x = x;
      rec.v = v;
      for (auto* ob : obs_) ob->on_inflow(rec);
    }
  }
  return any;
}

// Whether a grain of radius R centred at x (wrapped on periodic axes) at step time t is inside the
// domain on its closed axes, outside every outlet, and clear of every wall and grain: those of the
// last rebuild's cells around x (they have moved less than half the skin since, which the cells'
// width covers) and those inserted since.
template <int D>
bool TdmEngine<D>::place_free(Vec<D>& x, double R, double t) const {
  if (!sys_.clear_of_boundaries(x, R, t)) return false;
  auto clear = [&](std::size_t j, const Vec<D>& shift) {
    const double s = R + R_[j];
    return (x - x_[j] - shift).squaredNorm() >= s * s;
  };
  bool free = true;
  if (n_built_ > 0)
    grid_.around(grid_.coords(x), [&](int l, const Vec<D>& shift) {
      for (std::uint32_t j = cell_start_[l]; j < cell_start_[l + 1] && free; ++j) free = clear(j, shift);
    });
  for (std::size_t j = n_built_; j < N_ && free; ++j) {
    Vec<D> d = x - x_[j];  // the nearest image
    for (int k = 0; k < D; ++k)
      if (sys_.periodic[k]) d[k] -= L_[k] * std::round(d[k] / L_[k]);
    free = clear(j, x - x_[j] - d);
  }
  return free;
}

template <int D>
void TdmEngine<D>::rebuild() {
  ++rebuilds_;
  build_step_ = steps_;
  // 1. Remember touching contacts by particle ids (engine/soft/springs.hpp).
  soft::SpringMemory<D>& mem = springs_;
  {
    const std::size_t built = n_built_ && !off_.empty() ? off_[n_built_] : 0;  // entries of the last build
    auto on = [](std::uint8_t f) { return f != 0; };
    mem.reserve(static_cast<std::size_t>(std::count_if(touch_.begin(), touch_.begin() + built, on)),
                static_cast<std::size_t>(std::count_if(wl_touch_.begin(), wl_touch_.end(), on)));
  }
  for (std::size_t i = 0; i < n_built_ && !off_.empty(); ++i)  // the rows of the last build (grains inserted since come after)
    for (std::uint32_t e = off_[i]; e < off_[i + 1]; ++e)
      if (touch_[e])
        mem.remember_pair(id_[i], id_[nb_[e]], rot_ ? xi_[e] : Vec<D>::Zero(), mr_.empty() ? Spin<D>::Zero() : mr_[e]);
  for (std::size_t e = 0; e < wl_i_.size(); ++e)
    if (wl_touch_[e])
      mem.remember_wall(id_[wl_i_[e]], wall_slot(wl_w_[e], wl_f_[e]), rot_ ? wl_xi_[e] : Vec<D>::Zero(),
                        wl_mr_.empty() ? Spin<D>::Zero() : wl_mr_[e]);
  mem.sort();
  if (!gone_.empty() && std::find(gone_.begin(), gone_.end(), 1) != gone_.end()) drop_gone();
  set_ranges();
  n_built_ = N_;

  // 2. Wrap periodic axes, check the state, bin into cells.
  const std::size_t ncell = static_cast<std::size_t>(grid_.cells());
  cell_of_.resize(N_);
  cell_start_.assign(ncell + 1, 0);
  for (std::size_t i = 0; i < N_; ++i) {
    Vec<D>& x = x_[i];
    if (!x.allFinite()) {
      status_ = "unstable";
      message_ = fmt::format("particle {} has a non-finite position: the time step {} is too long for the contact "
                             "stiffness (stability limit {:.6g})",
                             id_[i], dt_, plan_.max_stable_dt);
      return;
    }
    for (int k = 0; k < D; ++k) {
      if (sys_.periodic[k]) {
        x[k] = wrap_periodic(x[k], sys_.lower[k], sys_.upper[k]);
      } else if (x[k] < sys_.lower[k] || x[k] > sys_.upper[k]) {
        status_ = "escaped";
        message_ = escape_message(id_[i], k, step_time(steps_), x[k]);
        return;
      }
    }
    const std::size_t c = static_cast<std::size_t>(grid_.linear(grid_.coords(x)));
    cell_of_[i] = static_cast<std::uint32_t>(c);
    ++cell_start_[c + 1];
  }
  std::partial_sum(cell_start_.begin(), cell_start_.end(), cell_start_.begin());

  // 3. Reorder particles by cell (stable counting sort) for memory locality.
  order_.resize(N_);
  {
    std::vector<std::uint32_t> fill(cell_start_.begin(), cell_start_.end() - 1);
    for (std::size_t i = 0; i < N_; ++i) order_[fill[cell_of_[i]]++] = static_cast<std::uint32_t>(i);
  }
  // f_ and tq_ are zero between steps (integrate() clears them), so they need no permutation, and
  // f_ is the scratch the vector arrays are gathered into (no array kept for the sort alone); the
  // other arrays go through one temporary of their type at a time (at most 8 bytes a particle).
  auto permute = [&](auto& a) {
    using T = typename std::decay_t<decltype(a)>::value_type;
    if constexpr (std::is_same_v<T, Vec<D>>) {
      for (std::size_t k = 0; k < N_; ++k) f_[k] = a[order_[k]];
      a.swap(f_);
    } else {
      std::vector<T> t(N_);
      for (std::size_t k = 0; k < N_; ++k) t[k] = a[order_[k]];
      a.swap(t);
    }
  };
  f_.resize(N_);
  permute(x_); permute(v_); permute(acc_);
  if (spins_) permute(w_);
  if (rot_) permute(alpha_);
  permute(R_); permute(m_); permute(minv_); permute(iinv_);
  permute(mat_); permute(id_);
  if (n_fixed_ > 0) permute(fixed_);
  std::fill(f_.begin(), f_.end(), Vec<D>::Zero());
  x0_ = x_;

  // 4. Half list: pairs within R_i + R_j + skin, each once: in the own cell j > i, and the
  // neighbour cells of larger index from the stencil built in setup(). Storage is sorted by cell,
  // so j > i for every entry. Each thread makes the rows of its range (set_ranges) into its own
  // lists, which are then joined in range order: the same list as one thread makes.
  off_.assign(N_ + 1, 0);
  const bool hashed = grid_.hashed();
  // Rows [i0, i1) appended to nb and sh; off_[i + 1] = the row's end within nb.
  auto make_rows = [&](std::uint32_t i0, std::uint32_t i1, std::vector<std::uint32_t>& nb,
                       std::vector<std::uint8_t>& sh) {
    nb.clear();
    sh.clear();
    if (hashed) {
      // Hashed cells: every cell around i (a bucket may also hold grains of far cells, which the
      // distance test drops), partners j > i only: each pair once, in the row of its lower index.
      for (std::uint32_t i = i0; i < i1; ++i) {
        const Vec<D> xi = x_[i];
        const double Ri = R_[i] + skin_;
        grid_.around(grid_.coords(xi), [&](int l, const Vec<D>& shift) {
          const std::uint8_t s = grid_.shift_index(shift);
          const Vec<D> xs = xi + shifts_[s];
          for (std::uint32_t j = cell_start_[l]; j < cell_start_[l + 1]; ++j) {
            if (j <= i) continue;
            const double cut = Ri + R_[j];
            if ((xs - x_[j]).squaredNorm() < cut * cut) {
              nb.push_back(j);
              sh.push_back(s);
            }
          }
        });
        off_[i + 1] = static_cast<std::uint32_t>(nb.size());
      }
      return;
    }
    if (i0 >= i1) return;
    // The cell holding i0: the last whose start is <= i0.
    std::size_t c = static_cast<std::size_t>(std::upper_bound(cell_start_.begin(), cell_start_.end(), i0) -
                                             cell_start_.begin()) - 1;
    for (; c < ncell && cell_start_[c] < i1; ++c) {
      const std::uint32_t cb = cell_start_[c], ce = cell_start_[c + 1];
      for (std::uint32_t i = std::max(cb, i0); i < std::min(ce, i1); ++i) {
        const Vec<D> xi = x_[i];
        const double Ri = R_[i] + skin_;
        const bool fi = is_fixed(i);  // two fixed grains never meet: no entry
        for (std::uint32_t j = i + 1; j < ce; ++j) {
          if (fi && fixed_[j]) continue;
          const double cut = Ri + R_[j];
          const Vec<D> dx = xi - x_[j];
          if (dx.squaredNorm() < cut * cut) {
            nb.push_back(j);
            sh.push_back(centre_shift_);
          }
        }
        for (std::uint32_t k = st_off_[c]; k < st_off_[c + 1]; ++k) {
          const std::uint32_t c2 = st_cell_[k];
          const std::uint8_t s = st_shift_[k];
          const Vec<D> xs = xi + shifts_[s];
          for (std::uint32_t j = cell_start_[c2]; j < cell_start_[c2 + 1]; ++j) {
            if (fi && fixed_[j]) continue;
            const double cut = Ri + R_[j];
            if ((xs - x_[j]).squaredNorm() < cut * cut) {
              nb.push_back(j);
              sh.push_back(s);
            }
          }
        }
        off_[i + 1] = static_cast<std::uint32_t>(nb.size());
      }
    }
  };
  // Touching flags and springs of entries [e0, e1) (rows [i0, i1)) recalled by particle ids.
  auto recall = [&](std::uint32_t i0, std::uint32_t i1) {
    const std::uint32_t e0 = off_[i0], e1 = off_[i1];
    std::fill(touch_.begin() + e0, touch_.begin() + e1, std::uint8_t{0});
    if (rot_) std::fill(xi_.begin() + e0, xi_.begin() + e1, Vec<D>::Zero());
    if (epsd_) std::fill(mr_.begin() + e0, mr_.begin() + e1, Spin<D>::Zero());
    if (mem.empty()) return;
    Vec<D> spring;
    for (std::uint32_t i = i0; i < i1; ++i)
      for (std::uint32_t e = off_[i]; e < off_[i + 1]; ++e)
        if (mem.recall_pair(id_[i], id_[nb_[e]], spring, epsd_ ? &mr_[e] : nullptr)) {
          touch_[e] = 1;
          if (rot_) xi_[e] = spring;
        }
  };
  // The entries' flags and springs, sized to the list without keeping the old ones (recall() sets
  // them all): a list grown past their storage gets it anew with an eighth to spare, not doubled as
  // a resize would (a spring is 24 bytes an entry in 3D).
  auto size_entries = [&] {
    auto fit = [n = nb_.size()](auto& a) {
      if (a.capacity() < n) {
        std::decay_t<decltype(a)>().swap(a);
        a.reserve(n + n / 8);
      }
      a.resize(n);
    };
    fit(touch_);
    if (rot_) fit(xi_);
    if (epsd_) fit(mr_);
  };
  if (T_ == 1) {
    make_rows(0, static_cast<std::uint32_t>(N_), nb_, sh_);
    size_entries();
    recall(0, static_cast<std::uint32_t>(N_));
  } else {
    if (nb_t_.size() < static_cast<std::size_t>(T_)) {
      nb_t_.resize(T_);
      sh_t_.resize(T_);
    }
    // (The first range's rows go straight into the joined list, which they begin.)
#pragma omp parallel num_threads(T_)
    {
      const int t = omp_get_thread_num();
      make_rows(lo_[t], hi_[t], t == 0 ? nb_ : nb_t_[t], t == 0 ? sh_ : sh_t_[t]);
    }
    // Each range's rows at their place in the joined list.
    std::vector<std::uint32_t> base(static_cast<std::size_t>(T_) + 1, 0);
    base[1] = static_cast<std::uint32_t>(nb_.size());
    for (int t = 1; t < T_; ++t) base[t + 1] = base[t] + static_cast<std::uint32_t>(nb_t_[t].size());
    nb_.resize(base[T_]);
    sh_.resize(base[T_]);
    size_entries();
#pragma omp parallel num_threads(T_)
    {
      const int t = omp_get_thread_num();
      if (t > 0) {
        std::copy(nb_t_[t].begin(), nb_t_[t].end(), nb_.begin() + base[t]);
        std::copy(sh_t_[t].begin(), sh_t_[t].end(), sh_.begin() + base[t]);
        for (std::uint32_t i = lo_[t]; i < hi_[t]; ++i) off_[i + 1] += base[t];
      }
#pragma omp barrier
      recall(lo_[t], hi_[t]);  // (reads off_[lo_[t]], the range before's)
    }
  }
  Vec<D> spring;
  // The force loop's ranges: equal shares of the list's entries (the rows above were split by
  // particles), the pair work of a step being proportional to them.
  if (T_ > 1) {
    const std::size_t total = nb_.size();
    for (int t = 1; t < T_; ++t) {
      const std::uint32_t target = static_cast<std::uint32_t>(total * static_cast<std::size_t>(t) / T_);
      const auto r = static_cast<std::uint32_t>(std::lower_bound(off_.begin(), off_.end(), target) - off_.begin());
      hi_[t - 1] = lo_[t] = std::clamp(r, lo_[t - 1], static_cast<std::uint32_t>(N_));
    }
  }

  // 5. Wall list.
  wl_i_.clear();
  wl_w_.clear();
  wl_f_.clear();
  const double t_now = step_time(steps_);
  std::vector<std::uint32_t> feats;
  for (std::size_t i = 0; i < N_; ++i) {
    if (is_fixed(i)) continue;  // a fixed grain meets no wall
    soft::walls_in_reach<D>(shapes_, x_[i], R_[i], skin_, t_now, feats, [&](std::uint32_t w, std::uint32_t f) {
      wl_i_.push_back(static_cast<std::uint32_t>(i));
      wl_w_.push_back(w);
      wl_f_.push_back(f);
    });
  }
  wl_touch_.assign(wl_i_.size(), 0);
  if (rot_) wl_xi_.assign(wl_i_.size(), Vec<D>::Zero());
  if (epsd_) wl_mr_.assign(wl_i_.size(), Spin<D>::Zero());
  if (!mem.empty())
    for (std::size_t e = 0; e < wl_i_.size(); ++e)
      if (mem.recall_wall(id_[wl_i_[e]], wall_slot(wl_w_[e], wl_f_[e]), spring, epsd_ ? &wl_mr_[e] : nullptr)) {
        wl_touch_[e] = 1;
        if (rot_) wl_xi_[e] = spring;
      }
  for (int t = 0; t < T_; ++t) {
    wlo_[t] = static_cast<std::uint32_t>(std::lower_bound(wl_i_.begin(), wl_i_.end(), lo_[t]) - wl_i_.begin());
    whi_[t] = static_cast<std::uint32_t>(std::lower_bound(wl_i_.begin(), wl_i_.end(), hi_[t]) - wl_i_.begin());
  }
  // 6. Particles that receive forces from a lower thread range.
  boundary_.assign(N_, 0);
  boundary_list_.clear();
  if (T_ > 1) {
    for (int t = 0; t < T_; ++t)
      for (std::uint32_t e = off_[lo_[t]]; e < off_[hi_[t]]; ++e)
        if (nb_[e] >= hi_[t]) boundary_[nb_[e]] = 1;
    for (std::uint32_t i = 0; i < N_; ++i)
      if (boundary_[i]) boundary_list_.push_back(i);
  }
}

// What the soft path's pair loop (engine/soft/forces.hpp) does differently in TDM: rows are the
// particles of one thread's range, forces on a particle of another range are spilled (added after
// the loop in range order), overlaps are tracked for the stability check, and each particle's
// walls follow its pairs and, with Fuse, its integration (its force is then complete).
template <int D>
template <bool Rot, bool Uniform, NormalLaw Law, bool Fuse, bool Roll>
struct TdmEngine<D>::RangePolicy : soft::NoSleepers {
  static constexpr bool kSleepers = false, kNear = false, kVirial = false, kOwners = false, kShifts = true,
                        kSparseRows = false;
  TdmEngine& eng;
  Acc& acc;
  WallLoads<D>& loads;
  std::vector<Spill<D>>& spill;
  const std::uint32_t lo, hi;
  std::uint32_t ew;  // wall entries are sorted by particle
  const std::uint32_t ew_end;
  bool moved = false;

  RangePolicy(TdmEngine& e, int t)
      : eng(e), acc(e.acc_t_[t]), loads(e.loads_t_[t]), spill(e.spill_[t]), lo(e.lo_[t]), hi(e.hi_[t]), ew(e.wlo_[t]), ew_end(e.whi_[t]) {}

  bool onset() const { return !eng.initial_; }
  const SoftContact& contact(std::uint32_t, std::uint32_t i, std::uint32_t j, SoftContact& scratch) const {
    if constexpr (Uniform) return eng.is_fixed(i) || eng.is_fixed(j) ? eng.cfixed_ : eng.cpair_;
    scratch = eng.pair_coeffs(i, j);
    return scratch;
  }
  // The batched loop's uniform constants (engine/soft/batch.hpp).
  static constexpr bool kTable = false;
  bool clip() const { return eng.cpair_.clip; }
  bool alt(std::uint32_t i, std::uint32_t j) const { return eng.is_fixed(i) || eng.is_fixed(j); }
  const SoftContact& contact_main() const { return eng.cpair_; }
  const SoftContact& contact_alt() const { return eng.cfixed_; }
  void began(std::uint32_t, std::uint32_t) { ++acc.new_pair; }
  void opened(std::uint32_t, std::uint32_t) {}
  void overlap(double delta, double Rs) {
    if (delta > acc.max_rel * Rs) acc.max_rel = delta / Rs;
    if (delta > acc.max_abs) acc.max_abs = delta;
  }
  [[gnu::always_inline]] void partner(Vec<D>* FF, Spin<D>* TQ, std::uint32_t j, const Vec<D>& f, const Spin<D>& t) {
    if (j >= lo && j < hi) {
      FF[j] -= f;
      if constexpr (Rot) TQ[j] += t;
    } else {
      spill.push_back({j, -f, t});
    }
  }
  void virial(const Vec<D>&, const Vec<D>&) {}
  [[gnu::always_inline]] void row_done(std::uint32_t i) {
    for (; ew < ew_end && eng.wl_i_[ew] == i; ++ew) eng.wall_contact_force<Rot, Uniform, Law, Roll>(ew, acc, loads);
    // Every pair entry has j > i (storage is sorted by cell), so i's force is complete here unless
    // a lower thread range still adds to it: integrate it now and never read it again this step.
    // (The engine's arrays are read here, once per row, rather than held through the row's loop.)
    if constexpr (Fuse) {
      if (eng.is_fixed(i)) {  // feels forces, never moves
        eng.f_[i].setZero();
        if constexpr (Rot) eng.tq_[i].setZero();
      } else if (!eng.boundary_[i]) {
        moved |= soft::kick_drift<D>(eng.f_[i], eng.acc_[i], eng.v_[i], eng.x_[i], eng.x0_[i], eng.minv_[i], eng.g_,
                                     eng.dt_, eng.half_skin2_);
        if constexpr (Rot) soft::kick_spin(eng.tq_[i], eng.alpha_[i], eng.w_[i], eng.iinv_[i], eng.dt_);
      }
    }
  }
};

// Pair forces of the particles in thread t's range (the soft path's loop); the touching flag counts
// contacts begun.
template <int D>
template <bool Rot, bool Uniform, NormalLaw Law, bool Fuse, bool Roll>
MATEP_FLATTEN void TdmEngine<D>::pair_range(int t) {
  RangePolicy<Rot, Uniform, Law, Fuse, Roll> pol(*this, t);
  const auto rows = soft::PairRows<D>::of(nullptr, off_.data(), nb_.data(), sh_.data(), touch_.data(), xi_.data(),
                                          shifts_.data(), epsd_ ? mr_.data() : nullptr);
  const soft::Arrays<D> pos{x_.data(), R_.data()};
  const auto bodies = soft::bodies_of(v_, acc_, f_, w_, alpha_, tq_);
  if constexpr (Uniform && !Roll)
    soft::pair_rows_batched<D, Law, Rot>(pos, bodies, rows, lo_[t], hi_[t], dt_, pol, batch_[t]);
  else
    soft::pair_rows<D, Law, Rot, Roll>(pos, bodies, rows, lo_[t], hi_[t], dt_, pol);
  acc_t_[t].moved = pol.moved;
}

template <int D>
template <bool Rot, bool Uniform, NormalLaw Law, bool Roll>
inline void TdmEngine<D>::wall_contact_force(std::uint32_t e, Acc& acc, WallLoads<D>& loads) {
  const std::uint32_t i = wl_i_[e];
  const int w = static_cast<int>(wl_w_[e]);
  bool began = false;
  Vec<D> no_spring = Vec<D>::Zero();
  Spin<D> no_spin = Spin<D>::Zero(), no_torque = Spin<D>::Zero();  // without rotation (no such arrays)
  const soft::WallContact<D> c = walls_.with_wall(w, wl_f_[e], [&](const auto& shape) {
    return soft::wall_contact<D, Law, Rot, Roll>(shape, wall_t_, dt_, !initial_, x_[i], R_[i], v_[i], acc_[i],
                                           Rot ? w_[i] : no_spin, Rot ? alpha_[i] : no_spin,
                                           Uniform ? cwall_[w] : wall_coeffs(w, i),
                                           wl_touch_[e], Rot ? wl_xi_[e] : no_spring, began, f_[i],
                                           Rot ? tq_[i] : no_torque,
                                           epsd_ ? &wl_mr_[e] : nullptr);
  });
  if (began) ++acc.new_wall;
  const double delta = c.delta;
  if (delta > 0.0) loads.add(static_cast<std::size_t>(w), anchors_[w], c.point, -dt_ * c.force);
  if (delta > acc.max_rel * R_[i]) acc.max_rel = delta / R_[i];
  if (delta > acc.max_abs) acc.max_abs = delta;
}

template <int D>
template <NormalLaw Law, bool Fuse>
void TdmEngine<D>::force_body(int t) {
  spill_[t].clear();
  if (rolling_) {  // rolling resistance acts on the spins: rot_ is set
    if (uniform_) pair_range<true, true, Law, Fuse, true>(t);
    else pair_range<true, false, Law, Fuse, true>(t);
  } else if (rot_) {
    if (uniform_) pair_range<true, true, Law, Fuse, false>(t);
    else pair_range<true, false, Law, Fuse, false>(t);
  } else {
    if (uniform_) pair_range<false, true, Law, Fuse, false>(t);
    else pair_range<false, false, Law, Fuse, false>(t);
  }
}

// Forces at the current positions. With fuse, each particle is also integrated to the next step
// as soon as its force is complete (integrate_one); the particles that receive forces from a
// lower thread range (boundary_) are integrated after the spills are added.
template <int D>
void TdmEngine<D>::forces(bool fuse) {
  for (auto& a : acc_t_) a = Acc{};
  // Walls at this step: the forces of step n are evaluated at t_n = steps_ dt; a moving surface's
  // velocity is taken at t_n (with the predicted velocities) and t_n - h/2 (with the half-step ones).
  wall_t_ = step_time(steps_);
  walls_.refresh(wall_t_, hdt_);
  auto body = [&](int t) {
    switch (law_) {
      case NormalLaw::Linear:
        fuse ? force_body<NormalLaw::Linear, true>(t) : force_body<NormalLaw::Linear, false>(t);
        break;
      case NormalLaw::Hertz:
        fuse ? force_body<NormalLaw::Hertz, true>(t) : force_body<NormalLaw::Hertz, false>(t);
        break;
      case NormalLaw::Viscoelastic:
        fuse ? force_body<NormalLaw::Viscoelastic, true>(t) : force_body<NormalLaw::Viscoelastic, false>(t);
        break;
    }
  };
  if (T_ == 1) {
    body(0);
  } else {
#pragma omp parallel num_threads(T_)
    body(omp_get_thread_num());
    for (int t = 0; t < T_; ++t)
      for (const auto& s : spill_[t]) {
        f_[s.j] += s.f;
        if (rot_) tq_[s.j] += s.t;
      }
    if (fuse) {
      bool moved = false;
      for (std::uint32_t i : boundary_list_) moved |= integrate_one(i);
      acc_t_[0].moved = acc_t_[0].moved || moved;
    }
  }
  for (const auto& a : acc_t_) {
    pair_begun_ += a.new_pair;
    wall_begun_ += a.new_wall;
    max_rel_ = std::max(max_rel_, a.max_rel);
    max_abs_ = std::max(max_abs_, a.max_abs);
  }
}

// Closes step n for particle i (v(t) from its new force) and opens step n + 1 (engine/soft/verlet.hpp):
// v(t + h/2) = v(t - h/2) + h a(t), x += h v(t + h/2). Returns whether it has moved more than half
// the skin since the last rebuild (a non-finite position counts as moved).
template <int D>
[[gnu::always_inline]] inline bool TdmEngine<D>::integrate_one(std::uint32_t i) {
  if (is_fixed(i)) {  // feels forces, never moves
    f_[i].setZero();
    if (rot_) tq_[i].setZero();
    return false;
  }
  const bool moved = soft::kick_drift<D>(f_[i], acc_[i], v_[i], x_[i], x0_[i], minv_[i], g_, dt_, half_skin2_);
  if (rot_) soft::kick_spin(tq_[i], alpha_[i], w_[i], iinv_[i], dt_);
  return moved;
}

template <int D>
void TdmEngine<D>::integrate(int t) {
  bool moved = false;
  for (std::uint32_t i = lo_[t]; i < hi_[t]; ++i) moved |= integrate_one(i);
  acc_t_[t].moved = moved;
}

template <int D>
ThermoSample TdmEngine<D>::sample(double time) {
  ThermoSample s;
  s.time = time;
  double mv2 = 0.0, rot = 0.0, pot = 0.0;
  const double q = inertia_factor<D>();
  for (std::size_t i = 0; i < N_; ++i) {
    const Vec<D> v = v_full(i);
    mv2 += m_[i] * v.squaredNorm();
    rot += q * m_[i] * R_[i] * R_[i] * w_full(i).squaredNorm();
    pot -= m_[i] * g_.dot(x_[i]);
  }
  // Elastic energy of the contacts and their virial sum r.F (the tangential force is normal to
  // r and adds nothing).
  double el = 0.0, vir = 0.0;
  auto stored = [](const SoftContact& c, double delta, const Vec<D>& xi) { return stored_energy<D>(c, delta, xi); };
  for (std::size_t i = 0; i < N_; ++i)
    for (std::uint32_t e = off_[i]; e < off_[i + 1]; ++e) {
      const std::uint32_t j = nb_[e];
      const Vec<D> dx = x_[i] - x_[j] + shifts_[sh_[e]];
      const double Rs = R_[i] + R_[j], r = dx.norm();
      if (r >= Rs) continue;
      const SoftContact c = pair_coeffs(i, j);
      const double delta = Rs - r;
      el += stored(c, delta, rot_ ? xi_[e] : Vec<D>::Zero());
      if (is_fixed(i) || is_fixed(j)) continue;  // a fixed grain is a boundary, as a wall: no virial
      const double vn = (v_full(i) - v_full(j)).dot(dx) / r;
      vir += r * normal_force(c, delta, -vn);
    }
  for (std::size_t e = 0; e < wl_i_.size(); ++e) {
    const std::uint32_t i = wl_i_[e];
    const double delta = -shapes_[wl_w_[e]]->at_feature(x_[i], R_[i], time, wl_f_[e]).gap;
    if (delta <= 0.0) continue;
    el += stored(wall_coeffs(static_cast<int>(wl_w_[e]), i), delta, rot_ ? wl_xi_[e] : Vec<D>::Zero());
  }
  s.kinetic_energy = 0.5 * mv2;
  s.rotational_energy = 0.5 * rot;
  s.potential_energy = pot;
  s.elastic_energy = el;
  s.soft = N_;
  s.grains = N_;
  s.grains_out = grains_out_;
  s.mass_out = mass_out_;
  s.grains_in = grains_in_;
  s.mass_in = mass_in_;
  const std::size_t moving = N_ - n_fixed_;  // fixed grains have no kinetic degrees of freedom
  s.temperature = moving > 0 ? mv2 / (D * static_cast<double>(moving)) : 0.0;
  s.collisions = pair_begun_ + wall_begun_;
  s.pressure = (mv2 + vir) / (D * sys_.volume());
  // The walls' loads: the threads' impulses in thread order, as means over the interval.
  if (time > last_sample_t_) {
    for (std::size_t t = 1; t < loads_t_.size(); ++t) {  // every thread the run has had
      loads_t_[0].add(loads_t_[t]);
      loads_t_[t].clear();
    }
    loads_t_[0].report(time - last_sample_t_, s.wall_loads);
    last_sample_t_ = time;
  }
  return s;
}

template <int D>
Snapshot<D> TdmEngine<D>::snapshot(double time) const {
  Snapshot<D> s;
  s.time = time;
  s.x.resize(N0_);
  s.v.resize(N0_);
  s.radius.resize(N0_);
  s.w.resize(N0_);
  for (std::size_t i = 0; i < N_; ++i) {
    const std::uint32_t k = id_[i];
    s.x[k] = x_[i];
    s.v[k] = v_full(i);
    s.w[k] = w_full(i);
    s.radius[k] = R_[i];
  }
  s.mode.assign(N0_, 1);  // every grain is soft (1); a fixed one 4 (the hybrid's numbers)
  for (std::size_t i = 0; i < N_; ++i)
    if (is_fixed(i)) s.mode[id_[i]] = 4;
  if (!removed_id_.empty()) keep_present(s, removed_id_);
  return s;
}

// Every touching contact of the lists at time t (after the step's forces): pairs, then walls.
template <int D>
void TdmEngine<D>::add_contacts(Snapshot<D>& s, double time) const {
  s.with_contacts = true;
  auto gone = [&](std::size_t i) { return !removed_id_.empty() && removed_id_[id_[i]] != 0; };
  auto body = [&](std::size_t i) {
    return soft::RowBody<D>{id_[i], x_[i], R_[i], v_full(i), w_full(i)};
  };
  const Vec<D> zero = Vec<D>::Zero();
  for (std::size_t i = 0; i < n_built_ && i < N_; ++i) {
    if (gone(i)) continue;
    for (std::uint32_t e = off_[i]; e < off_[i + 1]; ++e) {
      if (!touch_[e]) continue;
      const std::uint32_t j = nb_[e];
      if (gone(j)) continue;
      const Vec<D> dx = x_[i] - x_[j] + shifts_[sh_[e]];
      if (dx.squaredNorm() >= (R_[i] + R_[j]) * (R_[i] + R_[j])) continue;
      s.contacts.push_back(soft::pair_row<D>(pair_coeffs(i, j), body(i), body(j), dx, rot_ ? xi_[e] : zero));
    }
  }
  for (std::size_t e = 0; e < wl_i_.size(); ++e) {
    if (!wl_touch_[e]) continue;
    const std::uint32_t i = wl_i_[e];
    if (gone(i)) continue;
    const int w = static_cast<int>(wl_w_[e]);
    const WallPoint<D> p = shapes_[w]->at_feature(x_[i], R_[i], time, wl_f_[e]);
    if (!(p.gap < 0.0)) continue;
    s.contacts.push_back(soft::wall_row<D>(wall_coeffs(w, i), body(i), w, p, rot_ ? wl_xi_[e] : zero));
  }
}

template <int D>
RunResult<D> TdmEngine<D>::run() {
  const auto t0 = Clock::now();
  setup();
  RunResult<D> res;
  res.method = Method::Tdm;
  const std::uint64_t nsteps =
      N_ == 0 && clocks_.empty() ? 0 : static_cast<std::uint64_t>(std::llround((set_.end_time - t0_) / dt_));
  auto step_of = [&](double interval, std::uint64_t k) {
    return static_cast<std::uint64_t>(std::llround(static_cast<double>(k) * interval / dt_));
  };
  bool want_snap = false, want_contacts = false;
  for (auto* o : obs_) want_snap = want_snap || o->wants_snapshots();
  for (auto* o : obs_) want_contacts = want_contacts || (o->wants_snapshots() && o->wants_contacts());
  want_snap = want_snap && set_.snapshot_interval > 0.0;
  std::uint64_t& k_sample = k_sample_;
  std::uint64_t& k_snap = k_snap_;
  const double check_every = set_.checkpoint ? set_.checkpoint->interval : 0.0;
  // Whether step n needs the full-step state (a thermo row, a snapshot, a checkpoint or the end).
  // (A step with its forces computed apart and one with them fused into the integration give the
  // same bits: a run with more rows or checkpoints follows the same course.)
  auto due = [&](std::uint64_t n) {
    return n == 0 || n >= nsteps || (set_.thermo_interval > 0.0 && step_of(set_.thermo_interval, k_sample) <= n) ||
           (want_snap && step_of(set_.snapshot_interval, k_snap) <= n) ||
           (check_every > 0.0 && step_of(check_every, k_check_) <= n);
  };
  // Saves the state at step n when a checkpoint falls due there, the run ends or stops.
  auto checkpoint = [&](std::uint64_t n, bool last) {
    bool now = last;
    while (check_every > 0.0 && n > 0 && step_of(check_every, k_check_) <= n) {
      now = true;
      ++k_check_;
    }
    if (now) save_checkpoint();
  };
  auto emit = [&](std::uint64_t n, bool last) {
    const double t = step_time(n);
    bool do_sample = n == 0 || last;
    if (set_.thermo_interval > 0.0 && n > 0) {
      while (step_of(set_.thermo_interval, k_sample) <= n) {
        do_sample = true;
        ++k_sample;
      }
    }
    if (do_sample) {
      const ThermoSample s = sample(t);
      for (auto* o : obs_) o->on_sample(s);
    }
    if (want_snap) {
      bool do_snap = n == 0 || last;
      while (n > 0 && step_of(set_.snapshot_interval, k_snap) <= n) {
        do_snap = true;
        ++k_snap;
      }
      if (do_snap) {
        Snapshot<D> s = snapshot(t);
        if (want_contacts) add_contacts(s, t);
        for (auto* o : obs_)
          if (o->wants_snapshots()) o->on_snapshot(s);
      }
    }
  };
  auto check_stable = [&] {
    if (!(max_rel_ <= set_.unstable_overlap)) {
      status_ = "unstable";
      message_ = fmt::format("an overlap reached {:.3g} of the contact distance at t = {}: either the time step {} "
                             "is too long for the contact stiffness (stability limit {:.6g}; default step {:.6g}) "
                             "or the contacts are too soft for the impacts (raise stiffness or young)",
                             max_rel_, step_time(steps_), dt_, plan_.max_stable_dt, plan_.default_dt);
    }
  };
  auto after_move = [&] {
    ++steps_;
    particle_steps_ += static_cast<double>(N_);
    bool moved = false;
    for (const auto& a : acc_t_) moved = moved || a.moved;
    if (!sys_.outlets.empty() && scan_outlets()) moved = true;
    if (!clocks_.empty() && insert_due()) moved = true;
    // A turning wall sweeps towards the grains too: together with their half skin, half the skin.
    if (sweep_ > 0.0 && sweep_ * static_cast<double>(steps_ - build_step_) * dt_ > 0.5 * skin_) moved = true;
    if (moved && status_ == "ok") rebuild();
    if ((steps_ & 1023) == 0)
      for (auto* o : obs_) o->on_progress(step_time(steps_), steps_);
    if ((steps_ & 15) == 0 && set_.stop && set_.stop->load(std::memory_order_relaxed)) stopping_ = true;
  };

  const bool resuming = set_.checkpoint && set_.checkpoint->resume;
  if (resuming) {
    // Continue a saved state (positions and forces of a whole step): that step's rows are written
    // now unless the saved run had written them.
    StateReader r(*set_.checkpoint->resume);
    archive(r);
    if (!r.done()) throw StateError("the engine state is longer than this scene's (a checkpoint of another scene)");
    emit(steps_, steps_ >= nsteps);
  } else if (!clocks_.empty()) {
    insert_due();  // the grains due at t = 0
  }
  if (!resuming && (N_ > 0 || !clocks_.empty())) {
    rebuild();
    if (status_ == "ok") {
      // Forces at t = 0 give a(0) only: contacts that exist at t = 0 keep their springs unstretched
      // (zero: the first list recalls none).
      forces(false);
      initial_ = false;
      std::fill(xi_.begin(), xi_.end(), Vec<D>::Zero());
      std::fill(wl_xi_.begin(), wl_xi_.end(), Vec<D>::Zero());
      std::fill(mr_.begin(), mr_.end(), Spin<D>::Zero());
      std::fill(wl_mr_.begin(), wl_mr_.end(), Spin<D>::Zero());
      check_stable();
      // v holds v(t - h/2) between steps.
      for (std::size_t i = 0; i < N_; ++i)
        if (!is_fixed(i)) soft::start_half_step(v_[i], f_[i], minv_[i], g_, hdt_);
      if (rot_)
        for (std::size_t i = 0; i < N_; ++i)
          if (!is_fixed(i)) soft::start_half_step_spin(w_[i], tq_[i], iinv_[i], hdt_);
      emit(0, nsteps == 0);
    }
  }
  // Loop invariant: positions at step steps_, forces there computed (by forces(false)).
  while (status_ == "ok" && steps_ < nsteps) {
    if (steps_ >= set_.max_steps) break;
    if (T_ == 1) {
      integrate(0);
    } else {
#pragma omp parallel num_threads(T_)
      integrate(omp_get_thread_num());
    }
    after_move();
    // Steps that need no full-step state: forces and integration in one pass.
    while (status_ == "ok" && !stopping_ && !due(steps_) && steps_ < set_.max_steps) {
      forces(true);
      check_stable();
      after_move();
    }
    if (status_ != "ok") break;
    forces(false);
    check_stable();
    // A stop request (a signal) ends the run here, at a whole step, with its last row and snapshot.
    if (stopping_ && status_ == "ok" && steps_ < nsteps) {
      status_ = "interrupted";
      message_ = fmt::format("stopped on request at t = {:.17g}", step_time(steps_));
    }
    if (status_ == "ok" || status_ == "interrupted") checkpoint(steps_, steps_ >= nsteps || status_ != "ok");
    emit(steps_, steps_ >= nsteps || status_ != "ok");
  }
  if (status_ == "ok" && steps_ < nsteps) {
    status_ = "max_steps";
    message_ = fmt::format("stopped after {} steps at t = {} (max_steps)", steps_, step_time(steps_));
  }

  res.status = status_;
  res.message = message_;
  res.time = step_time(steps_);
  res.counts.pair = pair_begun_;
  res.counts.wall = wall_begun_;
  SoftStats& s = res.soft;
  for (auto f : touch_) s.contacts += f;
  for (auto f : wl_touch_) s.contacts += f;
  release_working_arrays();  // before the final state is gathered: the run's peak stays the steps'
  Snapshot<D> last = snapshot(res.time);  // the final state in particle-id order
  res.id = std::move(last.id);
  res.x = std::move(last.x);
  res.v = std::move(last.v);
  res.w = std::move(last.w);
  res.radius = std::move(last.radius);
  {  // materials by id, then per row
    std::vector<int> by_id(N0_, 0);
    for (std::size_t i = 0; i < N_; ++i) by_id[id_[i]] = mat_[i];
    res.material.resize(res.x.size());
    for (std::size_t k = 0; k < res.x.size(); ++k) res.material[k] = by_id[res.id.empty() ? k : res.id[k]];
  }
  res.grains_out = grains_out_;
  res.mass_out = mass_out_;
  res.grains_in = grains_in_;
  res.mass_in = mass_in_;
  for (const auto& c : clocks_) res.inlets.push_back(c.report());
  res.max_overlap = max_abs_;
  res.max_overlap_relative = max_rel_;
  s.steps = steps_;
  s.dt = dt_;
  record_plan(s, plan_);
  s.skin = skin_;
  s.rebuilds = rebuilds_;
  s.threads = T_;
  res.wall_seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  s.particle_steps_per_second =
      particle_steps_ / std::max(res.wall_seconds, 1e-9);
  return res;
}

}  // namespace

template <int D>
RunResult<D> run_tdm(System<D> system, const TdmSettings& settings, const std::vector<Observer<D>*>& observers,
                     const SoftPlan* plan) {
  TdmEngine<D> engine(system, settings, observers, plan);
  return engine.run();
}

template <int D>
SoftPlan tdm_preflight(const System<D>& system, const TdmSettings& settings) {
  return preflight(system, settings);
}

template SoftPlan tdm_preflight<2>(const System<2>&, const TdmSettings&);
template SoftPlan tdm_preflight<3>(const System<3>&, const TdmSettings&);
template RunResult<2> run_tdm<2>(System<2>, const TdmSettings&, const std::vector<Observer<2>*>&, const SoftPlan*);
template RunResult<3> run_tdm<3>(System<3>, const TdmSettings&, const std::vector<Observer<3>*>&, const SoftPlan*);

}  // namespace matep

// The event-driven core (EDM) of smooth and rough hard spheres (D = 3) and disks (D = 2): lazy
// particle state, event prediction from cell lists, the event queue and the system events.
//
// One event per particle lives in the queue (the earliest of its predicted pair collision, wall
// collision and cell crossing); stale events are recognised by per-particle collision counters
// (Smallenburg, Eur. Phys. J. E 45, 22 (2022), "Single" variant). Particles carry their own time
// and are advanced only when an event touches them; predictions use a neighbour's stored state
// without writing it (the lesson from DynamO's profile in DESIGN.md). Timed events of the run
// itself (thermo samples, snapshots, the end, an extension's substeps) are SystemEvent objects
// scheduled under ids N, N + 1, ... after the particles.
//
// Read top to bottom: set-up (init), the event loop (run), cells, motion, prediction, handling,
// collisions, observers. The core is a CRTP base: pure EDM (engine/edm/edm.cpp) adds nothing, the
// hybrid (engine/hybrid/) extends it through the hooks in "Extension hooks" below, which a pure
// EDM run resolves at compile time to nothing.
#pragma once

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "contact/fixed.hpp"
#include "contact/hard.hpp"
#include "contact/predict.hpp"
#include "contact/rough.hpp"
#include "contact/soft.hpp"
#include "contact/wall.hpp"
#include "engine/edm.hpp"
#include "engine/edm/collapse.hpp"
#include "engine/edm/neighbours.hpp"
#include "engine/grid.hpp"
#include "engine/huge_pages.hpp"
#include "engine/impulse_tally.hpp"
#include "engine/renumber.hpp"
#include "engine/rough_rules.hpp"
#include "engine/state_archive.hpp"
#include "engine/wall_loads.hpp"

namespace matep::edm {

template <int D>
struct alignas(D == 3 ? 64 : 16) Hot {
  Vec<D> x;      // position at time t
  Vec<D> v;      // velocity at time t
  double t;      // the particle's own (lazy) time
  double R;      // radius
};

// A timed event of the run itself, scheduled by the core under id N + its index. fire(t) handles
// it (and reschedules it if it recurs); returning false ends the run.
struct SystemEvent {
  const char* name;
  std::function<bool(double)> fire;
};

template <int D, class Queue, class Derived>
class EdmCore {
 public:
  template <class T>
  using Array = std::vector<T, HugePageAllocator<T>>;

  EdmCore(System<D>&& system, const EdmSettings& set, const std::vector<Observer<D>*>& obs)
      : sys_(std::move(system)), set_(set), N0_(static_cast<int>(sys_.size())),
        N_(N0_ + static_cast<int>(inlet_slots(sys_.inlets, set.end_time))) {
    for (auto* o : obs) {
      if (!o) continue;
      observers_.push_back(o);
      if (o->wants_collisions()) collision_observers_.push_back(o);
    }
  }

  // ---- extension hooks (the defaults: pure EDM) -----------------------------------------------
  // Called by init before the particle arrays of the system are released.
  void ext_setup() {}
  // Extra width of the cells beyond one largest diameter (the hybrid: its list skin).
  double ext_cell_margin() const { return 0.0; }
  // After the cells are built (rmax: the largest radius).
  void ext_cells_ready(double) {}
  // At t = 0, before the first sample and the first predictions.
  void ext_start() {}
  // Whether i flies between predicted events (its stored state may be extrapolated in time).
  bool moved_by_events(int) const { return true; }
  // Whether i's predicted events are live (a hard particle).
  bool predicted(int) const { return true; }
  // Whether neighbour j takes no part in i's pair predictions.
  bool ext_skip_neighbour(int, int) { return false; }
  // i's course changed (a new full prediction).
  void ext_on_predict(int) {}
  // A predicted collision of touching hard particles i and j (or i and wall w) at t: true when the
  // extension takes it over instead of the hard collision.
  bool ext_divert_pair(int, int, double) { return false; }
  // A pair event of i and j is being handled: what ext_divert_pair will read may be fetched now.
  void ext_prefetch_pair(int, int) {}
  // i's event is next in the queue (handled after the present one): what its handling reads first
  // may be fetched now.
  void ext_prefetch_next(int) {}
  bool ext_divert_wall(int, int, double) { return false; }
  void ext_snapshot(Snapshot<D>&) {}
  void ext_sample(ThermoSample&) {}
  void ext_result(RunResult<D>&) {}
  // Grain i has just been taken out by an outlet (its cell and queue entry are gone).
  void ext_removed(int) {}
  // Grain i has just been inserted by an inlet at t (in its cell; predicted after this hook).
  void ext_inserted(int, double) {}
  // The collapse watch of hard particle i fired at a collision just resolved: true when the
  // extension takes i over instead of the run ending with status "collapse".
  bool ext_collapse(int) { return false; }
  // Whether the core may find pair candidates from per-particle neighbour lists (EdmSettings::
  // lists).
  bool ext_lists() const { return true; }
  // How much farther apart than touching two shells may be and still list each other (the
  // hybrid: its largest capture distance, so that a hard grain that may be captured by a soft one
  // finds it in its list).
  double ext_list_margin() const { return 0.0; }
  // Whether the core may re-sort the particles' storage now (EdmSettings::resort; the hybrid: only
  // while no grain is soft, pending or asleep); if not, the re-sort waits for the next one due.
  bool ext_can_resort() const { return true; }
  // The extension's own arrays by particle index, permuted with the core's: permute(array) moves
  // row i to to[i] (an array not of N_ rows is left alone), and to[] renames a stored index.
  template <class Permute>
  void ext_permute(Permute&, const std::vector<std::uint32_t>&) {}
  // Whether the run may stop now on a stop request (an extension a step ahead says no; it must
  // then be ready at a later poll).
  bool ext_can_stop() const { return true; }

  // The scene's id of each particle, when the engine runs its grains in another order
  // (engine/renumber.hpp): the messages name grains by it, and it is the map the run reports
  // through (its observers wrapped in UserIds over it, its result mapped by to_user), which the
  // core keeps up to date when it re-sorts the particles (EdmSettings::resort).
  void track_ids(IdMap* ids) { ids_ = ids; }

  // Registers a system event; its id is the returned value (valid once init has run).
  int add_system_event(const char* name, std::function<bool(double)> fire) {
    system_.push_back({name, std::move(fire)});
    return N_ + static_cast<int>(system_.size()) - 1;
  }

  // Everything from the system, once the derived engine is constructed.
  void init(const RoughRules* rough) {
    const System<D>& sys = sys_;
    sys.check_fixed();
    n_fixed_ = static_cast<int>(sys.fixed_count());
    if (n_fixed_ > 0) fixed_ = sys.fixed;
    g_ = sys.gravity;
    gravity_ = g_.squaredNorm() > 0.0;
    lo_ = sys.lower;
    hi_ = sys.upper;
    L_ = hi_ - lo_;
    collapse_depth_ = CollapseWatch::depth_units(set_.collapse_decades);
    now_ = last_sample_time_ = last_snapshot_time_ = set_.start_time;
    // System events, in this order: thermo sampler, end of run, snapshots, then the extension's.
    sample_id_ = add_system_event("thermo", [this](double t) { return on_sample_event(t); });
    end_id_ = add_system_event("end", [this](double t) {
      save_checkpoint(t);  // the state at the end, to continue from
      return false;
    });
    snapshot_id_ = add_system_event("snapshot", [this](double t) { return on_snapshot_event(t); });
    // Checkpoints every interval: the event saves the state and changes nothing, so that a run with
    // them follows the same course as one without.
    if (set_.checkpoint && set_.checkpoint->interval > 0.0)
      checkpoint_id_ = add_system_event("checkpoint", [this](double t) { return on_checkpoint_event(t); });
    // Inlets: one system event each, and a particle slot per grain due (engine/inlet.hpp), absent
    // until inserted (with the inlet's largest radius, so that the cells hold it).
    next_id_ = N0_;
    for (std::size_t k = 0; k < sys_.inlets.size(); ++k) {
      const Inlet<D>& in = sys_.inlets[k];
      clocks_.emplace_back(in, k, set_.end_time);
      inlet_ids_.push_back(add_system_event("inlet", [this, k](double t) { return on_inlet_event(k, t); }));
      for (std::uint64_t s = 0; s < clocks_.back().slots; ++s) {
        sys_.x.push_back(sys_.lower);
        sys_.v.push_back(Vec<D>::Zero());
        sys_.radius.push_back(in.rmax);
        sys_.material.push_back(in.material);
        if (!sys_.w.empty()) sys_.w.push_back(Spin<D>::Zero());
        if (!sys_.fixed.empty()) sys_.fixed.push_back(0);
      }
    }
    if (n_fixed_ > 0) fixed_ = sys_.fixed;  // with the slots' flags
    if (N_ > N0_) {
      removed_.assign(static_cast<std::size_t>(N_), 0);
      std::fill(removed_.begin() + N0_, removed_.end(), std::uint8_t{1});
      absent_ = true;
    }

    derived().ext_setup();
    const double packing = sys.moving_packing(static_cast<std::size_t>(N0_));  // before the radii are released
    // Copy the input into the engine's arrays one array at a time, releasing each input array
    // as soon as it is copied (peak memory).
    hot_.resize(N_);
    double rmax = 0.0;
    for (int i = 0; i < N_; ++i) {
      hot_[i].x = sys.x[i];
      hot_[i].v = sys.v[i];
      hot_[i].t = set_.start_time;
      hot_[i].R = sys.radius[i];
      rmax = std::max(rmax, sys.radius[i]);
    }
    free_array(sys_.x);
    free_array(sys_.v);
    free_array(sys_.fixed);
    free_array(sys_.radius);
    cold_.resize(N_);
    for (int i = 0; i < N_; ++i) cold_[i].mat = sys.material[i];
    free_array(sys_.material);
    // m = density * ball volume (System::mass), as a per-material factor times R^D.
    for (const auto& mat : sys_.materials) mass_factor_.push_back(mat.density * ball_volume<D>(1.0));
    // The queue is allocated after the input arrays are gone (peak memory).
    queue_.emplace(static_cast<std::size_t>(N_) + std::max<std::size_t>(4, system_.size()));
    all_elastic_ = true;
    for (const auto& mat : sys.materials) all_elastic_ = all_elastic_ && mat.restitution.is_elastic();
    for (const auto& wall : sys.walls) {
      shapes_.push_back(wall.shape.get());
      anchors_.push_back(wall.shape->anchor());
      bracketed_walls_ = bracketed_walls_ || wall.geometry().bracketed();
    }
    wall_loads_.resize(shapes_.size());
    face_outlet_.fill(-1);
    for (std::size_t o = 0; o < sys.outlets.size(); ++o) {
      const Outlet<D>& out = sys.outlets[o];
      if (out.face >= 0) face_outlet_[static_cast<std::size_t>(out.face)] = static_cast<int>(o);
      else outlets_.push_back({out.region, static_cast<int>(o)});
    }
    setup_rough(rough);
    const double margin = derived().ext_cell_margin();
    lists_ = lists_chosen(set_.lists, set_.lists_auto, packing, gravity_, static_cast<std::size_t>(N_)) &&
             derived().ext_lists();
    sphere_ = lists_ && !gravity_;
    if (lists_) {
      shell_ = set_.shell * 2.0 * rmax;
      list_margin_ = derived().ext_list_margin();
      build_cells(2.0 * rmax, margin + 2.0 * shell_);
      build_lists();
    } else {
      build_cells(2.0 * rmax, margin);
    }
    derived().ext_cells_ready(rmax);
    const double every = resort_interval(set_.resort, static_cast<std::size_t>(N0_), packing);
    resort_step_ = every > 0.0 ? std::max<std::uint64_t>(1, static_cast<std::uint64_t>(every * N0_)) : 0;
  }

  template <class V>
  static void free_array(V& v) {
    V().swap(v);
  }

  // Whether i is a fixed grain (System::fixed): never predicted, never moved.
  bool is_fixed(int i) const { return n_fixed_ > 0 && fixed_[i] != 0; }
  static std::uint32_t ui(int i) { return static_cast<std::uint32_t>(i); }  // a particle index as an id
  // Whether i is absent: it has left through an outlet, or an inlet has not inserted it yet.
  bool is_removed(int i) const { return absent_ && removed_[i] != 0; }
  // Whether i flies between its events (its stored state may be extrapolated in time).
  bool flies(int i) const { return !is_fixed(i) && !is_removed(i) && derived().moved_by_events(i); }

  double mass(int i) const {
    const double R = hot_[i].R;
    return D == 3 ? mass_factor_[cold_[i].mat] * R * R * R : mass_factor_[cold_[i].mat] * R * R;
  }

  // ---- the event loop -------------------------------------------------------------------------
  RunResult<D> run() {
    const auto wall0 = std::chrono::steady_clock::now();
    for (auto* o : observers_)
      if (o->wants_snapshots()) snapshot_observers_.push_back(o);
    snapshots_ = set_.snapshot_interval > 0.0 && !snapshot_observers_.empty();
    for (auto* o : snapshot_observers_) contacts_ = contacts_ || (snapshots_ && o->wants_contacts());
    if (set_.checkpoint && set_.checkpoint->resume) {
      // Continue a saved state: the samples and snapshots up to it are already written.
      StateReader r(*set_.checkpoint->resume);
      derived().archive(r);
      if (!r.done()) throw StateError("the engine state is longer than this scene's (a checkpoint of another scene)");
      if (resort_step_) resort_at_ = (processed_ / resort_step_ + 1) * resort_step_;  // as the saved run had it
      // The end (popped when the state was saved at it), and the recurring events a longer run
      // still has due.
      queue_->set(end_id_, set_.end_time);
      rearm(sample_id_, sample_k_, set_.thermo_interval);
      if (snapshots_) rearm(snapshot_id_, snapshot_k_, set_.snapshot_interval);
      if (checkpoint_id_ >= 0) rearm(checkpoint_id_, checkpoint_k_, set_.checkpoint->interval);
    } else {
      const double t0 = set_.start_time;
      derived().ext_start();
      emit_sample(t0, /*interval=*/0.0);
      for (int i = 0; i < N_; ++i)
        if (!is_fixed(i) && !is_removed(i) && derived().predicted(i)) predict(i, t0);
      for (std::size_t k = 0; k < clocks_.size(); ++k)
        if (clocks_[k].pending()) queue_->set(inlet_ids_[k], clocks_[k].next_time());
      queue_->set(end_id_, set_.end_time);
      if (snapshots_) emit_snapshot(t0);
      rearm(sample_id_, 1, set_.thermo_interval);
      if (snapshots_) rearm(snapshot_id_, 1, set_.snapshot_interval);
      if (checkpoint_id_ >= 0) rearm(checkpoint_id_, 1, set_.checkpoint->interval);
    }

    RunResult<D> res;
    std::uint64_t polls = 0;
    while (!queue_->empty()) {
      if (resort_step_ && processed_ >= resort_at_) resort();
      // A stop request (a signal): leave before the next event, with the state after the last
      // (saved first when the run keeps checkpoints).
      if ((++polls & 0x3ff) == 0 && set_.stop && set_.stop->load(std::memory_order_relaxed) &&
          derived().ext_can_stop()) {
        status_ = "interrupted";
        message_ = fmt::format("stopped on request at t = {:.17g}", now_);
        save_checkpoint(now_);
        break;
      }
      const auto [id, t] = queue_->top();
      queue_->pop();
      now_ = t;
      if (id >= N_) {  // a system event
        if (!system_[static_cast<std::size_t>(id - N_)].fire(t)) break;
        continue;
      }
      if (processed_++ >= set_.max_events) {
        status_ = "max_events";
        message_ = fmt::format("stopped after run.max_events = {} events at t = {:.17g}",
                               set_.max_events, t);
        break;
      }
      if ((processed_ & 0x3fff) == 0)
        for (auto* o : observers_) o->on_progress(t, processed_);
      // Start fetching the next event's particle while this one is handled (large systems).
      if (!queue_->empty()) {
        const int next_id = queue_->top().first;
        if (next_id < N_) {
          __builtin_prefetch(&hot_[next_id]);
          __builtin_prefetch(&cold_[next_id]);
          derived().ext_prefetch_next(next_id);
        }
      }
      handle(id, t);
      if (!status_.empty()) break;
    }
    // Bring every particle to the final time and write the last row.
    const double t_end = status_.empty() ? set_.end_time : now_;
    // Particles moved by an extension stay where it left them.
    for (int i = 0; i < N_; ++i)
      if (flies(i)) advance(i, t_end);
    if (t_end > last_sample_time_ || counts_.samples == 1) emit_sample(t_end, t_end - last_sample_time_);
    if (snapshots_ && t_end > last_snapshot_time_) emit_snapshot(t_end);

    res.lists = lists_;
    res.resorts = resorts_;
    res.status = status_.empty() ? "ok" : status_;
    res.message = message_;
    res.time = t_end;
    res.counts = counts_;
    derived().ext_result(res);
    measure_overlaps(res);
    // Free the scheduling state before the result's arrays are allocated (peak memory).
    queue_.reset();
    free_array(head_);
    free_array(next_);
    res.material.resize(N_);
    for (int i = 0; i < N_; ++i) res.material[i] = cold_[i].mat;
    free_array(cold_);
    res.x.resize(N_);
    res.v.resize(N_);
    res.radius.resize(N_);
    for (int i = 0; i < N_; ++i) {
      res.x[i] = hot_[i].x;
      res.v[i] = hot_[i].v;
      res.radius[i] = hot_[i].R;
    }
    res.w = std::move(sys_.w);
    res.grains_out = grains_out_;
    res.mass_out = mass_out_;
    res.grains_in = grains_in_;
    res.mass_in = mass_in_;
    for (const auto& c : clocks_) res.inlets.push_back(c.report());
    if (absent_) keep_present(res, removed_);
    res.wall_seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
    return res;
  }

 protected:
  Derived& derived() { return static_cast<Derived&>(*this); }
  const Derived& derived() const { return static_cast<const Derived&>(*this); }

  // ---- system events ----------------------------------------------------------------------------
  bool on_sample_event(double t) {
    emit_sample(t, t - last_sample_time_);
    last_sample_time_ = t;
    ++sample_k_;
    const double next = set_.start_time + static_cast<double>(sample_k_) * set_.thermo_interval;
    // The end of the run writes its own row; skip a sample that would fall on it.
    if (next < set_.end_time * (1.0 - 1e-12)) queue_->set(sample_id_, next);
    return true;
  }
  // Schedules recurring event id at its k-th time (start_time + k interval) when it is due before the
  // end and not queued.
  void rearm(int id, std::uint64_t k, double interval) {
    if (id < 0 || interval <= 0.0 || queue_->contains(id)) return;
    const double next = set_.start_time + static_cast<double>(k) * interval;
    if (next >= now_ && next < set_.end_time * (1.0 - 1e-12)) queue_->set(id, next);
  }
  bool on_checkpoint_event(double t) {
    ++checkpoint_k_;
    const double next = set_.start_time + static_cast<double>(checkpoint_k_) * set_.checkpoint->interval;
    if (next < set_.end_time * (1.0 - 1e-12)) queue_->set(checkpoint_id_, next);
    save_checkpoint(t);
    return true;
  }

  // ---- checkpoints (engine/state_archive.hpp) ---------------------------------------------------
  // Hands the state between two events to the run (nothing when it keeps no checkpoints).
  void save_checkpoint(double t) {
    if (!set_.checkpoint || !set_.checkpoint->save) return;
    set_.checkpoint->save(t, [&](StateWriter& w) { derived().archive(w); });
  }
  struct QueueEntry {
    int id;
    double t;
  };
  // Everything the core's future depends on; what init makes from the scene is made again. The
  // queue is saved as its entries: its order is the total order on (t, id) (scheduler/), so the
  // entries alone fix what pops next.
  template <class A>
  void archive_core(A& a) {
    a.tag("edm.particles");
    a(now_);
    a(processed_);
    a.same(hot_, "particle slots");
    a.same(cold_, "particle slots");
    a.same(head_, "cells");
    a.same(next_, "particle slots");
    a.same(sys_.w, "spins");
    if (lists_) {
      a.tag("edm.lists");
      a.check(shell_, "the neighbour lists' shell");
      a.same(shell_c_, "particle slots");
      a(nb_cap_);
      a(nb_);
      a.same(nb_n_, "particle slots");
    }
    a.tag("edm.order");
    a(ids_->entries());
    a(resorts_);
    if constexpr (A::loading)
      if (ids_ == &own_ids_ && !ids_->entries().empty())
        throw StateError("the engine state is of a run that re-sorts its particles (run.resort) and this run reports in the engine's order");
    a.tag("edm.flows");
    a(removed_);
    a(absent_);
    a(grains_out_);
    a(mass_out_);
    a.same(clocks_, "inlets");
    a(next_id_);
    a(grains_in_);
    a(mass_in_);
    a.tag("edm.counters");
    a(wall_loads_);
    a(impulses_);
    a(counts_);
    a(virial_);
    a(prev_ke_);
    a(sample_k_);
    a(snapshot_k_);
    a(checkpoint_k_);
    a(last_sample_time_);
    a(last_snapshot_time_);
    a.tag("edm.queue");
    std::vector<QueueEntry> q;
    if constexpr (!A::loading) {
      const int ids = N_ + static_cast<int>(system_.size());
      for (int id = 0; id < ids; ++id)
        if (queue_->contains(id)) q.push_back({id, queue_->time_of(id)});
    }
    a(q);
    if constexpr (A::loading) {
      const int ids = N_ + static_cast<int>(system_.size());
      queue_->clear();
      for (const QueueEntry& e : q) {
        if (e.id < 0 || e.id >= ids || e.t != e.t)
          throw StateError("the engine state lists an event that this scene does not have (another scene)");
        queue_->set(e.id, e.t);
      }
    }
  }
  // Pure EDM: the core is the whole state.
  template <class A>
  void archive(A& a) {
    archive_core(a);
  }

  bool on_snapshot_event(double t) {
    emit_snapshot(t);
    last_snapshot_time_ = t;
    ++snapshot_k_;
    const double next = set_.start_time + static_cast<double>(snapshot_k_) * set_.snapshot_interval;
    if (next < set_.end_time * (1.0 - 1e-12)) queue_->set(snapshot_id_, next);
    return true;
  }

  enum : std::uint8_t { kNone = 0, kPair = 1, kWall = 2, kOutlet = 3 };

  // ---- cells ---------------------------------------------------------------------------------
  // Cells at least one largest diameter dmax plus an extension's list skin (margin) wide
  // (engine/grid.hpp), at most about two per particle (memory: coarsened, or hashed when the domain
  // is mostly empty), filled as linked lists whose first two entries the cell holds itself
  // (CellHead).
  void build_cells(double dmax, double margin) {
    check_periodic_axes<D>(lo_, hi_, sys_.periodic, dmax, margin);
    grid_.build(lo_, hi_, sys_.periodic, dmax + margin, std::max(64.0, 2.0 * N_), 1 << 20, /*hash=*/true);
    head_.assign(grid_.cells(), CellHead{});
    next_.assign(N_, -1);
    for (int i = 0; i < N_; ++i) {
      if (is_removed(i)) continue;  // a slot an inlet fills later
      cold_[i].cell = grid_.coords(hot_[i].x);
      cell_insert(i);
    }
  }
  int linear(const std::array<int, D>& c) const { return grid_.linear(c); }
  void cell_insert(int i) {
    CellHead& c = head_[linear(cold_[i].cell)];
    next_[i] = c.first;
    c.second = c.first;
    c.first = i;
  }
  void cell_remove(int i) {
    // Cells hold a particle or two: walking the list is cheaper than a back link per particle.
    CellHead& c = head_[linear(cold_[i].cell)];
    int* link = &c.first;
    while (*link != i) link = &next_[*link];
    *link = next_[i];
    c.second = c.first >= 0 ? next_[c.first] : -1;
  }
  // f(j) for the particles of cell lin, in the list's order (the last inserted first).
  template <class F>
  void for_cell(int lin, F&& f) const {
    const CellHead c = head_[lin];
    if (c.first < 0) return;
    f(c.first);
    for (int j = c.second; j >= 0; j = next_[j]) f(j);
  }

  // Visits the particles j != i of the cells around i's cell, f(j, shift) with the image shift
  // that brings j next to i. With layer_axis < 0 these are all 3^D cells; else only the layer one
  // cell further along layer_axis in direction layer_dir (the cells that just came into range
  // after a cell crossing).
  template <class F>
  void for_neighbours(int i, F&& f, int layer_axis = -1, int layer_dir = 0) const {
    walk_cells(i, f, [this](int j) { __builtin_prefetch(&hot_[j]); }, layer_axis, layer_dir);
  }
  // for_neighbours with the record to prefetch for each candidate chosen by the caller (`fetch(j)`:
  // the particle state for a prediction, the shell for a list build).
  template <class F, class Fetch>
  void walk_cells(int i, F&& f, Fetch&& fetch, int layer_axis = -1, int layer_dir = 0) const {
    const std::array<int, D> c = cold_[i].cell;
    // Fast path: a cell away from the grid's faces has its neighbours at fixed linear offsets.
    if (grid_.interior(c)) {
      const int lin = linear(c);
      const auto& offs = grid_.offsets(layer_axis, layer_dir);
      const Vec<D> zero = Vec<D>::Zero();
      // Collect first, prefetching each candidate, then test: the misses of a large system
      // overlap instead of following one another.
      constexpr int kBuf = 128;
      int buf[kBuf];
      int n = 0;
      for (const int off : offs)
        for_cell(lin + off, [&](int j) {
          if (j == i) return;
          if (n < kBuf) {
            fetch(j);
            buf[n++] = j;
          } else {
            f(j, zero);
          }
        });
      for (int m = 0; m < n; ++m) f(buf[m], zero);
      return;
    }
    grid_.around(
        c,
        [&](int lin, const Vec<D>& shift) {
          for_cell(lin, [&](int j) {
            if (j != i) f(j, shift);
          });
        },
        layer_axis, layer_dir);
  }

  // f(j, shift) for the particles j != i whose centres may lie within `reach` of i's (beyond the
  // cells around i's when reach exceeds a cell width: an extension whose lists reach further than
  // the cells' margin, the hybrid's soft list; at most two cell widths).
  template <class F>
  void for_neighbours_reach(int i, double reach, F&& f) const {
    double wmin = kNever;
    for (int k = 0; k < D; ++k) wmin = std::min(wmin, grid_.width(k));
    // With lists the cells hold each grain by its shell's centre, within shell_ of it per axis.
    if (reach + 2.0 * shell_ <= wmin) {
      for_neighbours(i, f);
      return;
    }
    grid_.around_wide(cold_[i].cell, [&](int lin, const Vec<D>& shift) {
      for_cell(lin, [&](int j) {
        if (j != i) f(j, shift);
      });
    });
  }

  // f(j, shift) for the particles of i's neighbour list (lists_), shift as for_neighbours gives it.
  template <class F>
  void for_list(int i, F&& f) const {
    const std::size_t b = static_cast<std::size_t>(i) * nb_cap_;
    for (int m = 0, n = nb_n_[i]; m < n; ++m)
      f(nb_id(nb_[b + m]), any_periodic_ ? Vec<D>(-shifts_[nb_shift(nb_[b + m])]) : Vec<D>(Vec<D>::Zero()));
  }

  // ---- re-sorting (EdmSettings::resort) ----------------------------------------------------------
  // The particles' storage in the Z (Morton) order of their cells (engine/edm/neighbours.hpp
  // morton_key), so that the records an event reads, its particle's and its candidates', lie near
  // one another in memory however the grains have mixed. Every record moves with all that names
  // it: the predictions' partners, the neighbour lists, the cells, the queue, the contacts' tally
  // and the map to the scene's ids (IdMap::permute), so that what the run reports is unchanged
  // but for the order in which events due at exactly the same time pop (the queue breaks such
  // ties by index). Particles keep their own times: nothing is advanced. Absent slots go last in
  // their order (an inlet's unfilled slots stay where it fills them, next_id_ onwards).
  void resort() {
    resort_at_ = (processed_ / resort_step_ + 1) * resort_step_;
    if (!derived().ext_can_resort()) return;
    const std::size_t n = static_cast<std::size_t>(N_);
    // The new order: by key, then by index; from[k] is the particle that becomes k, to its inverse.
    std::vector<std::uint32_t> from(n), to(n);
    {
      std::array<int, D> lo;
      lo.fill(std::numeric_limits<int>::max());
      for (int i = 0; i < N_; ++i)
        if (!is_removed(i))
          for (int k = 0; k < D; ++k) lo[k] = std::min(lo[k], cold_[i].cell[k]);
      std::vector<std::pair<std::uint64_t, std::uint32_t>> key(n);
      for (int i = 0; i < N_; ++i) {
        std::array<std::uint32_t, D> c{};
        for (int k = 0; k < D; ++k) c[k] = static_cast<std::uint32_t>(cold_[i].cell[k] - lo[k]);
        key[i] = {is_removed(i) ? std::numeric_limits<std::uint64_t>::max() : morton_key<D>(c), ui(i)};
      }
      std::sort(key.begin(), key.end());
      for (std::size_t k = 0; k < n; ++k) from[k] = key[k].second;
    }
    bool same = true;
    for (std::size_t k = 0; k < n; ++k) {
      to[from[k]] = static_cast<std::uint32_t>(k);
      same = same && from[k] == k;
    }
    if (same) return;
    ++resorts_;
    // Each array permuted in place along the permutation's cycles (rows of `width` elements): no
    // array is copied (peak memory).
    std::vector<bool> done;
    const auto permute = [&](auto& a, std::size_t width = 1) {
      if (width == 0 || a.size() != n * width) return;  // an optional array that is empty
      done.assign(n, false);
      std::vector<std::decay_t<decltype(a[0])>> row(width);
      for (std::size_t s = 0; s < n; ++s) {
        if (done[s]) continue;
        std::copy_n(a.begin() + static_cast<std::ptrdiff_t>(s * width), width, row.begin());
        std::size_t k = s;
        for (;;) {
          done[k] = true;
          const std::size_t j = from[k];
          auto dst = a.begin() + static_cast<std::ptrdiff_t>(k * width);
          if (j == s) {
            std::copy_n(row.begin(), width, dst);
            break;
          }
          std::copy_n(a.begin() + static_cast<std::ptrdiff_t>(j * width), width, dst);
          k = j;
        }
      }
    };
    permute(hot_);
    permute(cold_);
    for (Cold& c : cold_)
      if (c.type == kPair && c.partner >= 0) c.partner = static_cast<int>(to[static_cast<std::size_t>(c.partner)]);
    permute(fixed_);
    permute(removed_);
    permute(sys_.w);
    if (lists_) {
      const std::size_t cap = static_cast<std::size_t>(nb_cap_);
      permute(shell_c_);
      permute(nb_, cap);
      permute(nb_n_);
      for (std::size_t k = 0; k < n; ++k)
        for (std::size_t m = 0; m < nb_n_[k]; ++m) {
          std::uint32_t& e = nb_[k * cap + m];
          e = nb_entry(static_cast<int>(to[static_cast<std::size_t>(nb_id(e))]), nb_shift(e));
        }
    }
    derived().ext_permute(permute, to);
    // The cells again, each particle in the cell it was in (its position's, or its shell's centre's).
    std::fill(head_.begin(), head_.end(), CellHead{});
    std::fill(next_.begin(), next_.end(), -1);
    for (int i = 0; i < N_; ++i)
      if (!is_removed(i)) cell_insert(i);
    // The queue again, the particles' entries under their new indices.
    {
      std::vector<double> due(n, std::numeric_limits<double>::quiet_NaN());
      for (int i = 0; i < N_; ++i)
        if (queue_->contains(i)) due[static_cast<std::size_t>(i)] = queue_->time_of(i);
      std::vector<QueueEntry> sys;
      for (int id = N_; id < N_ + static_cast<int>(system_.size()); ++id)
        if (queue_->contains(id)) sys.push_back({id, queue_->time_of(id)});
      queue_->clear();
      for (std::size_t k = 0; k < n; ++k)
        if (const double t = due[from[k]]; t == t) queue_->set(static_cast<int>(k), t);
      for (const QueueEntry& e : sys) queue_->set(e.id, e.t);
    }
    impulses_.renumber(to);
    ids_->permute(from);
  }

  // ---- neighbour lists (EdmSettings::lists) -----------------------------------------------------
  // Each particle keeps the particles that may meet it while both stay inside their shells, the
  // construction of Smallenburg's EDMD (Eur. Phys. J. E 45, 22 (2022)): a shell of size shell_
  // about the centre the particle had when its list was made. Without gravity the shell is a ball
  // of radius shell_ (its exit solves |x + v t - c| = shell_, EDMD's formula), and the domain's
  // faces are crossings of their own; under gravity, where the ball's exit is a quartic, it is a
  // cube of half-width shell_ clipped to the domain's faces (a per-axis quadratic, as a cell face).
  // j is in i's list exactly when the two shells come closer than R_i + R_j (plus list_margin_,
  // an extension's), and then i is in j's (the lists are symmetric). A pair that meets does so
  // inside both shells, so it is in both lists at the predictions that find it; leaving the shell is an event (it replaces the cell
  // crossing) that makes a new list about the particle's centre there. The cells hold each
  // particle by its shell's centre and are one largest diameter plus two shells wide, so the 3^D
  // cells around a centre hold every particle whose shell may come within reach.
  bool lists_ = false;
  bool sphere_ = false;       // ball shells (no gravity); else cubes
  double shell_ = 0.0;        // the shells' radius (cubes: half-width)
  double list_margin_ = 0.0;  // ext_list_margin(): listed while the shells come closer than R_i + R_j + this
  int nb_cap_ = 0;            // entries per particle in nb_ (grown when a list would overflow)
  // A shell's centre and its particle's radius, side by side (what a list build reads of each
  // candidate).
  struct alignas(D == 3 ? 32 : 8) Shell {
    Vec<D> c;
    double R;
  };
  Array<Shell> shell_c_;      // shells
  // List of i: nb_[i * nb_cap_ + m], m < nb_n_[i]; each entry the partner's index and, above it,
  // its image shift index (CellGrid::shift_index; read in periodic scenes only) in one word
  // (engine/edm/neighbours.hpp kListIdBits): one load per candidate, 4 bytes an entry.
  Array<std::uint32_t> nb_;
  Array<std::uint16_t> nb_n_;  // entries in i's list
  static constexpr std::uint32_t kIdMask = (std::uint32_t{1} << kListIdBits) - 1;
  static_assert(CellGrid<D>::kStencil <= (1 << (32 - kListIdBits)), "an image shift index fits above the index");
  static int nb_id(std::uint32_t e) { return static_cast<int>(e & kIdMask); }
  static std::uint8_t nb_shift(std::uint32_t e) { return static_cast<std::uint8_t>(e >> kListIdBits); }
  static std::uint32_t nb_entry(int j, std::uint8_t sh) {
    return static_cast<std::uint32_t>(j) | (static_cast<std::uint32_t>(sh) << kListIdBits);
  }
  std::array<Vec<D>, CellGrid<D>::kStencil> shifts_{};  // shift_table(): added to x_i - x_j
  bool any_periodic_ = false;

  // Whether the shells of i and j (j's image moved by `shift`, as for_neighbours passes it) come
  // closer than R_i + R_j: the per-axis gaps of two cubes of half-width shell_.
  bool shells_meet(const Shell& a, const Shell& b, const Vec<D>& shift) const {
    const Vec<D> d = a.c - b.c - shift;
    if (sphere_) {
      const double s = a.R + b.R + 2.0 * shell_ + list_margin_;
      return d.squaredNorm() < s * s;
    }
    double g2 = 0.0;
    for (int k = 0; k < D; ++k) {
      const double gk = std::abs(d[k]) - 2.0 * shell_;
      if (gk > 0.0) g2 += gk * gk;
    }
    const double s = a.R + b.R + list_margin_;
    return g2 < s * s;
  }
  void nb_append(int i, int j, std::uint8_t sh) {
    if (nb_n_[i] == nb_cap_) nb_grow();
    const std::size_t at = static_cast<std::size_t>(i) * nb_cap_ + nb_n_[i];
    nb_[at] = nb_entry(j, sh);
    ++nb_n_[i];
  }
  // Gives every list 16 more entries (rare: a list longer than any before). Whole cache lines of
  // 16 entries: a list that straddles two lines costs a second miss at each prediction (measured
  // at packing 0.445: room grown by quarters, 12 to 20 entries, ran about 10 % slower).
  void nb_grow() {
    const int cap = nb_cap_ + 16;
    if (cap > 65535) throw std::runtime_error("a neighbour list would exceed 65535 entries: use a smaller run.shell");
    Array<std::uint32_t> nb(static_cast<std::size_t>(N_) * cap, 0);
    for (int i = 0; i < N_; ++i)
      for (int m = 0; m < nb_n_[i]; ++m)
        nb[static_cast<std::size_t>(i) * cap + m] = nb_[static_cast<std::size_t>(i) * nb_cap_ + m];
    nb_.swap(nb);
    nb_cap_ = cap;
  }
  // Takes i out of its list and of its neighbours' lists (swap with the last entry).
  void unlist(int i) {
    const std::size_t bi = static_cast<std::size_t>(i) * nb_cap_;
    for (int m = 0; m < nb_n_[i]; ++m) {
      const int j = nb_id(nb_[bi + m]);
      const std::size_t bj = static_cast<std::size_t>(j) * nb_cap_;
      const int last = nb_n_[j] - 1;
      for (int q = 0; q <= last; ++q)
        if (nb_id(nb_[bj + q]) == i) {
          nb_[bj + q] = nb_[bj + last];
          break;
        }
      --nb_n_[j];
    }
    nb_n_[i] = 0;
  }
  // i's list about its shell centre, with i added to each neighbour's list; `after_only`: only
  // neighbours of larger index (the first build, which visits every particle).
  void make_list(int i, bool after_only = false) {
    const bool fi = is_fixed(i);
    const Shell si = shell_c_[i];
    const auto add = [&](int j, const Vec<D>& shift) {
      if ((after_only && j < i) || (fi && is_fixed(j)) || !shells_meet(si, shell_c_[j], shift)) return;
      const std::uint8_t sh = any_periodic_ ? grid_.shift_index(shift) : 0;
      nb_append(i, j, sh);
      nb_append(j, i, static_cast<std::uint8_t>(CellGrid<D>::kStencil - 1 - sh));
    };
    walk_cells(i, add, [this](int j) { __builtin_prefetch(&shell_c_[j]); });
  }
  void build_lists() {
    for (int k = 0; k < D; ++k) any_periodic_ = any_periodic_ || sys_.periodic[k];
    shifts_ = grid_.shift_table();
    shell_c_.resize(N_);
    nb_n_.assign(N_, 0);
    nb_cap_ = 0;
    nb_grow();
    for (int i = 0; i < N_; ++i) shell_c_[i] = {hot_[i].x, hot_[i].R};
    for (int i = 0; i < N_; ++i)
      if (!is_removed(i)) make_list(i, /*after_only=*/true);
  }
  // A new shell about i's centre (i at its own time): out of the old lists and cell, into the new.
  void relist(int i) {
    unlist(i);
    cell_remove(i);
    shell_c_[i].c = hot_[i].x;
    cold_[i].cell = grid_.coords(hot_[i].x);
    cell_insert(i);
    make_list(i);
  }
  // Lower and upper bound of i's shell along axis k (the domain's faces clip it).
  double shell_lo(int i, int k) const { return std::max(lo_[k], shell_c_[i].c[k] - shell_); }
  double shell_hi(int i, int k) const { return std::min(hi_[k], shell_c_[i].c[k] + shell_); }

  // ---- motion ---------------------------------------------------------------------------------
  // Where i's flight puts its centre at time t, without advancing it (a fixed grain, or one an
  // extension moves, is where it is stored).
  Vec<D> position_at(int i, double t) const {
    const Hot<D>& h = hot_[i];
    const double dt = flies(i) ? t - h.t : 0.0;
    return h.x + h.v * dt + (0.5 * dt * dt) * g_;
  }
  // Its velocity at time t, likewise.
  Vec<D> velocity_at(int i, double t) const {
    const Hot<D>& h = hot_[i];
    return flies(i) ? Vec<D>(h.v + g_ * (t - h.t)) : h.v;
  }
  void advance(int i, double t) {
    if (!flies(i)) return;  // fixed, or moved by an extension (the hybrid's substeps)
    Hot<D>& h = hot_[i];
    const double dt = t - h.t;
    if (dt == 0.0) return;
    if (gravity_) {
      h.x += h.v * dt + (0.5 * dt * dt) * g_;
      h.v += g_ * dt;
    } else {
      h.x += h.v * dt;
    }
    h.t = t;
  }

  // ---- prediction -----------------------------------------------------------------------------
  // Each particle keeps two predictions: its earliest pair or wall event (ev_*) and its next cell
  // crossing (cross_*); the queue holds the earlier of the two. A crossing does not change the
  // particle's course, so afterwards only the cells that came into range need scanning.

  // Earliest cell-face crossing of particle i (at time `now`), or with neighbour lists its exit
  // from its shell.
  void predict_crossing(int i, double now) {
    const Hot<D>& h = hot_[i];
    double best = kNever;
    std::uint8_t aux = 0;
    for (int k = 0; k < D; ++k) {
      double lo, hi_face;
      if (sphere_) {
        lo = lo_[k];
        hi_face = hi_[k];
      } else if (lists_) {
        lo = shell_lo(i, k);
        hi_face = shell_hi(i, k);
      } else {
        const int c = cold_[i].cell[k];
        const double cw = grid_.width(k);
        lo = (c == 0) ? lo_[k] : lo_[k] + c * cw;
        hi_face = (c == grid_.count(k) - 1) ? hi_[k] : lo_[k] + (c + 1) * cw;
      }
      bool up = false;
      double dt;
      if (g_[k] == 0.0) {  // straight flight along this axis: the face ahead, never behind
        const double vk = h.v[k];
        up = vk > 0.0;
        dt = vk > 0.0 ? (hi_face - h.x[k]) / vk : vk < 0.0 ? (lo - h.x[k]) / vk : kNever;
        if (dt < 0.0) dt = 0.0;  // already past the face by round-off
      } else {
        dt = slab_exit_time(h.x[k], h.v[k], g_[k], lo, hi_face, up);
      }
      if (dt < best) {
        best = dt;
        aux = static_cast<std::uint8_t>(2 * k + (up ? 1 : 0));
      }
    }
    if (sphere_) {  // |x + v t - c| = s (Smallenburg's shell exit)
      const Vec<D> d = h.x - shell_c_[i].c;
      const double b = d.dot(h.v), v2 = h.v.squaredNorm();
      if (v2 > 0.0) {
        const double disc = b * b - v2 * (d.squaredNorm() - shell_ * shell_);
        const double ts = disc > 0.0 ? std::max(0.0, (-b + std::sqrt(disc)) / v2) : 0.0;
        if (ts < best) {
          best = ts;
          aux = 0xFF;
        }
      }
    }
    cold_[i].cross_t = now + best;
    cold_[i].aux = aux;
  }

  // Tests the neighbours of i (all, or one layer) and keeps the earliest pair event if it beats
  // the current best (best, type, partner).
  // An extension may take neighbours out (the hybrid: its soft, pending and sleeping particles).
  void test_pairs(int i, double now, double& best, std::uint8_t& type, int& partner, int layer_axis = -1,
                  int layer_dir = 0) {
    if (lists_) {
      test_list(i, now, best, type, partner);
      return;
    }
    const Hot<D>& hi = hot_[i];
    const Vec<D> xi = hi.x, vi = hi.v;
    const double Ri = hi.R;
    const std::uint8_t* const fixed = n_fixed_ > 0 ? fixed_.data() : nullptr;  // held in a register
    for_neighbours(
        i,
        [&](int j, const Vec<D>& shift) {
          const Hot<D>& hj = hot_[j];
          if (fixed && fixed[j]) [[unlikely]] {
            test_fixed(xi, vi, Ri, j, shift, best, type, partner);
            return;
          }
          if (derived().ext_skip_neighbour(i, j)) return;
          test_moving(Vec<D>(xi - hj.x - shift), vi, Ri, j, now, best, type, partner);
        },
        layer_axis, layer_dir);
  }

  // The same over i's neighbour list.
  void test_list(int i, double now, double& best, std::uint8_t& type, int& partner) {
    const Hot<D>& hi = hot_[i];
    const Vec<D> xi = hi.x, vi = hi.v;
    const double Ri = hi.R;
    const std::uint8_t* const fixed = n_fixed_ > 0 ? fixed_.data() : nullptr;
    const std::size_t b = static_cast<std::size_t>(i) * nb_cap_;
    const std::uint32_t* const L = nb_.data() + b;
    const int n = nb_n_[i];
    for (int m = 0; m < n; ++m) __builtin_prefetch(&hot_[nb_id(L[m])]);
    for (int m = 0; m < n; ++m) {
      const int j = nb_id(L[m]);
      const Hot<D>& hj = hot_[j];
      Vec<D> r = xi - hj.x;
      if (any_periodic_) r += shifts_[nb_shift(L[m])];
      if (fixed && fixed[j]) [[unlikely]] {
        test_fixed(xi, vi, Ri, j, any_periodic_ ? Vec<D>(-shifts_[nb_shift(L[m])]) : Vec<D>(Vec<D>::Zero()), best,
                   type, partner);
        continue;
      }
      if (derived().ext_skip_neighbour(i, j)) continue;
      test_moving(r, vi, Ri, j, now, best, type, partner);
    }
  }

  // The pair time of i (at `now`, velocity vi, radius Ri) with moving j, whose stored position is
  // d away from i's image (d = x_i - x_j with the image shift), kept if it beats best.
  [[gnu::always_inline]] void test_moving(const Vec<D>& d, const Vec<D>& vi, double Ri, int j, double now,
                                          double& best, std::uint8_t& type, int& partner) const {
    const Hot<D>& hj = hot_[j];
    const double dtj = now - hj.t;
    Vec<D> r = d - hj.v * dtj;
    Vec<D> v = vi - hj.v;
    if (gravity_) {
      r -= (0.5 * dtj * dtj) * g_;
      v -= g_ * dtj;
    }
    const double dt = pair_collision_time(r, v, Ri + hj.R, best);
    if (dt < best) {
      best = dt;
      type = kPair;
      partner = j;
    }
  }

  // A fixed neighbour j of i (position xi, velocity vi, radius Ri): an immovable sphere, so only i
  // moves and gravity does not cancel (contact/fixed.hpp). Out of line: the pair loop stays small.
  [[gnu::noinline]] void test_fixed(const Vec<D>& xi, const Vec<D>& vi, double Ri, int j, const Vec<D>& shift,
                                    double& best, std::uint8_t& type, int& partner) const {
    const Hot<D>& hj = hot_[j];
    const double dt = fixed_sphere_impact_time(Vec<D>(xi - hj.x - shift), vi, g_, Ri + hj.R, best);
    if (dt < best) {
      best = dt;
      type = kPair;
      partner = j;
    }
  }

  void schedule(int i) { queue_->set(i, std::min(cold_[i].ev_t, cold_[i].cross_t)); }

  // Full prediction for particle i, which must be at time `now`: crossing, walls, all pairs.
  void predict(int i, double now) {
    if (!derived().predicted(i)) return;  // an extension took i over at this event
    derived().ext_on_predict(i);
    predict_crossing(i, now);
    const Hot<D>& h = hot_[i];
    double best = kNever;
    std::uint8_t type = kNone;
    int partner = -1;
    const std::size_t nw = shapes_.size();
    for (std::size_t w = 0; w < nw; ++w) {
      const WallShape<D>& wall = *shapes_[w];
      if (bracketed_walls_ && wall.bracketed()) continue;  // after the pairs (below)
      const double dt = wall.impact_time(h.x, h.v, g_, h.R, now, kNever);
      if (dt < best) {
        best = dt;
        type = kWall;
        partner = static_cast<int>(w);
      }
    }
    test_pairs(i, now, best, type, partner);
    // Outlet regions: the entry of the centre (contact/outlet.hpp), an event like a collision.
    for (const auto& o : outlets_) {
      const double dt = o.region.entry_time(h.x, h.v, g_, best);
      if (dt < best) {
        best = dt;
        type = kOutlet;
        partner = o.index;
      }
    }
    // Bracketed walls (an oscillating plane): root search stopped at the earliest event found so
    // far. A wall impact cut off this way lies beyond an event whose handling re-predicts i (a
    // collision of i, or a stale pair event), so it is never lost.
    if (bracketed_walls_)
      for (std::size_t w = 0; w < nw; ++w) {
        const WallShape<D>& wall = *shapes_[w];
        if (!wall.bracketed()) continue;
        const double dt = wall.impact_time(h.x, h.v, g_, h.R, now, best);
        if (dt < best) {
          best = dt;
          type = kWall;
          partner = static_cast<int>(w);
        }
      }
    cold_[i].ev_t = now + best;
    cold_[i].type = type;
    cold_[i].partner = partner;
    if (type == kPair) cold_[i].pcount = cold_[partner].counter;
    schedule(i);
  }

  // After i crossed into a new cell along `axis` (dir = +1 / -1): new crossing, and pairs with the
  // layer of cells that came into range, against the stored earliest pair/wall event. The stored
  // event stays correct: if its partner has since changed course, the event is stale and its pop
  // triggers a full prediction; any collision of i with a particle that changed course is found
  // by that particle.
  void predict_after_crossing(int i, double now, int axis, int dir) {
    predict_crossing(i, now);
    const double stored = cold_[i].ev_t - now;
    double best = stored;
    std::uint8_t type = cold_[i].type;
    int partner = cold_[i].partner;
    test_pairs(i, now, best, type, partner, axis, dir);
    // Note the new partner may be the stored one with a new time (a stale event with it).
    if (best < stored) {
      cold_[i].partner = partner;
      cold_[i].type = type;
      cold_[i].pcount = cold_[partner].counter;
      cold_[i].ev_t = now + best;
    }
    schedule(i);
  }

  double restitution(int mi, int mj, double u) const {
    const auto& a = sys_.materials[mi].restitution;
    if (mi == mj) return a(u);
    return mixed_restitution(a, sys_.materials[mj].restitution, u);
  }

  // Collapse watch (engine/edm/collapse.hpp) and TC bookkeeping for a particle that just collided
  // at `now`.
  void note_collision(int i) {
    Cold& c = cold_[i];
    if (c.watch.note(now_ - c.last, collapse_depth_) && status_.empty() && !derived().ext_collapse(i)) {
      status_ = "collapse";
      message_ = fmt::format(
          "inelastic collapse: the collisions of particle {} came ever faster, its smoothed interval "
          "falling {:.1f} decades (from {:.3g} s to {:.3g} s) at t = {:.17g}; set run.tc > 0 (TC model) "
          "to make such collisions elastic, or use method = \"hybrid\"",
          ids_->user(static_cast<std::uint64_t>(i)), CollapseWatch::decades(c.watch.high - c.watch.fast),
          c.watch.high_seconds(), c.watch.fast_seconds(), now_);
    }
    c.last = now_;
  }

  // i (at t) reaches the domain's face along axis k (up: the upper one): an open face takes it out
  // of the run and a closed one stops the run (false either way); across a periodic face it wraps
  // by exactly one period (true). The cell crossing's and the shell exit's common end.
  bool cross_domain_face(int i, int k, bool up, double t) {
    if (!sys_.periodic[k]) {
      if (const int o = face_outlet_[static_cast<std::size_t>(2 * k + (up ? 1 : 0))]; o >= 0)
        remove_particle(i, t, o);
      else {
        status_ = "escaped";
        message_ = escape_message(ids_->user(static_cast<std::uint64_t>(i)), k, t, hot_[i].x[k]);
      }
      return false;
    }
    hot_[i].x[k] += up ? -L_[k] : L_[k];
    return true;
  }

  // i leaves its shell at t: through a face of the domain as a cell crossing would (an open face
  // takes it out, a closed one stops the run, a periodic one wraps it), then a new shell and list
  // about its centre, and the pairs of the new list tested against its stored event (its course
  // has not changed).
  void shell_exit(int i, double t) {
    advance(i, t);
    ++counts_.cell;
    const int k = cold_[i].aux / 2;
    const bool up = cold_[i].aux & 1;
    const bool at_face = cold_[i].aux != 0xFF && (sphere_ || (up ? shell_hi(i, k) == hi_[k] : shell_lo(i, k) == lo_[k]));
    if (at_face && !cross_domain_face(i, k, up, t)) return;
    relist(i);
    predict_after_crossing(i, t, -1, 0);
  }

  void handle(int i, double t) {
    if (!derived().predicted(i)) return;  // an event left from before an extension took i over
    if (cold_[i].cross_t <= cold_[i].ev_t) {
      if (lists_) {
        shell_exit(i, t);
        return;
      }
      advance(i, t);
      ++counts_.cell;
      const int k = cold_[i].aux / 2;
      const bool up = cold_[i].aux & 1;
      int c = cold_[i].cell[k] + (up ? 1 : -1);
      if (c < 0 || c >= grid_.count(k)) {
        if (!cross_domain_face(i, k, up, t)) return;
        c = up ? 0 : grid_.count(k) - 1;
      }
      cell_remove(i);
      cold_[i].cell[k] = c;
      cell_insert(i);
      predict_after_crossing(i, t, k, up ? 1 : -1);
      return;
    }
    switch (cold_[i].type) {
      case kPair: {
        const int j = cold_[i].partner;
        derived().ext_prefetch_pair(i, j);
        advance(i, t);
        if (cold_[j].counter != cold_[i].pcount) {  // partner changed course: re-predict
          ++counts_.stale;
          predict(i, t);
          return;
        }
        advance(j, t);
        if (derived().ext_divert_pair(i, j, t)) return;
        collide_pair(i, j);
        predict(i, t);
        if (!is_fixed(j)) predict(j, t);
        return;
      }
      case kWall: {
        advance(i, t);
        if (derived().ext_divert_wall(i, cold_[i].partner, t)) return;
        collide_wall(i, cold_[i].partner);
        predict(i, t);
        return;
      }
      case kOutlet:
        advance(i, t);
        remove_particle(i, t, cold_[i].partner);
        return;
      default:
        return;
    }
  }

  // Takes grain i (at time t) out of the run through outlet o (an index into System::outlets): out
  // of its cell and the queue, its counter bumped so that every prediction with it is stale, and its
  // departure reported to the observers (outflow.csv, the event log).
  void remove_particle(int i, double t, int o) {
    cell_remove(i);
    if (lists_) unlist(i);
    queue_->erase(i);
    ++cold_[i].counter;
    cold_[i].ev_t = cold_[i].cross_t = kNever;
    if (removed_.empty()) removed_.assign(static_cast<std::size_t>(N_), 0);
    absent_ = true;
    removed_[i] = 1;
    ++grains_out_;
    const double m = mass(i);
    mass_out_ += m;
    derived().ext_removed(i);
    if (observers_.empty()) return;
    OutflowRecord<D> rec;
    rec.time = t;
    rec.id = static_cast<std::uint32_t>(i);
    rec.outlet = static_cast<std::uint32_t>(o);
    rec.mass = m;
    rec.x = hot_[i].x;
    rec.v = hot_[i].v;
    if (!sys_.w.empty()) rec.w = sys_.w[i];
    for (auto* obs : observers_) obs->on_outflow(rec);
  }

  // Inlet k's grain due at t: a free place in its region (place_free), then the grain enters with
  // the next id; the inlet's next grain is scheduled either way.
  bool on_inlet_event(std::size_t k, double t) {
    InletClock<D>& c = clocks_[k];
    Vec<D> x, v;
    double R = 0.0;
    if (c.draw([&](Vec<D>& y, double r) { return place_free(y, r, t); }, x, R, v))
      insert_particle(next_id_++, k, x, R, v, t);
    if (c.pending()) queue_->set(inlet_ids_[k], c.next_time());
    return true;
  }

  // Whether a grain of radius R centred at x (wrapped here on periodic axes) at time t is clear of
  // the domain's closed faces, the outlets and the walls (System::clear_of_boundaries) and of every
  // grain.
  bool place_free(Vec<D>& x, double R, double t) const {
    if (!sys_.clear_of_boundaries(x, R, t)) return false;
    bool free = true;
    grid_.around(grid_.coords(x), [&](int lin, const Vec<D>& shift) {
      for_cell(lin, [&](int j) {
        const double s = R + hot_[j].R;
        if (free && (x - position_at(j, t) - shift).squaredNorm() < s * s) free = false;
      });
    });
    return free;
  }

  // Grain i (an absent slot) enters at x with radius R and velocity v at time t, from inlet k.
  void insert_particle(int i, std::size_t k, const Vec<D>& x, double R, const Vec<D>& v, double t) {
    const Inlet<D>& in = sys_.inlets[k];
    Hot<D>& h = hot_[i];
    h.x = x;
    h.v = v;
    h.t = t;
    h.R = R;
    cold_[i] = Cold{};
    cold_[i].mat = in.material;
    cold_[i].cell = grid_.coords(x);
    if (!sys_.w.empty()) sys_.w[i].setZero();
    removed_[i] = 0;
    ++grains_in_;
    const double m = mass(i);
    mass_in_ += m;
    cell_insert(i);
    if (lists_) {
      shell_c_[i] = {x, R};
      make_list(i);
    }
    derived().ext_inserted(i, t);
    if (derived().predicted(i)) predict(i, t);
    if (observers_.empty()) return;
    InflowRecord<D> rec;
    rec.time = t;
    rec.id = static_cast<std::uint32_t>(i);
    rec.inlet = static_cast<std::uint32_t>(k);
    rec.mass = m;
    rec.radius = R;
    rec.x = x;
    rec.v = v;
    for (auto* obs : observers_) obs->on_inflow(rec);
  }

  void collide_pair(int i, int j) {
    if (is_fixed(j)) {
      collide_fixed(i, j);
      return;
    }
    Hot<D>& a = hot_[i];
    Hot<D>& b = hot_[j];
    Vec<D> r = a.x - b.x;
    min_image(r);
    const double dist = r.norm();
    const Vec<D> n = r / dist;
    const double u = (a.v - b.v).dot(n);
    if (!(u < 0.0)) {
      // Touching without a normal approach (the predictor saw approach at round-off level): a
      // contact without impact, the zero-time limit of a collapsing group. It counts towards
      // the collapse detector, so that a run cannot repeat this event forever at one instant.
      ++counts_.stale;
      ++cold_[i].counter;
      ++cold_[j].counter;
      note_collision(i);
      note_collision(j);
      return;
    }
    double e = all_elastic_ ? 1.0 : restitution(cold_[i].mat, cold_[j].mat, -u);
    if (set_.tc > 0.0 && (now_ - cold_[i].last < set_.tc || now_ - cold_[j].last < set_.tc)) e = 1.0;
    CollisionRecord<D> rec;
    const bool log = !collision_observers_.empty();
    if (log) {
      rec.vi_before = a.v;
      rec.vj_before = b.v;
      fill_spins(rec, i, j, /*before=*/true);
    }
    const Vec<D> vi_before = a.v;
    const double J = rough_ && rough_rules_.is_rough(cold_[i].mat, cold_[j].mat)
                         ? rough_pair(i, j, n, e)
                         : smooth_pair_collision(a.v, b.v, mass(i), mass(j), n, e);
    virial_ += J * dist;  // r_ij . dp_i with dp_i = J n
    ++cold_[i].counter;
    ++cold_[j].counter;
    ++counts_.pair;
    note_collision(i);
    note_collision(j);
    if (contacts_) impulses_.add(ui(i), j, -1, a.x - a.R * n, mass(i) * (a.v - vi_before), n);
    if (log) {
      rec.mj = mass(j);
      rec.vj_after = b.v;
      emit_collision(rec, EventKind::PairCollision, i, j, e, n);
    }
  }

  // Collision of moving i with fixed grain j: j is infinitely heavy and at rest, so i reflects off it
  // as off a wall at rest whose normal is the pair's n (collide_wall), with the restitution (and the
  // rough rule) of the material pair. j's collision counter stays as it is (nobody's prediction with j
  // is invalidated: j has not changed course) and j is not counted by the collapse detector. Like a
  // wall collision it adds nothing to the virial (j is a boundary). The record is a pair record with
  // mj = infinity and vj = 0 (event log version 2, io/output.hpp).
  void collide_fixed(int i, int j) {
    Hot<D>& a = hot_[i];
    Vec<D> r = a.x - hot_[j].x;
    min_image(r);
    const Vec<D> n = r / r.norm();
    const double un = a.v.dot(n);
    if (!(un < 0.0)) {
      // Resting on the fixed grain within round-off: as collide_wall.
      note_collision(i);
      return;
    }
    double e = restitution(cold_[i].mat, cold_[j].mat, -un);
    if (set_.tc > 0.0 && now_ - cold_[i].last < set_.tc) e = 1.0;
    CollisionRecord<D> rec;
    const bool log = !collision_observers_.empty();
    if (log) {
      rec.vi_before = a.v;
      fill_spins(rec, i, j, /*before=*/true);
    }
    const Vec<D> vi_before = a.v;
    if (rough_ && rough_rules_.is_rough(cold_[i].mat, cold_[j].mat)) {
      const RoughResult<D> res = rough_wall_collision<D>(rough_body(i), n, e, rough_rules_.rule(cold_[i].mat, cold_[j].mat));
      a.v = res.v_i;
      sys_.w[i] = res.w_i;
    } else {
      smooth_wall_collision(a.v, mass(i), n, e);
    }
    ++cold_[i].counter;
    ++counts_.pair;
    note_collision(i);
    if (contacts_) impulses_.add(ui(i), j, -1, a.x - a.R * n, mass(i) * (a.v - vi_before), n);
    if (log) {
      rec.mj = kPlane;
      emit_collision(rec, EventKind::PairCollision, i, j, e, n);
    }
  }

  // Whether a bracketed wall's predicted impact of i at time t is a checkpoint (the search stopped
  // short of the wall: the gap is still open), re-predicted by the caller, not a collision.
  bool wall_checkpoint(int i, const WallShape<D>& wall, const WallPoint<D>& c) const {
    return wall.bracketed() && c.gap > 1e-9 * (hot_[i].R + wall.stroke());
  }

  // Collision with a wall, infinitely heavy, at rest or moving at u (its surface velocity at the
  // contact point): the normal relative velocity (v - u).n is reversed with the restitution at the
  // relative normal speed. The record carries the wall's velocity as vj (before = after; zero for
  // a wall at rest).
  void collide_wall(int i, int w) {
    Hot<D>& a = hot_[i];
    const auto& wall = sys_.walls[w];
    const WallPoint<D> c = wall.geometry().at_impact(a.x, a.v, a.R, now_);
    if (wall_checkpoint(i, wall.geometry(), c)) return;
    const Vec<D>& u = c.velocity;
    const Vec<D>& normal = c.normal;
    const double un = (a.v - u).dot(normal);
    if (!(un < 0.0)) {
      // Resting on the wall within round-off (gravity presses it in, no normal speed left):
      // the zero-time limit of a bouncing sequence. It counts towards the collapse detector so
      // that a run without a remedy stops instead of repeating this event forever.
      note_collision(i);
      return;
    }
    double e = restitution(cold_[i].mat, wall.material, -un);
    if (set_.tc > 0.0 && now_ - cold_[i].last < set_.tc) e = 1.0;
    CollisionRecord<D> rec;
    const bool log = !collision_observers_.empty();
    if (log) {
      rec.vi_before = a.v;
      fill_spins(rec, i, -1, /*before=*/true);
    }
    const Vec<D> v_before = a.v;
    if (rough_ && rough_rules_.is_rough(cold_[i].mat, wall.material))
      rough_wall(i, wall, normal, u, e);
    else
      smooth_moving_wall_collision(a.v, mass(i), normal, u, e);
    // The wall receives -m dv at the contact point (engine/wall_loads.hpp).
    const Vec<D> point = a.x - (a.R + c.gap) * normal;
    wall_loads_.add(static_cast<std::size_t>(w), anchors_[w], point, -mass(i) * (a.v - v_before));
    if (contacts_) impulses_.add(ui(i), -1, w, point, mass(i) * (a.v - v_before), normal);
    ++cold_[i].counter;
    ++counts_.wall;
    note_collision(i);
    if (log) {
      rec.vj_before = u;
      rec.vj_after = u;
      emit_collision(rec, EventKind::WallCollision, i, w, e, normal);
    }
  }

  // Completes a collision record of i with j (a particle, or the index of a wall) and hands it to the
  // observers that want collisions.
  void emit_collision(CollisionRecord<D>& rec, EventKind kind, int i, int j, double e, const Vec<D>& n) {
    rec.time = now_;
    rec.kind = kind;
    rec.i = static_cast<std::uint32_t>(i);
    rec.j = static_cast<std::uint32_t>(j);
    rec.mi = mass(i);
    rec.e = e;
    rec.normal = n;
    rec.vi_after = hot_[i].v;
    fill_spins(rec, i, kind == EventKind::PairCollision ? j : -1);
    for (auto* o : collision_observers_) o->on_collision(rec);
  }

  // The spins of i (and j >= 0) into the record's before or after fields.
  void fill_spins(CollisionRecord<D>& rec, int i, int j, bool before = false) const {
    if (sys_.w.empty()) return;
    (before ? rec.wi_before : rec.wi_after) = sys_.w[i];
    if (j >= 0) (before ? rec.wj_before : rec.wj_after) = sys_.w[j];
  }

  // ---- rough hard spheres (contact/rough.hpp; rules per material pair: engine/rough_rules.hpp) --
  // Smooth scenes never reach these: collide_pair / collide_wall test rough_ first, so a
  // frictionless run pays one predictable branch per collision and carries no spins.
  void setup_rough(const RoughRules* given) {
    rough_rules_ = given ? *given : make_rough_rules(sys_.materials);
    rough_ = rough_rules_.any;
    if (rough_ && sys_.w.size() != static_cast<std::size_t>(N_)) sys_.w.assign(N_, Spin<D>::Zero());
  }

  RoughBody<D> rough_body(int i) const {
    RoughBody<D> b;
    b.v = hot_[i].v;
    b.w = sys_.w[i];
    b.mass = mass(i);
    b.radius = hot_[i].R;
    b.q = inertia_factor<D>();
    return b;
  }

  // Rough binary collision of i and j (both at now_, touching with unit normal n from j to i);
  // returns the normal impulse J_n (the virial's r_ij . dp_i = |r_ij| J_n).
  double rough_pair(int i, int j, const Vec<D>& n, double e) {
    const RoughResult<D> r = rough_pair_collision<D>(rough_body(i), rough_body(j), n, e,
                                                     rough_rules_.rule(cold_[i].mat, cold_[j].mat));
    hot_[i].v = r.v_i;
    hot_[j].v = r.v_j;
    sys_.w[i] = r.w_i;
    sys_.w[j] = r.w_j;
    return r.normal_impulse;
  }

  // Rough collision of i with a wall moving at u (zero when static).
  void rough_wall(int i, const Wall<D>& wall, const Vec<D>& normal, const Vec<D>& u, double e) {
    const RoughResult<D> r = rough_wall_collision<D>(rough_body(i), normal, e,
                                                     rough_rules_.rule(cold_[i].mat, wall.material), u);
    hot_[i].v = r.v_i;
    sys_.w[i] = r.w_i;
  }

  bool rough_ = false;       // some material pair is rough (spins are carried and changed)
  RoughRules rough_rules_;   // per material pair (particle-particle and particle-wall)

  // All particles at time t (moved virtually, stored state untouched).
  void emit_snapshot(double t) {
    Snapshot<D> snap;
    snap.time = t;
    snap.x.resize(N_);
    snap.v.resize(N_);
    snap.radius.resize(N_);
    for (int i = 0; i < N_; ++i) {
      const Hot<D>& h = hot_[i];
      const double dt = flies(i) ? t - h.t : 0.0;
      snap.x[i] = position_at(i, t);
      snap.v[i] = h.v + g_ * dt;
      snap.radius[i] = h.R;
    }
    snap.w = sys_.w;
    if (contacts_) {
      snap.with_contacts = true;
      impulses_.take(t - last_snapshot_time_, snap.contacts);
    }
    derived().ext_snapshot(snap);
    if (n_fixed_ > 0 && snap.mode.empty()) {  // a pure run: 0 for a moving grain, 4 for a fixed one
      snap.mode.assign(N_, 0);
      for (int i = 0; i < N_; ++i) snap.mode[i] = is_fixed(i) ? 4 : 0;
    }
    if (absent_) keep_present(snap, removed_);
    for (auto* o : snapshot_observers_) o->on_snapshot(snap);
  }

  void emit_sample(double t, double interval) {
    ++counts_.samples;
    if (observers_.empty()) {
      virial_ = 0.0;
      wall_loads_.clear();
      return;
    }
    ThermoSample s;
    s.time = t;
    if (interval > 0.0) wall_loads_.report(interval, s.wall_loads);
    double mv2 = 0.0, pe = 0.0, rot = 0.0;
    for (int i = 0; i < N_; ++i) {
      if (is_removed(i)) continue;
      const Hot<D>& h = hot_[i];
      const double dt = flies(i) ? t - h.t : 0.0;
      Vec<D> v = h.v, x = h.x;
      if (dt != 0.0) {
        x += h.v * dt + (0.5 * dt * dt) * g_;
        v += g_ * dt;
      }
      mv2 += mass(i) * v.squaredNorm();
      if (gravity_) pe -= mass(i) * g_.dot(x);
    }
    if (!sys_.w.empty())
      for (int i = 0; i < N_; ++i)
        if (!is_removed(i)) rot += 0.5 * inertia_factor<D>() * mass(i) * hot_[i].R * hot_[i].R * sys_.w[i].squaredNorm();
    s.kinetic_energy = 0.5 * mv2;
    s.rotational_energy = rot;
    s.potential_energy = pe;
    const int present = N0_ + static_cast<int>(grains_in_) - static_cast<int>(grains_out_);
    const int moving = present - n_fixed_;  // fixed grains have no kinetic degrees of freedom
    s.temperature = moving > 0 ? mv2 / (D * moving) : 0.0;
    s.collisions = counts_.collisions();
    s.grains = static_cast<std::uint64_t>(present);
    s.grains_out = grains_out_;
    s.mass_out = mass_out_;
    s.grains_in = grains_in_;
    s.mass_in = mass_in_;
    derived().ext_sample(s);
    // P V = N T + (1/(d dt)) sum_collisions r_ij . dp_i  (docs/references.md §2.3;
    // Smallenburg's EDMD). The kinetic part uses the mean of the kinetic energies at the two ends
    // of the interval.
    const double ke_mean = prev_ke_ < 0.0 ? s.kinetic_energy : 0.5 * (prev_ke_ + s.kinetic_energy);
    const double V = sys_.volume();
    s.pressure = (2.0 * ke_mean / D + (interval > 0.0 ? virial_ / (D * interval) : 0.0)) / V;
    prev_ke_ = s.kinetic_energy;
    virial_ = 0.0;
    for (auto* o : observers_) o->on_sample(s);
  }

  void measure_overlaps(RunResult<D>& res) {
    double worst = 0.0, worst_rel = 0.0;
    for (int i = 0; i < N_; ++i) {
      if (is_removed(i)) continue;
      const Hot<D>& a = hot_[i];
      const bool fi = is_fixed(i);
      for_neighbours(i, [&](int j, const Vec<D>& shift) {
        if (j < i || (fi && is_fixed(j))) return;  // two fixed grains never meet
        const double sigma = a.R + hot_[j].R;
        const double ov = sigma - (a.x - hot_[j].x - shift).norm();
        if (ov > worst) worst = ov;
        if (ov / sigma > worst_rel) worst_rel = ov / sigma;
      });
      if (fi) continue;  // nor do a fixed grain and a wall
      for (const WallShape<D>* wall : shapes_) {
        const double ov = -wall->at(a.x, a.R, res.time).gap;
        if (ov > worst) worst = ov;
        if (ov / a.R > worst_rel) worst_rel = ov / a.R;
      }
    }
    res.max_overlap = worst;
    res.max_overlap_relative = worst_rel;
  }

  // The periodic image of a separation vector nearest to zero.
  void min_image(Vec<D>& r) const {
    for (int k = 0; k < D; ++k) {
      if (!sys_.periodic[k]) continue;
      if (r[k] > 0.5 * L_[k])
        r[k] -= L_[k];
      else if (r[k] < -0.5 * L_[k])
        r[k] += L_[k];
    }
  }


  System<D> sys_;  // materials, walls, geometry (particle arrays released)
  EdmSettings set_;
  int N0_;  // particles at the start
  int N_;   // particle slots: those at the start and one per grain the inlets have due
  std::optional<Queue> queue_;  // built once the input arrays are released
  std::vector<Observer<D>*> observers_, collision_observers_, snapshot_observers_;
  Vec<D> g_, lo_, hi_, L_;
  bool gravity_ = false, all_elastic_ = false;
  int n_fixed_ = 0;                   // fixed grains; fixed_ (one flag per particle) is empty without
  std::vector<std::uint8_t> fixed_;
  std::vector<const WallShape<D>*> shapes_;  // sys_.walls[w].shape
  std::vector<Vec<D>> anchors_;               // their anchors (torque reference)
  ImpulseTally<D> impulses_;  // the collisions' impulses since the last snapshot (contacts_)
  bool contacts_ = false;     // snapshots carry the contacts (an observer wants_contacts())
  WallLoads<D> wall_loads_;                   // the grains' impulses on the walls since the last sample
  bool bracketed_walls_ = false;  // some wall's impact time is a bracketing search
  // Outlets (System::outlets): the regions whose entry is an event, with their index among the
  // system's outlets; the open faces (2 axis + upper) by the same index, -1 where closed.
  struct OutletEvent {
    OutletRegion<D> region;
    int index;
  };
  std::vector<OutletEvent> outlets_;
  std::array<int, 2 * D> face_outlet_{};
  std::vector<std::uint8_t> removed_;  // per particle: absent (allocated when some slot is)
  bool absent_ = false;                // some slot is absent: removed_ is allocated
  std::uint64_t grains_out_ = 0;
  double mass_out_ = 0.0;
  // Inlets: their schedules and system event ids, the next id to give, what has come in.
  std::vector<InletClock<D>> clocks_;
  std::vector<int> inlet_ids_;
  int next_id_ = 0;
  std::uint64_t grains_in_ = 0;
  double mass_in_ = 0.0;
  std::int32_t collapse_depth_ = 0;  // run.collapse_decades in CollapseWatch units
  double now_ = 0.0;

  Array<Hot<D>> hot_;
  std::vector<double> mass_factor_;  // per material: density * ball_volume(1)
  // Everything else the event loop reads or writes about a particle, in one cache line, so that
  // handling an event touches two lines per particle however large the system.
  struct alignas(D == 3 ? 64 : 8) Cold {
    double ev_t = kNever;     // earliest pair or wall event (absolute time)
    double cross_t = kNever;  // next cell crossing (absolute time)
    double last = -kNever;    // time of the last collision (TC model, collapse detector)
    int partner = -1;         // pair partner or wall index of ev_t
    std::uint32_t pcount = 0; // partner's collision counter when predicted
    std::uint32_t counter = 0;// own collision counter
    CollapseWatch watch;      // engine/edm/collapse.hpp
    std::array<int, D> cell{};
    int mat = 0;
    std::uint8_t type = kNone;  // kind of ev_t
    std::uint8_t aux = 0;       // crossing: 2 * axis + up
  };
  Array<Cold> cold_;
  static_assert(D != 3 || sizeof(Cold) == 64, "a 3D particle's event data is one cache line");

  CellGrid<D> grid_;  // engine/grid.hpp
  // Each cell's list, the last inserted first: its first two particles held in the cell itself,
  // the rest linked through next_ from the second (next_ links the whole list, so removal is
  // unchanged). A cell holds half a particle on average in a gas at rho sigma^3 = 0.5: the walk
  // of 27 cells reads the cells' rows and next_ only for the cells that hold two or more.
  struct CellHead {
    int first = -1, second = -1;
  };
  Array<CellHead> head_;
  Array<int> next_;

  EventCounts counts_;
  double virial_ = 0.0;
  double prev_ke_ = -1.0;
  std::string status_, message_;
  IdMap own_ids_;
  IdMap* ids_ = &own_ids_;  // the scene's ids (track_ids; empty: the engine's order is the scene's)
  std::uint64_t resort_step_ = 0;  // particle events between two re-sorts (0: never)
  std::uint64_t resort_at_ = 0;    // the next re-sort when processed_ reaches it
  std::uint64_t resorts_ = 0;

  std::vector<SystemEvent> system_;  // ids N_, N_ + 1, ...
  int sample_id_ = -1, end_id_ = -1, snapshot_id_ = -1, checkpoint_id_ = -1;
  std::uint64_t sample_k_ = 1, snapshot_k_ = 1, checkpoint_k_ = 1;
  std::uint64_t processed_ = 0;  // particle events handled
  double last_sample_time_ = 0.0, last_snapshot_time_ = 0.0;
  bool snapshots_ = false;

};

}  // namespace matep::edm

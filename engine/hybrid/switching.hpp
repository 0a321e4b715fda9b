// The hybrid's switching rule (engine/hybrid.hpp states it; README "Hybrid dynamics"), on its own:
// at a collision of hard particles it says whether they stay hard or turn soft, and why.
//  * stability: the collision is the `repeats`-th in a row of a particle, each within k t_c of
//    its previous one (t_c: the soft contact duration of this impact) and no longer after it than
//    the one before (the intervals shrink, as in a bouncing sequence or a collapsing cluster),
//    while the particle has collided within the hysteresis time, and the impact speed has fallen
//    by the factor `fall` since the run's first collision (a collapse takes ever more of the
//    relative speed: a bouncing sequence or a collapsing line loses a factor e at each collision;
//    grains of a cluster of a cooling gas, touching gently in rapid runs of a few collisions that
//    end by themselves, do not: README "Hybrid dynamics", cooling_clusters.toml). Rapid
//    collisions whose intervals go up and down are a dense gas, which EDM resolves exactly: in
//    the stability map's dense elastic and mildly inelastic gases (phi 0.3-0.5, e >= 0.3) the
//    rule without the shrinking test turned grains soft where EDM runs to the end
//    (charts/README.md, stability map);
//  * cost: the smoothed interval between a particle's collisions is below cost_interval, the
//    crossover where TDM substeps are cheaper. The average is the mean of the intervals so far,
//    then, from the 8th on, an exponential average with weight 1/8, and it counts from the 4th
//    interval: a few short intervals, common between recollisions in a dense gas and right after
//    a grain returns hard next to others, do not carry it across;
//  * a wall collision without normal approach (resting on the wall) counts as unstable;
//  * a collision that dissipates nothing (restitution 1 at its impact speed, smooth) ends a rapid
//    run: inelastic collapse needs dissipation (docs/references.md §3.1: the number of grains
//    that can collapse grows without bound as e -> 1), and a dense elastic gas, which EDM
//    resolves exactly, turned grains soft by the run test alone (charts/README.md, "the pressure
//    of an elastic dense gas").
// The rule also remembers each particle's two most recent partners, whose collisions within the
// cluster window make them turn soft together (cluster()).
#pragma once

#include <cstdint>
#include <limits>
#include <vector>

namespace matep::hybrid {

enum class Switch : std::uint8_t { Stay, Stability, Cost };

class SwitchRule {
 public:
  struct Params {
    double stability = 2.0;        // k
    int repeats = 3;
    double fall = 1.0;             // the impact speed's fall over a run (1: any)
    double hysteresis = 0.0;       // collisions further apart than this reset the count
    double cost_interval = 0.0;    // cost_ratio x substep
    double cluster_window = 0.0;   // k x the plan's contact time
  };

  void reset(int n, const Params& p) {
    p_ = p;
    if (p_.repeats < 1) p_.repeats = 1;
    rec_.assign(n, Rec{});
  }
  const Params& params() const { return p_; }
  // The cost crossover changed during the run (hybrid.cost_ratio = "measured").
  void set_cost_interval(double interval) { p_.cost_interval = interval; }
  // Checkpoints (engine/state_archive.hpp): the per-particle histories (the parameters come from
  // the settings).
  template <class A>
  void archive(A& a) {
    a(rec_);
  }

  // The histories under new particle indices (the engine re-sorted its storage): permute(v) moves
  // row i of a per-particle array to to[i]; the remembered partners are renamed.
  template <class Permute>
  void permute(Permute& permute, const std::vector<std::uint32_t>& to) {
    permute(rec_);
    for (Rec& r : rec_)
      for (int& j : r.recent)
        if (j >= 0) j = static_cast<int>(to[static_cast<std::size_t>(j)]);
  }

  // A pair collision of hard particles i and j at t; last_i, last_j: the times of their previous
  // collisions (-infinity if none); contact_time(): t_c of this impact (called only when needed).
  // u: the impact's normal speed (0: not known; the run then goes by the intervals alone).
  // dissipative: the collision loses energy (false: elastic and smooth; it ends both runs).
  // ask_fall: the run must show the parameter's fall of the impact speed (the engine asks none of
  // a strongly inelastic impact, whose rapid runs the lookahead's reasoning covers).
  template <class Tc>
  Switch pair(int i, int j, double t, double last_i, double last_j, Tc&& contact_time, double u = 0.0,
              bool dissipative = true, bool ask_fall = true) {
    Rec &ri = rec_[i], &rj = rec_[j];
    const double since = t - (last_i > last_j ? last_i : last_j);
    bool stability = false;
    if (!dissipative) {
      ri.rapid = rj.rapid = 0;
    } else if (since < p_.hysteresis) {
      const double window = p_.stability * contact_time();
      stability = rapid(ri, t, last_i, window, u, ask_fall) | rapid(rj, t, last_j, window, u, ask_fall);
    }
    if (!(since < p_.hysteresis)) ri.rapid = rj.rapid = 0;
    note_interval(ri, t, last_i, u);
    note_interval(rj, t, last_j, u);
    if (stability) return Switch::Stability;
    if (cheaper_soft(ri) || cheaper_soft(rj)) return Switch::Cost;
    note_partner(ri, j, t);
    note_partner(rj, i, t);
    return Switch::Stay;
  }

  // A wall collision of hard i at t (resting: no normal approach left).
  template <class Tc>
  Switch wall(int i, double t, double last_i, bool resting, Tc&& contact_time, double u = 0.0,
              bool dissipative = true, bool ask_fall = true) {
    Rec& ri = rec_[i];
    const double since = t - last_i;
    bool stability = resting;
    if (!dissipative && !resting) ri.rapid = 0;
    else if (!stability && since < p_.hysteresis) stability = rapid(ri, t, last_i, p_.stability * contact_time(), u, ask_fall);
    if (!(since < p_.hysteresis)) ri.rapid = 0;
    note_interval(ri, t, last_i, u);
    if (stability) return Switch::Stability;
    if (cheaper_soft(ri)) return Switch::Cost;
    return Switch::Stay;
  }

  // f(j) for the recent partners of i whose collision with it lies within the cluster window of t.
  template <class F>
  void cluster(int i, double t, F&& f) const {
    const Rec& r = rec_[i];
    for (int k = 0; k < 2; ++k) {
      const int j = r.recent[k];
      if (j >= 0 && t - r.recent_t[k] < p_.cluster_window) f(j);
    }
  }

  // i joined the soft set (its interval average restarts) or returned hard (partners forgotten).
  void forget_interval(int i) {
    Rec& r = rec_[i];
    r.ema = kNever;
    r.prev = kNever;
    r.prevu = kNever;
    r.seen = 0;
  }
  void forget(int i) {
    forget_interval(i);
    rec_[i].recent[0] = rec_[i].recent[1] = -1;
  }

  double interval(int i) const { return rec_[i].ema; }
  // i's smoothed collision rate as the cost rule counts it (0 before its 4th interval).
  double rate(int i) const { return rec_[i].seen >= kCostAfter ? 1.0 / rec_[i].ema : 0.0; }
  // The crossover rate of the cost rule, 1 / (cost_ratio x substep): a region whose grains
  // collide faster than this on average is cheaper soft.
  double crossover_rate() const { return 1.0 / p_.cost_interval; }
  // The partner of i's collision before its latest one (-1 if none).
  int earlier_partner(int i) const { return rec_[i].recent[1]; }
  int recent(int i, int k) const { return rec_[i].recent[k]; }
  int rapid_count(int i) const { return rec_[i].rapid; }
  // Brings i's history towards the cache (a collision of i is about to be judged).
  void prefetch(int i) const { __builtin_prefetch(&rec_[static_cast<std::size_t>(i)], 1); }

 private:
  static constexpr double kNever = std::numeric_limits<double>::infinity();

  // A particle's history, in one cache line: a collision reads and writes all of it for both
  // particles (one line a grain instead of eight arrays; fetched ahead by prefetch()).
  struct alignas(64) Rec {
    double ema = kNever;
    double prev = kNever;   // the latest interval (-> the shrinking test)
    double prevu = kNever;  // and the impact speed of the latest collision
    double u0 = 0.0;        // the impact speed of the first collision of the rapid run
    double recent_t[2] = {-kNever, -kNever};
    int recent[2] = {-1, -1};  // the two latest partners
    int rapid = 0;
    int seen = 0;  // intervals in ema (capped at kEmaSpan)
  };
  static_assert(sizeof(Rec) == 64);

  // A rapid collision continues the run if its interval is within the window and neither its
  // interval nor its impact speed exceeds the previous collision's; within the window otherwise,
  // it starts a new run (from its impact speed u0). The run is unstable from its repeats-th
  // collision on, once the impact speed has fallen by `fall` from u0 (when asked).
  bool rapid(Rec& r, double t, double last, double window, double u, bool ask_fall) {
    const double dt = t - last;
    if (dt < window) {
      if (dt <= r.prev && u <= r.prevu && r.rapid > 0) {
        ++r.rapid;
      } else {
        r.rapid = 1;
        r.u0 = u;
      }
      return r.rapid >= p_.repeats && (!ask_fall || u * p_.fall <= r.u0);
    }
    r.rapid = 0;
    return false;
  }
  void note_interval(Rec& r, double t, double last, double u) {
    const double dt = t - last;
    r.prev = dt;
    r.prevu = u;
    if (!(dt < kNever)) return;  // the first collision: no interval yet
    const int n = r.seen < kEmaSpan ? ++r.seen : kEmaSpan;
    r.ema = n == 1 ? dt : r.ema + (dt - r.ema) / n;
  }
  bool cheaper_soft(const Rec& r) const { return r.seen >= kCostAfter && r.ema < p_.cost_interval; }
  static constexpr int kEmaSpan = 8, kCostAfter = 4;
  void note_partner(Rec& r, int j, double t) {
    r.recent[1] = r.recent[0];
    r.recent_t[1] = r.recent_t[0];
    r.recent[0] = j;
    r.recent_t[0] = t;
  }

  Params p_;
  std::vector<Rec> rec_;
};

}  // namespace matep::hybrid

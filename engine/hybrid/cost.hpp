// The hybrid's cost meter: what one hard collision and one soft particle-step cost in this scene on
// this machine, measured during the run (README "Hybrid dynamics", cost row).
// The hybrid alternates two kinds of work: between two substeps it handles hard events only (pair
// and wall collisions, cell crossings, stale events, the switching rule), and a substep advances
// the soft set. The meter reads the wall clock at each substep's start and end, so each gap
// between substeps is hard work and each substep soft work, and keeps
//  * the hard cost per particle-collision: the time between substeps over the particle-collisions
//    resolved in it (a pair collision counts twice: two grains change course; a wall collision once),
//    less the time of a gap without collisions (an exponential average over such gaps, weight 1/64:
//    the substep event's own handling, cell crossings), which the run pays whatever the rule
//    decides. Without that baseline a mostly soft scene, with a collision or none per gap, charged
//    each collision the whole gap: in a gravity bed of the stability map (e = 0.95, phi = 0.3) the
//    ratio ran up from 18 to 95 as the rule followed it;
//  * the soft cost per particle-step: the substeps' time over the awake soft grains they advanced.
// Both are sums over a sliding window that forgets with weight 1/kSpan per substep, so that they
// follow a scene whose dense part grows or thins. The hybrid times one substep in `stride` (and
// the gap after it): each sample then forgets what `stride` substeps would. A gap in which the
// run wrote output (a thermo row, a snapshot, a checkpoint) is left out: writing is neither
// method's cost.
// ratio() is the crossover cost_ratio of the rule (switching.hpp): hard cost per particle-collision
// over soft cost per particle-step; NaN until both have been measured (kMinCollisions particle-
// collisions and kMinSteps particle-steps in the window).
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

namespace matep::hybrid {

class CostMeter {
 public:
  using Clock = std::chrono::steady_clock;
  static constexpr double kSpan = 4096.0;         // substeps of memory
  static constexpr double kMinCollisions = 64.0;  // particle-collisions before the hard cost counts
  static constexpr double kMinSteps = 4096.0;     // soft particle-steps before the soft cost counts

  // stride: substeps per sample (the sums forget (1 - 1/kSpan)^stride per sample).
  explicit CostMeter(int stride = 1) : keep_(std::pow(1.0 - 1.0 / kSpan, std::max(1, stride))) {}

  // At the start of a substep: the hard work since the last substep's end. particle_collisions:
  // the run's count so far; wrote: whether output was written since the last substep.
  void substep_begin(Clock::time_point now, double particle_collisions, bool wrote) {
    if (started_ && !wrote) {
      const double gap = seconds(now - end_), n = particle_collisions - coll_at_end_;
      if (n > 0.0) {
        add_hard(std::max(0.0, gap - base_), n);
      } else {
        base_ = have_base_ ? base_ + (gap - base_) / 64.0 : gap;
        have_base_ = true;
      }
    }
    begin_ = now;
  }
  // At the end of a substep that advanced `stepped` awake soft grains.
  void substep_end(Clock::time_point now, double stepped, double particle_collisions) {
    add_soft(seconds(now - begin_), stepped);
    end_ = now;
    coll_at_end_ = particle_collisions;
    started_ = true;
  }

  // The window's sums, from measured durations (the tests feed them directly).
  void add_hard(double seconds, double particle_collisions) {
    hard_s_ = hard_s_ * keep_ + seconds;
    hard_n_ = hard_n_ * keep_ + particle_collisions;
  }
  void add_soft(double seconds, double particle_steps) {
    soft_s_ = soft_s_ * keep_ + seconds;
    soft_n_ = soft_n_ * keep_ + particle_steps;
  }

  double hard_seconds_per_collision() const { return hard_n_ >= kMinCollisions ? hard_s_ / hard_n_ : kNaN; }
  double soft_seconds_per_step() const { return soft_n_ >= kMinSteps ? soft_s_ / soft_n_ : kNaN; }
  double ratio() const { return hard_seconds_per_collision() / soft_seconds_per_step(); }

 private:
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  static double seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }
  double keep_;  // what a sample's sums keep of the earlier ones
  double hard_s_ = 0.0, hard_n_ = 0.0, soft_s_ = 0.0, soft_n_ = 0.0;
  Clock::time_point begin_{}, end_{};
  double coll_at_end_ = 0.0;
  double base_ = 0.0;              // a gap without collisions [s]
  bool have_base_ = false;         // a gap without collisions was seen
  bool started_ = false;
};

}  // namespace matep::hybrid

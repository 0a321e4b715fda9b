// The hybrid's rest rule (engine/hybrid.hpp states it; README "Hybrid dynamics"), on its own: when
// a soft grain falls asleep and when a sleeper wakes.
//  * quiet: its speed (spin included, as R w) stays below rest_speed at kQuietChecks consecutive
//    checks (four per rest time);
//  * balanced: the static force of its contact springs balances gravity to within W;
//  * W = rest_speed sqrt(m k), k the sum of its contacts' normal stiffnesses: a load change below W
//    stores less elastic energy, W^2/(2k), than the kinetic energy of a grain at rest_speed,
//    m rest_speed^2/2 (motion the rule counts as rest);
//  * settled: no neighbour it does not touch closes the gap to it within the rest time at their
//    present closing speed, nor within kTrendChecks check intervals at the rate the gap closed
//    since the last check (a contact about to form; asleep, the pair could not close it). The
//    second form sees a bed that goes on compacting at speeds below any rest_speed worth having,
//    closing contacts as it does (TDM's pour gains 1.2 % of its contacts between 0.75 s and
//    1.5 s), where a grain's speed at one moment is mostly its vibration;
//  * a sleeper wakes when its elastic load from awake neighbours moves by more than W (loaded),
//    when a touching grain approaches it faster than rest_speed (approached), or when one of its
//    contacts opens.
#pragma once

#include <cmath>

namespace matep::hybrid {

struct RestRule {
  static constexpr int kQuietChecks = 4;
  double rest_speed2 = 0.0;  // rest_speed^2; 0: no sleeping

  bool enabled() const { return rest_speed2 > 0.0; }
  // The quiet count after a check at squared speed s2.
  int quiet(int checks, double s2) const { return s2 < rest_speed2 ? checks + 1 : 0; }
  static bool candidate(int checks) { return checks >= kQuietChecks; }
  // W for a grain of mass m whose contacts have total normal stiffness k.
  double wake_threshold(double m, double k) const { return std::sqrt(rest_speed2 * m * k); }
  // Whether the contact springs' force f on a grain of mass m balances gravity g within W.
  template <class V>
  static bool balanced(const V& f, double m, const V& g, double W) {
    return (f + m * g).squaredNorm() <= W * W;
  }
  // Whether a sleeper's load has moved by dev, more than W.
  template <class V>
  static bool loaded(const V& dev, double W) {
    return dev.squaredNorm() > W * W;
  }
  // Whether a gap (> 0) closing at normal relative velocity un (< 0: closing) closes within time.
  static bool closing(double gap, double un, double time) { return un < 0.0 && gap < -un * time; }
  // Whether a gap (> 0) that was `before` at the last check closes within kTrendChecks more
  // check intervals at the rate it closed over the last one (the pour: README "Hybrid dynamics",
  // rest).
  static constexpr int kTrendChecks = 16;
  static bool closing_trend(double gap, double before) { return gap < before && gap < (before - gap) * kTrendChecks; }
  // Whether a touching grain approaching at normal relative velocity un (< 0: approaching) is
  // faster than rest_speed.
  bool approached(double un) const { return un < 0.0 && un * un > rest_speed2; }
};

}  // namespace matep::hybrid

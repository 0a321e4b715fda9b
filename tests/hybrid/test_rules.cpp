// The hybrid's switching and rest rules on their own (engine/hybrid/switching.hpp, rest.hpp), fed
// with collision times and forces chosen here, without running an engine.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "contact/vec.hpp"
#include "engine/hybrid/cost.hpp"
#include "engine/hybrid/rest.hpp"
#include "engine/hybrid/switching.hpp"

namespace matep::hybrid {
namespace {

constexpr double kNever = std::numeric_limits<double>::infinity();

SwitchRule rule(int n = 4) {
  SwitchRule r;
  SwitchRule::Params p;
  p.stability = 2.0;
  p.repeats = 3;
  p.hysteresis = 1.0;
  p.cost_interval = 1e-3;
  p.cluster_window = 0.02;
  r.reset(n, p);
  return r;
}

// t_c = 0.01: the stability window is k t_c = 0.02.
auto tc = [] { return 0.01; };

TEST(SwitchRule, TheRepeatsThCollisionWithinTheWindowTurnsThePairSoft) {
  SwitchRule r = rule();
  // Particle 0 collides with 1 at t = 0.5 (first collisions: nothing to compare with), then with
  // 2 every 0.015 < 0.02: the third rapid collision in a row is the switch.
  EXPECT_EQ(r.pair(0, 1, 0.5, -kNever, -kNever, tc), Switch::Stay);
  double last0 = 0.5, last2 = -kNever;
  double t = 0.5;
  for (int k = 1; k <= 2; ++k) {
    t += 0.015;
    EXPECT_EQ(r.pair(0, 2, t, last0, last2, tc), Switch::Stay) << k;
    last0 = last2 = t;
  }
  t += 0.015;
  EXPECT_EQ(r.pair(0, 2, t, last0, last2, tc), Switch::Stability);
}

TEST(SwitchRule, TheEarlierPartnerIsTheOneBeforeTheLatestCollision) {
  // The lookahead (hybrid.cpp) asks it after a collision the rule let stay hard: a grain going
  // back and forth between two others has its earlier partner on the far side.
  SwitchRule r = rule();
  EXPECT_EQ(r.earlier_partner(1), -1);
  EXPECT_EQ(r.pair(1, 0, 1.0, -kNever, -kNever, tc), Switch::Stay);
  EXPECT_EQ(r.earlier_partner(1), -1);
  EXPECT_EQ(r.pair(1, 2, 2.0, 1.0, -kNever, tc), Switch::Stay);
  EXPECT_EQ(r.earlier_partner(1), 0);
  EXPECT_EQ(r.earlier_partner(2), -1);
  EXPECT_EQ(r.pair(1, 0, 3.0, 2.0, 1.0, tc), Switch::Stay);
  EXPECT_EQ(r.earlier_partner(1), 2);
  EXPECT_EQ(r.earlier_partner(0), 1);
}

TEST(SwitchRule, ASlowCollisionBreaksTheRun) {
  SwitchRule r = rule();
  double t = 0.0, last = -kNever;
  for (double dt : {0.015, 0.015, 0.03, 0.015, 0.015}) {  // the 0.03 gap (> 0.02) resets the count
    t += dt;
    EXPECT_EQ(r.pair(0, 1, t, last, last, tc), Switch::Stay) << t;
    last = t;
  }
  EXPECT_EQ(r.rapid_count(0), 2);
  t += 0.015;
  EXPECT_EQ(r.pair(0, 1, t, last, last, tc), Switch::Stability);
}

TEST(SwitchRule, TheWindowIsAskedOnlyWithinTheHysteresis) {
  SwitchRule r = rule();
  int asked = 0;
  auto count = [&] {
    ++asked;
    return 0.01;
  };
  r.pair(0, 1, 5.0, 2.0, 3.0, count);  // 2 > hysteresis 1 since the last collision
  EXPECT_EQ(asked, 0);
  r.pair(0, 1, 5.5, 5.0, 5.0, count);
  EXPECT_EQ(asked, 1);
}

TEST(SwitchRule, CostSwitchesWhenTheSmoothedIntervalFallsBelowTheCrossover) {
  SwitchRule r = rule();
  // t_c tiny: the stability rule never fires. The average is the mean of the intervals so far:
  // 3 ms, then k intervals of 0.5 ms give (3 + 0.5 k) / (k + 1) ms, below the 1 ms crossover from
  // k = 5 on (k = 4: exactly 1 ms, not below).
  auto tiny = [] { return 1e-9; };
  double t = 0.0, last = -kNever;
  EXPECT_EQ(r.pair(0, 1, t, last, last, tiny), Switch::Stay);  // no interval yet
  EXPECT_EQ(r.interval(0), kNever);
  last = t;
  t += 3e-3;
  EXPECT_EQ(r.pair(0, 1, t, last, last, tiny), Switch::Stay);
  EXPECT_DOUBLE_EQ(r.interval(0), 3e-3);
  for (int k = 1; k <= 5; ++k) {
    last = t;
    t += 0.5e-3;
    EXPECT_EQ(r.pair(0, 1, t, last, last, tiny), k < 5 ? Switch::Stay : Switch::Cost) << k;
    EXPECT_NEAR(r.interval(0), (3e-3 + 0.5e-3 * k) / (k + 1), 1e-15) << k;
  }
  // From the 8th interval on, each moves the average by 1/8 of the difference.
  for (int k = 6; k <= 7; ++k) {
    last = t;
    t += 0.5e-3;
    r.pair(0, 1, t, last, last, tiny);
  }
  const double before = r.interval(0);
  last = t;
  t += 1.3e-3;
  r.pair(0, 1, t, last, last, tiny);
  EXPECT_NEAR(r.interval(0), before + (1.3e-3 - before) / 8.0, 1e-15);
  // A particle that returned hard starts its average again, and three short intervals (a grain
  // released next to others) are not yet a rate: the cost rule counts from the fourth.
  r.forget(0);
  r.forget(1);  // (its partner too: either one's average can switch the pair)
  EXPECT_EQ(r.interval(0), kNever);
  last = -kNever;
  for (int k = 0; k <= 4; ++k) {
    EXPECT_EQ(r.pair(0, 1, t, last, last, tiny), k < 4 ? Switch::Stay : Switch::Cost) << k;
    last = t;
    t += 1e-4;
  }
}

TEST(SwitchRule, RapidCollisionsWhoseIntervalsGrowAreADenseGasNotACollapse) {
  SwitchRule r = rule();
  // Every interval within the window k t_c = 0.02, but each longer than the one before: no run
  // builds up (a dense gas). Then two shrinking ones: the run of three completes.
  double t = 1.0, last = -kNever;
  r.pair(0, 1, t, last, last, tc);
  last = t;
  for (const double dt : {0.010, 0.012, 0.014, 0.016, 0.018}) {
    t += dt;
    EXPECT_EQ(r.pair(0, 1, t, last, last, tc), Switch::Stay) << dt;
    EXPECT_EQ(r.rapid_count(0), 1) << dt;
    last = t;
  }
  t += 0.017;
  EXPECT_EQ(r.pair(0, 1, t, last, last, tc), Switch::Stay);
  EXPECT_EQ(r.rapid_count(0), 2);
  last = t;
  t += 0.016;
  EXPECT_EQ(r.pair(0, 1, t, last, last, tc), Switch::Stability);
}

// A run needs shrinking impacts too: a bouncing sequence and a collapsing cluster lose relative
// speed at each collision; a dense gas's rapid collisions come at any speed. Shrinking intervals
// at rising impact speeds build no run; the same intervals at falling speeds complete one at the
// third; a faster impact inside a run starts it again.
TEST(SwitchRule, ARapidRunNeedsShrinkingImpactSpeedsToo) {
  SwitchRule r = rule();
  double t = 1.0, last = -kNever;
  r.pair(0, 1, t, last, last, tc, 1.0);
  last = t;
  double u = 1.0;
  for (const double dt : {0.018, 0.016, 0.014, 0.012}) {  // intervals shrink, impacts grow
    t += dt;
    u *= 1.1;
    EXPECT_EQ(r.pair(0, 1, t, last, last, tc, u), Switch::Stay) << dt;
    EXPECT_EQ(r.rapid_count(0), 1) << dt;
    last = t;
  }
  SwitchRule q = rule();
  t = 1.0;
  last = -kNever;
  q.pair(0, 1, t, last, last, tc, 1.0);
  last = t;
  u = 1.0;
  const double dts[] = {0.018, 0.016, 0.014};
  for (int k = 0; k < 3; ++k) {  // both shrink: the third rapid collision completes the run
    t += dts[k];
    u *= 0.8;
    EXPECT_EQ(q.pair(0, 1, t, last, last, tc, u), k < 2 ? Switch::Stay : Switch::Stability) << k;
    last = t;
  }
  SwitchRule w = rule();  // the wall rule alike: a faster impact restarts the count
  t = 1.0;
  last = -kNever;
  w.wall(0, t, last, false, tc, 1.0);
  last = t;
  for (const auto& [dt, speed] : {std::pair{0.018, 0.9}, std::pair{0.016, 0.95}, std::pair{0.014, 0.8}}) {
    t += dt;
    EXPECT_EQ(w.wall(0, t, last, false, tc, speed), Switch::Stay) << dt;
    last = t;
  }
  EXPECT_EQ(w.rapid_count(0), 2);  // 0.95 > 0.9 started a new run at the second
}

// hybrid.speed_fall: a run is unstable only once its impact speed has fallen by the factor since
// its first rapid collision. A bouncing sequence (each impact e = 0.5 times the one before, each
// interval shorter) gets there at its 8th rapid collision (0.5^7 <= 1/100 < 0.5^6); a run of
// gentle collisions in a cluster, which loses only 5 % of its speed each time, never does.
TEST(SwitchRule, ARapidRunMustLoseTheFallOfItsImpactSpeed) {
  SwitchRule::Params p;
  p.stability = 2.0;
  p.repeats = 3;
  p.fall = 100.0;
  p.hysteresis = 1.0;
  p.cost_interval = 1e-9;  // (the cost rule out of the way)
  p.cluster_window = 0.02;
  // A first collision at t = 1 with impact speed 1, then n rapid ones, the k-th ufac^k as fast
  // and dt_k = 0.018 dtfac^(k - 1) after the one before (shrinking: each is rapid and continues
  // the run); the rule's verdicts on those n (ask_fall: whether the caller asks the fall).
  const auto series = [&](bool wall, int n, double ufac, double dtfac, bool ask_fall) {
    SwitchRule r;
    r.reset(2, p);
    double t = 1.0, last = -kNever, dt = 0.018, u = 1.0;
    const auto hit = [&] {
      return wall ? r.wall(0, t, last, false, tc, u, true, ask_fall)
                  : r.pair(0, 1, t, last, last, tc, u, true, ask_fall);
    };
    EXPECT_EQ(hit(), Switch::Stay);  // the first collision: no interval
    last = t;
    std::vector<Switch> v;
    for (int k = 1; k <= n; ++k) {
      t += dt;
      u *= ufac;
      v.push_back(hit());
      EXPECT_EQ(r.rapid_count(0), k);  // a rapid run all along
      last = t;
      dt *= dtfac;
    }
    return v;
  };
  for (const bool wall : {false, true}) {
    const std::vector<Switch> bounce = series(wall, 8, 0.5, 0.9, true);
    for (int k = 1; k <= 8; ++k)
      EXPECT_EQ(bounce[k - 1], k < 8 ? Switch::Stay : Switch::Stability) << "wall " << wall << ", collision " << k;
    for (const Switch v : series(wall, 30, 0.95, 0.97, true)) EXPECT_EQ(v, Switch::Stay) << "wall " << wall;
    // No fall asked by the caller (a strongly inelastic impact): the 3rd switches.
    const std::vector<Switch> any = series(wall, 3, 0.95, 0.97, false);
    EXPECT_EQ(any[1], Switch::Stay);
    EXPECT_EQ(any[2], Switch::Stability) << "wall " << wall;
  }
}

TEST(SwitchRule, AnElasticCollisionEndsARapidRun) {
  // The shrinking run of the test above completes at its third rapid collision when the
  // collisions dissipate; elastic ones (no energy lost: no collapse possible) never count, and
  // one elastic collision inside a run starts it over. The wall rule alike, resting excepted.
  const double dts[] = {0.018, 0.016, 0.014, 0.012, 0.010};
  SwitchRule q = rule();
  double t = 1.0, last = -kNever, u = 1.0;
  q.pair(0, 1, t, last, last, tc, u, false);
  last = t;
  for (int k = 0; k < 5; ++k) {
    t += dts[k];
    u *= 0.8;
    EXPECT_EQ(q.pair(0, 1, t, last, last, tc, u, false), Switch::Stay) << k;
    EXPECT_EQ(q.rapid_count(0), 0) << k;
    last = t;
  }
  SwitchRule m = rule();  // dissipative, dissipative, elastic, dissipative, dissipative: no run of 3
  t = 1.0;
  last = -kNever;
  u = 1.0;
  m.pair(0, 1, t, last, last, tc, u);
  last = t;
  for (int k = 0; k < 4; ++k) {
    t += dts[k];
    u *= 0.8;
    EXPECT_EQ(m.pair(0, 1, t, last, last, tc, u, k != 2), Switch::Stay) << k;
    last = t;
  }
  EXPECT_EQ(m.rapid_count(0), 1);
  t += dts[4];
  u *= 0.8;
  EXPECT_EQ(m.pair(0, 1, t, last, last, tc, u), Switch::Stay);  // the second of the new run
  SwitchRule w = rule();
  t = 1.0;
  last = -kNever;
  w.wall(0, t, last, false, tc, 1.0, false);
  last = t;
  for (int k = 0; k < 4; ++k) {
    t += dts[k];
    EXPECT_EQ(w.wall(0, t, last, false, tc, 0.9 - 0.1 * k, false), Switch::Stay) << k;
    last = t;
  }
  EXPECT_EQ(w.wall(0, t + 0.01, last, true, tc, 0.0, false), Switch::Stability);  // resting on it
}

TEST(SwitchRule, RestingOnAWallIsUnstableAndClusterFollowsRecentPartners) {
  SwitchRule r = rule();
  EXPECT_EQ(r.wall(0, 1.0, -kNever, /*resting=*/true, tc), Switch::Stability);
  EXPECT_EQ(r.wall(1, 1.0, -kNever, /*resting=*/false, tc), Switch::Stay);
  // Partners within the cluster window (0.02) of t join; older ones do not.
  r.pair(2, 3, 2.00, -kNever, -kNever, tc);
  r.pair(2, 1, 2.05, 2.00, 1.0, tc);
  std::vector<int> seen;
  r.cluster(2, 2.06, [&](int j) { seen.push_back(j); });
  EXPECT_EQ(seen, std::vector<int>{1});
  seen.clear();
  r.cluster(2, 2.015, [&](int j) { seen.push_back(j); });
  EXPECT_EQ(seen, (std::vector<int>{1, 3}));
}

TEST(RestRule, WakeThresholdStoresTheKineticEnergyOfARestingGrain) {
  RestRule r;
  const double v = 0.01, m = 2e-3, k = 5e4;
  r.rest_speed2 = v * v;
  const double W = r.wake_threshold(m, k);
  // W^2 / (2k) = m v^2 / 2.
  EXPECT_NEAR(W * W / (2.0 * k), 0.5 * m * v * v, 1e-15 * m * v * v);
}

TEST(RestRule, QuietChecksBalanceLoadAndApproach) {
  RestRule r;
  r.rest_speed2 = 1e-4;
  int q = 0;
  for (int k = 0; k < RestRule::kQuietChecks - 1; ++k) q = r.quiet(q, 0.5e-4);
  EXPECT_FALSE(RestRule::candidate(q));
  q = r.quiet(q, 0.5e-4);
  EXPECT_TRUE(RestRule::candidate(q));
  EXPECT_EQ(r.quiet(q, 2e-4), 0);  // one fast check starts over
  const Vec<3> g(0.0, 0.0, -9.81);
  const double m = 1e-3, W = 1e-4;
  const Vec<3> support = -m * g;
  EXPECT_TRUE(RestRule::balanced(support, m, g, W));
  EXPECT_TRUE(RestRule::balanced(Vec<3>(support + Vec<3>(0.9e-4, 0.0, 0.0)), m, g, W));
  EXPECT_FALSE(RestRule::balanced(Vec<3>(support + Vec<3>(0.0, 1.1e-4, 0.0)), m, g, W));
  EXPECT_FALSE(RestRule::loaded(Vec<3>(0.0, 0.0, 0.9e-4), W));
  EXPECT_TRUE(RestRule::loaded(Vec<3>(0.0, 0.0, 1.1e-4), W));
  EXPECT_TRUE(r.approached(-0.011));
  EXPECT_FALSE(r.approached(-0.009));
  EXPECT_FALSE(r.approached(0.02));  // receding
}

TEST(RestRule, AGrainAboutToCloseAContactStaysAwake) {
  // A gap of 1e-5 m closing at 1 mm/s closes in 10 ms: within a rest time of 20 ms, not of 5 ms;
  // a receding or still neighbour never does.
  EXPECT_TRUE(RestRule::closing(1e-5, -1e-3, 0.02));
  EXPECT_FALSE(RestRule::closing(1e-5, -1e-3, 0.005));
  EXPECT_FALSE(RestRule::closing(1e-5, 1e-3, 1.0));
  EXPECT_FALSE(RestRule::closing(1e-5, 0.0, 1.0));
  // The trend over the last check interval: a gap that shrank from 1.5e-6 m to 1e-6 m closes
  // within two more intervals at that rate, within kTrendChecks; one that shrank from
  // 1.05e-6 m by 5e-8 m needs twenty; one that widened or stayed never closes.
  static_assert(RestRule::kTrendChecks >= 2 && RestRule::kTrendChecks < 20);
  EXPECT_TRUE(RestRule::closing_trend(1e-6, 1.5e-6));
  EXPECT_FALSE(RestRule::closing_trend(1e-6, 1.05e-6));
  EXPECT_TRUE(RestRule::closing_trend(1e-6, 1e-6 + 1e-6 / RestRule::kTrendChecks * 1.01));
  EXPECT_FALSE(RestRule::closing_trend(1e-6, 1e-6 + 1e-6 / RestRule::kTrendChecks * 0.99));
  EXPECT_FALSE(RestRule::closing_trend(1e-6, 0.9e-6));
  EXPECT_FALSE(RestRule::closing_trend(1e-6, 1e-6));
}

// The crossover can move during a run (hybrid.cost_ratio = "measured"): a smoothed interval of
// 0.8 ms stays hard under a 0.5 ms crossover and turns soft under a 1 ms one.
TEST(SwitchRule, AMovedCostCrossoverIsTheOneTheRuleUses) {
  for (const double crossover : {0.5e-3, 1e-3}) {
    SwitchRule r = rule();
    r.set_cost_interval(crossover);
    auto tiny = [] { return 1e-9; };
    double t = 0.0, last = -kNever;
    Switch v = Switch::Stay;
    for (int k = 0; k < 6; ++k) {
      v = r.pair(0, 1, t, last, last, tiny);
      last = t;
      t += 0.8e-3;
    }
    EXPECT_NEAR(r.interval(0), 0.8e-3, 1e-15);
    EXPECT_EQ(v, crossover < 0.8e-3 ? Switch::Stay : Switch::Cost) << crossover;
  }
}

// The cost meter: hard seconds per particle-collision over soft seconds per particle-step, each a
// sum over a window that forgets 1/4096 per substep; nothing until enough of each was seen.
TEST(CostMeter, TheRatioIsHardCostPerCollisionOverSoftCostPerStep) {
  CostMeter m;
  EXPECT_TRUE(std::isnan(m.ratio()));
  m.add_hard(2e-6, 1.0);  // 2 us for one particle-collision: too few to count yet
  m.add_soft(1e-4, 1000.0);
  EXPECT_TRUE(std::isnan(m.hard_seconds_per_collision()));
  EXPECT_TRUE(std::isnan(m.ratio()));
  for (int k = 0; k < 200; ++k) {
    m.add_hard(2e-6, 1.0);
    m.add_soft(1e-4, 1000.0);  // 0.1 us per particle-step
  }
  EXPECT_NEAR(m.hard_seconds_per_collision(), 2e-6, 1e-18);
  EXPECT_NEAR(m.soft_seconds_per_step(), 1e-7, 1e-19);
  EXPECT_NEAR(m.ratio(), 20.0, 1e-9);
  // The scene changes: collisions now cost 8 us. After 5 spans the old cost weighs e^-5 of the
  // window: the ratio is within 1 % of the new 80.
  for (int k = 0; k < 5 * 4096; ++k) {
    m.add_hard(8e-6, 1.0);
    m.add_soft(1e-4, 1000.0);
  }
  EXPECT_NEAR(m.ratio(), 80.0, 0.01 * 80.0);
  EXPECT_GT(m.ratio(), 79.0);
}

// The hybrid times one substep in eight: each sample forgets what eight substeps would, so the
// window still spans 4096 substeps (5 spans: 2560 samples), where a meter sampled at every
// substep still weighs the old cost after the same 2560 samples (e^-0.625 of the window).
TEST(CostMeter, ASampleOfEveryEighthSubstepForgetsWhatEightSubstepsWould) {
  CostMeter every8(8), every1;
  for (CostMeter* m : {&every8, &every1})
    for (int k = 0; k < 5 * 4096; ++k) {  // both windows hold only this cost
      m->add_hard(2e-6, 1.0);
      m->add_soft(1e-4, 1000.0);
    }
  EXPECT_NEAR(every8.ratio(), 20.0, 1e-9);
  EXPECT_NEAR(every1.ratio(), 20.0, 1e-9);
  for (int k = 0; k < 5 * 4096 / 8; ++k)
    for (CostMeter* m : {&every8, &every1}) {
      m->add_hard(8e-6, 1.0);
      m->add_soft(1e-4, 1000.0);
    }
  EXPECT_NEAR(every8.ratio(), 80.0, 0.01 * 80.0);
  EXPECT_LT(every1.ratio(), 60.0);  // 80 - 60 e^-0.625 = 47.9
}

// Fed by the clock: the substeps are soft work, the gaps between them hard work; a gap in which
// output was written is left out.
TEST(CostMeter, SubstepsAreSoftWorkAndTheGapsBetweenThemHardWork) {
  using C = CostMeter::Clock;
  using std::chrono::microseconds;
  CostMeter m;
  C::time_point t{};
  double coll = 0.0;
  for (int k = 0; k < 100; ++k) {
    const bool write = k % 10 == 5;  // a thermo row: this gap takes 1 ms more and is not counted
    t += microseconds(write ? 1030 : 30);
    coll += 3.0;  // 30 us for 3 particle-collisions: 10 us each
    m.substep_begin(t, coll, write);
    t += microseconds(50);  // 500 grains stepped in 50 us: 0.1 us each
    m.substep_end(t, 500.0, coll);
  }
  EXPECT_NEAR(m.hard_seconds_per_collision(), 1e-5, 1e-12);
  EXPECT_NEAR(m.soft_seconds_per_step(), 1e-7, 1e-14);
  EXPECT_NEAR(m.ratio(), 100.0, 1e-6);
  // Gaps without a collision (20 us: the substep event, crossings) are the baseline that every gap
  // pays: gaps of 50 us with 3 particle-collisions then cost (50 - 20) / 3 = 10 us a collision.
  CostMeter q;
  coll = 0.0;
  for (int k = 0; k < 400; ++k) {
    const bool quiet = k % 2 == 1;  // (the first gap, k = 0, is before the meter started)
    t += microseconds(quiet ? 20 : 50);
    if (!quiet) coll += 3.0;
    q.substep_begin(t, coll, false);
    t += microseconds(50);
    q.substep_end(t, 500.0, coll);
  }
  EXPECT_NEAR(q.hard_seconds_per_collision(), 1e-5, 1e-12);
}

}  // namespace
}  // namespace matep::hybrid

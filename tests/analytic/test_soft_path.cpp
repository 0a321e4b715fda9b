// The soft path shared by TDM and the hybrid's soft set (engine/soft/): the decision on a contact
// that already exists when a run starts. Such a contact began before the run, so its first force
// evaluation carries no onset weight (contact/soft.hpp at_onset: the weight corrects the dashpot of
// a contact that begins inside a step). Checked against the closed form of the clipped linear
// spring-dashpot started at overlap delta0 with approach speed u, in both engines:
//   m* delta'' = -k delta - gamma delta',  delta(0) = delta0, delta'(0) = u,
//   delta(t) = exp(-eta t) (A cos(w t) + B sin(w t)),  A = delta0, B = (u + eta delta0)/w,
// (eta = zeta w0, w = w0 sqrt(1 - zeta^2), w0 = sqrt(k/m*)); the force k delta + gamma delta'
// first vanishes at t_f, after which the pair separates at the relative speed -delta'(t_f).
#include <gtest/gtest.h>

#include <cmath>

#include "contact/soft.hpp"
#include "engine/hybrid.hpp"
#include "engine/tdm.hpp"
#include "tests/support/systems.hpp"

namespace matep {
namespace {

constexpr double kR = 0.01, kRho = 2500.0, kK = 1e4, kE = 0.5, kU = 0.5, kDelta0 = 2e-4;

System<3> pressed_pair() {
  System<3> s;
  s.lower = Vec<3>::Constant(-0.2);
  s.upper = Vec<3>::Constant(0.2);
  s.materials = {test::linear_material("glass", kRho, kK, kE)};
  const double x = kR - 0.5 * kDelta0;
  s.x = {Vec<3>(-x, 0.0, 0.0), Vec<3>(x, 0.0, 0.0)};
  s.v = {Vec<3>(0.5 * kU, 0.0, 0.0), Vec<3>(-0.5 * kU, 0.0, 0.0)};
  s.radius = {kR, kR};
  s.material = {0, 0};
  return s;
}

// The closed-form separation speed (see the header).
double exact_separation_speed() {
  const double m = kRho * ball_volume<3>(kR), mstar = 0.5 * m;
  const double zeta = linear_clipped_damping_ratio(kE);
  const double w0 = std::sqrt(kK / mstar), eta = zeta * w0, w = w0 * std::sqrt(1.0 - zeta * zeta);
  const double gamma = 2.0 * zeta * std::sqrt(mstar * kK);
  const double A = kDelta0, B = (kU + eta * kDelta0) / w;
  auto delta = [&](double t) { return std::exp(-eta * t) * (A * std::cos(w * t) + B * std::sin(w * t)); };
  auto rate = [&](double t) {
    return std::exp(-eta * t) * ((-eta * A + w * B) * std::cos(w * t) + (-eta * B - w * A) * std::sin(w * t));
  };
  auto force = [&](double t) { return kK * delta(t) + gamma * rate(t); };
  double lo = 0.0, hi = 0.0;
  while (force(hi) > 0.0) {
    lo = hi;
    hi += 0.01 / w;
  }
  for (int k = 0; k < 200; ++k) {
    const double mid = 0.5 * (lo + hi);
    (force(mid) > 0.0 ? lo : hi) = mid;
  }
  return -rate(0.5 * (lo + hi));
}

TEST(SoftPath, ContactPresentAtTheStartHasNoOnsetWeightInTdm) {
  TdmSettings ts;
  ts.end_time = 0.02;
  ts.threads = 1;
  const RunResult<3> r = run_tdm<3>(pressed_pair(), ts);
  ASSERT_EQ(r.status, "ok") << r.message;
  const double s = exact_separation_speed();
  EXPECT_NEAR(r.v[1][0] - r.v[0][0], s, 1e-3 * s);
  EXPECT_NEAR(r.v[0][0] + r.v[1][0], 0.0, 1e-12);
}

TEST(SoftPath, ContactPresentAtTheStartHasNoOnsetWeightInTheHybrid) {
  EdmSettings es;
  es.end_time = 0.02;
  const RunResult<3> r = run_hybrid<3>(pressed_pair(), es, HybridSettings{});
  ASSERT_EQ(r.status, "ok") << r.message;
  EXPECT_EQ(r.hybrid.by_overlap, 2u);
  const double s = exact_separation_speed();
  EXPECT_NEAR(r.v[1][0] - r.v[0][0], s, 1e-3 * s);
  EXPECT_NEAR(r.v[0][0] + r.v[1][0], 0.0, 1e-12);
}

}  // namespace
}  // namespace matep

// A freely cooling frictional granular gas (the acceptance case): e = 0.9, Coulomb
// mu = 0.3, Walton's rule with beta0 = 0.4, 512 spheres at packing fraction 0.1 in a periodic box.
// Friction feeds rotation; in the homogeneous cooling state both temperatures fall (Haff) while
// their ratio R = T_rot/T_tr (= E_rot/E_tr: three translational and three rotational degrees of
// freedom) settles to a constant (Huthmann & Zippelius, PRE 56, R6275 (1997); Luding et al.,
// PRE 58, 3416 (1998): the HCS of rough spheres is a scale-invariant state whose temperature
// ratio is fixed by e and the tangential rule). Checked here:
//  1. EDM: R rises from 0 (no initial spin) and falls from 1 (equipartition) to one value;
//  2. EDM and TDM continue the same settled states (EDM runs of ~44 collisions per particle,
//     rescaled to T = 1) with the same R within 5 %: TDM resolves each collision with the soft
//     linear law, a tangential spring and Coulomb friction (engine/soft_plan.cpp: k_t/k_n from the
//     same tangential_restitution beta0), stiff enough for binary collisions (contact time 3.5 % of
//     the mean free time at T = 1, overlaps below 3 % of d). Hertz-Mindlin is not used: its no-slip
//     tangential restitution is fixed by the Poisson ratio (about -0.95 ... -0.5, README "Rough
//     hard-sphere collisions") and cannot represent beta0 = 0.4.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "engine/edm.hpp"
#include "engine/tdm.hpp"
#include "tests/support/systems.hpp"

using namespace matep;

namespace {

constexpr int kSide = 8;  // N = 512: the box (L = 13.9 d, 15 mean free paths) stays homogeneous
constexpr int kN = kSide * kSide * kSide;
constexpr double kPhi = 0.1, kE = 0.9, kMu = 0.3, kBeta0 = 0.4;

// R(tau) along a run: tau = collisions per particle (2 x pair collisions / N).
struct Ratio final : Observer<3> {
  std::vector<double> tau, R;
  void on_sample(const ThermoSample& s) override {
    tau.push_back(2.0 * static_cast<double>(s.collisions) / kN);
    R.push_back(s.kinetic_energy > 0.0 ? s.rotational_energy / s.kinetic_energy : 0.0);
  }
  // Mean of R over the samples with tau in [a, b].
  double mean(double a, double b) const {
    double s = 0.0;
    int n = 0;
    for (std::size_t k = 0; k < R.size(); ++k)
      if (tau[k] >= a && tau[k] <= b) {
        s += R[k];
        ++n;
      }
    return n > 0 ? s / n : std::nan("");
  }
};

// Unit-diameter, unit-mass spheres at T = 1; spins Maxwellian at temperature T_rot (I <w_k^2> = T_rot).
System<3> rough_gas(std::uint64_t seed, double T_rot) {
  System<3> s = test::lattice_gas<3>(kSide, kPhi, 1.0, kE, seed);
  Material& m = s.materials[0];
  m.friction = kMu;
  m.tangential = "walton";
  m.tangential_restitution = kBeta0;
  const double I = 0.4 * 1.0 * 0.25;  // q m R^2
  std::mt19937_64 rng(seed + 1000);
  std::normal_distribution<double> g(0.0, std::sqrt(T_rot / I));
  s.w.resize(s.size());
  for (auto& w : s.w) w = T_rot > 0.0 ? Spin<3>(g(rng), g(rng), g(rng)) : Spin<3>::Zero();
  return s;
}

// The final state of a run as a new system, velocities and spins scaled by one factor so that
// T_tr = 1 (R unchanged; hard spheres are scale-invariant, and the soft run starts as stiff
// relative to the motion as the first one did).
System<3> continue_from(const System<3>& base, const RunResult<3>& res) {
  System<3> s = base;
  s.x = res.x;
  s.v = res.v;
  s.w = res.w;
  double mv2 = 0.0;
  for (const auto& v : s.v) mv2 += v.squaredNorm();  // unit masses
  const double f = 1.0 / std::sqrt(mv2 / (3.0 * kN));
  for (auto& v : s.v) v *= f;
  for (auto& w : s.w) w *= f;
  return s;
}

}  // namespace

TEST(RoughGas, EdmRatioSettlesFromBothSides) {
  // Haff cooling: tau grows as ln(1 + t/t0); t = 1200 reaches about 60 collisions per particle.
  const int seeds = 24;
  double from0 = 0.0, from1 = 0.0, early = 0.0, late0 = 0.0, late1 = 0.0;
  for (int k = 0; k < seeds; ++k) {
    for (const double Trot : {0.0, 1.0}) {
      EdmSettings set;
      set.end_time = 1200.0;
      set.thermo_interval = 2.0;
      Ratio r;
      const RunResult<3> res = run_edm<3>(rough_gas(100 + k, Trot), set, QueueKind::Calendar, {&r});
      ASSERT_EQ(res.status, "ok");
      ASSERT_GT(r.tau.back(), 55.0);
      (Trot == 0.0 ? from0 : from1) += r.mean(35.0, 45.0) / seeds;
      (Trot == 0.0 ? late0 : late1) += r.mean(45.0, 55.0) / seeds;
      if (Trot == 0.0) early += r.mean(4.0, 6.0) / seeds;
    }
  }
  fmt::print("EDM R = T_rot/T_tr: tau 4-6 from 0: {:.4f}; tau 35-45 from 0: {:.4f}, from 1: {:.4f}; tau 45-55: {:.4f}, "
             "{:.4f}\n",
             early, from0, from1, late0, late1);
  // Rising from 0 ...
  EXPECT_LT(early, 0.6 * from0);
  // ... and falling from equipartition to the same value (the run-to-run spread of one 512-particle
  // box over 10 collisions per particle is about 6 %, 1.3 % for the mean of 24),
  EXPECT_NEAR(from1 / from0, 1.0, 0.05);
  EXPECT_NEAR(late1 / late0, 1.0, 0.05);
  // which then stays put while the temperatures keep falling.
  EXPECT_NEAR(late0 / from0, 1.0, 0.04);
  EXPECT_NEAR(late1 / from1, 1.0, 0.04);
}

TEST(RoughGas, EdmAndTdmAgreeOnTheSettledRatio) {
  const double tc = 0.02;  // soft contact time (mean free time 0.57 at T = 1)
  const int seeds = 10;
  double edm = 0.0, tdm = 0.0, secs = 0.0;
  for (int k = 0; k < seeds; ++k) {
    const System<3> start = rough_gas(200 + k, 0.0);
    EdmSettings prep;
    prep.end_time = 300.0;  // about 44 collisions per particle: settled (test above)
    const RunResult<3> settled = run_edm<3>(start, prep, QueueKind::Calendar);
    ASSERT_EQ(settled.status, "ok");
    const System<3> s = continue_from(start, settled);

    EdmSettings es;
    es.end_time = 16.0;
    es.thermo_interval = 0.5;
    Ratio re;
    ASSERT_EQ(run_edm<3>(s, es, QueueKind::Calendar, {&re}).status, "ok");

    System<3> soft = s;
    Material& m = soft.materials[0];
    m.contact = "linear";
    // Linear spring-dashpot contact time t_c = sqrt(m*/k) sqrt(pi^2 + ln^2 e)
    // (docs/references.md §6.3).
    const double l = std::log(kE);
    m.stiffness = 0.5 * (std::numbers::pi * std::numbers::pi + l * l) / (tc * tc);
    TdmSettings ts;
    ts.end_time = 16.0;
    ts.threads = 1;
    ts.thermo_interval = 0.5;
    Ratio rt;
    const RunResult<3> rs = run_tdm<3>(soft, ts, {&rt});
    ASSERT_EQ(rs.status, "ok");
    secs += rs.wall_seconds;
    EXPECT_LT(rs.max_overlap_relative, 0.05);  // binary collisions of nearly hard spheres
    EXPECT_GT(rt.tau.back(), 12.0);
    edm += re.mean(2.0, 20.0) / seeds;
    tdm += rt.mean(2.0, 20.0) / seeds;
  }
  fmt::print("settled R = T_rot/T_tr over tau 2-15 of the continuation: EDM {:.4f}, TDM {:.4f}, TDM/EDM {:.4f} "
             "(TDM {:.1f} s)\n",
             edm, tdm, tdm / edm, secs);
  EXPECT_NEAR(tdm / edm, 1.0, 0.05);
}

// Soft contact laws (contact/soft.hpp), contact times (contact/timestep.hpp) and the binary
// reference integrator (contact/binary.hpp) against closed forms: effective parameters, exact
// restitution and duration of the linear law, second-order convergence, Coulomb cap, no
// attraction, angular momentum, history rotation, torque signs, time-step limits.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <tuple>

#include "contact/binary.hpp"
#include "contact/soft.hpp"
#include "contact/timestep.hpp"
#include "contact/vec.hpp"
#include "tests/support/random.hpp"

using namespace matep;

namespace {

constexpr double kPi = std::numbers::pi;

double sphere_mass(double rho, double R) { return rho * 4.0 / 3.0 * kPi * R * R * R; }

// Al oxide sphere of Chung & Ooi test 3 (docs/references.md §1.1).
struct AlOxide {
  static constexpr double E = 3.8e11, nu = 0.23, rho = 4000.0, R = 2.5e-3;
};

template <int D>
BinaryBody<D> body(double R, double m, double E, double nu) {
  BinaryBody<D> b;
  b.radius = R;
  b.mass = m;
  b.material = {E, nu};
  return b;
}

template <int D>
Vec<D> axis(int k) {
  Vec<D> v = Vec<D>::Zero();
  v[k] = 1.0;
  return v;
}

using matep::test::random_unit;

template <int D>
Spin<D> random_spin(std::mt19937_64& rng, double scale) {
  std::normal_distribution<double> g;
  Spin<D> w;
  for (int k = 0; k < w.size(); ++k) w[k] = scale * g(rng);
  return w;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Effective parameters (docs/references.md §6.1 and the m*, E* columns of the table in §1.2).

TEST(SoftEffective, IdenticalSpheresAndRigidWall) {
  const double E = 4.8e10, nu = 0.2;
  EXPECT_NEAR(effective_young(E, nu, E, nu), E / (2.0 * (1.0 - nu * nu)), 1e-6 * E);
  EXPECT_NEAR(effective_young(E, nu, kPlane, 0.3), E / (1.0 - nu * nu), 1e-6 * E);
  // G* = 1/((2 - nu1)/G1 + (2 - nu2)/G2) with G = E/(2(1 + nu)).
  const double G = E / (2.0 * (1.0 + nu)), E2 = 7e10, nu2 = 0.3, G2 = E2 / (2.0 * (1.0 + nu2));
  EXPECT_NEAR(effective_shear(E, nu, E2, nu2), 1.0 / ((2.0 - nu) / G + (2.0 - nu2) / G2), 1e-6 * G);
  EXPECT_NEAR(effective_shear(E, nu, kPlane, 0.0), G / (2.0 - nu), 1e-6 * G);
  EXPECT_DOUBLE_EQ(effective_radius(0.01, kPlane), 0.01);
  EXPECT_DOUBLE_EQ(effective_radius(0.01, 0.01), 0.005);
  EXPECT_DOUBLE_EQ(effective_mass(2.0, kPlane), 2.0);
  EXPECT_DOUBLE_EQ(effective_mass(2.0, 6.0), 1.5);
}

// docs/references.md §1.2: m* and E* of the Chung & Ooi cases.
TEST(SoftEffective, ChungOoiTable) {
  const double mg = sphere_mass(2800, 0.01);
  const PairParams glass = pair_params({4.8e10, 0.2}, 0.01, mg, {4.8e10, 0.2}, 0.01, mg);
  EXPECT_NEAR(glass.mstar, 5.864e-3, 5e-4 * 5.864e-3);
  EXPECT_NEAR(glass.Estar, 2.500e10, 5e-4 * 2.5e10);
  const PairParams al = wall_params({7e10, 0.3}, 0.1, sphere_mass(2699, 0.1));
  EXPECT_NEAR(al.mstar, 11.306, 5e-4 * 11.306);
  EXPECT_NEAR(al.Estar, 7.692e10, 5e-4 * 7.692e10);
  EXPECT_DOUBLE_EQ(al.Rstar, 0.1);
  const PairParams same = wall_params({7e10, 0.3}, 0.1, sphere_mass(2699, 0.1), {7e10, 0.3});
  EXPECT_NEAR(same.Estar, 3.846e10, 5e-4 * 3.846e10);
  const PairParams ox = wall_params({3.8e11, 0.23}, 2.5e-3, sphere_mass(4000, 2.5e-3));
  EXPECT_NEAR(ox.mstar, 2.618e-4, 5e-4 * 2.618e-4);
  EXPECT_NEAR(ox.Estar, 4.012e11, 5e-4 * 4.012e11);
}

// ---------------------------------------------------------------------------------------------
// Damping ratios and contact times against docs/references.md §6.2-§6.4.

TEST(SoftDamping, PublishedBetaValues) {
  // Thornton beta_n (docs/references.md §6.2): 0.6668, 0.2330, 0.0679, 0.00819
  // at e = 0.2, 0.5, 0.8, 0.98.
  EXPECT_NEAR(thornton_damping_ratio(0.2), 0.6668, 1e-4);
  EXPECT_NEAR(thornton_damping_ratio(0.5), 0.2330, 1e-4);
  EXPECT_NEAR(thornton_damping_ratio(0.8), 0.0679, 1e-4);
  EXPECT_NEAR(thornton_damping_ratio(0.98), 0.00819, 1e-5);
  EXPECT_EQ(thornton_damping_ratio(1.0), 0.0);
  // Naive |beta| = 0.456, 0.215, 0.0709, 0.00643 for the same e; zeta = sqrt(5/6) |beta|.
  const double s = std::sqrt(5.0 / 6.0);
  EXPECT_NEAR(tsuji_damping_ratio(0.2) / s, 0.456, 5e-4);
  EXPECT_NEAR(tsuji_damping_ratio(0.5) / s, 0.215, 5e-4);
  EXPECT_NEAR(tsuji_damping_ratio(0.8) / s, 0.0709, 5e-5);
  EXPECT_NEAR(tsuji_damping_ratio(0.98) / s, 0.00643, 5e-6);
  // Linear: e = exp(-pi zeta/sqrt(1 - zeta^2)).
  for (double e : {0.1, 0.5, 0.9}) {
    const double z = linear_damping_ratio(e);
    EXPECT_NEAR(std::exp(-kPi * z / std::sqrt(1.0 - z * z)), e, 1e-14);
  }
}

// Closed form of the clipped linear collision: continuity through critical damping, where
// e = exp(-2) and t_f omega0 = 2, and the inverse.
TEST(SoftDamping, ClippedLinearClosedForm) {
  const ClippedLinear c = linear_clipped_collision(1.0);
  EXPECT_NEAR(c.e, std::exp(-2.0), 1e-15);
  EXPECT_NEAR(c.time, 2.0, 1e-15);
  for (double dz : {1e-5, 1e-4}) {
    EXPECT_NEAR(linear_clipped_collision(1.0 - dz).e, std::exp(-2.0), 10 * dz);
    EXPECT_NEAR(linear_clipped_collision(1.0 + dz).e, std::exp(-2.0), 10 * dz);
  }
  double prev = 1.0;
  for (double z = 0.01; z < 20.0; z *= 1.1) {
    const double e = linear_clipped_collision(z).e;
    EXPECT_LT(e, prev);
    prev = e;
    EXPECT_NEAR(linear_clipped_damping_ratio(e), z, 1e-12 * z);
  }
  // Small damping: the clip changes e only at second order, e_clip ~ e (1 + 2 zeta^2).
  const double z = 1e-3;
  EXPECT_NEAR(linear_clipped_collision(z).e / std::exp(-kPi * z / std::sqrt(1 - z * z)) - 1.0,
              2.0 * z * z, 1e-8);
}

TEST(SoftTimes, LinearContactTimeTable) {
  // docs/references.md §6.3: t_c sqrt(k/m*) = 3.1434 (e = 0.9), 3.2172 (0.5), 3.8951 (0.1).
  EXPECT_NEAR(linear_contact_time(1.0, 1.0, 0.9), 3.1434, 1e-4);
  EXPECT_NEAR(linear_contact_time(1.0, 1.0, 0.5), 3.2172, 1e-4);
  EXPECT_NEAR(linear_contact_time(1.0, 1.0, 0.1), 3.8951, 1e-4);
  EXPECT_NEAR(linear_contact_time(4.0, 1.0, 1.0), 2.0 * kPi, 1e-12);
}

// docs/references.md §1.2 (all rows) for the closed forms; the duration constant by its Gamma form.
TEST(SoftTimes, HertzTable) {
  EXPECT_NEAR(kHertzDurationFactor, 0.8 * std::sqrt(kPi) * std::tgamma(0.4) / std::tgamma(0.9),
              1e-9);
  EXPECT_NEAR(kHertzTimeFactor, kHertzDurationFactor * std::pow(15.0 / 16.0, 0.4), 1e-9);
  struct Row {
    double v, mstar, Estar, Rstar, delta_um, F, tc_us;
  };
  const Row rows[] = {
      {20, sphere_mass(2800, 0.01) / 2, 4.8e10 / (2 * (1 - 0.04)), 0.005, 274.11, 10697, 40.34},
      {20, sphere_mass(2500, 0.01) / 2, 2e10 / (2 * (1 - 0.0625)), 0.005, 368.30, 7108, 54.20},
      {0.2, sphere_mass(2699, 0.1), 7e10 / (1 - 0.09), 0.1, 49.72, 11370, 731.7},
      {0.2, sphere_mass(1800, 0.1), 4e10 / (1 - 0.1225), 0.1, 52.12, 7233, 767.1},
      {0.2, sphere_mass(2699, 0.1), 7e10 / (2 * (1 - 0.09)), 0.1, 65.60, 8617, 965.4},
      {3.9, sphere_mass(4000, 2.5e-3), 3.8e11 / (1 - 0.0529), 2.5e-3, 8.089, 615.4, 6.105},
      {3.9, sphere_mass(7000, 2.5e-3), 1e11 / (1 - 0.0625), 2.5e-3, 17.19, 506.8, 12.97},
  };
  for (const Row& r : rows) {
    const double d = hertz_max_overlap(r.mstar, r.Rstar, r.Estar, r.v);
    EXPECT_NEAR(d * 1e6 / r.delta_um, 1.0, 1e-3);
    EXPECT_NEAR(hertz_max_force(r.mstar, r.Rstar, r.Estar, r.v) / r.F, 1.0, 1e-3);
    const double tc = hertz_contact_time(r.mstar, r.Rstar, r.Estar, r.v);
    EXPECT_NEAR(tc * 1e6 / r.tc_us, 1.0, 1e-3);
    EXPECT_NEAR(tc, kHertzDurationFactor * d / r.v, 1e-9 * tc);
    // Energy at the turning point: m* v^2/2 = (2/5) F_max delta_max.
    EXPECT_NEAR(0.5 * r.mstar * r.v * r.v,
                0.4 * hertz_max_force(r.mstar, r.Rstar, r.Estar, r.v) * d,
                1e-9 * r.mstar * r.v * r.v);
  }
}

TEST(SoftTimes, RayleighExamples) {
  // docs/references.md §6.4.
  EXPECT_NEAR(rayleigh_time(0.01, 2800, 4.8e10, 0.2) / 1.293e-5, 1.0, 1e-3);
  EXPECT_NEAR(rayleigh_time(0.01, 2500, 2e10, 0.25) / 1.914e-5, 1.0, 1e-3);
  EXPECT_NEAR(rayleigh_time(0.1, 2699, 7e10, 0.3) / 1.075e-4, 1.0, 1e-3);
  EXPECT_NEAR(rayleigh_time(2.5e-3, 4000, 3.8e11, 0.23) / 1.383e-6, 1.0, 1e-3);
  EXPECT_NEAR(rayleigh_time(2.5e-3, 7000, 1e11, 0.25) / 3.581e-6, 1.0, 1e-3);
}

// The Verlet limit, checked by running the usual DEM scheme (dashpot at the half-step velocity)
// for a free damped spring just below and just above it.
class VerletLimit : public ::testing::TestWithParam<double> {};

TEST_P(VerletLimit, StableBelowUnstableAbove) {
  const double m = 2.0, k = 50.0, gamma = GetParam() * 2.0 * std::sqrt(k * m);
  const double hmax = verlet_max_step_spring(m, k, gamma);
  if (gamma == 0.0) {
    EXPECT_NEAR(hmax, 2.0 / std::sqrt(k / m), 1e-15);
  }
  auto amplitude = [&](double h) {
    double x = 1.0, v = 0.0, a = -k * x / m;
    double amax = 0.0;
    for (int n = 0; n < 20000; ++n) {
      const double vh = v + 0.5 * h * a;
      x += h * vh;
      a = (-k * x - gamma * vh) / m;
      v = vh + 0.5 * h * a;
      amax = std::max(amax, std::abs(x));
      if (!(amax < 1e6)) break;
    }
    return amax;
  };
  EXPECT_LT(amplitude(0.995 * hmax), 10.0);
  EXPECT_GT(amplitude(1.005 * hmax), 1e6);
}

INSTANTIATE_TEST_SUITE_P(SoftTimes, VerletLimit, ::testing::Values(0.0, 0.05, 0.3, 1.0, 3.0));

// LIGGGHTS' Hooke stiffness gives the Hertz maximum overlap at V (m* V^2 = k delta^2).
TEST(SoftTimes, LinearStiffnessMatchesHertzOverlap) {
  const PairParams p =
      wall_params({AlOxide::E, AlOxide::nu}, AlOxide::R, sphere_mass(AlOxide::rho, AlOxide::R));
  const double k = linear_stiffness(p, 3.9);
  EXPECT_NEAR(3.9 * std::sqrt(p.mstar / k) / hertz_max_overlap(p, 3.9), 1.0, 1e-12);
}

// ---------------------------------------------------------------------------------------------
// The binary integrator with the linear law: e and t_c exact.

namespace {

struct LinearCase {
  double e;
  bool attractive;
};

template <int D>
void check_linear_exact(const LinearCase& c) {
  const double R = AlOxide::R, m = sphere_mass(AlOxide::rho, AlOxide::R);
  BinaryBody<D> b = body<D>(R, m, AlOxide::E, AlOxide::nu);
  const Vec<D> n = axis<D>(D - 1);
  b.v = -3.9 * n;
  const PairParams p = wall_params(b.material, R, m);
  SoftLaw law = SoftLaw::linear(linear_stiffness(p, 3.9), c.e);
  law.attractive = c.attractive;
  BinaryOptions opt;
  opt.steps_per_contact = 20000;
  const BinaryResult<D> r = collide_wall<D>(law, b, n, SoftMaterial::rigid(), opt);
  ASSERT_TRUE(r.separated);
  EXPECT_NEAR(r.v_i.dot(n) / 3.9, c.e, 1e-6 * c.e);
  if (c.attractive) {
    // docs/references.md §6.3: t_c = sqrt(m*/k) sqrt(pi^2 + ln^2 e); the force pulls
    // before the end.
    const double tc =
        std::sqrt(m / law.stiffness) * std::sqrt(kPi * kPi + std::log(c.e) * std::log(c.e));
    EXPECT_NEAR(r.contact_time / tc, 1.0, 1e-6);
    if (c.e < 1.0) {
      EXPECT_LT(r.min_normal, 0.0);
    }
  } else {
    const double tf = std::sqrt(m / law.stiffness) *
                      linear_clipped_collision(linear_clipped_damping_ratio(c.e)).time;
    EXPECT_NEAR(r.force_time / tf, 1.0, 1e-6);
    EXPECT_GE(r.min_normal, 0.0);
  }
}

}  // namespace

class LinearExact : public ::testing::TestWithParam<std::tuple<double, bool>> {};

TEST_P(LinearExact, RestitutionAndDuration3D) {
  check_linear_exact<3>({std::get<0>(GetParam()), std::get<1>(GetParam())});
}
TEST_P(LinearExact, RestitutionAndDuration2D) {
  check_linear_exact<2>({std::get<0>(GetParam()), std::get<1>(GetParam())});
}

INSTANTIATE_TEST_SUITE_P(Soft, LinearExact,
                         ::testing::Combine(::testing::Values(0.05, 0.1, 0.3, 0.5, 0.7, 0.9, 0.99,
                                                              1.0),
                                            ::testing::Bool()));

// Second order: halving dt quarters the error of e (exact references: the linear law's e, and
// the Hertz law with the exact damping ratio, whose e equals the input by construction).
class VerletOrder : public ::testing::TestWithParam<int> {};

TEST_P(VerletOrder, HalvingDtQuartersTheError) {
  const double R = AlOxide::R, m = sphere_mass(AlOxide::rho, AlOxide::R), e = 0.4;
  BinaryBody<3> b = body<3>(R, m, AlOxide::E, AlOxide::nu);
  const Vec<3> n(0, 0, 1);
  b.v << 0.0, 0.0, -3.9;
  SoftLaw law;
  switch (GetParam()) {
    case 0:
      law = SoftLaw::linear(linear_stiffness(wall_params(b.material, R, m), 3.9), e);
      break;
    case 1:
      law = SoftLaw::linear(linear_stiffness(wall_params(b.material, R, m), 3.9), e);
      law.attractive = true;
      break;
    default:
      law = SoftLaw::hertz(e).resolved();
      break;
  }
  double err[3];
  for (int k = 0; k < 3; ++k) {
    BinaryOptions opt;
    opt.steps_per_contact = 50.0 * (1 << k);
    err[k] = collide_wall<3>(law, b, n, SoftMaterial::rigid(), opt).v_i[2] / 3.9 - e;
  }
  for (int k = 0; k < 2; ++k) {
    EXPECT_NEAR(err[k] / err[k + 1], 4.0, 0.5)
        << "errors " << err[0] << " " << err[1] << " " << err[2];
  }
}

INSTANTIATE_TEST_SUITE_P(Soft, VerletOrder, ::testing::Values(0, 1, 2));

// ---------------------------------------------------------------------------------------------
// The force function on random states.

namespace {

template <int D>
void random_force_checks(NormalLaw which) {
  std::mt19937_64 rng(7 + D + 10 * static_cast<int>(which));
  std::uniform_real_distribution<double> U(0.0, 1.0);
  const double R = AlOxide::R, m = sphere_mass(AlOxide::rho, R);
  for (int trial = 0; trial < 20000; ++trial) {
    const double Ri = R * (0.5 + U(rng)), Rj = R * (0.5 + U(rng));
    const PairParams p = pair_params({AlOxide::E, AlOxide::nu}, Ri, m, {2e11, 0.3}, Rj, 2 * m);
    SoftLaw law;
    switch (which) {
      case NormalLaw::Linear:
        law = SoftLaw::linear(1e7, 0.05 + 0.95 * U(rng));
        break;
      case NormalLaw::Hertz:
        law = SoftLaw::hertz(0.05 + 0.95 * U(rng), 0.0, HertzDamping::Thornton);
        break;
      case NormalLaw::Viscoelastic:
        law = SoftLaw::viscoelastic(1e-6 * U(rng));
        break;
    }
    law.friction = 0.05 + U(rng);
    const SoftContact c = soft_contact(law, p);
    const Vec<D> n = random_unit<D>(rng);
    const double delta = 1e-5 * R * U(rng);
    const Vec<D> vi = 5.0 * random_unit<D>(rng) * U(rng), vj = 5.0 * random_unit<D>(rng) * U(rng);
    const Spin<D> wi = random_spin<D>(rng, 1e3), wj = random_spin<D>(rng, 1e3);
    const double li = pair_lever_arm(Ri, delta), lj = pair_lever_arm(Rj, delta);
    ContactKinematics<D> k;
    k.delta = delta;
    k.n = n;
    k.v = contact_velocity<D>(vi, wi, li, vj, wj, lj, n);
    k.dxi = 1e-7 * k.v;
    ContactHistory<D> h;
    h.xi = 1e-6 * R * random_unit<D>(rng) * U(rng);  // may have a normal part: rotated away
    const ContactForce<D> f = soft_contact_force<D>(c, k, h);
    // Never attractive, Coulomb cap, the history stays in the tangent plane.
    ASSERT_GE(f.normal, 0.0);
    ASSERT_LE(f.tangential.norm(), law.friction * f.normal * (1.0 + 1e-12) + 1e-300);
    ASSERT_NEAR(f.tangential.dot(n), 0.0, 1e-12 * (1.0 + f.tangential.norm()));
    ASSERT_NEAR(h.xi.dot(n), 0.0, 1e-12 * (h.xi.norm() + 1e-300));
    ASSERT_NEAR(f.force.dot(n), f.normal, 1e-9 * (f.normal + f.tangential.norm()) + 1e-300);
    // Torques: (x_i - x_j) x F + tau_i + tau_j = 0 for x_i - x_j = (l_i + l_j) n.
    const Spin<D> ti = contact_torque<D>(n, f.tangential, li),
                  tj = contact_torque<D>(n, f.tangential, lj);
    const Spin<D> total = lever_moment<D>(Vec<D>((li + lj) * n), f.force) + ti + tj;
    ASSERT_LT(total.norm(), 1e-12 * (li + lj) * (f.force.norm() + 1e-300));
  }
}

}  // namespace

TEST(SoftForce, RandomStates3D) {
  random_force_checks<3>(NormalLaw::Linear);
  random_force_checks<3>(NormalLaw::Hertz);
  random_force_checks<3>(NormalLaw::Viscoelastic);
}
TEST(SoftForce, RandomStates2D) {
  random_force_checks<2>(NormalLaw::Linear);
  random_force_checks<2>(NormalLaw::Hertz);
  random_force_checks<2>(NormalLaw::Viscoelastic);
}

// A strongly separating contact: the raw force is negative, the returned force zero (and the
// tangential force with it); an attractive linear law keeps the pull.
TEST(SoftForce, NeverAttractsUnlessAsked) {
  const PairParams p = wall_params({AlOxide::E, AlOxide::nu}, AlOxide::R, 1e-3);
  ContactKinematics<3> k;
  k.delta = 1e-9;
  k.n = Vec<3>(0, 0, 1);
  k.v = Vec<3>(0.5, 0.0, 10.0);
  k.dxi = 1e-8 * k.v;
  for (SoftLaw law : {SoftLaw::linear(1e6, 0.3, 0.5), SoftLaw::hertz(0.3, 0.5),
                      SoftLaw::viscoelastic(1e-5, 0.5)}) {
    ContactHistory<3> h;
    const ContactForce<3> f = soft_contact_force<3>(soft_contact(law, p), k, h);
    EXPECT_LT(f.normal_raw, 0.0);
    EXPECT_EQ(f.normal, 0.0);
    EXPECT_EQ(f.force.norm(), 0.0);
    EXPECT_EQ(h.xi.norm(), 0.0);
  }
  SoftLaw pull = SoftLaw::linear(1e6, 0.3);
  pull.attractive = true;
  ContactHistory<3> h;
  EXPECT_LT(soft_contact_force<3>(soft_contact(pull, p), k, h).normal, 0.0);
}

// When the normal turns, the stored spring is turned into the new tangent plane with its length.
TEST(SoftForce, HistoryFollowsTheTangentPlane) {
  const PairParams p = wall_params({AlOxide::E, AlOxide::nu}, AlOxide::R, 1e-3);
  SoftLaw law = SoftLaw::linear(1e6, 1.0, 1e9);  // no damping, no slip
  const SoftContact c = soft_contact(law, p);
  ContactHistory<3> h;
  h.xi = Vec<3>(1e-6, 0.0, 0.0);
  const double th = 0.3;
  ContactKinematics<3> k;
  k.delta = 1e-6;
  k.n = Vec<3>(std::sin(th), 0.0, std::cos(th));  // turned by th about y
  const ContactForce<3> f = soft_contact_force<3>(c, k, h);
  EXPECT_NEAR(h.xi.dot(k.n), 0.0, 1e-22);
  EXPECT_NEAR(h.xi.norm(), 1e-6, 1e-18);
  EXPECT_NEAR(h.xi[0], 1e-6 * std::cos(th), 1e-18);
  EXPECT_NEAR(h.xi[2], -1e-6 * std::sin(th), 1e-18);
  EXPECT_NEAR((f.tangential + c.kt * h.xi).norm(), 0.0, 1e-12 * c.kt * 1e-6);
}

// Sliding rescales the spring to the cap: after the call, F_t = -k_t xi exactly.
TEST(SoftForce, SlidingRescalesTheSpring) {
  const PairParams p = wall_params({AlOxide::E, AlOxide::nu}, AlOxide::R, 1e-3);
  const SoftContact c = soft_contact(SoftLaw::linear(1e6, 0.8, 0.1), p);
  ContactHistory<3> h;
  ContactKinematics<3> k;
  k.delta = 1e-6;
  k.n = Vec<3>(0, 0, 1);
  k.v = Vec<3>(1.0, 0.0, -0.1);
  k.dxi = Vec<3>(1e-4, 0.0, 0.0);
  const ContactForce<3> f = soft_contact_force<3>(c, k, h);
  ASSERT_TRUE(f.sliding);
  EXPECT_NEAR(f.tangential.norm(), 0.1 * f.normal, 1e-12 * f.normal);
  EXPECT_NEAR(f.tangential[0], -0.1 * f.normal, 1e-12 * f.normal);  // opposes the slip
  EXPECT_NEAR((f.tangential + c.kt * h.xi).norm(), 0.0, 1e-12 * f.normal);
}

// ---------------------------------------------------------------------------------------------
// Whole collisions: cap, no attraction, momentum and angular momentum, torque signs.

namespace {

template <int D>
void oblique_pair_conservation(NormalLaw which, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  for (int trial = 0; trial < 10; ++trial) {
    const double Ri = AlOxide::R * (0.5 + U(rng)), Rj = AlOxide::R * (0.5 + U(rng));
    BinaryBody<D> a = body<D>(Ri, sphere_mass(AlOxide::rho, Ri), AlOxide::E, AlOxide::nu);
    BinaryBody<D> b = body<D>(Rj, sphere_mass(7000, Rj), 1e11, 0.25);
    const Vec<D> n = random_unit<D>(rng);
    a.v = 2.0 * random_unit<D>(rng);
    b.v = 2.0 * random_unit<D>(rng);
    if ((a.v - b.v).dot(n) > -0.5) {
      const double s = (a.v - b.v).dot(n) + 0.5 + U(rng);
      a.v -= s * n;
    }
    a.w = random_spin<D>(rng, 2e3);
    b.w = random_spin<D>(rng, 2e3);
    SoftLaw law;
    switch (which) {
      case NormalLaw::Linear:
        law = SoftLaw::linear(2e6, 0.1 + 0.9 * U(rng));
        break;
      case NormalLaw::Hertz:
        law = SoftLaw::hertz(0.1 + 0.9 * U(rng), 0.0, HertzDamping::Thornton);
        break;
      case NormalLaw::Viscoelastic:
        law = SoftLaw::viscoelastic(1e-7 * U(rng));
        break;
    }
    law.friction = 0.05 + 0.5 * U(rng);
    BinaryOptions opt;
    opt.record = true;
    const BinaryResult<D> r = collide_pair<D>(law, a, b, n, opt);
    ASSERT_TRUE(r.separated);
    EXPECT_GE(r.min_normal, 0.0);
    EXPECT_LE(r.max_friction_excess, 1e-12 * r.max_force);
    for (const BinarySample& s : r.trace) ASSERT_GE(s.normal, 0.0);
    // Linear momentum, and angular momentum about the first contact point (the origin):
    // L = sum m x x v + I w. The torque rule conserves it exactly, and so does the scheme.
    const Vec<D> P0 = a.mass * a.v + b.mass * b.v, P1 = a.mass * r.v_i + b.mass * r.v_j;
    const double pscale = a.mass * a.v.norm() + b.mass * b.v.norm();
    EXPECT_LT((P1 - P0).norm(), 1e-13 * pscale);
    const double qf = inertia_factor<D>();
    const Vec<D> xa0 = a.radius * n, xb0 = -b.radius * n;
    const Spin<D> L0 = a.mass * lever_moment<D>(xa0, a.v) + b.mass * lever_moment<D>(xb0, b.v) +
                       qf * a.mass * a.radius * a.radius * a.w +
                       qf * b.mass * b.radius * b.radius * b.w;
    const Spin<D> L1 =
        a.mass * lever_moment<D>(r.x_i, r.v_i) + b.mass * lever_moment<D>(r.x_j, r.v_j) +
        qf * a.mass * a.radius * a.radius * r.w_i + qf * b.mass * b.radius * b.radius * r.w_j;
    const double Lscale =
        pscale * (a.radius + b.radius) + qf * (a.mass * a.radius * a.radius * a.w.norm() +
                                               b.mass * b.radius * b.radius * b.w.norm());
    EXPECT_LT((L1 - L0).norm(), 1e-12 * Lscale);
    // The spins did change (the check is not vacuous).
    EXPECT_GT((r.w_i - a.w).norm(), 1.0);
  }
}

}  // namespace

TEST(SoftCollision, CapMomentumNoAttraction3D) {
  oblique_pair_conservation<3>(NormalLaw::Linear, 11);
  oblique_pair_conservation<3>(NormalLaw::Hertz, 12);
  oblique_pair_conservation<3>(NormalLaw::Viscoelastic, 13);
}
TEST(SoftCollision, CapMomentumNoAttraction2D) {
  oblique_pair_conservation<2>(NormalLaw::Linear, 21);
  oblique_pair_conservation<2>(NormalLaw::Hertz, 22);
  oblique_pair_conservation<2>(NormalLaw::Viscoelastic, 23);
}

// Torque sign: a body sliding in +t over a wall (normal n) is set rolling forward. In gross
// sliding (tan theta >= (1 + 1/q) mu (1 + e)) the rigid-body rule (docs/references.md §6.6) gives
// v_t' = v_t - mu (1 + e) v_n and |omega'| = mu (1 + e) v_n/(q R), with the sense of a rolling
// wheel: 3D (t = x, n = z) omega_y' = +(5/2) mu (1 + e) v_n/R; 2D (t = x, n = y)
// omega_z' = -2 mu (1 + e) v_n/R.
class TorqueSign : public ::testing::TestWithParam<int> {};

namespace {
template <int D>
void check_sliding_wall(const SoftLaw& law) {
  const double R = AlOxide::R, m = sphere_mass(AlOxide::rho, R);
  const double mu = law.friction, e = law.restitution, vn = 1.0, vt = 2.0, q = inertia_factor<D>();
  BinaryBody<D> b = body<D>(R, m, AlOxide::E, AlOxide::nu);
  const Vec<D> n = axis<D>(D - 1), t = axis<D>(0);
  b.v = vt * t - vn * n;
  const BinaryResult<D> r = collide_wall<D>(law, b, n);
  EXPECT_NEAR(r.v_i.dot(n), e * vn, 1e-4 * vn);
  EXPECT_NEAR(r.v_i.dot(t), vt - mu * (1 + e) * vn, 1e-4 * vt);
  const double w = mu * (1 + e) * vn / (q * R);
  if constexpr (D == 3) {
    EXPECT_NEAR(r.w_i[1], w, 1e-3 * w);
    EXPECT_NEAR(r.w_i[0], 0.0, 1e-9 * w);
    EXPECT_NEAR(r.w_i[2], 0.0, 1e-9 * w);
  } else {
    EXPECT_NEAR(r.w_i[0], -w, 1e-3 * w);
  }
}
}  // namespace

TEST_P(TorqueSign, GrossSlidingOnAWall) {
  const PairParams p =
      wall_params({AlOxide::E, AlOxide::nu}, AlOxide::R, sphere_mass(AlOxide::rho, AlOxide::R));
  const SoftLaw law = GetParam() == 0 ? SoftLaw::linear(linear_stiffness(p, 1.0), 0.8, 0.1)
                                      : SoftLaw::hertz(0.8, 0.1).resolved();
  check_sliding_wall<3>(law);
  check_sliding_wall<2>(law);
}

INSTANTIATE_TEST_SUITE_P(Soft, TorqueSign, ::testing::Values(0, 1));

// Sticking limit of the linear law with an undamped tangential spring: the contact-point
// velocity reverses as beta0 = -cos(pi t_tau sqrt((1 + 1/q) k_t/k_n)) (soft.hpp, DERIVED).
class StickingRestitution : public ::testing::TestWithParam<std::tuple<double, double>> {};

namespace {
template <int D>
void check_sticking(double kt_ratio, double e) {
  const double R = AlOxide::R, m = sphere_mass(AlOxide::rho, R), q = inertia_factor<D>();
  BinaryBody<D> b = body<D>(R, m, AlOxide::E, AlOxide::nu);
  const Vec<D> n = axis<D>(D - 1), t = axis<D>(0);
  const double vn = 0.039, ut = 0.01;
  b.v = ut * t - vn * n;
  SoftLaw law = SoftLaw::linear(linear_stiffness(wall_params(b.material, R, m), 3.9), e, 1e9);
  law.attractive = true;  // t_c of docs/references.md §6.3
  law.kt_ratio = kt_ratio;
  law.tangential_damping = false;
  BinaryOptions opt;
  opt.steps_per_contact = 2000;
  const BinaryResult<D> r = collide_wall<D>(law, b, n, SoftMaterial::rigid(), opt);
  const Vec<D> u = contact_velocity<D>(r.v_i, r.w_i, R, Vec<D>::Zero(), Spin<D>::Zero(), 0.0, n);
  const double beta = -u.dot(t) / ut;
  EXPECT_NEAR(beta, linear_sticking_restitution(kt_ratio, q, e), 2e-3)
      << "D = " << D << ", kt/kn = " << kt_ratio << ", e = " << e;
  // The inverse holds on the first half period of the tangential oscillation.
  const double ttau = std::sqrt(1.0 + std::pow(std::log(e) / kPi, 2));
  if (ttau * std::sqrt((1.0 + 1.0 / q) * kt_ratio) <= 1.0) {
    EXPECT_NEAR(linear_kt_ratio_for(linear_sticking_restitution(kt_ratio, q, e), q, e), kt_ratio,
                1e-6 * kt_ratio);
  }
}
}  // namespace

TEST_P(StickingRestitution, LinearTangentialSpring) {
  const auto [kt, e] = GetParam();
  check_sticking<3>(kt, e);
  check_sticking<2>(kt, e);
}

INSTANTIATE_TEST_SUITE_P(Soft, StickingRestitution,
                         ::testing::Combine(::testing::Values(2.0 / 7.0, 1.0 / 7.0, 1.0 / 14.0,
                                                              0.25),
                                            ::testing::Values(1.0, 0.5)));

TEST(SoftSticking, PerfectlyRoughRatios) {
  EXPECT_NEAR(linear_sticking_restitution(2.0 / 7.0, 0.4), 1.0, 1e-15);
  EXPECT_NEAR(linear_sticking_restitution(1.0 / 3.0, 0.5), 1.0, 1e-15);
  EXPECT_NEAR(linear_kt_ratio_for(1.0, 0.4), 2.0 / 7.0, 1e-15);
  EXPECT_NEAR(linear_kt_ratio_for(-1.0, 0.4), 0.0, 1e-15);  // smooth
}

// Viscoelastic law: small-A restitution against the first-order term DERIVED from the elastic
// Hertz path, 1 - e = (3/2) C1 A (K/m*)^(2/5) v^(1/5) with K = (4/3) E* sqrt(R*) and
// C1 = Gamma(3/5) sqrt(pi)/(2^(1/5) 5^(2/5) Gamma(21/10)) = 1.15344 (the constant of Ramirez,
// Poschel, Brilliantov & Schwager, PRE 60, 4465 (1999), docs/references.md §6.5); A = 0 is elastic.
TEST(SoftViscoelastic, FirstOrderRestitution) {
  const double C1 = std::tgamma(0.6) * std::sqrt(kPi) /
                    (std::pow(2.0, 0.2) * std::pow(5.0, 0.4) * std::tgamma(2.1));
  EXPECT_NEAR(C1, 1.15344, 1e-5);
  const double R = AlOxide::R, m = sphere_mass(AlOxide::rho, R);
  BinaryBody<3> b = body<3>(R, m, AlOxide::E, AlOxide::nu);
  const Vec<3> n(0, 0, 1);
  const PairParams p = wall_params(b.material, R, m);
  const double K = 4.0 / 3.0 * p.Estar * std::sqrt(p.Rstar);
  const double A =
      0.004 / (1.5 * C1 * std::pow(K / m, 0.4) * std::pow(1.0, 0.2));  // 1 - e = 0.004 at 1 m/s
  for (double v : {1.0, 32.0}) {
    b.v = -v * n;
    const double e = collide_wall<3>(SoftLaw::viscoelastic(A), b, n).v_i[2] / v;
    const double first = 1.5 * C1 * A * std::pow(K / m, 0.4) * std::pow(v, 0.2);
    EXPECT_NEAR((1.0 - e) / first, 1.0, 0.01) << "v = " << v;
  }
  b.v = -1.0 * n;
  EXPECT_NEAR(collide_wall<3>(SoftLaw::viscoelastic(0.0), b, n).v_i[2], 1.0, 1e-6);  // elastic
}

// The exact Hertz damping ratio reproduces e, and the two fits behave as documented.
TEST(SoftDamping, HertzExactAndFits) {
  for (double e : {0.1, 0.3, 0.5, 0.7, 0.9, 0.98, 0.999}) {
    EXPECT_NEAR(hertz_clipped_collision(hertz_clipped_damping_ratio(e)).e, e, 1e-10);
  }
  // As e -> 1 the energy loss is first order in zeta (DERIVED on the elastic path):
  // 1 - e = (4 pi/5) sqrt(15/8) zeta; with Tsuji's zeta = sqrt(5/6) |ln e|/pi this is |ln e|, so
  // the naive rule is right in that limit.
  EXPECT_NEAR(hertz_clipped_damping_ratio(0.999) / tsuji_damping_ratio(0.999), 1.0, 1e-3);
  EXPECT_EQ(hertz_clipped_damping_ratio(1.0), 0.0);
  // Elastic duration in units of (m*^2/(K^2 v))^(1/5): 2.94328 (5/4)^(2/5).
  EXPECT_NEAR(hertz_clipped_collision(0.0).time, kHertzDurationFactor * std::pow(1.25, 0.4), 1e-9);
}

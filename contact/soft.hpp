// Soft-sphere (time-driven) contact laws: effective parameters, normal laws (linear
// spring-dashpot, Hertz with Tsuji-type damping, viscoelastic Kuwabara-Kono/Brilliantov) and the
// Mindlin-Deresiewicz / Cundall-Strack tangential spring with Coulomb cap. Pure functions of the
// relative state of one contact; docs/references.md §6 gives every formula used here.
//
// Conventions (all laws):
//  * n is the unit contact normal pointing from j to i (n = (x_i - x_j)/|x_i - x_j|; for a plane
//    wall, the wall normal, which points to the side where the particle lives). This matches
//    contact/hard.hpp and Wall<D>::normal.
//  * delta = R_i + R_j - |x_i - x_j| > 0 is the overlap (wall: R_i - (x_i - p).n).
//  * Contact point: on i at x_i - l_i n, on j at x_j + l_j n, with lever arms l_i = R_i - delta/2,
//    l_j = R_j - delta/2 for a pair (LAMMPS pair granular, Yade Law2_ScGeom_MindlinPhys use the
//    same split) and l_i = R_i - delta for a plane (the point lies on the plane). Because l_i + l_j
//    equals the centre distance, the torques below conserve total angular momentum exactly.
//  * Relative contact velocity v_c = v_i - v_j - (l_i w_i + l_j w_j) x n; its normal part
//    v_n = v_c.n = (v_i - v_j).n is negative while approaching, d(delta)/dt = -v_n; its tangential
//    part v_t = v_c - v_n n. (With m = -n, pointing from i to j, this reads
//    v_t = v_ij - (v_ij.m)m + (l_i w_i + l_j w_j) x m.)
//  * The force F = F_n n + F_t acts on i, -F on j. Torques: tau_i = -l_i n x F_t,
//    tau_j = -l_j n x F_t (same sign: both spheres are pushed to roll the same way).
//  * In 2D, Spin<2> holds the z component: w x r = w (-r_y, r_x) and r x f = r_x f_y - r_y f_x.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>

#include "contact/vec.hpp"

namespace matep {

// ---------------------------------------------------------------------------------------------
// Small vector helpers shared by 2D and 3D.

// w x r for an angular velocity w and a vector r (2D: w is the z component).
template <int D>
inline Vec<D> spin_cross(const Spin<D>& w, const Vec<D>& r) {
  if constexpr (D == 2) {
    return Vec<D>(-w[0] * r[1], w[0] * r[0]);
  } else {
    return Vec<D>(w[1] * r[2] - w[2] * r[1], w[2] * r[0] - w[0] * r[2], w[0] * r[1] - w[1] * r[0]);
  }
}

// r x f as an angular quantity (2D: the z component).
template <int D>
inline Spin<D> lever_moment(const Vec<D>& r, const Vec<D>& f) {
  if constexpr (D == 2) {
    Spin<D> m;
    m[0] = r[0] * f[1] - r[1] * f[0];
    return m;
  } else {
    return Spin<D>(r[1] * f[2] - r[2] * f[1], r[2] * f[0] - r[0] * f[2], r[0] * f[1] - r[1] * f[0]);
  }
}

// The same two on plain numbers, for the batched loop's lanes (engine/soft/batch.hpp; Eigen's
// vectors there would keep the loop from running lane-wise, and the plain form here would cost
// the one-contact loops their speed). The same products in the same order: a test holds the two
// forms equal bit for bit.
template <int D>
[[gnu::always_inline]] inline void spin_cross_to(const double* w, const double* r, double* out) {
  if constexpr (D == 2) {
    out[0] = -w[0] * r[1];
    out[1] = w[0] * r[0];
  } else {
    out[0] = w[1] * r[2] - w[2] * r[1];
    out[1] = w[2] * r[0] - w[0] * r[2];
    out[2] = w[0] * r[1] - w[1] * r[0];
  }
}
template <int D>
[[gnu::always_inline]] inline void lever_moment_to(const double* r, const double* f, double* out) {
  if constexpr (D == 2) {
    out[0] = r[0] * f[1] - r[1] * f[0];
  } else {
    out[0] = r[1] * f[2] - r[2] * f[1];
    out[1] = r[2] * f[0] - r[0] * f[2];
    out[2] = r[0] * f[1] - r[1] * f[0];
  }
}

// Moment of inertia factor q = I/(m R^2): solid sphere 2/5 (D = 3), solid disk 1/2 (D = 2).
template <int D>
inline constexpr double inertia_factor() {
  return D == 3 ? 0.4 : 0.5;
}

// ---------------------------------------------------------------------------------------------
// Effective parameters (docs/references.md §6.1, LIGGGHTS global_properties.cpp). A plane wall is
// infinitely large and heavy: pass kPlane (+infinity) as its radius and mass; a rigid wall also
// has young = kPlane, so its compliance terms vanish (E* = E/(1 - nu^2) for the particle alone).

inline constexpr double kPlane = std::numeric_limits<double>::infinity();

// E* = 1/((1 - nu1^2)/E1 + (1 - nu2^2)/E2).
inline double effective_young(double E1, double nu1, double E2, double nu2) {
  return 1.0 / ((1.0 - nu1 * nu1) / E1 + (1.0 - nu2 * nu2) / E2);
}
// G* = 1/(2(2 - nu1)(1 + nu1)/E1 + 2(2 - nu2)(1 + nu2)/E2) = 1/((2 - nu1)/G1 + (2 - nu2)/G2).
inline double effective_shear(double E1, double nu1, double E2, double nu2) {
  return 1.0 / (2.0 * (2.0 - nu1) * (1.0 + nu1) / E1 + 2.0 * (2.0 - nu2) * (1.0 + nu2) / E2);
}
// R* = R1 R2/(R1 + R2), written 1/(1/R1 + 1/R2) so that R2 = kPlane gives R1.
inline double effective_radius(double R1, double R2) { return 1.0 / (1.0 / R1 + 1.0 / R2); }
// m* = m1 m2/(m1 + m2); m2 = kPlane gives m1.
inline double effective_mass(double m1, double m2) { return 1.0 / (1.0 / m1 + 1.0 / m2); }

// Elastic constants of one body for a soft contact.
struct SoftMaterial {
  double young = 0.0;    // E [Pa]; kPlane for a rigid body
  double poisson = 0.0;  // nu
  static SoftMaterial rigid() { return {kPlane, 0.0}; }
};

// Effective parameters of one contact.
struct PairParams {
  double Estar = 0.0;  // effective Young's modulus
  double Gstar = 0.0;  // effective shear modulus
  double Rstar = 0.0;  // effective radius
  double mstar = 0.0;  // effective mass
  // Rolling inertia (Ai et al. 2011, eq. 17): I_r = 1 / (1/(I_i + m_i R_i^2) + 1/(I_j + m_j R_j^2)),
  // each body's inertia about its contact point (a wall's term is 0); only the Epsd dashpot uses it.
  double Ir = 0.0;
};

inline PairParams pair_params(const SoftMaterial& a, double Ra, double ma, const SoftMaterial& b,
                              double Rb, double mb) {
  return {effective_young(a.young, a.poisson, b.young, b.poisson),
          effective_shear(a.young, a.poisson, b.young, b.poisson), effective_radius(Ra, Rb),
          effective_mass(ma, mb)};
}

// Sphere (or disk) against a plane wall of material `wall` (SoftMaterial::rigid() by default).
inline PairParams wall_params(const SoftMaterial& a, double R, double m,
                              const SoftMaterial& wall = SoftMaterial::rigid()) {
  return pair_params(a, R, m, wall, kPlane, kPlane);
}

// ---------------------------------------------------------------------------------------------
// Damping ratios. Every dashpot below is written gamma = 2 zeta sqrt(m* S), with S the tangent
// stiffness dF/d(delta) (linear: k_n; Hertz: S_n = 2 E* sqrt(R* delta)) and zeta the damping
// ratio (fraction of critical damping).

// Linear spring-dashpot that may pull until delta = 0 (docs/references.md §6.3):
// e = exp(-pi zeta/sqrt(1 - zeta^2))  <=>  zeta = -ln e / sqrt(pi^2 + ln^2 e).
inline double linear_damping_ratio(double e) {
  if (e >= 1.0) return 0.0;
  const double l = std::log(e);
  return -l / std::sqrt(std::numbers::pi * std::numbers::pi + l * l);
}

// Linear spring-dashpot whose force is clipped at zero (no attraction): the contact ends when
// k delta + gamma d(delta)/dt = 0, i.e. at the inflection point of x(t) = delta. DERIVED from the
// closed-form damped oscillator (delta(0) = 0, delta'(0) = v; cf. Schwager & Poschel, Granular
// Matter 9, 465 (2007)), with omega0 = sqrt(k/m*), eta = zeta omega0:
//  zeta < 1: omega = omega0 sqrt(1 - zeta^2),
//            t_f = (pi - atan2(2 eta omega, omega^2 - eta^2))/omega,
//            e = exp(-eta t_f) ((eta/omega) sin(omega t_f) - cos(omega t_f));
//  zeta = 1: t_f = 2/omega0, e = exp(-2);
//  zeta > 1: lambda_1,2 = omega0 (zeta -+ sqrt(zeta^2 - 1)), r = lambda_2/lambda_1,
//            t_f = 2 ln r/(lambda_2 - lambda_1), e = r^(-(r + 1)/(r - 1)).
// Returns e and t_f omega0 for a damping ratio zeta >= 0.
struct ClippedLinear {
  double e;
  double time;  // t_f sqrt(k/m*)
};
inline ClippedLinear linear_clipped_collision(double zeta) {
  if (zeta <= 0.0) return {1.0, std::numbers::pi};
  const double dz = zeta - 1.0;
  if (std::abs(dz) < 1e-7) {  // critical damping (both branches tend to it continuously)
    return {std::exp(-2.0), 2.0};
  }
  if (zeta < 1.0) {
    const double w = std::sqrt(1.0 - zeta * zeta);  // omega/omega0
    const double tf = (std::numbers::pi - std::atan2(2.0 * zeta * w, w * w - zeta * zeta)) / w;
    return {std::exp(-zeta * tf) * ((zeta / w) * std::sin(w * tf) - std::cos(w * tf)), tf};
  }
  const double s = std::sqrt(zeta * zeta - 1.0);
  const double l1 = zeta - s, l2 = zeta + s;  // in units of omega0
  const double r = l2 / l1;
  return {std::pow(r, -(r + 1.0) / (r - 1.0)), 2.0 * std::log(r) / (l2 - l1)};
}

// Inverse of linear_clipped_collision: the damping ratio that gives restitution e in (0, 1]
// (e decreases monotonically with zeta; bisection on log zeta to full double precision).
inline double linear_clipped_damping_ratio(double e) {
  if (e >= 1.0) return 0.0;
  double lo = 0.0, hi = 1.0;
  while (linear_clipped_collision(hi).e > e) hi *= 2.0;
  for (int it = 0; it < 200 && hi - lo > 1e-16 * hi; ++it) {
    const double mid = 0.5 * (lo + hi);
    (linear_clipped_collision(mid).e > e ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

// Hertz with Tsuji-type damping, the "naive" rule (LIGGGHTS normal_model_hertz.h,
// docs/references.md §6.2): gamma_n = -2 sqrt(5/6) beta sqrt(S_n m*),
// beta = ln e / sqrt(ln^2 e + pi^2), i.e. zeta = sqrt(5/6) |beta|. It is exact as e -> 1
// (first-order energy loss) but, with the force clipped at zero, misses at low e.
inline double tsuji_damping_ratio(double e) {
  if (e >= 1.0) return 0.0;
  const double l = std::log(e);
  return std::sqrt(5.0 / 6.0) * (-l) / std::sqrt(l * l + std::numbers::pi * std::numbers::pi);
}

// Hertz with the Thornton, Cummins & Cleary correction (Powder Technol. 233, 30 (2013), eqs. B6-B7,
// as used by Yade Ip2_FrictMat_FrictMat_MindlinPhys and Kratos GammaForHertzThornton):
// alpha(e) = e (h1 + e (h2 + ... + e h10)), zeta = sqrt(1/(1 - (1 + e)^2 exp(alpha)) - 1), with
// gamma_n = 2 zeta sqrt(S_n m*) (no sqrt(5/6) factor). A fit for the clipped (non-attractive)
// force; it does not vanish at e = 1 (zeta(0.999) = 0.0047), so e = 1 is special-cased to 0.
inline double thornton_damping_ratio(double e) {
  if (e >= 1.0) return 0.0;
  static constexpr double h[10] = {-6.918798, -16.41105, 146.8049,  -796.4559, 2928.711,
                                   -7206.864, 11494.29,  -11342.18, 6276.757,  -1489.915};
  double a = 0.0;
  for (int k = 9; k >= 0; --k) a = (a + h[k]) * e;
  return std::sqrt(1.0 / (1.0 - (1.0 + e) * (1.0 + e) * std::exp(a)) - 1.0);
}

// Hertz with Tsuji-type damping and the force clipped at zero, solved exactly (DERIVED; no fit).
// With K = (4/3) E* sqrt(R*), the impact m* x'' = -K x^3/2 - 2 zeta sqrt(1.5 K m*) x^1/4 x' is
// scale-free: in units x_s = (m* v^2/K)^(2/5), t_s = x_s/v it reads
// X'' = -X^3/2 - 2 zeta sqrt(3/2) X^1/4 X', X(0) = 0, X'(0) = 1, so e depends on zeta only (Tsuji,
// Tanaka & Ishida 1992). hertz_clipped_collision integrates it (classical RK4 in s = t^(1/4), where
// the solution is smooth at first contact) up to the instant the force vanishes, and returns e and
// that instant in units of t_s = (m*^2/(K^2 v))^(1/5). Accurate to about 1e-10 in e.
struct ClippedHertz {
  double e;
  double time;  // force duration / (m*^2/(K^2 v))^(1/5)
};
ClippedHertz hertz_clipped_collision(double zeta);
// The damping ratio that gives restitution e in (0, 1] exactly (the inverse of the above).
double hertz_clipped_damping_ratio(double e);

// ---------------------------------------------------------------------------------------------
// Contact laws chosen at run time.

enum class NormalLaw { Linear, Hertz, Viscoelastic };
// Hertz damping ratio from e: Exact (default: hertz_clipped_damping_ratio, e exact for any e; a
// few milliseconds, so resolve it once per pair of materials), Thornton (TCC 2013 fit, as in Yade
// and Kratos: within 0.1% for e <= 0.9 but 0.8% low at e = 0.98 and 1.6% low at e = 0.999) or
// Tsuji (the naive LIGGGHTS rule: right as e -> 1, 150% high at e = 0.1).
enum class HertzDamping { Exact, Thornton, Tsuji };

// A contact law between two materials: value type, no virtual calls. Pair-dependent constants
// (E*, R*, m*) are folded in by soft_contact() below.
// Rolling resistance of the soft contacts (Ai, Chen, Rotter & Ooi, "Assessment of rolling resistance
// models in discrete element simulations", Powder Technol. 206, 269 (2011)): none; model A, the
// constant directional torque (Constant); model C, the elastic-plastic spring-dashpot (Epsd).
enum class RollingModel : std::uint8_t { None, Constant, Epsd };

struct SoftLaw {
  NormalLaw normal = NormalLaw::Hertz;
  double restitution = 1.0;  // e in (0, 1] (Linear, Hertz)
  // Linear: normal stiffness k_n [N/m]; linear_stiffness() gives LIGGGHTS' Hertz-equivalent value.
  double stiffness = 0.0;
  // Linear: let the dashpot pull (F_n < 0) until delta = 0. Then gamma from docs/references.md §6.3
  // gives e and t_c = sqrt(m*/k) sqrt(pi^2 + ln^2 e) exactly. Default false: the force is clipped
  // at zero and gamma is chosen by linear_clipped_damping_ratio(), which again gives e exactly.
  bool attractive = false;
  // Linear: an explicit normal damping coefficient gamma_n [kg/s] (Material::dissipation); >= 0
  // overrides `restitution` (the damping ratio then varies with m* from pair to pair).
  double gamma_n = -1.0;
  HertzDamping damping = HertzDamping::Exact;  // Hertz only
  // Viscoelastic: A [s] in F = K (delta^3/2 + 3/2 A sqrt(delta) delta').
  double dissipation_time = 0.0;
  double friction = 0.0;  // Coulomb mu: |F_t| <= mu |F_n|
  // Rolling resistance (RollingModel): the coefficient mu_r (the torque is at most mu_r R* F_n) and,
  // for Epsd, the damping ratio eta_r of the rolling dashpot.
  RollingModel rolling = RollingModel::None;
  double rolling_friction = 0.0;
  double rolling_damping = 0.0;
  // Linear: k_t = kt_ratio k_n (LIGGGHTS: 1, or 2/7 with ktToKnUser; 2/7 makes the tangential
  // oscillation of solid spheres as fast as the normal one; see linear_kt_ratio_for()).
  // Hertz/Viscoelastic: k_t = 8 G* sqrt(R* delta).
  double kt_ratio = 2.0 / 7.0;
  bool tangential_damping = true;  // gamma_t with the normal damping ratio (Viscoelastic: A k_t)
  // Damping ratio zeta (Linear, Hertz); < 0: derived from `restitution` by soft_contact(). The
  // derivation can cost milliseconds (Exact, clipped Linear): call resolved() once per pair of
  // materials and keep the result.
  double zeta = -1.0;

  double damping_ratio() const {
    if (zeta >= 0.0) return zeta;
    if (normal == NormalLaw::Linear) {
      return attractive ? linear_damping_ratio(restitution)
                        : linear_clipped_damping_ratio(restitution);
    }
    if (normal == NormalLaw::Hertz) {
      switch (damping) {
        case HertzDamping::Thornton:
          return thornton_damping_ratio(restitution);
        case HertzDamping::Tsuji:
          return tsuji_damping_ratio(restitution);
        case HertzDamping::Exact:
          return hertz_clipped_damping_ratio(restitution);
      }
    }
    return 0.0;
  }
  SoftLaw resolved() const {
    SoftLaw l = *this;
    l.zeta = damping_ratio();
    return l;
  }

  static SoftLaw linear(double kn, double e, double mu = 0.0) {
    SoftLaw l;
    l.normal = NormalLaw::Linear;
    l.stiffness = kn;
    l.restitution = e;
    l.friction = mu;
    return l;
  }
  static SoftLaw hertz(double e, double mu = 0.0, HertzDamping d = HertzDamping::Exact) {
    SoftLaw l;
    l.normal = NormalLaw::Hertz;
    l.restitution = e;
    l.friction = mu;
    l.damping = d;
    return l;
  }
  static SoftLaw viscoelastic(double A, double mu = 0.0) {
    SoftLaw l;
    l.normal = NormalLaw::Viscoelastic;
    l.dissipation_time = A;
    l.friction = mu;
    return l;
  }
};

// LIGGGHTS Hooke stiffness that gives the Hertz maximum overlap at the characteristic speed V
// (docs/references.md §6.3): k_n = (16/15) sqrt(R*) E* (15 m* V^2/(16 sqrt(R*) E*))^(1/5).
inline double linear_stiffness(const PairParams& p, double V) {
  const double s = std::sqrt(p.Rstar) * p.Estar;
  return (16.0 / 15.0) * s * std::pow(15.0 * p.mstar * V * V / (16.0 * s), 0.2);
}

// Tangential restitution of a sticking contact (the beta0 of the rough hard-sphere rule,
// docs/references.md §6.6: v_t' = -beta0 v_t for the contact-point velocity) for the linear law
// with an undamped tangential spring and no slip. DERIVED: the contact-point velocity u obeys
// m* u' = -(1 + 1/q) k_t xi (q = I/(m R^2); both bodies solid with the same q), so
// u(t) = u0 cos(omega_t t), omega_t = sqrt((1 + 1/q) k_t/m*), and over the contact time t_c
// beta0 = -cos(omega_t t_c). With t_c = t_tau pi/omega_n (t_tau = 1 for e = 1 and
// sqrt(1 + ln^2 e/pi^2) for the attractive law), beta0 = -cos(pi t_tau sqrt((1 + 1/q) k_t/k_n)).
// k_t/k_n = 2/7 (spheres) or 1/3 (disks) gives beta0 = +1 at e = 1: the tangential oscillation
// completes half a period, like the perfectly rough hard sphere.
inline double linear_sticking_restitution(double kt_ratio, double q, double e = 1.0) {
  const double l = e < 1.0 ? std::log(e) : 0.0;
  const double ttau = std::sqrt(1.0 + l * l / (std::numbers::pi * std::numbers::pi));
  return -std::cos(std::numbers::pi * ttau * std::sqrt((1.0 + 1.0 / q) * kt_ratio));
}
// Inverse for the first half period: the k_t/k_n that gives beta0 in [-1, 1].
inline double linear_kt_ratio_for(double beta0, double q, double e = 1.0) {
  const double l = e < 1.0 ? std::log(e) : 0.0;
  const double ttau = std::sqrt(1.0 + l * l / (std::numbers::pi * std::numbers::pi));
  const double a = std::acos(-std::clamp(beta0, -1.0, 1.0)) / (std::numbers::pi * ttau);
  return a * a * q / (1.0 + q);
}

// A law resolved for one pair: the hot-path constants.
struct SoftContact {
  NormalLaw normal = NormalLaw::Hertz;
  // Linear:       F_n = kn delta + gn delta',          F_t = -kt xi - gt v_t
  // Hertz:        F_n = kn delta^3/2 + gn delta^1/4 delta',
  //               F_t = -kt sqrt(delta) xi - gt delta^1/4 v_t
  // Viscoelastic: F_n = kn delta^3/2 + gn sqrt(delta) delta',
  //               F_t = -kt sqrt(delta) xi - gt sqrt(delta) v_t
  double kn = 0.0, gn = 0.0, kt = 0.0, gt = 0.0;
  double mu = 0.0;
  bool clip = true;    // F_n >= 0
  double zeta = 0.0;   // normal damping ratio (Linear, Hertz)
  double mstar = 0.0;  // for diagnostics
  // Rolling resistance (rolling_torque below): the model, the full-mobilisation lever mu_r R*, the
  // rolling stiffness per unit secant normal stiffness 2.25 mu_r^2 R*^2 (k_r = that times k_n, or
  // times k_n sqrt(delta) for the Hertzian laws) and the dashpot's 2 eta_r sqrt(I_r) (C_r = that
  // times sqrt(k_r)).
  RollingModel rolling = RollingModel::None;
  double roll_lever = 0.0, roll_kr = 0.0, roll_cr = 0.0;
};

inline SoftContact soft_contact(const SoftLaw& law, const PairParams& p) {
  SoftContact c;
  c.normal = law.normal;
  c.mu = law.friction;
  c.mstar = p.mstar;
  if (law.rolling != RollingModel::None && law.rolling_friction > 0.0) {
    // Ai et al. (2011): M_m = mu_r R* F_n (eq. 13); model C's k_r = 2.25 k_n mu_r^2 R*^2 (eq. 16) and
    // C_r = eta_r 2 sqrt(I_r k_r) (eqs. 17-18).
    c.rolling = law.rolling;
    c.roll_lever = law.rolling_friction * p.Rstar;
    c.roll_kr = 2.25 * c.roll_lever * c.roll_lever;
    c.roll_cr = 2.0 * law.rolling_damping * std::sqrt(p.Ir);
  }
  const double hertz_k = (4.0 / 3.0) * p.Estar * std::sqrt(p.Rstar);  // docs/references.md §6.2
  const double mindlin_k = 8.0 * p.Gstar * std::sqrt(p.Rstar);        // S_t = 8 G* sqrt(R* delta)
  switch (law.normal) {
    case NormalLaw::Linear: {
      c.clip = !law.attractive;
      c.kn = law.stiffness;
      c.zeta = law.gamma_n >= 0.0 ? law.gamma_n / (2.0 * std::sqrt(p.mstar * c.kn))
                                  : law.damping_ratio();
      c.gn = 2.0 * c.zeta * std::sqrt(p.mstar * c.kn);  // docs/references.md §6.3
      c.kt = law.kt_ratio * c.kn;
      // Same damping ratio in both directions: gamma_t = gamma_n sqrt(k_t/k_n) (LIGGGHTS uses
      // gamma_t = gamma_n, which is this rule for k_t = k_n).
      c.gt = law.tangential_damping ? 2.0 * c.zeta * std::sqrt(p.mstar * c.kt) : 0.0;
      break;
    }
    case NormalLaw::Hertz: {
      c.zeta = law.damping_ratio();
      c.kn = hertz_k;
      // gamma_n = 2 zeta sqrt(S_n m*) with S_n = 2 E* sqrt(R* delta) (docs/references.md §6.2)
      c.gn = 2.0 * c.zeta * std::sqrt(2.0 * p.Estar * std::sqrt(p.Rstar) * p.mstar);
      c.kt = mindlin_k;
      // gamma_t = 2 zeta sqrt(S_t m*) (LIGGGHTS; Yade's betas = betan)
      c.gt = law.tangential_damping ? 2.0 * c.zeta * std::sqrt(mindlin_k * p.mstar) : 0.0;
      break;
    }
    case NormalLaw::Viscoelastic: {
      // F = (2Y sqrt(R*)/(3(1 - nu^2))) (delta^3/2 + 3/2 A sqrt(delta) delta'): Brilliantov, Spahn,
      // Hertzsch & Poschel, PRE 53, 5382 (1996) for two equal spheres, whose prefactor is
      // (4/3) E* sqrt(R*); the dissipative term is A S_n delta' (Kelvin-Voigt with time A).
      c.kn = hertz_k;
      c.gn = 1.5 * law.dissipation_time * hertz_k;
      c.kt = mindlin_k;
      // Tangential Kelvin-Voigt with the same time A: gamma_t = A S_t (a choice, not a citation).
      c.gt = law.tangential_damping ? law.dissipation_time * mindlin_k : 0.0;
      break;
    }
  }
  return c;
}

// The normal force of each law, the one place its formula is written (see SoftContact), before
// clipping, at overlap delta >= 0 and normal relative velocity vn = -delta' (< 0 approaching).
template <NormalLaw Law>
[[gnu::always_inline]] inline double normal_force_law(double kn, double gn, double delta, double vn) {
  if constexpr (Law == NormalLaw::Linear) {
    return kn * delta - gn * vn;
  } else if constexpr (Law == NormalLaw::Hertz) {
    const double s = std::sqrt(delta);
    return kn * delta * s - gn * std::sqrt(s) * vn;
  } else {
    const double s = std::sqrt(delta);
    return kn * delta * s - gn * s * vn;
  }
}
template <NormalLaw Law>
[[gnu::always_inline]] inline double normal_force_law(const SoftContact& c, double delta, double vn) {
  return normal_force_law<Law>(c.kn, c.gn, delta, vn);
}
// Its spring part (no dashpot): k_n delta or k_n delta^3/2.
template <NormalLaw Law>
inline double elastic_normal_force(const SoftContact& c, double delta) {
  if constexpr (Law == NormalLaw::Linear) return c.kn * delta;
  return c.kn * delta * std::sqrt(delta);
}
// dF_n/d(delta) of the spring at overlap delta (k_n; 3/2 k_n sqrt(delta) for the Hertzian laws).
inline double normal_stiffness(const SoftContact& c, double delta) {
  if (!(delta > 0.0)) return 0.0;
  return c.normal == NormalLaw::Linear ? c.kn : 1.5 * c.kn * std::sqrt(delta);
}

// Normal force magnitude along n, before clipping, at overlap delta >= 0 and overlap rate
// delta' = -v_n (the law chosen at run time).
inline double normal_force_raw(const SoftContact& c, double delta, double delta_dot) {
  switch (c.normal) {
    case NormalLaw::Linear:
      return normal_force_law<NormalLaw::Linear>(c, delta, -delta_dot);
    case NormalLaw::Hertz:
      return normal_force_law<NormalLaw::Hertz>(c, delta, -delta_dot);
    case NormalLaw::Viscoelastic:
      return normal_force_law<NormalLaw::Viscoelastic>(c, delta, -delta_dot);
  }
  return 0.0;
}

// Normal force: clipped at zero unless the law allows attraction.
inline double normal_force(const SoftContact& c, double delta, double delta_dot) {
  const double f = normal_force_raw(c, delta, delta_dot);
  return (c.clip && f < 0.0) ? 0.0 : f;
}

// First touch inside a step. A contact found overlapping by delta at t_{n+1}, approached at
// speed u over the step, began tau = delta/u earlier (clamped to [0, h]); returns tau/h.
// Returns -1 (no correction) when the pair is not approaching.
inline double onset_fraction(double delta, double u, double h) {
  if (!(u > 0.0)) return -1.0;
  return delta < u * h ? delta / (u * h) : 1.0;
}

// Correction of the first step of a contact (DERIVED). Velocity Verlet applies the force sampled
// at t_{n+1} over the window [t_{n+1} - h/2, t_{n+1} + h/2] (its two half kicks). A linear
// dashpot's force jumps from 0 to gamma u at first touch, so the sampled impulse gamma u h
// misses the true gamma u (tau + h/2) (for tau < h/2 the window starts before the touch; for
// tau > h/2 the previous sample, taken before the touch, missed gamma u (tau - h/2)): the first
// sample's dashpots are weighted by tau/h + 1/2, which makes the dissipated impulse exact to
// first order and the collision's outcome second order in h. Hertz and viscoelastic dashpots
// vanish at delta = 0 and need no weight. (The spring's kink at first touch is left alone: its
// error mirrors the one at separation, so the two cancel on average; weighting only the first
// step, as for the dashpot, makes an elastic gas drift.)
template <NormalLaw Law>
inline void at_onset(SoftContact& c, double x) {
  if constexpr (Law == NormalLaw::Linear) {
    c.gn *= x + 0.5;
    c.gt *= x + 0.5;
  }
}

// Energy stored in a contact at overlap delta with tangential spring xi: k_n delta^2/2 (linear) or
// (2/5) k_n delta^(5/2) (Hertz, viscoelastic: F = k_n delta^(3/2)), plus k_t |xi|^2/2 with the
// tangential stiffness at this overlap (k_t sqrt(delta) for the Hertzian laws).
template <int D>
inline double stored_energy(const SoftContact& c, double delta, const Vec<D>& xi) {
  double u, kt = c.kt;
  if (c.normal == NormalLaw::Linear) {
    u = 0.5 * c.kn * delta * delta;
  } else {
    u = 0.4 * c.kn * delta * delta * std::sqrt(delta);
    kt *= std::sqrt(delta);
  }
  return u + 0.5 * kt * xi.squaredNorm();
}

// ---------------------------------------------------------------------------------------------
// One contact: kinematics in, force out, history updated.

// Lever arms (see the conventions at the top).
inline double pair_lever_arm(double R, double delta) { return R - 0.5 * delta; }
inline double wall_lever_arm(double R, double delta) { return R - delta; }

// Velocity of i's contact point relative to j's: v_i - v_j - (l_i w_i + l_j w_j) x n.
template <int D>
inline Vec<D> contact_velocity(const Vec<D>& vi, const Spin<D>& wi, double li, const Vec<D>& vj,
                               const Spin<D>& wj, double lj, const Vec<D>& n) {
  const Spin<D> w = li * wi + lj * wj;
  return vi - vj - spin_cross<D>(w, n);
}
// The same on plain numbers (as spin_cross_to).
template <int D>
[[gnu::always_inline]] inline void contact_velocity_to(const double* vi, const double* wi, double li,
                                                       const double* vj, const double* wj, double lj,
                                                       const double* n, double* out) {
  constexpr int S = D == 2 ? 1 : 3;
  double w[S], c[D];
  for (int q = 0; q < S; ++q) w[q] = li * wi[q] + lj * wj[q];
  spin_cross_to<D>(w, n, c);
  for (int q = 0; q < D; ++q) out[q] = vi[q] - vj[q] - c[q];
}

template <int D>
struct ContactKinematics {
  double delta = 0.0;           // overlap (> 0 in contact)
  Vec<D> n = Vec<D>::Zero();    // unit normal from j to i
  Vec<D> v = Vec<D>::Zero();    // relative contact-point velocity (contact_velocity), for damping
  Vec<D> dxi = Vec<D>::Zero();  // tangential displacement since the last call, usually v_t dt
};

// Per-contact memory: the Cundall-Strack tangential spring xi, kept in the tangent plane.
template <int D>
struct ContactHistory {
  Vec<D> xi = Vec<D>::Zero();
};

template <int D>
struct ContactForce {
  Vec<D> force = Vec<D>::Zero();       // on i (on j: -force)
  Vec<D> tangential = Vec<D>::Zero();  // F_t, the tangential part of force
  double normal = 0.0;                 // F_n (>= 0 unless the law is attractive)
  double normal_raw = 0.0;             // F_n before clipping
  bool sliding = false;                // the Coulomb cap was active
};

// Torque on a body from the tangential force, for lever arm l: -l n x F_t (on j pass its own
// arm and the same F_t: tau_j = -l_j n x F_t).
template <int D>
inline Spin<D> contact_torque(const Vec<D>& n, const Vec<D>& Ft, double arm) {
  return -arm * lever_moment<D>(n, Ft);
}

// The rolling-resistance torque on i of one contact (on j: minus it), Ai, Chen, Rotter & Ooi,
// Powder Technol. 206, 269 (2011). wr is the relative angular velocity w_i - w_j (a wall: its own
// spin), dth the relative rotation over the step, fn the normal force (clipped); only their rolling
// parts count (3D: the twist along n is removed). M_m = mu_r R* F_n.
//   Constant (model A, eq. 12): M = -M_m wr/|wr| while wr != 0.
//   Epsd (model C, eqs. 14-19): the spring torque mk -= k_r dth, capped at |mk| <= M_m; below the
//   cap a dashpot adds -C_r wr, at full mobilisation it is off (the paper's f = 0).
// mk is the contact's spring torque (Epsd), kept in the rolling plane.
template <int D, NormalLaw Law>
[[gnu::always_inline]] inline Spin<D> rolling_torque(const SoftContact& c, double delta, double fn, const Vec<D>& n,
                                                     Spin<D> wr, Spin<D> dth, Spin<D>& mk) {
  if constexpr (D == 3) {
    wr -= wr.dot(n) * n;
    dth -= dth.dot(n) * n;
  }
  const double Mm = c.roll_lever * (fn > 0.0 ? fn : 0.0);
  if (c.rolling == RollingModel::Constant) {
    const double w = wr.norm();
    return w > 0.0 ? Spin<D>((-Mm / w) * wr) : Spin<D>(Spin<D>::Zero());
  }
  const double kn = Law == NormalLaw::Linear ? c.kn : c.kn * std::sqrt(delta > 0.0 ? delta : 0.0);
  const double kr = c.roll_kr * kn;
  if constexpr (D == 3) mk -= mk.dot(n) * n;
  mk -= kr * dth;
  const double m2 = mk.squaredNorm();
  if (m2 >= Mm * Mm) {
    mk *= m2 > 0.0 ? Mm / std::sqrt(m2) : 0.0;
    return mk;
  }
  return mk - (c.roll_cr * std::sqrt(kr)) * wr;
}

// Force on i for one contact; updates the history. Tangential model (Cundall & Strack,
// Geotechnique 29, 47 (1979); Mindlin-Deresiewicz stiffness for Hertz, docs/references.md §6.2):
//  1. rotate xi into the current tangent plane, keeping its length (LIGGGHTS shear history):
//     xi <- (xi - (xi.n) n) |xi|/|xi - (xi.n) n|;
//  2. xi += tangential part of dxi;
//  3. trial F_t = -k_t xi - gamma_t v_t;
//  4. if |F_t| > mu |F_n|: F_t <- mu |F_n| F_t/|F_t| (sliding), and the spring is rescaled so
//     that it alone carries the cap, xi = -F_t/k_t (the dashpot does no work while sliding).
// Law is the normal law known at compile time (the engine's hot loop); soft_contact_force()
// below dispatches on c.normal at run time. The arithmetic is contact_force_core's, on plain
// numbers, with no early return and its rare cases (a spring to turn into the tangent plane, a
// sliding contact) in blocks without side effects, so that a loop over many contacts runs lane-wise
// (engine/soft/batch.hpp: the compiler turns the blocks into selects) while a one-contact call
// still skips them. Sums of products are taken left to right.
template <int D>
[[gnu::always_inline]] inline double dot3(const double* a, const double* b) {
  double s = a[0] * b[0];
  for (int c = 1; c < D; ++c) s += a[c] * b[c];
  return s;
}
template <int D>
[[gnu::always_inline]] inline double dot3(const Vec<D>& a, const Vec<D>& b) {
  return dot3<D>(a.data(), b.data());
}
// The contact's constants (kn, gn, kt, gt, mu, clip: SoftContact), overlap delta, unit normal n,
// contact velocity v and tangential displacement dxi (ContactKinematics); xi: the spring, updated.
// Out: the force on i, its tangential part, F_n after and before clipping, and whether it slides.
template <int D, NormalLaw Law>
[[gnu::always_inline]] inline void contact_force_core(double kn, double gn, double kt, double gt, double mu, bool clip,
                                                      double delta, const double* n, const double* v,
                                                      const double* dxi, double* xi, double* force,
                                                      double* tangential, double& normal, double& normal_raw,
                                                      bool& sliding) {
  delta = delta > 0.0 ? delta : 0.0;
  const double vn = dot3<D>(v, n);
  // Normal force and the tangential coefficients at this overlap (see SoftContact).
  const double fn = normal_force_law<Law>(kn, gn, delta, vn);
  if constexpr (Law != NormalLaw::Linear) {
    const double s = std::sqrt(delta);
    kt *= s;
    gt *= Law == NormalLaw::Hertz ? std::sqrt(s) : s;
  }
  normal_raw = fn;
  normal = (clip && fn < 0.0) ? 0.0 : fn;
  // Frictionless with no spring: no tangential force, no history (selected at the end).
  bool spring = false;
  for (int q = 0; q < D; ++q) spring = spring || xi[q] != 0.0;
  const bool none = mu == 0.0 && !spring;

  // 1. Into the tangent plane, keeping the length: multiply by 1/sqrt(1 - r), r = xin^2/l2.
  // Between two steps the normal turns by a tiny angle and r ~ angle^2; for r < 1e-4 the series
  // 1 + r/2 + 3r^2/8 errs by less than 5r^3/16. (xin = 0: xi is left as it is.) The rare cases
  // sit in blocks that a lane-wise loop turns into selects and a one-contact call skips.
  double x0[D], x[D];
  for (int q = 0; q < D; ++q) x0[q] = x[q] = xi[q];
  const double xin = dot3<D>(x0, n);
  if (xin != 0.0) {
    const double l2 = dot3<D>(x0, x0);
    for (int q = 0; q < D; ++q) x[q] = x0[q] - xin * n[q];
    const double r = xin * xin / l2;
    if (r < 1e-4) {
      const double sc = 1.0 + r * (0.5 + 0.375 * r);
      for (int q = 0; q < D; ++q) x[q] *= sc;
    } else {
      const double m2 = dot3<D>(x, x);
      const double sc = m2 > 0.0 ? std::sqrt(l2 / (m2 > 0.0 ? m2 : 1.0)) : 0.0;
      for (int q = 0; q < D; ++q) x[q] = m2 > 0.0 ? x[q] * sc : 0.0;
    }
  }
  // 2. The step's tangential displacement; round-off of a nearly normal dxi or of the rescaling
  // removed.
  const double dn = dot3<D>(dxi, n);
  for (int q = 0; q < D; ++q) x[q] += dxi[q] - dn * n[q];
  const double xn = dot3<D>(x, n);
  for (int q = 0; q < D; ++q) x[q] -= xn * n[q];
  // 3. The trial force.
  double Ft[D];
  for (int q = 0; q < D; ++q) Ft[q] = -kt * x[q] - gt * (v[q] - vn * n[q]);
  // 4. The Coulomb cap (v_t carries round-off along n: F_t and xi are kept in the plane).
  const double cap = mu * std::abs(normal);
  const double f2 = dot3<D>(Ft, Ft);
  const bool slides = f2 > cap * cap;
  if (slides) {
    const double fs = cap / std::sqrt(f2);
    for (int q = 0; q < D; ++q) Ft[q] *= fs;
    const double sn = dot3<D>(Ft, n);
    for (int q = 0; q < D; ++q) Ft[q] -= sn * n[q];
    for (int q = 0; q < D; ++q) x[q] = kt > 0.0 ? -Ft[q] / (kt > 0.0 ? kt : 1.0) : 0.0;
  }
  for (int q = 0; q < D; ++q) {
    tangential[q] = none ? 0.0 : Ft[q];
    force[q] = none ? normal * n[q] : normal * n[q] + Ft[q];
    xi[q] = none ? x0[q] : x[q];
  }
  sliding = !none && slides;
}

template <int D, NormalLaw Law>
[[gnu::always_inline]] inline ContactForce<D> soft_contact_force_law(const SoftContact& c,
                                                                     const ContactKinematics<D>& k,
                                                                     ContactHistory<D>& h) {
  ContactForce<D> out;
  contact_force_core<D, Law>(c.kn, c.gn, c.kt, c.gt, c.mu, c.clip, k.delta, k.n.data(), k.v.data(), k.dxi.data(),
                             h.xi.data(), out.force.data(), out.tangential.data(), out.normal, out.normal_raw,
                             out.sliding);
  return out;
}

template <int D>
inline ContactForce<D> soft_contact_force(const SoftContact& c, const ContactKinematics<D>& k,
                                          ContactHistory<D>& h) {
  switch (c.normal) {
    case NormalLaw::Linear:
      return soft_contact_force_law<D, NormalLaw::Linear>(c, k, h);
    case NormalLaw::Hertz:
      return soft_contact_force_law<D, NormalLaw::Hertz>(c, k, h);
    case NormalLaw::Viscoelastic:
      break;
  }
  return soft_contact_force_law<D, NormalLaw::Viscoelastic>(c, k, h);
}

}  // namespace matep

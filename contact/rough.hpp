// Instantaneous collision operators for rough (frictional) hard spheres (3D) and disks (2D) with
// rotation: the event-driven counterpart of the soft Hertz-Mindlin / Coulomb contact of
// contact/soft.hpp. Pure functions; the caller evaluates the normal restitution e (e.g. with
// contact/restitution.hpp) and passes the tangential model of the material pair.
//
// Conventions (the same as contact/soft.hpp, taken at first contact, delta = 0):
//  * n is the unit normal from j to i (wall: the wall normal, pointing to the body's side).
//  * Lever arms are the radii: the contact point is x_i - R_i n on i and x_j + R_j n on j.
//  * Relative contact-point velocity v_c = v_i - v_j - (R_i w_i + R_j w_j) x n (contact_velocity);
//    v_n = v_c.n < 0 while approaching, v_t = v_c - v_n n.
//  * The impulse J = J_n n + J_t acts on i, -J on j; the angular impulses are
//    -R_i n x J_t on i and -R_j n x J_t on j (contact_torque; same sign on both).
//  * 2D: Spin<2> is the z component.
//
// The rule (Walton, Mech. Mater. 16, 239 (1993); Lun, JFM 233, 539 (1991);
// docs/references.md §6.6):
//    v_n' = -e v_n,    v_t' = -beta v_t   (contact-point velocities),
// so J_n = -(1 + e) m* v_n and J_t = -(1 + beta) m_t v_t, with m* = 1/(1/m_i + 1/m_j) and the
// tangential effective mass (DERIVED: a tangential impulse J on i changes v_t by
// J (1/m_i + 1/m_j + R_i^2/I_i + R_j^2/I_j), since (n x J) x n = J for J perpendicular to n,
// in 2D and 3D alike):
//    1/m_t = 1/m_i + 1/m_j + R_i^2/I_i + R_j^2/I_j = (1 + 1/q_i)/m_i + (1 + 1/q_j)/m_j,
// with q = I/(m R^2) (2/5 solid sphere, 1/2 solid disk). For q_i = q_j = q this is
// m_t = m* q/(1 + q) for any sizes; a wall (m_j = infinity) leaves the particle's terms only.
// Normal and tangential directions decouple (the lever arms are along n), so the kinetic energy
// (translational + rotational) changes by exactly
//    -(1 - e^2) m* v_n^2/2 - (1 - beta^2) m_t |v_t|^2/2  <= 0 for e, beta in [-1, 1],
// and the angular momentum of each body about the contact point is unchanged (the impulse acts
// at that point).
//
// Gross sliding (Coulomb): |J_t| = mu J_n gives 1 + beta = mu (1 + e) (m*/m_t) |v_n|/|v_t|, and
// m*/m_t = 1 + 1/q for equal q (7/2 spheres, 3 disks); the seed's eq. 3.29 (Zamankhan & Huang;
// docs/references.md §S.3.3.3) is this expression written with the masses and the non-dimensional
// inertia of each body.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "contact/soft.hpp"
#include "contact/vec.hpp"

namespace matep {

// Tangential restitution models for a pair of materials.
enum class TangentialLaw {
  // beta = min(beta0, -1 + mu (1 + e) (m*/m_t) |v_n|/|v_t|): sticking with beta0 unless Coulomb
  // sliding limits it (Walton 1993; Lun 1991; docs/references.md §6.6).
  Walton,
  // beta = beta0 whatever the impact (no Coulomb limit); beta0 in [-1, 1].
  Constant,
  // The seed report's FEM fit, its eq. 3.30 (Huang's finite-element simulations;
  // docs/references.md §S.3.3.3), capped by Coulomb sliding. The extracted text of the seed is
  // garbled; it is read here as
  //    (1 + beta)/(1 + e) = 0.12 (arctan(|v_n|/|v_t|))^2.98 + 0.92,
  // the angle in radians (arctan of the normal over the tangential contact-point speed, the
  // impact angle measured from the tangent plane, 0 ... pi/2). The fit alone does not know mu and
  // gives 1 + beta >= 0.92 (1 + e) even at grazing incidence, which Coulomb friction cannot
  // deliver; so 1 + beta is capped by the sliding value mu (1 + e) (m*/m_t) |v_n|/|v_t|
  // (= (1 + 1/q) mu (1 + e) |v_n|/|v_t| for equal q), and beta is kept in [-1, 1] (the fit
  // reaches 1 + beta = 1.38 (1 + e) at normal incidence).
  FemFit,
};

struct TangentialModel {
  TangentialLaw law = TangentialLaw::Walton;
  double friction = 0.0;  // Coulomb mu (Walton, FemFit); kPlane (infinity) means no sliding
  double beta0 = 0.4;     // Walton: the sticking limit (seed report: 0.4 after Maw's data,
                          // Lun & Bent; docs/references.md §S.3.1); Constant: beta itself.
                          // In [-1, 1].

  static TangentialModel walton(double mu, double beta0 = 0.4) {
    return {TangentialLaw::Walton, mu, beta0};
  }
  static TangentialModel constant(double beta) { return {TangentialLaw::Constant, 0.0, beta}; }
  static TangentialModel fem_fit(double mu) { return {TangentialLaw::FemFit, mu, 0.4}; }
};

// The seed's eq. 3.30 as read above, uncapped: (1 + beta)/(1 + e) at impact angle
// arctan(|v_n|/|v_t|) (radians).
inline double fem_fit_ratio(double vn_abs, double vt_abs) {
  const double a = vt_abs > 0.0 ? std::atan(vn_abs / vt_abs) : 0.5 * std::numbers::pi;
  return 0.12 * std::pow(a, 2.98) + 0.92;
}

// 1/m_t = (1 + 1/q_i)/m_i + (1 + 1/q_j)/m_j (m_j = kPlane for a wall).
inline double rough_tangential_mass(double mi, double qi, double mj, double qj) {
  const double inv_j = std::isinf(mj) ? 0.0 : (1.0 + 1.0 / qj) / mj;
  return 1.0 / ((1.0 + 1.0 / qi) / mi + inv_j);
}

struct RoughBeta {
  double beta = -1.0;    // v_t' = -beta v_t, in [-1, 1]
  bool sliding = false;  // the Coulomb limit set beta (gross sliding); false: sticking value
};

// The tangential restitution for normal and tangential contact-point speeds |v_n|, |v_t| >= 0,
// normal restitution e and mass ratio k = m*/m_t (1 + 1/q for equal q).
inline RoughBeta rough_beta(const TangentialModel& m, double e, double vn_abs, double vt_abs,
                            double k) {
  RoughBeta out;
  if (m.law == TangentialLaw::Constant) {
    out.beta = std::clamp(m.beta0, -1.0, 1.0);
    return out;
  }
  // Coulomb sliding value of 1 + beta (infinite when there is no tangential motion to stop).
  double slide = std::numeric_limits<double>::infinity();
  if (vt_abs > 0.0) {
    const double mun = m.friction * vn_abs;  // mu |v_n| (0 when either is 0, even mu = inf)
    slide = mun > 0.0 ? k * (1.0 + e) * mun / vt_abs : 0.0;
  }
  // Sticking value of beta (returned as is: beta0 exactly for Walton).
  const double stick = m.law == TangentialLaw::Walton
                           ? std::clamp(m.beta0, -1.0, 1.0)
                           : std::min(1.0, (1.0 + e) * fem_fit_ratio(vn_abs, vt_abs) - 1.0);
  out.sliding = slide < 1.0 + stick;
  out.beta = out.sliding ? std::max(-1.0, slide - 1.0) : stick;
  return out;
}

// One body of a rough collision.
template <int D>
struct RoughBody {
  Vec<D> v = Vec<D>::Zero();
  Spin<D> w = Spin<D>::Zero();
  double mass = 1.0;
  double radius = 1.0;
  double q = inertia_factor<D>();  // I/(m R^2)
};

template <int D>
struct RoughResult {
  Vec<D> v_i = Vec<D>::Zero(), v_j = Vec<D>::Zero();  // wall: v_j is the wall velocity
  Spin<D> w_i = Spin<D>::Zero(), w_j = Spin<D>::Zero();
  double beta = -1.0;       // tangential restitution applied
  bool sliding = false;     // Coulomb sliding (see RoughBeta)
  double normal_impulse = 0.0;              // J_n = -(1 + e) m* v_n (>= 0 when approaching)
  Vec<D> tangential_impulse = Vec<D>::Zero();  // J_t on i
  double tangential_speed = 0.0;            // |v_t| before
  double normal_speed = 0.0;                // v_n before (< 0 when approaching)
};

namespace detail {
template <int D>
inline void rough_apply(RoughResult<D>& r, const TangentialModel& model, double e,
                        const Vec<D>& vc, const Vec<D>& n, double mstar, double mt) {
  const double vn = vc.dot(n);
  Vec<D> vt = vc - vn * n;
  const double vtn = vt.norm();
  const RoughBeta b = rough_beta(model, e, std::abs(vn), vtn, mstar / mt);
  r.beta = b.beta;
  r.sliding = b.sliding;
  r.normal_speed = vn;
  r.tangential_speed = vtn;
  r.normal_impulse = -(1.0 + e) * mstar * vn;
  r.tangential_impulse = -(1.0 + b.beta) * mt * vt;
}
}  // namespace detail

// Binary collision of two rough spheres/disks touching with unit normal n (j to i). Precondition
// (as for smooth_pair_collision): they approach, v_n < 0. Total linear momentum and the angular
// momentum about the contact point are conserved; see the header comment for the energy.
template <int D>
inline RoughResult<D> rough_pair_collision(const RoughBody<D>& i, const RoughBody<D>& j,
                                           const Vec<D>& n, double e,
                                           const TangentialModel& model) {
  RoughResult<D> r;
  const Vec<D> vc = contact_velocity<D>(i.v, i.w, i.radius, j.v, j.w, j.radius, n);
  const double mstar = effective_mass(i.mass, j.mass);
  const double mt = rough_tangential_mass(i.mass, i.q, j.mass, j.q);
  detail::rough_apply<D>(r, model, e, vc, n, mstar, mt);
  const Vec<D> J = r.normal_impulse * n + r.tangential_impulse;
  r.v_i = i.v + J / i.mass;
  r.v_j = j.v - J / j.mass;
  const double Ii = i.q * i.mass * i.radius * i.radius;
  const double Ij = j.q * j.mass * j.radius * j.radius;
  r.w_i = i.w + contact_torque<D>(n, r.tangential_impulse, i.radius) / Ii;
  r.w_j = j.w + contact_torque<D>(n, r.tangential_impulse, j.radius) / Ij;
  return r;
}

// A rough sphere/disk against an infinitely heavy plane wall of unit normal n (pointing to the
// body's side) translating at wall_velocity (no spin). m* = m, m_t = m q/(1 + q).
template <int D>
inline RoughResult<D> rough_wall_collision(const RoughBody<D>& i, const Vec<D>& n, double e,
                                           const TangentialModel& model,
                                           const Vec<D>& wall_velocity = Vec<D>::Zero()) {
  RoughResult<D> r;
  const Vec<D> vc = i.v - wall_velocity - spin_cross<D>(i.radius * i.w, n);
  const double mt = rough_tangential_mass(i.mass, i.q, kPlane, 1.0);
  detail::rough_apply<D>(r, model, e, vc, n, i.mass, mt);
  const Vec<D> J = r.normal_impulse * n + r.tangential_impulse;
  r.v_i = i.v + J / i.mass;
  r.v_j = wall_velocity;
  const double Ii = i.q * i.mass * i.radius * i.radius;
  r.w_i = i.w + contact_torque<D>(n, r.tangential_impulse, i.radius) / Ii;
  r.w_j.setZero();
  return r;
}

// Lun & Savage's five categories of a collision by its tangential restitution
// (docs/references.md §S.3.1): -1 smooth (surfaces slip, spins untouched); (-1, 0) sliding (slip,
// some translational energy goes into rotation); 0 rolling (no tangential contact velocity left);
// (0, 1) sticking (v_t reversed); +1 perfectly rough (tangential energy fully returned). Note that
// a Walton collision limited by Coulomb friction (RoughBeta::sliding) may end with beta in
// [0, beta0).
enum class RoughRegime { Smooth, Sliding, Rolling, Sticking, PerfectlyRough };

inline RoughRegime lun_savage_regime(double beta) {
  if (beta <= -1.0) return RoughRegime::Smooth;
  if (beta < 0.0) return RoughRegime::Sliding;
  if (beta == 0.0) return RoughRegime::Rolling;
  if (beta < 1.0) return RoughRegime::Sticking;
  return RoughRegime::PerfectlyRough;
}

}  // namespace matep

// Contact durations, Hertz impact peaks and time-step limits for soft-sphere (time-driven)
// integration. docs/references.md §1.2 (Hertz impact, Johnson 1985 as used by Chung & Ooi 2011),
// §6.3 (linear spring-dashpot) and §6.4 (Rayleigh step).
#pragma once

#include <cmath>
#include <numbers>

#include "contact/soft.hpp"

namespace matep {

// 2 int_0^1 (1 - x^(5/2))^(-1/2) dx = (4/5) sqrt(pi) Gamma(2/5)/Gamma(9/10)
// (docs/references.md §1.2, §9).
inline constexpr double kHertzDurationFactor = 2.9432751843;
// kHertzDurationFactor (15/16)^(2/5): t_c = 2.86827 (m*^2/(R* E*^2 v))^(1/5).
inline constexpr double kHertzTimeFactor = 2.8682656992;

// Maximum overlap of an elastic Hertz impact at normal relative speed v:
// delta_max = (15 m* v^2/(16 E* sqrt(R*)))^(2/5).
inline double hertz_max_overlap(double mstar, double Rstar, double Estar, double v) {
  return std::pow(15.0 * mstar * v * v / (16.0 * Estar * std::sqrt(Rstar)), 0.4);
}
inline double hertz_max_overlap(const PairParams& p, double v) {
  return hertz_max_overlap(p.mstar, p.Rstar, p.Estar, v);
}

// Peak force F_max = (4/3) E* sqrt(R*) delta_max^(3/2).
inline double hertz_max_force(double mstar, double Rstar, double Estar, double v) {
  const double d = hertz_max_overlap(mstar, Rstar, Estar, v);
  return (4.0 / 3.0) * Estar * std::sqrt(Rstar) * d * std::sqrt(d);
}
inline double hertz_max_force(const PairParams& p, double v) {
  return hertz_max_force(p.mstar, p.Rstar, p.Estar, v);
}

// Elastic Hertz contact duration t_c = 2.86827 (m*^2/(R* E*^2 v))^(1/5) = 2.94328 delta_max/v.
inline double hertz_contact_time(double mstar, double Rstar, double Estar, double v) {
  return kHertzTimeFactor * std::pow(mstar * mstar / (Rstar * Estar * Estar * v), 0.2);
}
inline double hertz_contact_time(const PairParams& p, double v) {
  return hertz_contact_time(p.mstar, p.Rstar, p.Estar, v);
}

// Linear spring-dashpot duration with the force allowed to pull until delta = 0
// (docs/references.md §6.3): t_c = sqrt(m*/k) sqrt(pi^2 + ln^2 e).
inline double linear_contact_time(double mstar, double k, double e) {
  const double l = e < 1.0 ? std::log(e) : 0.0;
  return std::sqrt(mstar / k) * std::sqrt(std::numbers::pi * std::numbers::pi + l * l);
}

// Linear spring-dashpot with the force clipped at zero: the duration of the force,
// t_f = sqrt(m*/k) * linear_clipped_collision(zeta(e)).time (see soft.hpp).
inline double linear_clipped_contact_time(double mstar, double k, double e) {
  return std::sqrt(mstar / k) * linear_clipped_collision(linear_clipped_damping_ratio(e)).time;
}

// Rayleigh-wave time step (docs/references.md §6.4; Yade RayleighWaveTimeStep, DIRT sweep.py):
// dt_R = pi R sqrt(rho/G)/(0.1631 nu + 0.8766), G = E/(2(1 + nu)). Practice: 0.1-0.3 dt_R.
inline double rayleigh_time(double R, double rho, double E, double nu) {
  const double G = E / (2.0 * (1.0 + nu));
  return std::numbers::pi * R * std::sqrt(rho / G) / (0.1631 * nu + 0.8766);
}

// Stability of velocity Verlet for m x'' = -k x - gamma x', with the dashpot evaluated at the
// half-step velocity v_{n+1/2} (the usual DEM form: positions and forces at t_{n+1}, velocities
// known only at t_{n+1/2} when forces are computed). With omega0 = sqrt(k/m), eta = gamma/(2m) and
// h = dt, the scheme is the leapfrog map
//   v_{n+1/2} = (1 - 2 eta h) v_{n-1/2} - h omega0^2 x_n,   x_{n+1} = x_n + h v_{n+1/2},
// with trace 2 - h^2 omega0^2 - 2 eta h and determinant 1 - 2 eta h. Jury's conditions
// (|det| < 1, |trace| < 1 + det) give h^2 omega0^2 + 4 eta h < 4 and eta h < 1, i.e.
//   h < 2/(eta + sqrt(eta^2 + omega0^2))   (DERIVED; = 2/omega0 without damping).
// A scene's time step must stay below this for the stiffest contact (Hertz: use the tangent
// stiffness S_n at the largest expected overlap); in practice a tenth of it or less.
inline double verlet_max_step(double omega0, double eta = 0.0) {
  return 2.0 / (eta + std::sqrt(eta * eta + omega0 * omega0));
}
inline double verlet_max_step_spring(double mass, double k, double gamma = 0.0) {
  return verlet_max_step(std::sqrt(k / mass), gamma / (2.0 * mass));
}

// Largest stable step for a resolved contact law at a given overlap: the tangent normal stiffness
// S and damping coefficient at delta, with m*. (The tangential spring of solid spheres oscillates
// with k_t (1 + 1/q)/m*; for Hertz-Mindlin that is 8G*(1 + 1/q)/(2E*) ~ 3 times S_n/m*, so the
// tangential spring sets the limit when friction is on.)
inline double verlet_max_step(const SoftContact& c, double delta, double q = 0.4) {
  double S = c.kn, g = c.gn, St = c.kt, gt = c.gt;
  if (c.normal != NormalLaw::Linear) {
    const double s = std::sqrt(delta);
    S = 1.5 * c.kn * s;
    St = c.kt * s;
    const double gs = c.normal == NormalLaw::Hertz ? std::sqrt(s) : s;
    g *= gs;
    gt *= gs;
  }
  const double hn = verlet_max_step_spring(c.mstar, S, g);
  if (c.mu <= 0.0 || St <= 0.0) return hn;
  const double mt = c.mstar * q / (1.0 + q);  // tangential effective mass of the contact point
  const double ht = verlet_max_step_spring(mt, St, gt);
  return hn < ht ? hn : ht;
}

// Contact duration of a law at normal impact speed v, as used to pick a time step: the exact
// duration for the linear law (clipped or not), the elastic Hertz duration otherwise (damping
// lengthens a Hertz contact only slightly; the viscoelastic law shortens the force duration).
inline double soft_contact_time(const SoftLaw& law, const PairParams& p, double v) {
  if (law.normal == NormalLaw::Linear) {
    const double k = law.stiffness;
    const double zeta =
        law.gamma_n >= 0.0 ? law.gamma_n / (2.0 * std::sqrt(p.mstar * k)) : law.damping_ratio();
    const double t0 = std::sqrt(p.mstar / k);
    if (law.attractive) {  // pi/omega, omega = omega0 sqrt(1 - zeta^2) (docs/references.md §6.3)
      return zeta < 1.0 ? t0 * std::numbers::pi / std::sqrt(1.0 - zeta * zeta)
                        : t0 * linear_clipped_collision(zeta).time;  // overdamped: never returns
    }
    return t0 * linear_clipped_collision(zeta).time;
  }
  return hertz_contact_time(p, v);
}

}  // namespace matep

// The half-step (velocity Verlet) integrator of the soft path, used by TDM and by the hybrid's soft
// set. Between steps a particle holds v(t - h/2) and the acceleration a(t - h) of the previous
// force; with the force F(t) of the current positions:
//   a(t) = F/m + g;  v(t + h/2) = v(t - h/2) + h a(t);  x(t + h) = x(t) + h v(t + h/2)   (kick_drift)
//   v(t) = v(t - h/2) + h/2 a(t)                                                       (full_step)
// Dashpots and the sliding direction are evaluated at the predicted v(t - h/2) + h/2 a(t - h)
// (second order; engine/soft/forces.hpp). Spins follow the same scheme with the torque over
// I = q m R^2 (kick_spin).
#pragma once

#include "contact/vec.hpp"

namespace matep::soft {

// One kick and drift of particle i with force f (cleared here for the next accumulation): stores
// a, v and x, and returns whether the particle is now more than sqrt(lim2) from x0 (the position of
// the last neighbour-list build; a non-finite position counts as moved); d2out receives the squared
// distance from x0 (NaN for a non-finite position). Written out by component: this runs once per
// particle and step and its memory traffic is most of a dilute gas's cost (a force that is already
// zero is not written again).
template <int D>
[[gnu::always_inline]] inline bool kick_drift(Vec<D>& force, Vec<D>& acc, Vec<D>& vel, Vec<D>& pos, const Vec<D>& x0,
                                              double minv, const Vec<D>& g, double dt, double lim2, double& d2out) {
  double* f = force.data();
  double* a = acc.data();
  double* v = vel.data();
  double* x = pos.data();
  const double* p0 = x0.data();
  bool nonzero = false;
  double d2 = 0.0;
  for (int k = 0; k < D; ++k) {
    nonzero |= f[k] != 0.0;
    const double ak = f[k] * minv + g[k];
    a[k] = ak;
    v[k] += dt * ak;
    x[k] += dt * v[k];
    const double dk = x[k] - p0[k];
    d2 += dk * dk;
  }
  if (nonzero)
    for (int k = 0; k < D; ++k) f[k] = 0.0;
  d2out = d2;
  return !(d2 <= lim2);
}
template <int D>
[[gnu::always_inline]] inline bool kick_drift(Vec<D>& force, Vec<D>& acc, Vec<D>& vel, Vec<D>& pos, const Vec<D>& x0,
                                              double minv, const Vec<D>& g, double dt, double lim2) {
  double d2;
  return kick_drift<D>(force, acc, vel, pos, x0, minv, g, dt, lim2, d2);
}

// The spin's kick: alpha = torque / I, w(t + h/2) = w(t - h/2) + h alpha; the torque is cleared.
template <class S>
[[gnu::always_inline]] inline void kick_spin(S& torque, S& alpha, S& spin, double iinv, double dt) {
  const S al = torque * iinv;
  torque.setZero();
  alpha = al;
  spin += dt * al;
}

// The full-step velocity v(t) = v(t - h/2) + h/2 (F/m + g) from the half-step one.
template <int D>
[[gnu::always_inline]] inline Vec<D> full_step(const Vec<D>& vh, const Vec<D>& f, double minv, const Vec<D>& g,
                                               double hdt) {
  return vh + hdt * (f * minv + g);
}

// The first force evaluation of a run gives a(0) only: the half-step state is v(-h/2) = v(0) - h/2
// a(0) (and the same for spins), so that the first kick_drift reaches v(h/2) = v(0) + h/2 a(0).
// Contacts present then began before the run: no onset weight, springs left unstretched.
template <class V>
[[gnu::always_inline]] inline void start_half_step(V& v, const V& force, double inv, const V& g, double hdt) {
  v -= hdt * (force * inv + g);
}
template <class S>
[[gnu::always_inline]] inline void start_half_step_spin(S& w, const S& torque, double iinv, double hdt) {
  w -= hdt * (torque * iinv);
}

}  // namespace matep::soft

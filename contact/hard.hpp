// Instantaneous collision operators for smooth hard spheres.
#pragma once

namespace matep {

// Smooth binary collision: with unit normal n = (r_i - r_j)/|r_i - r_j| and normal relative
// velocity u = (v_i - v_j).n < 0, the normal impulse on i is J = -(1 + e) m* u n with
// m* = m_i m_j / (m_i + m_j) (e.g. Poschel & Schwager 2005, ch. 3). Momentum is conserved and the
// normal relative kinetic energy m* u^2 / 2 is multiplied by e^2. Returns the impulse magnitude
// -(1 + e) m* u >= 0 along n.
template <class V>
inline double smooth_pair_collision(V& vi, V& vj, double mi, double mj, const V& n, double e) {
  const double u = (vi - vj).dot(n);
  const double mstar = mi * mj / (mi + mj);
  const double J = -(1.0 + e) * mstar * u;
  vi += (J / mi) * n;
  vj -= (J / mj) * n;
  return J;
}

// Smooth collision with an infinitely heavy plane of unit normal n: v_n' = -e v_n.
template <class V>
inline double smooth_wall_collision(V& v, double m, const V& n, double e) {
  const double u = v.dot(n);
  const double J = -(1.0 + e) * m * u;
  v += (J / m) * n;
  return J;
}

// Smooth collision with an infinitely heavy plane of unit normal n moving at velocity u: the
// normal relative velocity is reversed, (v' - u).n = -e (v - u).n; the tangential velocity is kept.
template <class V>
inline double smooth_moving_wall_collision(V& v, double m, const V& n, const V& u, double e) {
  const double un = (v - u).dot(n);
  const double J = -(1.0 + e) * m * un;
  v += (J / m) * n;
  return J;
}

}  // namespace matep

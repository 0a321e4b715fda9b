// Reference integrator for ONE isolated soft collision (sphere-sphere or sphere-plane, 3D spheres
// or 2D disks, with translation and rotation). It starts at first contact (delta = 0), integrates
// by velocity Verlet until the bodies separate, and reports the post-collision velocities and
// spins with the peaks of the force history. The tests use it to check the soft contact laws
// against Chung & Ooi (2011) and against the hard-sphere collision rules (contact/rough.hpp).
//
// Scheme (step h): v_half = v + h/2 a; x += h v_half; forces at the new positions; v = v_half +
// h/2 a_new, and the same for spins. Velocity-dependent forces (dashpots, the friction direction)
// are evaluated at the Euler-predicted end-of-step velocity v + h a, which keeps the scheme second
// order (the half-step velocity would make it first order); the tangential spring grows by the
// half-step contact velocity times h, consistent with the positions. Two events are located
// inside a step by regula falsi (Illinois) and the step is cut there: the end of contact
// (delta = 0; the force at that instant is the limit from inside, so a dashpot that may pull is
// integrated exactly) and, for clipped laws, the moment the unclipped normal force vanishes
// (the force has a kink there). Stick-slip transitions are not located.
#pragma once

#include <vector>

#include "contact/soft.hpp"
#include "contact/vec.hpp"

namespace matep {

template <int D>
struct BinaryBody {
  Vec<D> v = Vec<D>::Zero();    // velocity at first contact
  Spin<D> w = Spin<D>::Zero();  // angular velocity at first contact
  double radius = 1.0;
  double mass = 1.0;  // moment of inertia q m R^2, q = inertia_factor<D>() (2/5 or 1/2)
  SoftMaterial material;
};

struct BinaryOptions {
  double dt = 0.0;  // 0: soft_contact_time(law, pair, |v_n|) / steps_per_contact
  double steps_per_contact = 200.0;
  long max_steps = 10'000'000;  // then separated = false (e.g. an overdamped attractive law)
  bool record = false;          // keep one BinarySample per step
};

struct BinarySample {
  double t = 0.0;
  double delta = 0.0;
  double normal = 0.0;      // F_n (after clipping)
  double tangential = 0.0;  // |F_t|
};

template <int D>
struct BinaryResult {
  // State when contact ends (delta back to 0).
  Vec<D> v_i = Vec<D>::Zero(), v_j = Vec<D>::Zero();
  Spin<D> w_i = Spin<D>::Zero(), w_j = Spin<D>::Zero();
  // Centres at that moment, in a frame where the first contact point is the origin (pair:
  // x_i = R_i n, x_j = -R_j n at first contact; wall: the plane passes through the origin).
  Vec<D> x_i = Vec<D>::Zero(), x_j = Vec<D>::Zero();
  double max_force = 0.0;            // largest F_n
  double max_overlap = 0.0;          // largest delta
  double contact_time = 0.0;         // first contact until delta = 0 again
  double force_time = 0.0;           // first contact until F_n vanishes for good (<= contact_time)
  double min_normal = 0.0;           // smallest F_n seen (< 0 only for an attractive law)
  double max_friction_excess = 0.0;  // max over steps of (|F_t| - mu |F_n|); <= 0 up to round-off
  double dt = 0.0;
  long steps = 0;
  bool separated = false;  // false: max_steps reached
  std::vector<BinarySample> trace;
};

// Two bodies touching at first contact; n is the unit normal from j to i and the bodies must
// approach ((v_i - v_j).n < 0; otherwise the result is returned at once with separated = true).
template <int D>
BinaryResult<D> collide_pair(const SoftLaw& law, const BinaryBody<D>& i, const BinaryBody<D>& j,
                             const Vec<D>& n, const BinaryOptions& opt = {});

// A body touching an infinite plane wall of unit normal `normal` (pointing to the body's side).
template <int D>
BinaryResult<D> collide_wall(const SoftLaw& law, const BinaryBody<D>& i, const Vec<D>& normal,
                             const SoftMaterial& wall = SoftMaterial::rigid(),
                             const BinaryOptions& opt = {});

extern template BinaryResult<2> collide_pair<2>(const SoftLaw&, const BinaryBody<2>&,
                                                const BinaryBody<2>&, const Vec<2>&,
                                                const BinaryOptions&);
extern template BinaryResult<3> collide_pair<3>(const SoftLaw&, const BinaryBody<3>&,
                                                const BinaryBody<3>&, const Vec<3>&,
                                                const BinaryOptions&);
extern template BinaryResult<2> collide_wall<2>(const SoftLaw&, const BinaryBody<2>&, const Vec<2>&,
                                                const SoftMaterial&, const BinaryOptions&);
extern template BinaryResult<3> collide_wall<3>(const SoftLaw&, const BinaryBody<3>&, const Vec<3>&,
                                                const SoftMaterial&, const BinaryOptions&);

}  // namespace matep

// Soft contacts as data (Snapshot::contacts, kind 1): the force of one contact at a snapshot, from
// the state then: positions, full-step velocities and spins, and the contact's tangential spring.
// The law of contact/soft.hpp is evaluated once more with a zero spring increment, so the elastic
// parts are the step's own (the normal spring at this overlap, the tangential spring as the step
// left it) and the dashpots see the full-step velocities (the step used predicted ones, which
// differ by O(h) in the dashpots alone). TDM and the hybrid's soft set (engine/tdm/tdm.cpp,
// engine/hybrid/hybrid.cpp) both build their rows here.
#pragma once

#include <cstdint>

#include "contact/soft.hpp"
#include "contact/wall.hpp"
#include "engine/observer.hpp"

namespace matep::soft {

// A particle's state as the rows read it (values: the engines compute the full-step velocities).
template <int D>
struct RowBody {
  std::uint32_t id;
  Vec<D> x;
  double R;
  Vec<D> v;
  Spin<D> w;
};

// The contact of a and b, whose separation x_a - x_b (periodic image included) is dx, with the
// spring xi oriented for a; a row with i < j (the force on the smaller id).
template <int D>
ContactRow<D> pair_row(const SoftContact& c, const RowBody<D>& a, const RowBody<D>& b, const Vec<D>& dx,
                       const Vec<D>& xi) {
  const double rr = dx.norm();
  ContactKinematics<D> k;
  k.n = dx / rr;
  k.delta = a.R + b.R - rr;
  const double la = pair_lever_arm(a.R, k.delta), lb = pair_lever_arm(b.R, k.delta);
  k.v = contact_velocity<D>(a.v, a.w, la, b.v, b.w, lb, k.n);
  ContactHistory<D> h{xi};
  const ContactForce<D> f = soft_contact_force<D>(c, k, h);
  ContactRow<D> row;
  row.kind = 1;
  row.overlap = k.delta;
  row.point = a.x - (a.R - 0.5 * k.delta) * k.n;  // the middle of the overlap
  const bool swap = b.id < a.id;
  row.i = swap ? b.id : a.id;
  row.j = swap ? a.id : b.id;
  row.fn = (swap ? -f.normal : f.normal) * k.n;
  row.ft = swap ? Vec<D>(-f.tangential) : f.tangential;
  return row;
}

// The contact of a with wall `wall` at the wall point p (WallShape::at or a feature's), spring xi.
template <int D>
ContactRow<D> wall_row(const SoftContact& c, const RowBody<D>& a, std::int32_t wall, const WallPoint<D>& p,
                       const Vec<D>& xi) {
  ContactKinematics<D> k;
  k.n = p.normal;
  k.delta = -p.gap;
  const double la = wall_lever_arm(a.R, k.delta);
  k.v = a.v - p.velocity - spin_cross<D>(la * a.w, k.n);
  ContactHistory<D> h{xi};
  const ContactForce<D> f = soft_contact_force<D>(c, k, h);
  ContactRow<D> row;
  row.kind = 1;
  row.i = a.id;
  row.j = -1;
  row.wall = wall;
  row.overlap = k.delta;
  row.point = a.x - (a.R - k.delta) * k.n;
  row.fn = f.normal * k.n;
  row.ft = f.tangential;
  return row;
}

}  // namespace matep::soft

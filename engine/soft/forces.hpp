// The soft-contact force loop, the one used by TDM and by the hybrid's soft set: pair contacts from
// a half neighbour list in rows (a row = one particle's entries), then the caller's wall contacts
// through wall_contact() below. Templated on the normal law (contact/soft.hpp) and on rotation; a
// Policy says what differs between the engines:
//   TDM: rows are all particles of a thread's range in storage order, forces on a particle of
//        another range are spilled, each particle is integrated as soon as its force is complete
//        (row_done), overlaps are tracked for the stability check;
//   hybrid: rows are its soft particles (and rows appended when particles join or wake), it flags
//        touching and nearby particles for the release rule, and a sleeping end of a contact (rest
//        rule) feels the springs only.
// Kinematics (contact/soft.hpp conventions): the dashpots and the sliding direction see the
// predicted velocities v(t - h/2) + h/2 a(t - h) (engine/soft/verlet.hpp), the tangential spring
// grows by h times the half-step contact velocity, and a contact that begins inside the step is
// weighted by onset_fraction/at_onset. A contact present before the first force evaluation of a
// run began before it: that evaluation applies no onset weight (the policy's onset() is false).
// Rolling resistance (a contact's c.rolling): the rotation branch adds rolling_torque
// (contact/soft.hpp) to i and its opposite to j (a wall: against the wall's own spin); the
// spring-dashpot model's torques are PairRows::mr and wall_contact's mr (null when not used).
#pragma once

#include <cmath>
#include <cstdint>
#include <vector>

#include "contact/soft.hpp"
#include "contact/plane.hpp"
#include "contact/wall.hpp"

namespace matep::soft {

// The arrays the loop reads and writes, indexed by the caller's particle index (raw pointers: the
// force writes would otherwise make the compiler reload every vector's data pointer at each use).
template <int D>
struct Bodies {
  const Vec<D>* v = nullptr;       // half-step velocities v(t - h/2)
  const Vec<D>* acc = nullptr;     // accelerations a(t - h)
  Vec<D>* f = nullptr;             // forces being accumulated
  const Spin<D>* w = nullptr;      // half-step spins (rotation only)
  const Spin<D>* alpha = nullptr;  // angular accelerations (rotation only)
  Spin<D>* tq = nullptr;           // torques being accumulated (rotation only)
};

// The Bodies of an engine's state vectors (rotation arrays may be empty when nothing rotates).
template <int D>
Bodies<D> bodies_of(const std::vector<Vec<D>>& v, const std::vector<Vec<D>>& acc, std::vector<Vec<D>>& f,
                    const std::vector<Spin<D>>& w, const std::vector<Spin<D>>& alpha, std::vector<Spin<D>>& tq) {
  return {v.data(), acc.data(), f.data(), w.data(), alpha.data(), tq.data()};
}

// Positions and radii, as separate arrays (TDM) or inside each particle's record (the hybrid: the
// EDM core's hot state). The loop copies the accessor, so its pointers stay in registers.
template <int D>
struct Arrays {
  const Vec<D>* x;
  const double* R;
  const Vec<D>& pos(std::uint32_t i) const { return x[i]; }
  double radius(std::uint32_t i) const { return R[i]; }
};
template <int D, class Rec>
struct Records {
  const Rec* p;  // p[i].x, p[i].R
  const Vec<D>& pos(std::uint32_t i) const { return p[i].x; }
  double radius(std::uint32_t i) const { return p[i].R; }
};

// A half neighbour list in rows: row r holds entries off[r] .. off[r + 1] of the particle
// owner[r] (owner null: row r is particle r); an entry is the partner j, the index of the
// periodic image shift to add to x_i - x_j, the touching flag and (with rotation) the spring.
template <int D>
struct PairRows {
  const std::uint32_t* owner = nullptr;
  const std::uint32_t* off = nullptr;
  const std::uint32_t* nb = nullptr;
  const std::uint8_t* sh = nullptr;
  std::uint8_t* touch = nullptr;
  Vec<D>* xi = nullptr;
  const Vec<D>* shift = nullptr;  // image shifts by index
  Spin<D>* mr = nullptr;          // rolling spring torques (Epsd rolling resistance; else null)

  // Rows 0 .. n - 1 of particles 0 .. n - 1 (owner null) or of owner[r], as CSR arrays.
  static PairRows of(const std::uint32_t* owner, const std::uint32_t* off, const std::uint32_t* nb,
                     const std::uint8_t* sh, std::uint8_t* touch, Vec<D>* xi, const Vec<D>* shift,
                     Spin<D>* mr = nullptr) {
    return {owner, off, nb, sh, touch, xi, shift, mr};
  }
};

// The hooks of pair_rows's policy that only the hybrid's extras use (sleepers, near flags), left
// empty: a policy without them (TDM's) derives from this.
struct NoSleepers {
  void touching(std::uint32_t, std::uint32_t) {}
  void near(std::uint32_t, std::uint32_t) {}
  double near_skin() const { return 0.0; }
  bool any_asleep() const { return false; }
  bool asleep(std::uint32_t) const { return false; }
  bool approached(double) const { return false; }
  void wake(std::uint32_t) {}
};

// The rolling-resistance torque on i of one contact (rolling_torque) from the half-step spins
// whi, whj, i's predicted spin wpi and j's angular acceleration alj (a wall: its spin and zero):
// the relative rotation over the step h (h times the half-step relative spin, weighted by a new
// contact's onset fraction) and the predicted relative spin. mr: the contact's spring torque
// (spring-dashpot model; null: none kept), zeroed when the contact is fresh (it begins at this
// evaluation: a spring left from an earlier contact of the same entry is gone).
template <int D, NormalLaw Law>
[[gnu::always_inline]] inline Spin<D> rolling_step(const SoftContact& c, double delta, double fn, const Vec<D>& n,
                                       const Spin<D>& whi, const Spin<D>& wpi, const Spin<D>& whj,
                                       const Spin<D>& alj, double h, double onset, bool fresh, Spin<D>* mr) {
  if (fresh && mr) mr->setZero();
  Spin<D> dth = h * (whi - whj);
  if (onset >= 0.0) dth *= onset;
  Spin<D> none = Spin<D>::Zero();
  return rolling_torque<D, Law>(c, delta, fn, n, Spin<D>(wpi - whj - (0.5 * h) * alj), dth, mr ? *mr : none);
}

// Pair forces of rows [r0, r1); the policy keeps the counters. Roll: the scene has rolling
// resistance (an instantiation of its own, so that the loop of a scene without it carries no trace
// of it). The policy provides (see the engines for the two):
//   static constexpr bool kSleepers, kNear, kVirial;
//   bool onset() const;                       // may a contact begun now get its onset weight?
//   const SoftContact& contact(e, i, j, SoftContact& scratch);
//   void began(i, j);  void opened(i, j);  void overlap(delta, Rs);
//   void touching(i, j);  void near(i, j);  double near_skin() const;
//   bool any_asleep() const;  bool asleep(i) const;  bool approached(un) const;  void wake(k);
//   void partner(f, tq, j, F, tj);   (j receives -F and the torque tj; f, tq: the Bodies' arrays)
//   void virial(F, dx);  void row_done(i);
//   static constexpr bool kOwners (row r is particle owner[r]; otherwise particle r), kShifts (some
//   axis is periodic: add the entries' image shifts), kSparseRows (short rows: the owner's force is
//   added per contact instead of once per row, through own_force(f, i, F) and own_torque(tq, i, T),
//   so that a threaded caller may divert it: the hybrid's rows of one particle may lie in two
//   threads' ranges).
template <int D, NormalLaw Law, bool Rot, bool Roll, class Pos, class Policy>
[[gnu::always_inline]] inline void pair_rows(const Pos P, const Bodies<D>& b, const PairRows<D>& L, std::uint32_t r0,
                                             std::uint32_t r1, double h, Policy& pol) {
  const double hdt = 0.5 * h;
  const Vec<D>* const V = b.v;
  const Vec<D>* const AC = b.acc;
  Vec<D>* const FF = b.f;
  const std::uint32_t* const NB = L.nb;
  const std::uint32_t* const OFF = L.off;
  const std::uint8_t* const SH = L.sh;
  std::uint8_t* const TOUCH = L.touch;
  const Vec<D>* const SHIFT = L.shift;
  const std::uint32_t* const OWNER = L.owner;
  Vec<D>* const XI = L.xi;
  Spin<D>* const MR = L.mr;
  const Spin<D>* const WH = b.w;
  const Spin<D>* const AL = b.alpha;
  Spin<D>* const TQ = b.tq;
  const bool onset_ok = pol.onset();
  for (std::uint32_t r = r0; r < r1; ++r) {
    std::uint32_t i = r;
    if constexpr (Policy::kOwners) i = OWNER[r];
    const Vec<D> xi = P.pos(i);
    const double Ri = P.radius(i);
    // i's half-step and predicted velocities are read where a contact needs them (most entries
    // of a dilute gas are not in contact).
    Vec<D> fi = Vec<D>::Zero();
    Spin<D> ti = Spin<D>::Zero();
    // The owner's force and torque (fi, ti) are summed over the row and added once (TDM's long
    // rows), or added per contact (kSparseRows: the hybrid's short rows).
    const std::uint32_t end = OFF[r + 1];
    for (std::uint32_t e = OFF[r]; e < end; ++e) {
      const std::uint32_t j = NB[e];
      Vec<D> dx = xi - P.pos(j);
      if constexpr (Policy::kShifts) dx += SHIFT[SH[e]];  // no periodic axis: the shift is zero
      const double Rs = Ri + P.radius(j);
      const double r2 = dx.squaredNorm();
      if constexpr (Policy::kNear) {
        const double cut = Rs + pol.near_skin();
        if (r2 < cut * cut) pol.near(i, j);
      }
      if (r2 >= Rs * Rs) {
        if (TOUCH[e]) {
          TOUCH[e] = 0;
          if constexpr (Rot) XI[e].setZero();
          pol.opened(i, j);
        }
        continue;
      }
      const double rr = std::sqrt(r2);
      const Vec<D> n = dx * (1.0 / rr);
      const double delta = Rs - rr;
      const Vec<D> vhi = V[i], vpi = V[i] + hdt * AC[i];
      double onset = -1.0;  // first step of this contact: the part of the step spent in contact
      const bool fresh = !TOUCH[e];
      if (fresh) {
        TOUCH[e] = 1;
        pol.began(i, j);
        if (onset_ok) onset = onset_fraction(delta, -(vhi - V[j]).dot(n), h);
      }
      pol.overlap(delta, Rs);
      pol.touching(i, j);
      // The contact's constants: the policy's (a table entry, or computed into `local`), or
      // their first-step weighted copy.
      SoftContact local;
      const SoftContact* cp = &pol.contact(e, i, j, local);
      if (onset >= 0.0) {
        if (cp != &local) local = *cp;
        at_onset<Law>(local, onset);
        cp = &local;
      }
      const SoftContact& c = *cp;
      // Predicted velocities at the new time: v(t + h/2) + h/2 a(t).
      const Vec<D> vj = V[j] + hdt * AC[j];
      // A sleeping end (rest rule) is pushed by the springs only; a touching grain that
      // approaches it faster than rest_speed wakes it.
      bool sleep_i = false, sleep_j = false;
      if constexpr (Policy::kSleepers) {
        if (pol.any_asleep()) {
          sleep_i = pol.asleep(i);
          sleep_j = pol.asleep(j);
          if (sleep_i || sleep_j) {
            const double un = (vhi - V[j]).dot(n);  // < 0: approaching (n points from j to i)
            if (pol.approached(un)) pol.wake(sleep_i ? i : j);
          }
        }
      }
      Vec<D> F, Fel;
      Spin<D> tj = Spin<D>::Zero();
      if constexpr (!Rot) {
        double fn = normal_force_law<Law>(c, delta, (vpi - vj).dot(n));
        if (c.clip && fn < 0.0) fn = 0.0;
        F = fn * n;
        if (sleep_i || sleep_j) Fel = elastic_normal_force<Law>(c, delta) * n;
      } else {
        const double li = pair_lever_arm(Ri, delta), lj = pair_lever_arm(P.radius(j), delta);
        ContactKinematics<D> k;
        k.delta = delta;
        k.n = n;
        const Spin<D> whi = WH[i], wpi = WH[i] + hdt * AL[i];
        k.v = contact_velocity<D>(vpi, wpi, li, vj, WH[j] + hdt * AL[j], lj, n);
        k.dxi = h * contact_velocity<D>(vhi, whi, li, V[j], WH[j], lj, n);
        if (onset >= 0.0) k.dxi *= onset;  // the spring stretches only since first touch
        ContactHistory<D> hist{XI[e]};
        const ContactForce<D> cf = soft_contact_force_law<D, Law>(c, k, hist);
        XI[e] = hist.xi;
        F = cf.force;
        // tau = -l n x F_t on both bodies (contact/soft.hpp conventions).
        const Spin<D> m = lever_moment<D>(n, cf.tangential);
        if (sleep_i || sleep_j) {
          const double kt = Law == NormalLaw::Linear ? c.kt : c.kt * std::sqrt(delta);
          const Vec<D> ft = -kt * XI[e];
          Fel = elastic_normal_force<Law>(c, delta) * n + ft;
          const Spin<D> mel = lever_moment<D>(n, ft);
          if constexpr (Policy::kSparseRows) pol.own_torque(TQ, i, Spin<D>(-(li * (sleep_i ? mel : m))));
          else ti -= li * (sleep_i ? mel : m);
          tj = -lj * (sleep_j ? mel : m);
        } else {
          if constexpr (Policy::kSparseRows) pol.own_torque(TQ, i, Spin<D>(-(li * m)));
          else ti -= li * m;
          tj = -lj * m;
        }
        if (Roll && c.rolling != RollingModel::None) {  // rolling resistance: -M on j
          const Spin<D> M = rolling_step<D, Law>(c, delta, cf.normal, n, whi, wpi, WH[j], AL[j], h, onset, fresh,
                                                 MR ? &MR[e] : nullptr);
          if constexpr (Policy::kSparseRows) pol.own_torque(TQ, i, M);
          else ti += M;
          tj -= M;
        }
      }
      if constexpr (Policy::kSleepers) {
        if constexpr (Policy::kSparseRows) pol.own_force(FF, i, sleep_i ? Fel : F);
        else fi += sleep_i ? Fel : F;
        pol.partner(FF, TQ, j, sleep_j ? Fel : F, tj);
      } else {
        if constexpr (Policy::kSparseRows) pol.own_force(FF, i, F);
        else fi += F;
        pol.partner(FF, TQ, j, F, tj);
      }
      if constexpr (Policy::kVirial) pol.virial(F, dx);
    }
    if constexpr (!Policy::kSparseRows) {
      FF[i] += fi;
      if constexpr (Rot) TQ[i] += ti;
    }
    pol.row_done(i);
  }
}

// One wall contact of particle i at time t (the walls' state: contact/wall.hpp): adds its force and
// torque to f and tq, keeps the touching flag and the spring, and returns the overlap (<= 0: no
// contact), the force and the contact point (for the wall's load). `began` is set when the contact begins at this evaluation; `onset_ok` as in pair_rows.
// Shape: WallShape<D> (any wall, through its virtual interface) or a class with the same at() and
// surface_velocity(), such as PlaneInstant<D>, whose calls the compiler then inlines (the engines'
// fast path for planes; see WallsNow below).
template <int D>
struct WallContact {
  double delta = 0.0;              // overlap (<= 0: no contact)
  Vec<D> force = Vec<D>::Zero();   // the contact's force on the particle
  Vec<D> point = Vec<D>::Zero();   // the wall's surface point of the contact, x - (R - delta) n
};

template <int D, NormalLaw Law, bool Rot, bool Roll, class Shape = WallShape<D>>
[[gnu::always_inline]] inline WallContact<D> wall_contact(const Shape& W, double t, double h, bool onset_ok,
                                                  const Vec<D>& x, double R, const Vec<D>& vh, const Vec<D>& acc,
                                                  const Spin<D>& wh, const Spin<D>& alpha, SoftContact c,
                                                  std::uint8_t& touch, Vec<D>& xi, bool& began, Vec<D>& f,
                                                  Spin<D>& tq, Spin<D>* mr = nullptr) {
  const double hdt = 0.5 * h;
  const WallPoint<D> wp = W.at(x, R, t);
  const Vec<D>& n = wp.normal;
  const Vec<D>& u = wp.velocity;
  const double delta = -wp.gap;
  began = false;
  WallContact<D> out;
  out.delta = delta;
  if (delta <= 0.0) {
    if (touch) {
      touch = 0;
      if constexpr (Rot) xi.setZero();
    }
    return out;
  }
  out.point = x - (R - delta) * n;
  double onset = -1.0;
  const bool fresh = !touch;
  if (fresh) {
    touch = 1;
    began = true;
    // The surface's velocity at the half step (the half-step velocities' frame).
    if (onset_ok) onset = onset_fraction(delta, -(vh - W.surface_velocity(x, R, t - hdt)).dot(n), h);
  }
  if (onset >= 0.0) at_onset<Law>(c, onset);
  const Vec<D> vi = vh + hdt * acc - u;  // relative to the wall
  if constexpr (!Rot) {
    double fn = normal_force_law<Law>(c, delta, vi.dot(n));
    if (c.clip && fn < 0.0) fn = 0.0;
    out.force = fn * n;
    f += out.force;
  } else {
    const double li = wall_lever_arm(R, delta);
    ContactKinematics<D> k;
    k.delta = delta;
    k.n = n;
    k.v = vi - spin_cross<D>(li * Spin<D>(wh + hdt * alpha), n);
    k.dxi = h * (vh - W.surface_velocity(x, R, t - hdt) - spin_cross<D>(li * wh, n));
    if (onset >= 0.0) k.dxi *= onset;
    ContactHistory<D> hist{xi};
    const ContactForce<D> cf = soft_contact_force_law<D, Law>(c, k, hist);
    xi = hist.xi;
    out.force = cf.force;
    f += cf.force;
    tq += contact_torque<D>(n, cf.tangential, li);
    if (Roll && c.rolling != RollingModel::None) {  // against the wall's own spin
      const Spin<D> ws = W.spin();
      tq += rolling_step<D, Law>(c, delta, cf.normal, n, wh, Spin<D>(wh + hdt * alpha), ws, Spin<D>::Zero(), h, onset,
                                 fresh, mr);
    }
  }
  return out;
}

// The wall-list entries of a particle at x (radius R) at time t: fn(w, feature) for each wall whose
// gap may fall below skin before the list is rebuilt (a moving wall: plus twice its stroke), each
// feature of a multi-contact wall (a mesh's facets) on its own. TDM's and the hybrid's list builds.
template <int D, class Fn>
void walls_in_reach(const std::vector<const WallShape<D>*>& shapes, const Vec<D>& x, double R, double skin, double t,
                    std::vector<std::uint32_t>& scratch, Fn&& fn) {
  for (std::size_t w = 0; w < shapes.size(); ++w) {
    const WallShape<D>& W = *shapes[w];
    const double reach = skin + 2.0 * W.stroke();
    if (W.multi_contact()) {
      scratch.clear();
      W.features_near(x, R, reach, t, scratch);
      for (const std::uint32_t f : scratch) fn(static_cast<std::uint32_t>(w), f);
    } else if (W.at(x, R, t).gap < reach) {
      fn(static_cast<std::uint32_t>(w), 0u);
    }
  }
}

// The walls of one force evaluation: each plane frozen at the evaluation's times (PlaneInstant,
// whose calls the compiler inlines), any other shape through its interface. refresh() before each
// evaluation; with_wall(w, feature, f) calls f with the one or the other (the shape's feature:
// contact/wall.hpp): the physics is the same.
template <int D>
class WallsNow {
 public:
  void assign(const std::vector<const WallShape<D>*>& shapes) {
    shapes_ = shapes;
    planes_.clear();
    for (const WallShape<D>* s : shapes_) planes_.push_back(as_plane<D>(s));
    now_.assign(shapes_.size(), PlaneInstant<D>{});
  }
  void refresh(double t, double hdt) {
    for (std::size_t w = 0; w < shapes_.size(); ++w)
      if (planes_[w]) now_[w] = planes_[w]->instant(t, hdt);
  }
  // Wall w's feature `feature` (contact/wall.hpp; 0 for a shape with one contact per grain).
  // Two forms only (the loop inlines each): a frozen plane, or any shape's feature through the
  // interface (at_feature: a shape with one contact per grain answers its at()).
  template <class F>
  [[gnu::always_inline]] auto with_wall(std::size_t w, std::uint32_t feature, F&& f) const {
    if (planes_[w]) return f(now_[w]);
    return f(FeatureView<D>{*shapes_[w], feature});
  }
  std::size_t size() const { return shapes_.size(); }

 private:
  std::vector<const WallShape<D>*> shapes_;
  std::vector<const PlaneWall<D>*> planes_;  // shapes_[w] where it is a plane, else null
  std::vector<PlaneInstant<D>> now_;
};

}  // namespace matep::soft

// The batched form of the soft path's pair loop (engine/soft/forces.hpp pair_rows), for TDM's
// rows and the hybrid's soft set: the same physics, the same arithmetic in the same order, laid out
// so that the contact formulas run lane-wise (SIMD) over many contacts at once instead of one
// contact's long chain of square roots and divisions at a time. The rows' entries are walked in
// order and done a batch of kCap contacts at a time, in three passes:
//   1. compaction: every list entry's distance; an entry in contact is appended to the batch
//      (entry, particles, separation, whether it begins now, its constants), a contact that has
//      opened closes (the hybrid: near flags for its release rule);
//   2. the contact kernel over the batch, lane by lane (the bodies' velocities read by index):
//      normal, onset weight, kinematics, the law (contact/soft.hpp contact_force_core, the one
//      place its formula is written), the spring read and written back;
//   3. accumulation in list order: each row's force and torque summed and added once (TDM: a row
//      may span two batches), or each contact's added as it comes (the hybrid's short rows of
//      owners, through the policy, which spills what another thread owns); the partners' through
//      the policy; the hybrid's sleeping ends (springs only) and touching flags; then the policy's
//      row_done (walls, fused integration) for every row whose entries are all done. Partners
//      j > i in TDM's rows, so a row's particle is complete then. Every force is summed in the
//      order pair_rows sums it: the results are bit-identical to pair_rows's.
// Not for rolling resistance (its models keep a spring torque per contact): pair_rows runs it.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <limits>

#include "engine/soft/forces.hpp"

namespace matep::soft {

template <int D>
struct ContactBatch {
  static constexpr int S = D == 3 ? 3 : 1;  // spin components
  static constexpr int kCap = 256;          // contacts per batch
  // Columns (column c holds entries c kCap .. c kCap + kCap - 1): in, the separation, R_i + R_j
  // and the squared distance; out, the overlap, the force on i, l_i m (i's torque is minus it)
  // and j's torque.
  enum : int { kDx = 0, kRs = kDx + D, kR2, kDelta, kF, kTi = kF + D, kTj = kTi + S, kColumns = kTj + S };
  alignas(64) std::array<double, kCap * kColumns> col;
  alignas(64) std::array<std::uint32_t, kCap> i, j, e;
  alignas(64) std::array<std::uint32_t, kCap> ci;        // the constants' index (a policy's table)
  alignas(64) std::array<std::uint8_t, kCap> alt, fresh;  // alt: the fixed-grain constants; fresh: begun now
};

// Pair forces of rows [r0, r1), the policy as for pair_rows plus its constants:
//   static constexpr bool kTable;  bool clip() const;
//   kTable false (TDM): bool alt(i, j);  const SoftContact& contact_main();  const SoftContact& contact_alt();
//     (the uniform constants: a pair of moving grains, and a pair with a fixed grain; one law);
//   kTable true (the hybrid): const SoftContact* table();  std::uint32_t contact_index(e)
//     (each entry's constants in a table; one law, so one clip).
// The hybrid's extras run outside the kernel: its near flags in the compaction, its touching flags,
// its sleepers (springs-only forces, waking) and virial in the accumulation, each in pair_rows's
// order and with its expressions.
template <int D, NormalLaw Law, bool Rot, class Pos, class Policy>
[[gnu::always_inline]] inline void pair_rows_batched(const Pos P, const Bodies<D>& b, const PairRows<D>& L,
                                                     std::uint32_t r0, std::uint32_t r1, double h, Policy& pol,
                                                     ContactBatch<D>& B) {
  // Rows of owners are short rows: each contact's own force is added as it comes.
  static_assert(!Policy::kOwners || Policy::kSparseRows);
  constexpr bool kTable = Policy::kTable;
  constexpr bool kSparse = Policy::kSparseRows;
  constexpr int S = ContactBatch<D>::S;
  constexpr int C = ContactBatch<D>::kCap;
  using CB = ContactBatch<D>;
  const double hdt = 0.5 * h;
  const std::uint32_t* const NB = L.nb;
  const std::uint32_t* const OFF = L.off;
  const std::uint32_t* const OWNER = L.owner;
  const std::uint8_t* const SH = L.sh;
  std::uint8_t* const TOUCH = L.touch;
  const Vec<D>* const SHIFT = L.shift;
  // The arrays as plain numbers (an empty array, such as the springs of a run without pairs, is null).
  auto raw = [](auto* p) { return p ? p->data() : nullptr; };
  double* const XI = Rot ? raw(L.xi) : nullptr;
  const bool onset_ok = pol.onset();
  const bool clip = pol.clip();  // the law's (one law per run)
  double kn0 = 0.0, gn0 = 0.0, kt0 = 0.0, gt0 = 0.0, mu0 = 0.0;
  double kn1 = 0.0, gn1 = 0.0, kt1 = 0.0, gt1 = 0.0, mu1 = 0.0;
  const SoftContact* CT = nullptr;
  if constexpr (kTable) {
    CT = pol.table();
  } else {
    const SoftContact& c0 = pol.contact_main();
    const SoftContact& c1 = pol.contact_alt();
    kn0 = c0.kn, gn0 = c0.gn, kt0 = c0.kt, gt0 = c0.gt, mu0 = c0.mu;
    kn1 = c1.kn, gn1 = c1.gn, kt1 = c1.kt, gt1 = c1.gt, mu1 = c1.mu;
  }
  double skin = 0.0;
  if constexpr (Policy::kNear) skin = pol.near_skin();
  const double* const V = raw(b.v);
  const double* const AC = raw(b.acc);
  const double* const WH = Rot ? raw(b.w) : nullptr;
  const double* const AL = Rot ? raw(b.alpha) : nullptr;
  Vec<D>* const FF = b.f;
  Spin<D>* const TQ = b.tq;
  double* const T = B.col.data();
  auto particle = [&](std::uint32_t r) {
    if constexpr (Policy::kOwners) return OWNER[r];
    else return r;
  };

  // The walk's cursor (row r, entry e), the row being accumulated (cur, with fi and ti so far) and
  // the first row whose row_done is still due.
  constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
  std::uint32_t r = r0, e = r0 < r1 ? OFF[r0] : 0;
  std::uint32_t cur = kNone, due = r0;
  Vec<D> fi = Vec<D>::Zero();
  Spin<D> ti = Spin<D>::Zero();
  auto flush = [&] {
    if (cur == kNone) return;
    FF[cur] += fi;
    if constexpr (Rot) TQ[cur] += ti;
    cur = kNone;
  };
  while (r < r1) {
    // 1. Compaction, up to C contacts.
    int n = 0;
    for (; r < r1; ++r) {
      const std::uint32_t i = particle(r);
      const Vec<D> xi = P.pos(i);
      const double Ri = P.radius(i);
      const std::uint32_t end = OFF[r + 1];
      for (; e < end && n < C; ++e) {
        const std::uint32_t j = NB[e];
        Vec<D> dx = xi - P.pos(j);
        if constexpr (Policy::kShifts) dx += SHIFT[SH[e]];
        const double Rs = Ri + P.radius(j);
        const double r2 = dx.squaredNorm();
        if constexpr (Policy::kNear) {
          const double cut = Rs + skin;
          if (r2 < cut * cut) pol.near(i, j);
        }
        // Written whether or not in contact (the slot is kept only if it is): no branch on the
        // contact test, which a bed's lists make unpredictable.
        const bool in = r2 < Rs * Rs;
        const std::uint8_t was = TOUCH[e];
        B.i[n] = i;
        B.j[n] = j;
        B.e[n] = e;
        B.fresh[n] = was == 0;
        for (int c = 0; c < D; ++c) T[(CB::kDx + c) * C + n] = dx[c];
        T[CB::kRs * C + n] = Rs;
        T[CB::kR2 * C + n] = r2;
        if constexpr (kTable) B.ci[n] = pol.contact_index(e);
        else B.alt[n] = pol.alt(i, j);
        TOUCH[e] = in;
        if (!in && was) {  // the contact has opened (rare: a predictable branch)
          if constexpr (Rot)
            for (int c = 0; c < D; ++c) XI[D * e + c] = 0.0;
          pol.opened(i, j);
        }
        n += in;
      }
      if (e < end) break;  // the batch is full inside row r
    }
    // 2. The contact kernel, lane by lane: pair_rows's expressions on plain numbers.
    {
      const std::uint32_t* const BI = B.i.data();
      const std::uint32_t* const BJ = B.j.data();
      const std::uint32_t* const BE = B.e.data();
      const std::uint32_t* const CI = B.ci.data();
      const std::uint8_t* const FR = B.fresh.data();
      const std::uint8_t* const AT = B.alt.data();
#pragma GCC ivdep
      for (int k = 0; k < n; ++k) {
        const std::uint32_t pi = BI[k], pj = BJ[k];
        const double rr = std::sqrt(T[CB::kR2 * C + k]);
        const double inv = 1.0 / rr;
        double nv[D], vhi[D], vpi[D], vhj[D], vj[D], du[D];
        for (int c = 0; c < D; ++c) {
          nv[c] = T[(CB::kDx + c) * C + k] * inv;
          vhi[c] = V[D * pi + c];
          vpi[c] = vhi[c] + hdt * AC[D * pi + c];
          vhj[c] = V[D * pj + c];
          vj[c] = vhj[c] + hdt * AC[D * pj + c];
          du[c] = vhi[c] - vhj[c];
        }
        const double delta = T[CB::kRs * C + k] - rr;
        T[CB::kDelta * C + k] = delta;
        const double onset = FR[k] && onset_ok ? onset_fraction(delta, -dot3<D>(du, nv), h) : -1.0;
        double kn, gn, kt, gt, mu;
        if constexpr (kTable) {
          const SoftContact& c = CT[CI[k]];
          kn = c.kn, gn = c.gn, kt = c.kt, gt = c.gt, mu = c.mu;
        } else {
          const bool alt = AT[k] != 0;
          kn = alt ? kn1 : kn0;
          gn = alt ? gn1 : gn0;
          kt = alt ? kt1 : kt0;
          gt = alt ? gt1 : gt0;
          mu = alt ? mu1 : mu0;
        }
        if constexpr (Law == NormalLaw::Linear) {  // at_onset: the dashpots' first-step weight
          gn = onset >= 0.0 ? gn * (onset + 0.5) : gn;
          gt = onset >= 0.0 ? gt * (onset + 0.5) : gt;
        }
        double F[D];
        if constexpr (!Rot) {
          double dv[D];
          for (int q = 0; q < D; ++q) dv[q] = vpi[q] - vj[q];
          double fn = normal_force_law<Law>(kn, gn, delta, dot3<D>(dv, nv));
          fn = clip && fn < 0.0 ? 0.0 : fn;
          for (int q = 0; q < D; ++q) F[q] = fn * nv[q];
        } else {
          const std::uint32_t pe = BE[k];
          const double li = pair_lever_arm(P.radius(pi), delta), lj = pair_lever_arm(P.radius(pj), delta);
          double whi[S], wpi[S], whj[S], wpj[S];
          for (int q = 0; q < S; ++q) {
            whi[q] = WH[S * pi + q];
            wpi[q] = whi[q] + hdt * AL[S * pi + q];
            whj[q] = WH[S * pj + q];
            wpj[q] = whj[q] + hdt * AL[S * pj + q];
          }
          double cv[D], u[D], dxi[D], xi[D], Ft[D], m[S];
          contact_velocity_to<D>(vpi, wpi, li, vj, wpj, lj, nv, cv);
          contact_velocity_to<D>(vhi, whi, li, vhj, whj, lj, nv, u);
          for (int q = 0; q < D; ++q) {
            const double d = h * u[q];
            dxi[q] = onset >= 0.0 ? d * onset : d;
            xi[q] = XI[D * pe + q];
          }
          double fn, fraw;
          bool sliding;
          contact_force_core<D, Law>(kn, gn, kt, gt, mu, clip, delta, nv, cv, dxi, xi, F, Ft, fn, fraw, sliding);
          for (int q = 0; q < D; ++q) XI[D * pe + q] = xi[q];
          lever_moment_to<D>(nv, Ft, m);
          for (int q = 0; q < S; ++q) {
            T[(CB::kTi + q) * C + k] = li * m[q];
            T[(CB::kTj + q) * C + k] = -lj * m[q];
          }
        }
        for (int q = 0; q < D; ++q) T[(CB::kF + q) * C + k] = F[q];
      }
    }
    // 3. Accumulation in list order.
    for (int k = 0; k < n; ++k) {
      const std::uint32_t pi = B.i[k], pj = B.j[k];
      if constexpr (!kSparse) {
        if (pi != cur) {
          flush();
          cur = pi;
          fi.setZero();
          ti.setZero();
        }
      }
      if (B.fresh[k]) pol.began(pi, pj);
      pol.overlap(T[CB::kDelta * C + k], T[CB::kRs * C + k]);
      pol.touching(pi, pj);
      Vec<D> F, dx;
      for (int c = 0; c < D; ++c) {
        F[c] = T[(CB::kF + c) * C + k];
        dx[c] = T[(CB::kDx + c) * C + k];
      }
      Spin<D> mi = Spin<D>::Zero(), tj = Spin<D>::Zero();
      if constexpr (Rot)
        for (int q = 0; q < S; ++q) {
          mi[q] = T[(CB::kTi + q) * C + k];
          tj[q] = T[(CB::kTj + q) * C + k];
        }
      // A sleeping end (rest rule) is pushed by the springs only, and a touching grain that
      // approaches it faster than rest_speed wakes it (pair_rows's expressions).
      Vec<D> Fi = F, Fj = F;
      bool sleep_i = false;
      if constexpr (Policy::kSleepers) {
        if (pol.any_asleep()) {
          sleep_i = pol.asleep(pi);
          const bool sleep_j = pol.asleep(pj);
          if (sleep_i || sleep_j) {
            const double delta = T[CB::kDelta * C + k];
            const double rr = std::sqrt(T[CB::kR2 * C + k]);
            const Vec<D> nrm = dx * (1.0 / rr);
            const Vec<D>* const VV = b.v;
            const double un = (VV[pi] - VV[pj]).dot(nrm);  // < 0: approaching
            if (pol.approached(un)) pol.wake(sleep_i ? pi : pj);
            const SoftContact* cp = nullptr;
            if constexpr (kTable) cp = &CT[B.ci[k]];
            else cp = B.alt[k] ? &pol.contact_alt() : &pol.contact_main();
            const SoftContact& c = *cp;
            Vec<D> Fel = elastic_normal_force<Law>(c, delta) * nrm;
            if constexpr (Rot) {
              const double kt = Law == NormalLaw::Linear ? c.kt : c.kt * std::sqrt(delta);
              const Vec<D> ft = -kt * L.xi[B.e[k]];
              Fel += ft;
              const Spin<D> mel = lever_moment<D>(nrm, ft);
              if (sleep_i) mi = pair_lever_arm(P.radius(pi), delta) * mel;
              if (sleep_j) tj = -pair_lever_arm(P.radius(pj), delta) * mel;
            }
            if (sleep_i) Fi = Fel;
            if (sleep_j) Fj = Fel;
          }
        }
      }
      if constexpr (kSparse) {
        if constexpr (Rot) pol.own_torque(TQ, pi, Spin<D>(-mi));
        pol.own_force(FF, pi, Fi);
      } else {
        fi += Fi;
        if constexpr (Rot) ti -= mi;
      }
      pol.partner(FF, TQ, pj, Fj, tj);
      if constexpr (Policy::kVirial) pol.virial(F, dx);
    }
    // Rows before the cursor's are done: their walls and integration.
    if constexpr (!kSparse)
      if (cur != kNone && cur < particle(r)) flush();
    for (; due < r; ++due) pol.row_done(particle(due));
  }
  flush();
  for (; due < r1; ++due) pol.row_done(particle(due));
}

}  // namespace matep::soft

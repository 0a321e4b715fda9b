// The batched pair loop (engine/soft/batch.hpp) against the one-contact loop it replaces in TDM
// (engine/soft/forces.hpp pair_rows): on the same lists and bodies both must leave the same forces,
// torques, springs, touching flags and counters, bit for bit, and each particle's force must be
// complete when its row is closed (the fused integration reads it then). The scenes cover what
// the batch does differently: a row longer than a batch (a large grain among small ones), contacts
// that open, begin (with and without the onset weight) or go on with a spring, grains fixed in
// place (the second constants), periodic image shifts, both laws and 2D and 3D. Also: the plain-
// number kinematics the batch uses equal the vector forms bit for bit.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <algorithm>
#include <random>
#include <utility>
#include <vector>

#include "contact/soft.hpp"
#include "engine/soft/batch.hpp"
#include "engine/soft/forces.hpp"

using namespace matep;

namespace {

// How many elements of a and b (Eigen vectors, or (index, vector) pairs) differ in any bit.
template <class V>
std::size_t bit_differences(const std::vector<V>& a, const std::vector<V>& b) {
  if (a.size() != b.size()) return std::max(a.size(), b.size());
  std::size_t n = 0;
  for (std::size_t k = 0; k < a.size(); ++k) {
    if constexpr (requires { a[k].first; })
      n += a[k].first != b[k].first ||
           std::memcmp(a[k].second.data(), b[k].second.data(), sizeof(double) * a[k].second.size()) != 0;
    else
      n += std::memcmp(a[k].data(), b[k].data(), sizeof(double) * a[k].size()) != 0;
  }
  return n;
}

// A policy with everything TDM's has that matters here: constants by fixed flag, counters,
// partner forces applied at once, and a record of each particle's force and torque at row_done.
template <int D>
struct Probe : soft::NoSleepers {
  static constexpr bool kSleepers = false, kNear = false, kVirial = false, kOwners = false, kShifts = true,
                        kSparseRows = false;
  const std::vector<std::uint8_t>& fixed;
  SoftContact c0, c1;
  bool onset_ok = true;
  const Vec<D>* f = nullptr;
  const Spin<D>* tq = nullptr;
  std::vector<Vec<D>> f_done;
  std::vector<Spin<D>> t_done;
  std::vector<std::uint32_t> done_order;
  std::uint64_t begun = 0, opened_n = 0;
  double max_rel = 0.0;

  Probe(const std::vector<std::uint8_t>& fx, const SoftContact& a, const SoftContact& b, bool ok)
      : fixed(fx), c0(a), c1(b), onset_ok(ok) {}
  static constexpr bool kTable = false;
  bool onset() const { return onset_ok; }
  bool clip() const { return c0.clip; }
  bool alt(std::uint32_t i, std::uint32_t j) const { return fixed[i] || fixed[j]; }
  const SoftContact& contact_main() const { return c0; }
  const SoftContact& contact_alt() const { return c1; }
  const SoftContact& contact(std::uint32_t, std::uint32_t i, std::uint32_t j, SoftContact&) const {
    return alt(i, j) ? c1 : c0;
  }
  void began(std::uint32_t, std::uint32_t) { ++begun; }
  void opened(std::uint32_t, std::uint32_t) { ++opened_n; }
  void overlap(double delta, double Rs) {
    if (delta > max_rel * Rs) max_rel = delta / Rs;
  }
  void partner(Vec<D>* FF, Spin<D>* TQ, std::uint32_t j, const Vec<D>& F, const Spin<D>& t) {
    FF[j] -= F;
    TQ[j] += t;
  }
  void virial(const Vec<D>&, const Vec<D>&) {}
  void row_done(std::uint32_t i) {
    done_order.push_back(i);
    f_done[i] = f[i];
    t_done[i] = tq[i];
  }
};

template <int D>
struct Scene {
  std::vector<Vec<D>> x, v, acc, f, xi;
  std::vector<Spin<D>> w, alpha, tq;
  std::vector<double> R;
  std::vector<std::uint8_t> fixed, sh, touch;
  std::vector<std::uint32_t> off, nb;
  std::vector<Vec<D>> shift;
};

// Grains on a jittered lattice of spacing a bit under a diameter (most neighbours overlap), one
// large grain first, overlapping those it covers (its row is longer than a batch), a periodic axis along x whose images carry a
// shift, and lists (j > i) within R_i + R_j + skin. Entries get random touching flags and springs:
// a flagged entry not in contact opens; an unflagged one in contact begins.
template <int D>
Scene<D> make_scene(unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  Scene<D> s;
  const int side = D == 3 ? 9 : 30;
  const double d = 1.0, a = 0.985 * d, L = side * a, skin = 0.1 * d;
  s.x.push_back(Vec<D>::Constant(0.5 * L));
  s.R.push_back(D == 3 ? 4.0 : 10.0);  // it overlaps the lattice grains inside it
  auto lattice = [&](auto&& self, int k, Vec<D> p) -> void {
    if (k == D) {
      for (int c = 0; c < D; ++c) p[c] += 0.02 * d * U(rng);
      s.x.push_back(p);
      s.R.push_back(0.5 * d * (1.0 + 0.02 * U(rng)));
      return;
    }
    for (int n = 0; n < side; ++n) {
      p[k] = (n + 0.5) * a;
      self(self, k + 1, p);
    }
  };
  lattice(lattice, 0, Vec<D>::Zero());
  const std::size_t N = s.x.size();
  // Image shifts: index 0 none, 1 and 2 along +x and -x.
  s.shift = {Vec<D>::Zero(), Vec<D>::Zero(), Vec<D>::Zero()};
  s.shift[1][0] = L;
  s.shift[2][0] = -L;
  s.off.push_back(0);
  for (std::size_t i = 0; i < N; ++i) {
    for (std::size_t j = i + 1; j < N; ++j)
      for (std::uint8_t k = 0; k < 3; ++k) {
        const Vec<D> dx = s.x[i] - s.x[j] + s.shift[k];
        const double cut = s.R[i] + s.R[j] + skin;
        if (dx.squaredNorm() < cut * cut) {
          s.nb.push_back(static_cast<std::uint32_t>(j));
          s.sh.push_back(k);
        }
      }
    s.off.push_back(static_cast<std::uint32_t>(s.nb.size()));
  }
  const std::size_t E = s.nb.size();
  s.touch.resize(E);
  s.xi.resize(E);
  for (std::size_t e = 0; e < E; ++e) {
    s.touch[e] = U(rng) > -0.4;
    s.xi[e] = Vec<D>::Zero();
    if (s.touch[e] && U(rng) > -0.5)
      for (int c = 0; c < D; ++c) s.xi[e][c] = 1e-3 * U(rng);
  }
  for (std::size_t i = 0; i < N; ++i) {
    Vec<D> v, g;
    Spin<D> w, al;
    for (int c = 0; c < D; ++c) {
      v[c] = U(rng);
      g[c] = 50.0 * U(rng);
    }
    for (int c = 0; c < w.size(); ++c) {
      w[c] = 3.0 * U(rng);
      al[c] = 100.0 * U(rng);
    }
    s.v.push_back(v);
    s.acc.push_back(g);
    s.w.push_back(w);
    s.alpha.push_back(al);
    s.f.push_back(Vec<D>::Zero());
    s.tq.push_back(Spin<D>::Zero());
    s.fixed.push_back(U(rng) > 0.9);
  }
  return s;
}

SoftContact constants(NormalLaw law, double mu, double scale) {
  SoftContact c;
  c.normal = law;
  c.kn = law == NormalLaw::Linear ? 2e5 * scale : 3e6 * scale;
  c.gn = 40.0 * scale;
  c.kt = law == NormalLaw::Linear ? 2.0 / 7.0 * c.kn : 5e6 * scale;
  c.gt = 30.0 * scale;
  c.mu = mu;
  return c;
}

template <int D, NormalLaw Law, bool Rot>
void check_same(unsigned seed, bool onset_ok, double mu, double mu_alt) {
  Scene<D> a = make_scene<D>(seed), b = a;
  const std::size_t N = a.x.size();
  const double h = 1e-4;
  auto run = [&](Scene<D>& s, bool batched, Probe<D>& pol) {
    pol.f = s.f.data();
    pol.tq = s.tq.data();
    pol.f_done.assign(N, Vec<D>::Constant(-1.0));
    pol.t_done.assign(N, Spin<D>::Constant(-1.0));
    const auto rows = soft::PairRows<D>::of(nullptr, s.off.data(), s.nb.data(), s.sh.data(), s.touch.data(),
                                            s.xi.data(), s.shift.data());
    const soft::Bodies<D> bodies = soft::bodies_of(s.v, s.acc, s.f, s.w, s.alpha, s.tq);
    const soft::Arrays<D> pos{s.x.data(), s.R.data()};
    if (batched) {
      soft::ContactBatch<D> batch;
      soft::pair_rows_batched<D, Law, Rot>(pos, bodies, rows, 0, static_cast<std::uint32_t>(N), h, pol, batch);
    } else {
      soft::pair_rows<D, Law, Rot, false>(pos, bodies, rows, 0, static_cast<std::uint32_t>(N), h, pol);
    }
  };
  Probe<D> pa(a.fixed, constants(Law, mu, 1.0), constants(Law, mu_alt, 1.7), onset_ok);
  Probe<D> pb(b.fixed, constants(Law, mu, 1.0), constants(Law, mu_alt, 1.7), onset_ok);
  run(a, false, pa);
  run(b, true, pb);

  // The scene exercises what it should.
  ASSERT_GT(a.off[1] - a.off[0], static_cast<std::uint32_t>(soft::ContactBatch<D>::kCap));
  EXPECT_GT(pa.begun, 10u);
  EXPECT_GT(pa.opened_n, 10u);
  EXPECT_GT(pa.max_rel, 0.0);
  // Bit for bit.
  EXPECT_EQ(pa.begun, pb.begun);
  EXPECT_EQ(pa.opened_n, pb.opened_n);
  EXPECT_EQ(pa.max_rel, pb.max_rel);
  EXPECT_EQ(pa.done_order, pb.done_order);
  EXPECT_EQ(a.touch, b.touch);
  std::size_t moving = 0;
  for (std::size_t i = 0; i < N; ++i) {
    moving += a.f[i].squaredNorm() > 0.0;
    // Complete at its row's close: nothing added afterwards.
    EXPECT_EQ(pa.f_done[i], a.f[i]) << i;
  }
  std::size_t differ = bit_differences(a.f, b.f) + bit_differences(pa.f_done, pb.f_done) + bit_differences(a.xi, b.xi);
  if constexpr (Rot) differ += bit_differences(a.tq, b.tq) + bit_differences(pa.t_done, pb.t_done);
  EXPECT_EQ(differ, 0u);
  EXPECT_GT(moving, N / 2);
}

TEST(SoftBatch, HertzWithFrictionSameAsOneContactLoop3D) { check_same<3, NormalLaw::Hertz, true>(1, true, 0.5, 0.5); }
TEST(SoftBatch, HertzFirstEvaluationSameAsOneContactLoop3D) { check_same<3, NormalLaw::Hertz, true>(2, false, 0.3, 0.3); }
TEST(SoftBatch, LinearWithFrictionSameAsOneContactLoop3D) { check_same<3, NormalLaw::Linear, true>(3, true, 0.4, 0.4); }
TEST(SoftBatch, LinearFrictionlessSameAsOneContactLoop3D) { check_same<3, NormalLaw::Linear, false>(4, true, 0.0, 0.0); }
TEST(SoftBatch, ViscoelasticSameAsOneContactLoop3D) { check_same<3, NormalLaw::Viscoelastic, true>(5, true, 0.2, 0.2); }
TEST(SoftBatch, HertzWithFrictionSameAsOneContactLoop2D) { check_same<2, NormalLaw::Hertz, true>(6, true, 0.5, 0.5); }
TEST(SoftBatch, LinearFrictionlessSameAsOneContactLoop2D) { check_same<2, NormalLaw::Linear, false>(7, true, 0.0, 0.0); }
// Friction on for moving pairs, off for pairs with a fixed grain: the frictionless case (no
// spring: no tangential force) and the sliding case side by side in one batch.
TEST(SoftBatch, MixedFrictionlessAndSlidingSameAsOneContactLoop3D) {
  check_same<3, NormalLaw::Linear, true>(8, true, 0.4, 0.0);
}

// A policy with everything the hybrid's soft set has (engine/hybrid/hybrid.cpp SoftPolicy): rows
// of owners (a particle's entries may lie in several rows), each entry's constants from a table,
// near and touching flags, sleepers pushed by the springs only and woken when approached, a
// particle's own force added per contact and spilled when another thread owns it, the partner's
// likewise (a fixed partner gets nothing), and the virial.
template <int D>
struct HybridProbe {
  static constexpr bool kSleepers = true, kNear = true, kVirial = true, kOwners = true, kShifts = true,
                        kSparseRows = true, kTable = true;
  const std::vector<SoftContact>& tab;
  const std::vector<std::uint32_t>& cidx;
  const std::vector<std::uint8_t>& fixed;
  const std::vector<std::uint8_t>& asleep_;
  const std::vector<std::uint8_t>& own;  // 1: this thread's particle
  bool onset_ok = true;
  double skin = 0.05;
  std::vector<std::uint8_t> touching_f, near_f, lost_f;
  std::vector<std::pair<std::uint32_t, Vec<D>>> spill_f;
  std::vector<std::pair<std::uint32_t, Spin<D>>> spill_t;
  std::uint64_t begun = 0;
  double vir = 0.0;
  bool fixed_j = false;

  HybridProbe(const std::vector<SoftContact>& t, const std::vector<std::uint32_t>& ci, const std::vector<std::uint8_t>& fx,
              const std::vector<std::uint8_t>& sl, const std::vector<std::uint8_t>& ow, bool ok)
      : tab(t), cidx(ci), fixed(fx), asleep_(sl), own(ow), onset_ok(ok), touching_f(fx.size()), near_f(fx.size()),
        lost_f(fx.size()) {}
  bool onset() const { return onset_ok; }
  bool clip() const { return tab[0].clip; }
  const SoftContact* table() const { return tab.data(); }
  std::uint32_t contact_index(std::uint32_t e) const { return cidx[e]; }
  const SoftContact& contact(std::uint32_t e, std::uint32_t, std::uint32_t, SoftContact&) const { return tab[cidx[e]]; }
  void began(std::uint32_t, std::uint32_t) { ++begun; }
  void opened(std::uint32_t i, std::uint32_t j) {
    if (asleep_[i]) lost_f[i] = 1;
    if (asleep_[j]) lost_f[j] = 1;
  }
  void overlap(double, double) {}
  std::uint64_t touching_n = 0, near_n = 0;
  void touching(std::uint32_t i, std::uint32_t j) {
    ++touching_n;
    touching_f[i] = touching_f[j] = 1;
  }
  void near(std::uint32_t i, std::uint32_t j) {
    ++near_n;
    if (!fixed[j]) near_f[i] = near_f[j] = 1;
  }
  double near_skin() const { return skin; }
  bool any_asleep() const { return true; }
  bool asleep(std::uint32_t i) const { return asleep_[i] != 0; }
  bool approached(double un) const { return un < -0.3; }
  void wake(std::uint32_t k) { lost_f[k] = 1; }
  void own_force(Vec<D>* FF, std::uint32_t i, const Vec<D>& f) {
    if (own[i]) FF[i] += f;
    else spill_f.push_back({i, f});
  }
  void own_torque(Spin<D>* TQ, std::uint32_t i, const Spin<D>& t) {
    if (own[i]) TQ[i] += t;
    else spill_t.push_back({i, t});
  }
  void partner(Vec<D>* FF, Spin<D>* TQ, std::uint32_t j, const Vec<D>& f, const Spin<D>& t) {
    fixed_j = fixed[j] != 0;
    if (fixed_j) return;
    if (!own[j]) {
      spill_f.push_back({j, Vec<D>(-f)});
      spill_t.push_back({j, t});
      return;
    }
    FF[j] -= f;
    TQ[j] += t;
  }
  void virial(const Vec<D>& F, const Vec<D>& dx) {
    if (!fixed_j) vir += F.dot(dx);
  }
  void row_done(std::uint32_t) {}
};

// The same pairs as make_scene's lists, in the hybrid's layout: rows in a shuffled order of owners,
// the large grain's entries split over two rows far apart; entries' constants drawn from a table
// of three; a fifth of the grains asleep and a third owned by another thread.
template <int D, NormalLaw Law, bool Rot>
void check_same_hybrid(unsigned seed, bool onset_ok, double mu) {
  Scene<D> a = make_scene<D>(seed);
  const std::size_t N = a.x.size();
  std::mt19937_64 rng(seed + 100);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  // Rows: (owner, entries) in a new order.
  std::vector<std::pair<std::uint32_t, std::vector<std::uint32_t>>> rows;
  for (std::uint32_t i = 0; i < N; ++i) {
    std::vector<std::uint32_t> ents;
    for (std::uint32_t e = a.off[i]; e < a.off[i + 1]; ++e) ents.push_back(e);
    if (i == 0) {  // the large grain: two rows
      const std::size_t half = ents.size() / 2;
      rows.push_back({i, std::vector<std::uint32_t>(ents.begin(), ents.begin() + half)});
      rows.push_back({i, std::vector<std::uint32_t>(ents.begin() + half, ents.end())});
    } else {
      rows.push_back({i, ents});
    }
  }
  std::shuffle(rows.begin(), rows.end(), rng);
  std::vector<std::uint32_t> owner, off{0}, nb, cidx;
  std::vector<std::uint8_t> sh, touch;
  std::vector<Vec<D>> xi;
  for (const auto& [i, ents] : rows) {
    owner.push_back(i);
    for (const std::uint32_t e : ents) {
      nb.push_back(a.nb[e]);
      sh.push_back(a.sh[e]);
      touch.push_back(a.touch[e]);
      xi.push_back(a.xi[e]);
      cidx.push_back(static_cast<std::uint32_t>(U(rng) * 3.0));
    }
    off.push_back(static_cast<std::uint32_t>(nb.size()));
  }
  std::vector<SoftContact> tab = {constants(Law, mu, 1.0), constants(Law, 0.0, 1.7), constants(Law, mu, 0.6)};
  std::vector<std::uint8_t> asleep(N), own(N);
  for (std::size_t i = 0; i < N; ++i) {
    asleep[i] = U(rng) < 0.2;
    own[i] = U(rng) < 0.67;
  }
  struct Out {
    std::vector<Vec<D>> f, xi;
    std::vector<Spin<D>> tq;
    std::vector<std::uint8_t> touch;
  };
  const double h = 1e-4;
  auto run = [&](bool batched, HybridProbe<D>& pol) {
    Out o{a.f, xi, a.tq, touch};
    const auto L = soft::PairRows<D>::of(owner.data(), off.data(), nb.data(), sh.data(), o.touch.data(), o.xi.data(),
                                         a.shift.data());
    const soft::Bodies<D> bodies = soft::bodies_of(a.v, a.acc, o.f, a.w, a.alpha, o.tq);
    const soft::Arrays<D> pos{a.x.data(), a.R.data()};
    const auto R = static_cast<std::uint32_t>(owner.size());
    if (batched) {
      soft::ContactBatch<D> batch;
      soft::pair_rows_batched<D, Law, Rot>(pos, bodies, L, 0, R, h, pol, batch);
    } else {
      soft::pair_rows<D, Law, Rot, false>(pos, bodies, L, 0, R, h, pol);
    }
    return o;
  };
  HybridProbe<D> pa(tab, cidx, a.fixed, asleep, own, onset_ok), pb(tab, cidx, a.fixed, asleep, own, onset_ok);
  const Out oa = run(false, pa), ob = run(true, pb);

  // The scene exercises what it should: contacts begin, sleepers wake or lose a contact, grains
  // are near without touching (more near calls than touching ones), forces spill.
  EXPECT_GT(pa.begun, 10u);
  std::size_t lost = 0;
  for (std::size_t i = 0; i < N; ++i) lost += pa.lost_f[i];
  EXPECT_GT(lost, 5u);
  EXPECT_GT(pa.near_n, pa.touching_n + 10);
  EXPECT_GT(pa.spill_f.size(), 100u);
  EXPECT_NE(pa.vir, 0.0);
  // Bit for bit.
  EXPECT_EQ(pa.begun, pb.begun);
  EXPECT_EQ(pa.touching_n, pb.touching_n);
  EXPECT_EQ(pa.near_n, pb.near_n);
  EXPECT_EQ(pa.touching_f, pb.touching_f);
  EXPECT_EQ(pa.near_f, pb.near_f);
  EXPECT_EQ(pa.lost_f, pb.lost_f);
  EXPECT_EQ(std::memcmp(&pa.vir, &pb.vir, sizeof(double)), 0);
  EXPECT_EQ(oa.touch, ob.touch);
  ASSERT_EQ(pa.spill_f.size(), pb.spill_f.size());
  ASSERT_EQ(pa.spill_t.size(), pb.spill_t.size());
  std::size_t differ = bit_differences(pa.spill_f, pb.spill_f) + bit_differences(pa.spill_t, pb.spill_t) +
                       bit_differences(oa.f, ob.f) + bit_differences(oa.xi, ob.xi);
  if constexpr (Rot) differ += bit_differences(oa.tq, ob.tq);
  EXPECT_EQ(differ, 0u);
}

TEST(SoftBatch, HybridPolicyHertzWithFrictionSameAsOneContactLoop3D) {
  check_same_hybrid<3, NormalLaw::Hertz, true>(21, true, 0.5);
}
TEST(SoftBatch, HybridPolicyLinearFrictionlessSameAsOneContactLoop3D) {
  check_same_hybrid<3, NormalLaw::Linear, false>(22, true, 0.0);
}
TEST(SoftBatch, HybridPolicyLinearWithFrictionFirstEvaluation2D) {
  check_same_hybrid<2, NormalLaw::Linear, true>(23, false, 0.4);
}
TEST(SoftBatch, HybridPolicyViscoelasticSameAsOneContactLoop2D) {
  check_same_hybrid<2, NormalLaw::Viscoelastic, true>(24, true, 0.3);
}

// The plain-number kinematics of the batch equal the vector forms bit for bit.
TEST(SoftBatch, PlainKinematicsEqualVectorForms) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> U(-3.0, 3.0);
  for (int trial = 0; trial < 1000; ++trial) {
    Vec<3> vi, vj, n, f;
    Spin<3> wi, wj;
    for (int c = 0; c < 3; ++c) {
      vi[c] = U(rng);
      vj[c] = U(rng);
      n[c] = U(rng);
      f[c] = U(rng);
      wi[c] = U(rng);
      wj[c] = U(rng);
    }
    const double li = U(rng), lj = U(rng);
    const Vec<3> cv = contact_velocity<3>(vi, wi, li, vj, wj, lj, n);
    double out[3];
    contact_velocity_to<3>(vi.data(), wi.data(), li, vj.data(), wj.data(), lj, n.data(), out);
    for (int c = 0; c < 3; ++c) ASSERT_EQ(out[c], cv[c]);
    const Spin<3> m = lever_moment<3>(n, f);
    lever_moment_to<3>(n.data(), f.data(), out);
    for (int c = 0; c < 3; ++c) ASSERT_EQ(out[c], m[c]);
    const Vec<2> v2i(vi[0], vi[1]), v2j(vj[0], vj[1]), n2(n[0], n[1]), f2(f[0], f[1]);
    Spin<2> w2i, w2j;
    w2i[0] = wi[0];
    w2j[0] = wj[0];
    const Vec<2> cv2 = contact_velocity<2>(v2i, w2i, li, v2j, w2j, lj, n2);
    contact_velocity_to<2>(v2i.data(), w2i.data(), li, v2j.data(), w2j.data(), lj, n2.data(), out);
    for (int c = 0; c < 2; ++c) ASSERT_EQ(out[c], cv2[c]);
    lever_moment_to<2>(n2.data(), f2.data(), out);
    ASSERT_EQ(out[0], lever_moment<2>(n2, f2)[0]);
  }
}

}  // namespace

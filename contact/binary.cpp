// Reference integrator for one soft collision; see binary.hpp for the scheme.
#include "contact/binary.hpp"
#include "contact/roots.hpp"

#include <algorithm>
#include <cmath>

#include "contact/timestep.hpp"

namespace matep {

namespace {

template <int D>
struct State {
  Vec<D> xi = Vec<D>::Zero(), xj = Vec<D>::Zero();
  Vec<D> vi = Vec<D>::Zero(), vj = Vec<D>::Zero();
  Vec<D> ai = Vec<D>::Zero(), aj = Vec<D>::Zero();
  Spin<D> wi = Spin<D>::Zero(), wj = Spin<D>::Zero();
  Spin<D> bi = Spin<D>::Zero(), bj = Spin<D>::Zero();  // angular accelerations
  ContactHistory<D> hist;
  double t = 0.0;
  // Diagnostics of the force evaluated in this state.
  double delta = 0.0, Fn = 0.0, Fraw = 0.0, Ft = 0.0;
};

template <int D>
class Collision {
 public:
  Collision(const SoftContact& c, bool wall, const Vec<D>& wall_normal, const BinaryBody<D>& i,
            const BinaryBody<D>& j)
      : c_(c),
        wall_(wall),
        N_(wall_normal),
        Ri_(i.radius),
        Rj_(wall ? 0.0 : j.radius),
        mi_(i.mass),
        mj_(wall ? kPlane : j.mass) {
    const double q = inertia_factor<D>();
    Ii_ = q * mi_ * Ri_ * Ri_;
    Ij_ = wall ? kPlane : q * mj_ * Rj_ * Rj_;
  }

  // Forces in state o (positions already set), with half-step velocities (vh*, wh*) for the
  // spring increment over a step of length h and predicted velocities (vp*, wp*) for damping.
  // close: evaluate the contact law even at delta <= 0 (with delta = 0), the limit from inside.
  void forces(State<D>& o, const Vec<D>& vhi, const Spin<D>& whi, const Vec<D>& vhj,
              const Spin<D>& whj, const Vec<D>& vpi, const Spin<D>& wpi, const Vec<D>& vpj,
              const Spin<D>& wpj, double h, bool close) const {
    Vec<D> n;
    double li, lj;
    if (wall_) {
      n = N_;
      o.delta = Ri_ - o.xi.dot(N_);
      li = wall_lever_arm(Ri_, o.delta);
      lj = 0.0;
    } else {
      const Vec<D> d = o.xi - o.xj;
      const double dist = d.norm();
      n = d / dist;
      o.delta = Ri_ + Rj_ - dist;
      li = pair_lever_arm(Ri_, o.delta);
      lj = pair_lever_arm(Rj_, o.delta);
    }
    Vec<D> F = Vec<D>::Zero();
    Spin<D> ti = Spin<D>::Zero(), tj = Spin<D>::Zero();
    o.Fn = o.Fraw = o.Ft = 0.0;
    if (o.delta > 0.0 || close) {
      ContactKinematics<D> k;
      k.delta = std::max(o.delta, 0.0);
      k.n = n;
      k.v = contact_velocity<D>(vpi, wpi, li, vpj, wpj, lj, n);
      k.dxi = h * contact_velocity<D>(vhi, whi, li, vhj, whj, lj, n);
      const ContactForce<D> f = soft_contact_force<D>(c_, k, o.hist);
      F = f.force;
      ti = contact_torque<D>(n, f.tangential, li);
      tj = contact_torque<D>(n, f.tangential, lj);
      o.Fn = f.normal;
      o.Fraw = f.normal_raw;
      o.Ft = f.tangential.norm();
    } else {
      o.hist.xi.setZero();
    }
    o.ai = F / mi_;
    o.bi = ti / Ii_;
    if (wall_) {
      o.aj.setZero();
      o.bj.setZero();
    } else {
      o.aj = -F / mj_;
      o.bj = tj / Ij_;
    }
  }

  // First-contact state: forces with delta = 0 treated as contact (a dashpot acts at once).
  void start(State<D>& s) const {
    forces(s, s.vi, s.wi, s.vj, s.wj, s.vi, s.wi, s.vj, s.wj, 0.0, true);
  }

  State<D> step(const State<D>& s, double h, bool close) const {
    State<D> o = s;
    const Vec<D> vhi = s.vi + 0.5 * h * s.ai, vhj = s.vj + 0.5 * h * s.aj;
    const Spin<D> whi = s.wi + 0.5 * h * s.bi, whj = s.wj + 0.5 * h * s.bj;
    o.xi = s.xi + h * vhi;
    if (!wall_) o.xj = s.xj + h * vhj;
    const Vec<D> vpi = s.vi + h * s.ai, vpj = s.vj + h * s.aj;
    const Spin<D> wpi = s.wi + h * s.bi, wpj = s.wj + h * s.bj;
    forces(o, vhi, whi, vhj, whj, vpi, wpi, vpj, wpj, h, close);
    o.vi = vhi + 0.5 * h * o.ai;
    o.wi = whi + 0.5 * h * o.bi;
    if (!wall_) {
      o.vj = vhj + 0.5 * h * o.aj;
      o.wj = whj + 0.5 * h * o.bj;
    }
    o.t = s.t + h;
    return o;
  }

  // The step length x in (0, h] at which value(step(s, x)) crosses from > 0 to <= 0, located by
  // regula falsi with the Illinois modification; returns the state on the <= 0 side.
  template <class Value>
  State<D> locate(const State<D>& s, double fa, State<D> ob, double fb, double h, bool close,
                  Value value) const {
    illinois_root(
        [&](double x) {
          const State<D> ox = step(s, x, close);
          const double fx = value(ox);
          if (fx <= 0.0) ob = ox;
          return fx;
        },
        0.0, fa, h, fb, 1e-14 * h, 200);
    return ob;
  }

  bool wall() const { return wall_; }

 private:
  SoftContact c_;
  bool wall_;
  Vec<D> N_;
  double Ri_, Rj_, mi_, mj_, Ii_ = 0.0, Ij_ = 0.0;
};

template <int D>
BinaryResult<D> run(const SoftLaw& law_in, const PairParams& p, bool wall, const Vec<D>& n,
                    const BinaryBody<D>& bi, const BinaryBody<D>& bj, const BinaryOptions& opt) {
  BinaryResult<D> r;
  const SoftLaw law = law_in.resolved();  // the damping ratio once
  const SoftContact c = soft_contact(law, p);
  const Collision<D> col(c, wall, n, bi, bj);

  State<D> s;
  s.vi = bi.v;
  s.wi = bi.w;
  if (wall) {
    s.xi = bi.radius * n;  // plane through the origin
  } else {
    s.xi = bi.radius * n;
    s.xj = -bj.radius * n;
    s.vj = bj.v;
    s.wj = bj.w;
  }
  r.v_i = s.vi;
  r.v_j = s.vj;
  r.w_i = s.wi;
  r.w_j = s.wj;
  r.x_i = s.xi;
  r.x_j = s.xj;
  const double vn = (s.vi - s.vj).dot(n);
  if (!(vn < 0.0)) {
    r.separated = true;
    return r;
  }
  const double tc = soft_contact_time(law, p, -vn);
  const double h = opt.dt > 0.0 ? opt.dt : tc / opt.steps_per_contact;
  r.dt = h;
  if (!(h > 0.0) || !std::isfinite(h)) return r;  // impossible parameters: separated = false
  // Graded start: the damping forces of the Hertz (delta^1/4) and viscoelastic (delta^1/2) laws
  // are not smooth at first contact, which makes uniform steps converge like h^1.25 only. Over a
  // window W = t_c/20 the step boundaries follow t_k = W (k/K)^2 with K = ceil(2W/h) (the last
  // graded step is about h); the local errors then sum to O(h^2). Smooth laws (linear, or
  // undamped Hertz, where uniform steps keep Verlet's time symmetry) use uniform steps.
  const bool graded = c.normal != NormalLaw::Linear && (c.gn > 0.0 || c.gt > 0.0);
  const double W = graded ? std::min(tc / 20.0, 1e6 * h) : 0.0;
  const long K = static_cast<long>(std::ceil(2.0 * W / h));
  auto step_length = [&](long k) {  // k = 0, 1, ...
    if (k >= K) return h;
    const double a = static_cast<double>(k) / K, b = static_cast<double>(k + 1) / K;
    return W * (b * b - a * a);
  };
  col.start(s);

  auto account = [&](const State<D>& o) {
    r.max_force = std::max(r.max_force, o.Fn);
    r.max_overlap = std::max(r.max_overlap, o.delta);
    r.min_normal = std::min(r.min_normal, o.Fn);
    r.max_friction_excess = std::max(r.max_friction_excess, o.Ft - c.mu * std::abs(o.Fn));
    if (opt.record) r.trace.push_back({o.t, o.delta, o.Fn, o.Ft});
  };
  account(s);

  bool force_ended = false;
  while (r.steps < opt.max_steps) {
    const double hk = step_length(r.steps);
    State<D> o = col.step(s, hk, false);
    ++r.steps;
    if (o.delta <= 0.0) {
      o = col.step(s, hk, true);
      o = col.locate(s, s.delta > 0.0 ? s.delta : 1e-300, o, o.delta, hk, true,
                     [](const State<D>& x) { return x.delta; });
      account(o);
      r.separated = true;
      s = o;
      break;
    }
    if (c.clip && !force_ended && s.Fraw > 0.0 && o.Fraw <= 0.0) {
      o = col.locate(s, s.Fraw, o, o.Fraw, hk, false, [](const State<D>& x) { return x.Fraw; });
      force_ended = true;
      r.force_time = o.t;
    }
    account(o);
    s = o;
  }
  r.contact_time = s.t;
  if (!force_ended) r.force_time = s.t;
  r.v_i = s.vi;
  r.w_i = s.wi;
  r.x_i = s.xi;
  if (!wall) {
    r.v_j = s.vj;
    r.w_j = s.wj;
    r.x_j = s.xj;
  }
  return r;
}

}  // namespace

template <int D>
BinaryResult<D> collide_pair(const SoftLaw& law, const BinaryBody<D>& i, const BinaryBody<D>& j,
                             const Vec<D>& n, const BinaryOptions& opt) {
  const PairParams p = pair_params(i.material, i.radius, i.mass, j.material, j.radius, j.mass);
  return run<D>(law, p, false, n, i, j, opt);
}

template <int D>
BinaryResult<D> collide_wall(const SoftLaw& law, const BinaryBody<D>& i, const Vec<D>& normal,
                             const SoftMaterial& wall, const BinaryOptions& opt) {
  const PairParams p = wall_params(i.material, i.radius, i.mass, wall);
  return run<D>(law, p, true, normal, i, i, opt);
}

template BinaryResult<2> collide_pair<2>(const SoftLaw&, const BinaryBody<2>&, const BinaryBody<2>&,
                                         const Vec<2>&, const BinaryOptions&);
template BinaryResult<3> collide_pair<3>(const SoftLaw&, const BinaryBody<3>&, const BinaryBody<3>&,
                                         const Vec<3>&, const BinaryOptions&);
template BinaryResult<2> collide_wall<2>(const SoftLaw&, const BinaryBody<2>&, const Vec<2>&,
                                         const SoftMaterial&, const BinaryOptions&);
template BinaryResult<3> collide_wall<3>(const SoftLaw&, const BinaryBody<3>&, const Vec<3>&,
                                         const SoftMaterial&, const BinaryOptions&);

}  // namespace matep

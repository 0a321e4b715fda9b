#include "engine/soft_plan.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "contact/timestep.hpp"

namespace matep {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

std::string key(const Material& m, const char* k) { return fmt::format("material.{}.{}", m.name, k); }

NormalLaw law_kind(const Material& m) {
  if (m.contact == "linear") return NormalLaw::Linear;
  if (m.contact == "hertz") return NormalLaw::Hertz;
  if (m.contact == "viscoelastic") return NormalLaw::Viscoelastic;
  // Unset: Hertz when the elastic constants are given, else linear when a stiffness is.
  if (m.young && m.poisson) return NormalLaw::Hertz;
  if (m.stiffness) return NormalLaw::Linear;
  throw std::invalid_argument(fmt::format(
      "{}: not set, and neither young/poisson (Hertz) nor stiffness (linear) is given; a soft-sphere "
      "run needs a contact law for every particle material",
      key(m, "contact")));
}

const char* law_name(NormalLaw k) {
  switch (k) {
    case NormalLaw::Linear: return "linear";
    case NormalLaw::Hertz: return "hertz";
    case NormalLaw::Viscoelastic: return "viscoelastic";
  }
  return "?";
}

// The constant e a linear or Hertz law needs from a material.
double constant_e(const Material& m, NormalLaw kind) {
  if (m.restitution.model != Restitution::Model::Constant)
    throw std::invalid_argument(fmt::format(
        "{}: a velocity-dependent restitution model cannot drive the {} contact law, which takes "
        "one constant e (use e = VALUE, or contact = \"viscoelastic\" whose e falls with impact speed)",
        key(m, "restitution"), law_name(kind)));
  if (!(m.restitution.e > 0.0))
    throw std::invalid_argument(fmt::format(
        "{}: e = {} cannot be reached by a soft contact law (a dashpot gives 0 < e <= 1)",
        key(m, "restitution"), m.restitution.e));
  return m.restitution.e;
}

// Mean of two optional values; a value set on one side only is used alone.
double mix(const std::optional<double>& a, const std::optional<double>& b, double fallback) {
  if (a && b) return 0.5 * (*a + *b);
  if (a) return *a;
  if (b) return *b;
  return fallback;
}

void require_elastic(const Material& m, NormalLaw kind) {
  if (!m.young)
    throw std::invalid_argument(fmt::format("{}: missing; contact = \"{}\" needs young and poisson",
                                            key(m, "young"), law_name(kind)));
  if (!m.poisson)
    throw std::invalid_argument(fmt::format("{}: missing; contact = \"{}\" needs young and poisson",
                                            key(m, "poisson"), law_name(kind)));
}

// The scene's one rolling-resistance model: every material that sets rolling_friction > 0 names the
// same one (unset: "epsd"); rolling or rolling_damping without rolling_friction, and rolling_damping
// with the constant-torque model, are refused.
RollingModel rolling_model_of(const std::vector<Material>& materials) {
  RollingModel model = RollingModel::None;
  const Material* first = nullptr;
  for (const Material& m : materials) {
    if (!m.rolling_friction) {
      if (!m.rolling.empty() || m.rolling_damping)
        throw std::invalid_argument(fmt::format("{}: missing; {} needs the rolling-resistance coefficient mu_r",
                                                key(m, "rolling_friction"),
                                                m.rolling.empty() ? key(m, "rolling_damping") : key(m, "rolling")));
      continue;
    }
    const RollingModel mm = m.rolling == "constant" ? RollingModel::Constant : RollingModel::Epsd;
    if (mm == RollingModel::Constant && m.rolling_damping)
      throw std::invalid_argument(fmt::format(
          "{}: set, but rolling = \"constant\" has no dashpot (only rolling = \"epsd\" uses it)",
          key(m, "rolling_damping")));
    if (*m.rolling_friction == 0.0) continue;
    if (first && mm != model)
      throw std::invalid_argument(fmt::format(
          "{}: \"{}\" differs from material.{}.rolling = \"{}\"; a run uses one rolling-resistance model",
          key(m, "rolling"), mm == RollingModel::Constant ? "constant" : "epsd", first->name,
          model == RollingModel::Constant ? "constant" : "epsd"));
    model = mm;
    if (!first) first = &m;
  }
  return model;
}

template <int D>
SoftLaw make_law(NormalLaw kind, const Material& a, const Material& b, RollingModel rolling) {
  SoftLaw l;
  l.normal = kind;
  l.friction = mix(a.friction, b.friction, 0.0);
  // Rolling resistance mixed like mu (Ai et al. 2011 use eta_r = 0.3: the default damping ratio).
  l.rolling_friction = mix(a.rolling_friction, b.rolling_friction, 0.0);
  l.rolling = l.rolling_friction > 0.0 ? rolling : RollingModel::None;
  l.rolling_damping = mix(a.rolling_damping, b.rolling_damping, 0.3);
  const double q = inertia_factor<D>();
  switch (kind) {
    case NormalLaw::Linear: {
      const double ea = constant_e(a, kind);
      const double eb = constant_e(b, kind);
      l.restitution = 0.5 * (ea + eb);
      const double ka = *a.stiffness;
      // Two springs of one material give that material's k; different ones their harmonic mean.
      l.stiffness = b.stiffness ? 2.0 * ka * *b.stiffness / (ka + *b.stiffness) : ka;
      if (a.dissipation || b.dissipation) l.gamma_n = mix(a.dissipation, b.dissipation, 0.0);
      const double beta0 = mix(a.tangential_restitution, b.tangential_restitution, 1.0);
      // k_t/k_n from the sticking tangential restitution beta0 (contact/soft.hpp); beta0 = 1 (the
      // default) gives k_t/k_n = 2/7 for spheres and 1/3 for disks at e = 1.
      l.kt_ratio = linear_kt_ratio_for(beta0, q, 1.0);
      break;
    }
    case NormalLaw::Hertz: {
      const double ea = constant_e(a, kind);
      const double eb = constant_e(b, kind);
      l.restitution = 0.5 * (ea + eb);
      l.damping = HertzDamping::Exact;
      break;
    }
    case NormalLaw::Viscoelastic: {
      if (!a.dissipation)
        throw std::invalid_argument(fmt::format(
            "{}: missing; contact = \"viscoelastic\" needs the dissipation time A [s] (>= 0)",
            key(a, "dissipation")));
      l.dissipation_time = b.dissipation ? 0.5 * (*a.dissipation + *b.dissipation) : *a.dissipation;
      break;
    }
  }
  return l.resolved();
}

}  // namespace

template <int D>
SoftPlan plan_soft(const System<D>& sys) {
  SoftPlan plan;
  const int M = static_cast<int>(sys.materials.size());
  plan.materials = M;
  std::vector<char> used(M, 0), wall_used(M, 0);
  std::vector<double> rmin(M, kInf), rmax(M, 0.0);
  // Fixed grains (System::fixed): per material, the smallest radius of a moving and of a fixed grain
  // (a contact of the two has m* = the moving grain's mass).
  std::vector<double> rmin_moving(M, kInf), rmin_fixed(M, kInf);
  for (std::size_t i = 0; i < sys.size(); ++i) {
    const int m = sys.material[i];
    used[m] = 1;
    rmin[m] = std::min(rmin[m], sys.radius[i]);
    rmax[m] = std::max(rmax[m], sys.radius[i]);
    double& r = sys.is_fixed(i) ? rmin_fixed[m] : rmin_moving[m];
    r = std::min(r, sys.radius[i]);
  }
  for (const Inlet<D>& in : sys.inlets) {  // the grains an inlet will insert (engine/inlet.hpp)
    const int m = in.material;
    used[m] = 1;
    rmin[m] = std::min(rmin[m], in.rmin);
    rmax[m] = std::max(rmax[m], in.rmax);
    rmin_moving[m] = std::min(rmin_moving[m], in.rmin);
  }
  for (const auto& w : sys.walls) wall_used[w.material] = 1;

  // Law kind per particle material; all particle materials must share one.
  std::vector<NormalLaw> kind(M, NormalLaw::Hertz);
  int first = -1;
  for (int a = 0; a < M; ++a) {
    if (!used[a]) continue;
    const Material& m = sys.materials[a];
    kind[a] = law_kind(m);
    if (first < 0) first = a;
    if (kind[a] != kind[first])
      throw std::invalid_argument(fmt::format(
          "{}: \"{}\" differs from material.{}.contact = \"{}\"; all particle materials of a soft-sphere "
          "run use one contact law",
          key(m, "contact"), law_name(kind[a]), sys.materials[first].name, law_name(kind[first])));
    if (kind[a] == NormalLaw::Linear && !m.stiffness)
      throw std::invalid_argument(
          fmt::format("{}: missing; contact = \"linear\" needs the normal stiffness k_n [N/m]", key(m, "stiffness")));
    if (kind[a] != NormalLaw::Linear) require_elastic(m, kind[a]);
  }
  if (first < 0) return plan;  // no particles
  const NormalLaw K = kind[first];
  plan.law = K;
  for (int a = 0; a < M; ++a) {
    const Material& m = sys.materials[a];
    if (!wall_used[a] || used[a] || m.contact.empty()) continue;
    if (law_kind(m) != K)
      throw std::invalid_argument(fmt::format(
          "{}: \"{}\" (a wall material) differs from the particles' contact law \"{}\"", key(m, "contact"),
          m.contact, law_name(K)));
  }
  if (K != NormalLaw::Linear) {
    for (int a = 0; a < M; ++a) {
      const Material& m = sys.materials[a];
      if (wall_used[a] && !used[a] && (m.young.has_value() != m.poisson.has_value()))
        require_elastic(m, K);  // a wall with only one of the two constants is a typo
    }
  }

  plan.elastic.assign(M, SoftMaterial{});
  for (int a = 0; a < M; ++a) {
    const Material& m = sys.materials[a];
    if (m.young && m.poisson) plan.elastic[a] = {*m.young, *m.poisson};
  }
  const RollingModel roll = rolling_model_of(sys.materials);
  plan.inertia_factor = inertia_factor<D>();
  plan.laws.assign(static_cast<std::size_t>(M) * M, SoftLaw{});
  for (int a = 0; a < M; ++a)
    for (int b = 0; b < M; ++b)
      if (used[a] && used[b])
        plan.laws[a * M + b] = make_law<D>(K, sys.materials[a], sys.materials[b], roll);
  const int W = static_cast<int>(sys.walls.size());
  plan.wall_laws.assign(static_cast<std::size_t>(W) * M, SoftLaw{});
  plan.wall_elastic.assign(W, SoftMaterial::rigid());
  for (int w = 0; w < W; ++w) {
    const Material& wm = sys.materials[sys.walls[w].material];
    if (wm.young && wm.poisson && K != NormalLaw::Linear) plan.wall_elastic[w] = {*wm.young, *wm.poisson};
    for (int a = 0; a < M; ++a)
      if (used[a]) plan.wall_laws[w * M + a] = make_law<D>(K, sys.materials[a], wm, roll);
  }
  for (const auto& l : plan.laws) plan.friction = plan.friction || l.friction > 0.0;
  for (const auto& l : plan.wall_laws) plan.friction = plan.friction || l.friction > 0.0;
  for (const auto* laws : {&plan.laws, &plan.wall_laws})
    for (const auto& l : *laws) plan.rolling = plan.rolling || l.rolling != RollingModel::None;
  if (plan.rolling) plan.rolling_model = roll;
  plan.friction = plan.friction || plan.rolling;  // rolling resistance acts on the spins

  // Largest expected normal impact speed: twice the fastest particle (head-on), plus the fall
  // through the domain's height along gravity, plus the fastest spin's surface speed.
  double vmax = 0.0;
  for (std::size_t i = 0; i < sys.size(); ++i) {
    double s = sys.v[i].norm();
    if (!sys.w.empty()) s += sys.w[i].norm() * sys.radius[i];
    vmax = std::max(vmax, s);
  }
  for (const Inlet<D>& in : sys.inlets)  // an inlet's mean velocity and four standard deviations
    vmax = std::max(vmax, in.velocity.norm() + 4.0 * in.spread * std::sqrt(static_cast<double>(D)));
  const double g = sys.gravity.norm();
  double H = 0.0;
  if (g > 0.0)
    for (int k = 0; k < D; ++k) H += std::abs(sys.gravity[k]) / g * (sys.upper[k] - sys.lower[k]);
  // An oscillating wall adds its peak speed 2 pi f |A|.
  double wall_speed = 0.0;
  for (const auto& w : sys.walls) wall_speed = std::max(wall_speed, w.geometry().max_speed());
  plan.impact_speed = 2.0 * vmax + std::sqrt(2.0 * g * H) + wall_speed;

  const double q = inertia_factor<D>();
  plan.contact_time = kInf;
  plan.rayleigh_time = kInf;
  plan.max_stable_dt = kInf;
  auto consider = [&](const SoftContact& c, const PairParams& p, const SoftLaw& law, const std::string& what) {
    const double v = plan.impact_speed;
    if (law.normal == NormalLaw::Linear || v > 0.0)
      plan.contact_time = std::min(plan.contact_time, soft_contact_time(law, p, v));
    const double delta = law.normal == NormalLaw::Linear ? 0.0 : (v > 0.0 ? hertz_max_overlap(p, v) : 0.0);
    const double h = verlet_max_step(c, delta, q);
    if (h < plan.max_stable_dt) {
      plan.max_stable_dt = h;
      plan.limiting = what;
    }
  };
  for (int a = 0; a < M; ++a) {
    if (!used[a]) continue;
    const Material& ma = sys.materials[a];
    if (ma.young && ma.poisson)
      plan.rayleigh_time = std::min(plan.rayleigh_time, rayleigh_time(rmin[a], ma.density, *ma.young, *ma.poisson));
    const double mass_a = ma.density * ball_volume<D>(rmin[a]);
    for (int b = 0; b < M; ++b) {
      if (!used[b]) continue;
      const double mass_b = sys.materials[b].density * ball_volume<D>(rmin[b]);
      const SoftContact c = pair_contact(plan, a, rmin[a], mass_a, b, rmin[b], mass_b);
      PairParams p{c.normal == NormalLaw::Linear ? 0.0 : effective_young(plan.elastic[a].young, plan.elastic[a].poisson,
                                                                     plan.elastic[b].young, plan.elastic[b].poisson),
                   0.0, effective_radius(rmin[a], rmin[b]), effective_mass(mass_a, mass_b)};
      consider(c, p, plan.laws[a * M + b],
               fmt::format("material.{} - material.{} contact at radius {}", ma.name, sys.materials[b].name,
                           std::min(rmin[a], rmin[b])));
    }
    for (int w = 0; w < W; ++w) {
      const SoftContact c = wall_contact(plan, w, a, rmin[a], mass_a);
      PairParams p{c.normal == NormalLaw::Linear
                       ? 0.0
                       : effective_young(plan.elastic[a].young, plan.elastic[a].poisson, plan.wall_elastic[w].young,
                                         plan.wall_elastic[w].poisson),
                   0.0, rmin[a], mass_a};
      consider(c, p, plan.wall_laws[w * M + a],
               fmt::format("material.{} - wall.{} contact at radius {}", ma.name, sys.walls[w].name, rmin[a]));
    }
  }
  // A moving grain against a fixed one: the pair's m* is the moving grain's mass (the fixed grain is
  // infinitely heavy), which lengthens the contact and changes the Verlet limit (Hertz: the overlap
  // at the impact speed grows with m*).
  if (!sys.fixed.empty()) {
    for (int a = 0; a < M; ++a) {
      if (!(rmin_moving[a] < kInf)) continue;
      const Material& ma = sys.materials[a];
      const double mass_a = ma.density * ball_volume<D>(rmin_moving[a]);
      for (int b = 0; b < M; ++b) {
        if (!(rmin_fixed[b] < kInf)) continue;
        const SoftContact c = pair_contact(plan, a, rmin_moving[a], mass_a, b, rmin_fixed[b], kPlane);
        PairParams p{c.normal == NormalLaw::Linear ? 0.0 : effective_young(plan.elastic[a].young, plan.elastic[a].poisson,
                                                                       plan.elastic[b].young, plan.elastic[b].poisson),
                     0.0, effective_radius(rmin_moving[a], rmin_fixed[b]), mass_a};
        consider(c, p, plan.laws[a * M + b],
                 fmt::format("material.{} - fixed material.{} contact at radius {}", ma.name, sys.materials[b].name,
                             std::min(rmin_moving[a], rmin_fixed[b])));
      }
    }
  }
  plan.default_dt = kSoftStepFraction * std::min(plan.contact_time, plan.rayleigh_time);
  if (!std::isfinite(plan.default_dt)) plan.default_dt = 0.0;  // nothing sets a time scale
  return plan;
}

SoftContact pair_contact(const SoftPlan& plan, int ma, double Ri, double mi, int mb, double Rj, double mj) {
  const SoftLaw& law = plan.laws[static_cast<std::size_t>(ma) * plan.materials + mb];
  PairParams p;
  p.Rstar = effective_radius(Ri, Rj);
  p.mstar = effective_mass(mi, mj);
  // Each body's inertia about the contact point, (q + 1) m R^2 (a fixed grain's is infinite).
  const double q1 = plan.inertia_factor + 1.0;
  p.Ir = 1.0 / (1.0 / (q1 * mi * Ri * Ri) + 1.0 / (q1 * mj * Rj * Rj));
  if (law.normal != NormalLaw::Linear) {
    const SoftMaterial& a = plan.elastic[ma];
    const SoftMaterial& b = plan.elastic[mb];
    p.Estar = effective_young(a.young, a.poisson, b.young, b.poisson);
    p.Gstar = effective_shear(a.young, a.poisson, b.young, b.poisson);
  }
  return soft_contact(law, p);
}

SoftContact wall_contact(const SoftPlan& plan, int w, int ma, double R, double m) {
  const SoftLaw& law = plan.wall_laws[static_cast<std::size_t>(w) * plan.materials + ma];
  PairParams p;
  p.Rstar = R;
  p.mstar = m;
  p.Ir = (plan.inertia_factor + 1.0) * m * R * R;
  if (law.normal != NormalLaw::Linear) {
    const SoftMaterial& a = plan.elastic[ma];
    const SoftMaterial& b = plan.wall_elastic[w];
    p.Estar = effective_young(a.young, a.poisson, b.young, b.poisson);
    p.Gstar = effective_shear(a.young, a.poisson, b.young, b.poisson);
  }
  return soft_contact(law, p);
}

template SoftPlan plan_soft<2>(const System<2>&);
template SoftPlan plan_soft<3>(const System<3>&);

}  // namespace matep

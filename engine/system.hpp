// The validated description of a system the engine runs: geometry, materials, walls and the
// initial particle state. io/ builds it from a scene file; tests build it directly.
#pragma once


#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <numbers>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "contact/outlet.hpp"
#include "contact/plane.hpp"
#include "contact/restitution.hpp"
#include "contact/vec.hpp"
#include "contact/wall.hpp"
#include "engine/grid.hpp"
#include "engine/inlet.hpp"
#include "engine/state_archive.hpp"

namespace matep {

struct Material {
  std::string name;
  double density = 1.0;
  Restitution restitution;
  std::optional<double> young;     // Pa (TDM contact laws)
  std::optional<double> poisson;   // -
  std::optional<double> friction;  // Coulomb mu (rough spheres, TDM tangential)
  // Rolling resistance of the soft contacts (contact/soft.hpp rolling_torque): mu_r, the model
  // ("" unset | "constant" | "epsd") and the Epsd dashpot's damping ratio eta_r.
  std::optional<double> rolling_friction;
  std::string rolling;
  std::optional<double> rolling_damping;
  // Soft-sphere (TDM) contact law, all optional; unset = the engine's default.
  std::string contact;                           // "" (unset) | "linear" | "hertz" | "viscoelastic"
  std::optional<double> stiffness;               // normal stiffness k_n (> 0)
  std::optional<double> dissipation;             // normal damping gamma_n (>= 0)
  std::optional<double> tangential_restitution;  // beta_t in [-1, 1]
  // Rough hard spheres (EDM, engine/rough_rules.hpp): "" (unset) | "walton" | "constant" | "fem_fit".
  std::string tangential;
};

// A wall: a shape (contact/wall.hpp: a plane, ...) and the material it is made of.
template <int D>
struct Wall {
  std::string name;
  int material = 0;
  std::shared_ptr<const WallShape<D>> shape;

  const WallShape<D>& geometry() const { return *shape; }
};

// A plane wall through `point` with unit `normal` (contact/plane.hpp), oscillating as
// p(t) = point + amplitude sin(2 pi frequency t) when both are set.
template <int D>
Wall<D> plane_wall(std::string name, const Vec<D>& point, const Vec<D>& normal, int material = 0,
                   const Vec<D>& amplitude = Vec<D>::Zero(), double frequency = 0.0) {
  return {std::move(name), material, std::make_shared<PlaneWall<D>>(point, normal, amplitude, frequency)};
}

// An outlet ([outlet.NAME]): a region where a grain whose centre enters is taken out of the run
// (contact/outlet.hpp). face >= 0 marks an open face of the domain, 2 axis + (1 for the upper face):
// its region is the half space beyond that face, and a grain whose centre crosses it is removed, not
// "escaped".
template <int D>
struct Outlet {
  std::string name;
  OutletRegion<D> region;
  int face = -1;
};

// Ball volume: 4/3 pi r^3 in 3D, pi r^2 in 2D (disks of unit thickness).
template <int D>
double ball_volume(double r);

template <int D>
struct System {
  static constexpr int dimension = D;
  Vec<D> lower = Vec<D>::Zero();
  Vec<D> upper = Vec<D>::Ones();
  std::array<bool, D> periodic{};
  Vec<D> gravity = Vec<D>::Zero();
  std::vector<Material> materials;
  std::vector<Wall<D>> walls;
  std::vector<Outlet<D>> outlets;  // empty: a closed system (a grain leaving the domain stops the run)
  std::vector<Inlet<D>> inlets;    // engine/inlet.hpp; their grains get the ids after the initial ones

  // Initial particle state, indexed by particle id.
  std::vector<Vec<D>> x;
  std::vector<Vec<D>> v;
  std::vector<Spin<D>> w;
  std::vector<double> radius;
  std::vector<int> material;
  // Fixed grains ([particles.NAME] fixed = true): immovable spheres that take part in contacts but
  // are never moved (zero velocity and spin, no gravity). Empty: none is fixed (no memory).
  std::vector<std::uint8_t> fixed;

  std::size_t size() const { return x.size(); }
  // The smallest and largest radius of the run: of the grains at the start and of those the inlets
  // insert (infinity and 0 when there are none).
  std::pair<double, double> radius_range() const {
    double lo = std::numeric_limits<double>::infinity(), hi = 0.0;
    for (const double r : radius) {
      lo = std::min(lo, r);
      hi = std::max(hi, r);
    }
    for (const Inlet<D>& in : inlets) {
      lo = std::min(lo, in.rmin);
      hi = std::max(hi, in.rmax);
    }
    return {lo, hi};
  }
  // x wrapped into the domain along its periodic axes (engine/grid.hpp wrap_periodic).
  Vec<D> wrapped(Vec<D> x) const {
    for (int k = 0; k < D; ++k)
      if (periodic[k]) x[k] = wrap_periodic(x[k], lower[k], upper[k]);
    return x;
  }
  // The outlet (index into outlets) whose region holds x (wrapped on the periodic axes), or -1.
  int outlet_at(const Vec<D>& x) const {
    const Vec<D> y = wrapped(x);
    for (std::size_t o = 0; o < outlets.size(); ++o)
      if (outlets[o].region.inside(y)) return static_cast<int>(o);
    return -1;
  }
  // Whether a grain of radius R centred at x (wrapped here on the periodic axes) at time t lies
  // inside the domain on its closed axes, in no outlet, and clear of every wall: where an inlet may
  // put it (the engines then check the grains).
  bool clear_of_boundaries(Vec<D>& x, double R, double t) const {
    x = wrapped(x);
    for (int k = 0; k < D; ++k)
      if (!periodic[k] && (x[k] - R < lower[k] || x[k] + R > upper[k])) return false;
    if (outlet_at(x) >= 0) return false;
    for (const Wall<D>& w : walls)
      if (!(w.geometry().at(x, R, t).gap > 0.0)) return false;
    return true;
  }
  bool is_fixed(std::size_t i) const { return !fixed.empty() && fixed[i] != 0; }
  std::size_t fixed_count() const {
    std::size_t n = 0;
    for (const std::uint8_t f : fixed) n += f != 0;
    return n;
  }
  double volume() const {
    double V = 1.0;
    for (int k = 0; k < D; ++k) V *= upper[k] - lower[k];
    return V;
  }
  // The volume of the moving (not fixed) grains among the first n over the domain's: what the
  // event-driven "auto" rules judge by (engine/edm/neighbours.hpp).
  double moving_packing(std::size_t n) const {
    double v = 0.0;
    for (std::size_t i = 0; i < n; ++i)
      if (!is_fixed(i)) v += ball_volume<D>(radius[i]);
    return v / volume();
  }
  double moving_packing() const { return moving_packing(size()); }
  // Mass of particle i: density times volume (3D) or times area per unit thickness (2D).
  double mass(std::size_t i) const;
  // Throws std::invalid_argument unless `fixed` is empty or has one flag per particle and every
  // fixed grain is at rest (zero velocity and spin): the engines' precondition.
  void check_fixed() const;
};

// Settings of an event-driven run (everything not part of the physical system).
struct EdmSettings {
  double start_time = 0.0;  // the time of the system's state (run.start_time): walls move in absolute time
  double end_time = 1.0;
  double tc = 0.0;                // TC model (Luding & McNamara 1998); 0 = off
  double thermo_interval = 0.0;   // 0 = only t = 0 and end
  double snapshot_interval = 0.0; // 0 = none; else snapshots at t = 0, every interval and the end
  std::uint64_t max_events = std::numeric_limits<std::uint64_t>::max();
  // Inelastic-collapse watch (engine/edm/collapse.hpp): a particle whose smoothed collision
  // interval falls this many decades below its recent level stops the run with status "collapse"
  // (the hybrid turns it soft instead); 0 = off.
  double collapse_decades = 4.0;
  // Pair candidates from per-particle neighbour lists with shells (engine/edm/core.hpp) instead of
  // the cells around each particle; pure EDM only. lists_auto: lists where engine/edm/neighbours.hpp
  // lists_pay says so. shell: the shells' size (ball radius, or cube half-width under gravity) in
  // largest diameters.
  bool lists = false;
  bool lists_auto = false;
  double shell = 0.125;
  // Re-sorting (engine/edm/core.hpp): the particles' storage put in space order (the cells' Z
  // order) at the start and again every `resort` particle events per particle; 0 = never; < 0 =
  // where engine/edm/neighbours.hpp resort_pays says so. Pure EDM only.
  double resort = -1.0;
  // When set and it turns true (a signal handler may set it), the run stops between two events
  // with status "interrupted": the state is that after the last event handled.
  const std::atomic<bool>* stop = nullptr;
  // Checkpoints (engine/state_archive.hpp): where the run's states go, and one to resume from.
  const CheckpointHooks* checkpoint = nullptr;
};

}  // namespace matep

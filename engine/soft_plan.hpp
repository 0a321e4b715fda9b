// From a System's materials to the soft-sphere (TDM) contact laws of every material pair, and the
// time step: the default (a fraction of the shortest Rayleigh and contact times) and the Verlet
// stability limit a user's step must stay below. README "Soft-sphere contact laws" documents the
// material keys and the mixing rule implemented here.
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

#include "contact/soft.hpp"
#include "engine/result.hpp"
#include "engine/system.hpp"

namespace matep {

// Default time step = kSoftStepFraction * min(Rayleigh time, contact time at the largest expected
// impact speed). The seed report asks for at most 2% of the shortest collision time
// (docs/references.md §S.3.2.3).
inline constexpr double kSoftStepFraction = 0.02;

struct SoftPlan {
  int materials = 0;
  NormalLaw law = NormalLaw::Hertz;  // the one normal law of every pair and wall contact
  // laws[a * materials + b]: resolved law (damping ratio fixed) between particle materials a, b.
  std::vector<SoftLaw> laws;
  // Elastic constants per material (young = 0 where the law does not need them).
  std::vector<SoftMaterial> elastic;
  // wall_laws[w * materials + a]: wall w against a particle of material a; wall_elastic[w].
  std::vector<SoftLaw> wall_laws;
  std::vector<SoftMaterial> wall_elastic;
  bool friction = false;       // some pair or wall law has mu > 0 or rolling resistance (rotation is integrated)
  bool rolling = false;        // some pair or wall law has rolling resistance
  RollingModel rolling_model = RollingModel::None;  // the one rolling model of the scene
  double inertia_factor = 0.4; // I / (m R^2) of the grains (2/5 spheres, 1/2 disks)
  double impact_speed = 0.0;   // largest expected normal impact speed used for the times below
  double contact_time = 0.0;   // shortest contact duration over pairs and walls (inf if none)
  double rayleigh_time = 0.0;  // shortest Rayleigh time over materials with elastic constants (inf if none)
  double default_dt = 0.0;     // kSoftStepFraction * min(contact_time, rayleigh_time)
  double max_stable_dt = 0.0;  // Verlet limit of the stiffest contact at the largest expected overlap
  std::string limiting;        // which contact sets max_stable_dt (for messages)
};

// Throws std::invalid_argument with a message of the form "material.NAME.KEY: ..." for materials
// that cannot make a soft contact (a Hertz law without young/poisson, a linear law without
// stiffness, a velocity-dependent restitution model with a law that takes a constant e, two
// materials with different laws, ...). Walls whose material lacks elastic constants are rigid.
template <int D>
SoftPlan plan_soft(const System<D>& sys);

// The plan's figures in a run's SoftStats (default and limiting steps, contact and Rayleigh times,
// impact speed).
inline void record_plan(SoftStats& s, const SoftPlan& plan) {
  s.default_dt = plan.default_dt;
  s.max_stable_dt = plan.max_stable_dt;
  s.contact_time = plan.contact_time;
  s.rayleigh_time = plan.rayleigh_time;
  s.impact_speed = plan.impact_speed;
}

// The contact constants of one pair, for particles of radius Ri, Rj and mass mi, mj.
SoftContact pair_contact(const SoftPlan& plan, int ma, double Ri, double mi, int mb, double Rj, double mj);
// Particle (material ma, radius R, mass m) against wall w.
SoftContact wall_contact(const SoftPlan& plan, int w, int ma, double R, double m);

}  // namespace matep

// Observers hang off the drivers: event log, thermo sampler, progress. The engine never prints;
// it reports here. Hooks that a run does not need cost one predictable branch.
#pragma once

#include <cstdint>
#include <vector>

#include "contact/vec.hpp"
#include "engine/result.hpp"

namespace matep {

enum class EventKind : std::uint8_t {
  PairCollision = 1,
  WallCollision = 2,
  CellCrossing = 3,
  ToSoft = 4,  // hybrid: particle switched to TDM
  ToHard = 5,  // hybrid: particle switched back to EDM
  Outflow = 6, // a grain left through an outlet (i: its id, j: the outlet's index)
  Inflow = 7,  // a grain entered from an inlet (i: its id, j: the inlet's index)
};

// A grain inserted by an inlet (engine/inlet.hpp): its id, radius, mass and state as it entered.
template <int D>
struct InflowRecord {
  double time = 0.0;
  std::uint32_t id = 0;
  std::uint32_t inlet = 0;  // index into System::inlets
  double mass = 0.0, radius = 0.0;
  Vec<D> x = Vec<D>::Zero(), v = Vec<D>::Zero();
};

// A grain taken out of the run by an outlet (one row of outflow.csv): its state as it entered.
// TDM and the hybrid's soft grains give the velocity of their last half step.
template <int D>
struct OutflowRecord {
  double time = 0.0;
  std::uint32_t id = 0;
  std::uint32_t outlet = 0;  // index into System::outlets
  double mass = 0.0;
  Vec<D> x = Vec<D>::Zero(), v = Vec<D>::Zero();
  Spin<D> w = Spin<D>::Zero();
};

// One resolved collision, with the state just before and just after it. For a wall collision
// j is the wall index and mj, vj_*, wj_* are zero.
template <int D>
struct CollisionRecord {
  double time = 0.0;
  EventKind kind = EventKind::PairCollision;
  std::uint32_t i = 0, j = 0;
  double mi = 0.0, mj = 0.0;
  double e = 1.0;  // normal restitution applied
  Vec<D> normal = Vec<D>::Zero();
  Vec<D> vi_before = Vec<D>::Zero(), vj_before = Vec<D>::Zero();
  Vec<D> vi_after = Vec<D>::Zero(), vj_after = Vec<D>::Zero();
  Spin<D> wi_before = Spin<D>::Zero(), wj_before = Spin<D>::Zero();
  Spin<D> wi_after = Spin<D>::Zero(), wj_after = Spin<D>::Zero();
};

// A thermodynamic sample (one row of thermo.csv).
struct ThermoSample {
  double time = 0.0;
  double kinetic_energy = 0.0;
  double rotational_energy = 0.0;
  double potential_energy = 0.0;  // -sum m g.x
  double elastic_energy = 0.0;    // energy stored in soft contacts (0 for hard spheres)
  double temperature = 0.0;       // (1/N) sum m v^2 / d
  std::uint64_t collisions = 0;   // cumulative pair + wall collisions (soft: contacts begun)
  double pressure = 0.0;          // kinetic + collisional virial over the last interval
  std::uint64_t soft = 0;         // particles in the soft set (awake or asleep): EDM 0, TDM all
  std::uint64_t grains = 0;       // grains present
  std::uint64_t grains_out = 0;   // grains removed by outlets so far
  double mass_out = 0.0;          // their mass
  std::uint64_t grains_in = 0;    // grains inserted by inlets so far
  double mass_in = 0.0;           // their mass
  // Per wall, the mean force of the grains on it and its torque about the wall's anchor over the
  // interval since the previous sample (engine/wall_loads.hpp): six numbers per wall, in wall order
  // (empty at t = 0).
  std::vector<double> wall_loads;
};

// One contact at a snapshot (Snapshot::contacts, written when an observer wants_contacts()).
//   kind 1, a soft contact (TDM, the hybrid's soft set): its force at the snapshot time, from the
//     state then (positions, full-step velocities and the contact's spring), the contact law
//     evaluated without growing the spring (engine/soft/contact_rows.hpp);
//   kind 0, hard collisions (EDM, the hybrid's hard grains): the impulses of the pair's (or the
//     grain and wall's) collisions since the previous snapshot, divided by that interval: the mean
//     force over it (engine/impulse_tally.hpp), and `collisions` the number of them.
// The force is the one on grain i; a pair's other grain j receives its opposite. i < j for pairs;
// j = -1 and wall = the wall's index for a wall contact (wall = -1 for a pair). fn is the normal
// part (along the line of centres), ft the tangential part; point is the contact point (kind 0:
// that of the last collision in the interval); overlap the contact's overlap (kind 0: zero).
template <int D>
struct ContactRow {
  std::uint8_t kind = 1;
  std::uint32_t collisions = 0;
  std::uint32_t i = 0;
  std::int64_t j = -1;
  std::int32_t wall = -1;
  double overlap = 0.0;
  Vec<D> point = Vec<D>::Zero(), fn = Vec<D>::Zero(), ft = Vec<D>::Zero();
};

// A contact row's grains renamed by id(k), i < j kept for pairs: swapping them turns the force on
// i into the force on the other grain (an engine that renumbers its grains).
template <int D, class Id>
void rename_contact(ContactRow<D>& c, Id&& id) {
  c.i = static_cast<std::uint32_t>(id(c.i));
  if (c.j < 0) return;
  c.j = static_cast<std::int64_t>(id(static_cast<std::uint64_t>(c.j)));
  if (c.j < static_cast<std::int64_t>(c.i)) {
    const std::uint32_t i = static_cast<std::uint32_t>(c.j);
    c.j = c.i;
    c.i = i;
    c.fn = -c.fn;
    c.ft = -c.ft;
  }
}

// The state of every particle at one time, in particle-id order (a snapshot). Once grains have
// left through an outlet the rows are those present, in increasing id, and id gives each row's
// particle id (empty: row k is particle k).
template <int D>
struct Snapshot {
  double time = 0.0;
  std::vector<std::uint32_t> id;
  std::vector<Vec<D>> x, v;
  std::vector<Spin<D>> w;  // empty when the system has no spins
  std::vector<double> radius;
  std::vector<std::uint8_t> mode;  // hybrid: 0 hard, 1 soft, 3 asleep; 4 fixed (any method; empty: none of these)
  std::vector<std::int32_t> cluster;  // hybrid: soft cluster id, -1 for hard (empty: none)
  bool with_contacts = false;           // contacts were asked for (an observer wants_contacts())
  std::vector<ContactRow<D>> contacts;  // then: the contacts at this time (ContactRow)
};

template <int D>
class Observer {
 public:
  virtual ~Observer() = default;
  virtual bool wants_collisions() const { return false; }
  virtual void on_collision(const CollisionRecord<D>&) {}
  virtual void on_sample(const ThermoSample&) {}
  virtual bool wants_snapshots() const { return false; }
  virtual void on_snapshot(const Snapshot<D>&) {}
  // Whether the snapshots should carry the contacts (Snapshot::contacts).
  virtual bool wants_contacts() const { return false; }
  virtual void on_outflow(const OutflowRecord<D>&) {}
  virtual void on_inflow(const InflowRecord<D>&) {}
  // Called every few thousand events with the simulated time and the events so far.
  virtual void on_progress(double /*time*/, std::uint64_t /*events*/) {}
};

}  // namespace matep

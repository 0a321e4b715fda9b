// Test helpers for open flows: an observer that records every grain in and out and every thermo row
// (and, in a hybrid run, which grains were soft when they left), and the five walls of an open-top
// bin in scene text.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "engine/observer.hpp"

namespace matep::test {

template <int D>
struct FlowRecorder final : Observer<D> {
  std::vector<InflowRecord<D>> in;
  std::vector<OutflowRecord<D>> out;
  std::vector<ThermoSample> rows;
  std::map<std::uint32_t, bool> soft;  // hybrid: the grains' modes from the switch records
  std::size_t out_soft = 0;            // grains removed while soft
  bool wants_collisions() const override { return true; }
  void on_collision(const CollisionRecord<D>& c) override {
    if (c.kind == EventKind::ToSoft) soft[c.i] = true;
    if (c.kind == EventKind::ToHard) soft[c.i] = false;
  }
  void on_inflow(const InflowRecord<D>& r) override { in.push_back(r); }
  void on_outflow(const OutflowRecord<D>& r) override {
    out.push_back(r);
    out_soft += soft[r.id];
  }
  void on_sample(const ThermoSample& s) override { rows.push_back(s); }
};

// [wall.*] tables of glass: a lid at z = top and four side walls around [0, w]^2 (3D).
inline std::string bin_walls(const std::string& w, const std::string& top) {
  return "[wall.lid]\ntype = \"plane\"\npoint = [0.0, 0.0, " + top +
         "]\nnormal = [0.0, 0.0, -1.0]\nmaterial = \"glass\"\n"
         "[wall.left]\ntype = \"plane\"\npoint = [0.0, 0.0, 0.0]\nnormal = [1.0, 0.0, 0.0]\nmaterial = \"glass\"\n"
         "[wall.right]\ntype = \"plane\"\npoint = [" + w +
         ", 0.0, 0.0]\nnormal = [-1.0, 0.0, 0.0]\nmaterial = \"glass\"\n"
         "[wall.front]\ntype = \"plane\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 1.0, 0.0]\nmaterial = \"glass\"\n"
         "[wall.back]\ntype = \"plane\"\npoint = [0.0, " + w +
         ", 0.0]\nnormal = [0.0, -1.0, 0.0]\nmaterial = \"glass\"\n";
}

// A bin of glass (Hertz, e = 0.6, mu = 0.4) 0.05 m square under a lid at 0.12 m, its floor at
// z = 0 holed at the centre by a disk of radius `hole` (the domain reaches 0.03 m below it), under
// gravity: the run to `end_time` in TDM, `particles` its [particles.*] tables.
inline std::string holed_bin(const std::string& end_time, const std::string& hole, const std::string& particles) {
  return R"([run]
dimension = 3
method = "tdm"
end_time = )" + end_time + R"(
seed = 3
gravity = [0.0, 0.0, -9.81]
[domain]
lower = [0.0, 0.0, -0.03]
upper = [0.05, 0.05, 0.12]
[material.glass]
density = 2500.0
restitution = 0.6
contact = "hertz"
young = 1.0e7
poisson = 0.3
friction = 0.4
)" + particles + R"([wall.floor]
type = "plane"
point = [0.025, 0.025, 0.0]
normal = [0.0, 0.0, 1.0]
hole = {shape = "disk", radius = )" + hole + R"(}
material = "glass"
)" + bin_walls("0.05", "0.12");
}

// The holed bin with 20 grains on its floor, fed from a shower inlet and drained through the
// floor's hole (tests/analytic/test_inlets.cpp: the accounts balance in each method;
// tests/unit/test_edm_resort.cpp).
inline const std::string kFeed = holed_bin("0.3", "0.008", R"([particles.bed]
material = "glass"
radius = 0.0025
count = 20
region = {lower = [0.0, 0.0, 0.0], upper = [0.05, 0.05, 0.03]}
)") + R"([inlet.shower]
type = "disk"
point = [0.025, 0.025, 0.1]
normal = [0.0, 0.0, 1.0]
radius = 0.02
material = "glass"
grain_radius = [0.002, 0.0025]
rate = 1500
velocity = [0.0, 0.0, -0.5]
spread = 0.05
[outlet.bottom]
type = "face"
face = "z-"
)";

}  // namespace matep::test

// Outlets in the three engines (System::outlets): a grain whose centre enters an outlet's region
// leaves the run. EDM (and the hybrid's hard grains) remove it at the exact entry time of its
// flight (an event); TDM and the hybrid's soft grains at the first step that ends inside.
// Conservation: grains present + grains removed = grains at the start at every thermo row, mass
// likewise, and every removed grain is reported once.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <variant>

#include "engine/edm.hpp"
#include "engine/hybrid.hpp"
#include "engine/tdm.hpp"
#include "io/scene.hpp"
#include "tests/support/flows.hpp"

namespace matep {
namespace {

template <int D>
using Recorder = test::FlowRecorder<D>;

constexpr double kG = 9.81;

// One grain (radius 0.01, a linear soft material) at x0 with velocity v0 in the closed unit box.
template <int D>
System<D> one_grain(const Vec<D>& x0, const Vec<D>& v0, const Vec<D>& g) {
  System<D> s;
  s.lower = Vec<D>::Zero();
  s.upper = Vec<D>::Ones();
  s.gravity = g;
  Material m;
  m.name = "glass";
  m.density = 2500.0;
  m.contact = "linear";
  m.stiffness = 1e4;
  m.restitution = Restitution::constant(0.9);
  s.materials.push_back(m);
  s.x = {x0};
  s.v = {v0};
  s.w = {Spin<D>::Zero()};
  s.radius = {0.01};
  s.material = {0};
  return s;
}

template <int D>
Outlet<D> outlet(const OutletRegion<D>& r, int face = -1) {
  return Outlet<D>{"out", r, face};
}

Vec<3> v3(double a, double b, double c) { return Vec<3>(a, b, c); }

// EDM: the grain leaves at the exact entry time of its flight into each kind of region.
TEST(Outlets, EdmRemovesAtTheExactEntryTime) {
  struct Case {
    const char* what;
    Vec<3> x0, v0, g;
    Outlet<3> o;
    double t, z_exit;
  };
  const double tf = std::sqrt(2.0 * 0.6 / kG);  // a fall from z = 0.8 to z = 0.2
  const std::vector<Case> cases = {
      {"plane, falling", v3(0.5, 0.5, 0.8), v3(0, 0, 0), v3(0, 0, -kG),
       outlet<3>(OutletRegion<3>::half_space(v3(0, 0, 0.2), v3(0, 0, 1))), tf, 0.2},
      {"tilted plane, flying", v3(0.2, 0.5, 0.5), v3(2, 0, 0), v3(0, 0, 0),
       outlet<3>(OutletRegion<3>::half_space(v3(0.6, 0.5, 0.5), v3(-1, 0, 0))), 0.2, 0.5},
      {"box", v3(0.1, 0.5, 0.5), v3(2, 0, 0), v3(0, 0, 0),
       outlet<3>(OutletRegion<3>::box(v3(0.6, 0.4, 0.4), v3(0.9, 0.6, 0.6))), 0.25, 0.5},
      {"cylinder, end", v3(0.1, 0.5, 0.5), v3(2, 0, 0), v3(0, 0, 0),
       outlet<3>(OutletRegion<3>::cylinder(v3(0.7, 0.5, 0.5), v3(1, 0, 0), 0.1, 0.1)), 0.3, 0.5},
      {"cylinder, side, falling", v3(0.5, 0.5, 0.8), v3(0, 0, 0), v3(0, 0, -kG),
       outlet<3>(OutletRegion<3>::cylinder(v3(0.2, 0.5, 0.1), v3(1, 0, 0), 0.1, 0.6)), tf, 0.2},
      {"open face", v3(0.5, 0.5, 0.8), v3(0, 0, 0), v3(0, 0, -kG),
       outlet<3>(OutletRegion<3>::half_space(v3(0, 0, 0), v3(0, 0, 1)), 4), std::sqrt(2.0 * 0.8 / kG), 0.0},
  };
  for (const auto& c : cases) {
    for (const bool hybrid : {false, true}) {
      System<3> s = one_grain<3>(c.x0, c.v0, c.g);
      s.outlets = {c.o};
      Recorder<3> rec;
      EdmSettings set;
      set.end_time = 1.0;
      set.thermo_interval = 0.05;
      const RunResult<3> r = hybrid ? run_hybrid<3>(s, set, HybridSettings{}, {&rec})
                                    : run_edm<3>(s, set, QueueKind::Calendar, {&rec});
      SCOPED_TRACE(std::string(c.what) + (hybrid ? " (hybrid)" : " (edm)"));
      EXPECT_EQ(r.status, "ok") << r.message;
      ASSERT_EQ(rec.out.size(), 1u);
      const auto& o = rec.out[0];
      EXPECT_NEAR(o.time, c.t, 1e-12 * c.t);
      EXPECT_EQ(o.id, 0u);
      EXPECT_EQ(o.outlet, 0u);
      EXPECT_NEAR(o.mass, s.mass(0), 1e-18);
      // Where and how fast it entered: the flight's state at the entry time.
      const Vec<3> x = c.x0 + c.v0 * c.t + 0.5 * c.t * c.t * c.g, v = c.v0 + c.g * c.t;
      EXPECT_LT((o.x - x).norm(), 1e-11);
      EXPECT_LT((o.v - v).norm(), 1e-11);
      if (c.g.norm() > 0) {
        EXPECT_NEAR(o.x[2], c.z_exit, 1e-11);
      }
      // Gone from the final state and from every later row.
      EXPECT_TRUE(r.x.empty());
      EXPECT_EQ(r.grains_out, 1u);
      EXPECT_NEAR(r.mass_out, s.mass(0), 1e-18);
      for (const auto& row : rec.rows) {
        const bool gone = row.time >= c.t;
        EXPECT_EQ(row.grains, gone ? 0u : 1u) << row.time;
        EXPECT_EQ(row.grains_out, gone ? 1u : 0u) << row.time;
        if (gone) {
          EXPECT_EQ(row.kinetic_energy, 0.0);
        }
      }
    }
  }
}

// 2D: a disk enters a circular outlet region (the time where the centre reaches the circle).
TEST(Outlets, EdmDiskRegionIn2D) {
  System<2> s = one_grain<2>(Vec<2>(0.1, 0.5), Vec<2>(1.0, 0.0), Vec<2>::Zero());
  s.outlets = {outlet<2>(OutletRegion<2>::cylinder(Vec<2>(0.7, 0.6), Vec<2>::Zero(), 0.2, 0.0))};
  Recorder<2> rec;
  EdmSettings set;
  set.end_time = 1.0;
  const RunResult<2> r = run_edm<2>(s, set, QueueKind::Heap, {&rec});
  ASSERT_EQ(rec.out.size(), 1u);
  // x(t) = 0.1 + t meets (x - 0.7)^2 + 0.1^2 = 0.2^2 at x = 0.7 - sqrt(0.03).
  EXPECT_NEAR(rec.out[0].time, 0.6 - std::sqrt(0.03), 1e-13);
  EXPECT_EQ(r.grains_out, 1u);
}

// TDM: removed at the first step that ends with the centre inside; reported with that position.
TEST(Outlets, TdmRemovesAtTheFirstStepInside) {
  System<3> s = one_grain<3>(v3(0.5, 0.5, 0.8), v3(0, 0, 0), v3(0, 0, -kG));
  s.outlets = {outlet<3>(OutletRegion<3>::half_space(v3(0, 0, 0.2), v3(0, 0, 1)))};
  Recorder<3> rec;
  TdmSettings set;
  set.end_time = 0.5;
  set.dt = 1e-4;
  set.thermo_interval = 0.05;
  const RunResult<3> r = run_tdm<3>(s, set, {&rec});
  EXPECT_EQ(r.status, "ok") << r.message;
  ASSERT_EQ(rec.out.size(), 1u);
  const double tf = std::sqrt(2.0 * 0.6 / kG);
  EXPECT_GE(rec.out[0].time, tf);
  EXPECT_LT(rec.out[0].time, tf + set.dt * (1 + 1e-9));
  EXPECT_LT(rec.out[0].x[2], 0.2);
  EXPECT_GT(rec.out[0].x[2], 0.2 - kG * (tf + set.dt) * set.dt);
  EXPECT_TRUE(r.x.empty());
  EXPECT_EQ(rec.rows.back().grains, 0u);
  EXPECT_EQ(rec.rows.back().grains_out, 1u);
}

// A bin with a holed floor drained through the open lower face of the domain and through a box in
// one corner of the floor (where the hybrid's grains are soft: a bed forms there), in all three
// methods: the bookkeeping holds at every row and at the end.
const std::string kDrain = test::holed_bin("0.35", "0.01", R"([particles.beads]
material = "glass"
radius = 0.0025
count = 150
arrangement = "random"
region = {lower = [0.0, 0.0, 0.005], upper = [0.05, 0.05, 0.11]}
)") + R"([outlet.bottom]
type = "face"
face = "z-"
[outlet.corner]
type = "box"
lower = [0.0, 0.0, -0.01]
upper = [0.012, 0.012, 0.004]
)";

TEST(Outlets, ConservationInEveryMethod) {
  for (const int mode : {0, 1, 2, 3}) {  // EDM with cells, EDM with neighbour lists, TDM, the hybrid
    const Method m = mode <= 1 ? Method::Edm : mode == 2 ? Method::Tdm : Method::Hybrid;
    SCOPED_TRACE(std::string(method_name(m)) + (mode == 1 ? ", lists" : ""));
    // EDM: an elastic, frictionless gas (the inelastic bed is the dense case EDM cannot run alone).
    std::vector<std::string> set{std::string("run.method=") + method_name(m)};
    if (m == Method::Edm) {
      set.push_back("material.glass.restitution=1.0");
      set.push_back("material.glass.friction=0.0");
    }
    const Scene sc = load_scene_string(kDrain, "drain.toml", ".", set);
    const System<3>& sys = std::get<System<3>>(sc.system);
    const std::size_t N = sys.size();
    double mass0 = 0.0;
    for (std::size_t i = 0; i < N; ++i) mass0 += sys.mass(i);
    Recorder<3> rec;
    EdmSettings es;
    es.end_time = sc.end_time;
    es.thermo_interval = 0.01;
    es.lists = mode == 1;  // gravity: cube shells; the open face is left through a shell's face
    TdmSettings ts;
    ts.end_time = sc.end_time;
    ts.thermo_interval = 0.01;
    ts.threads = 2;
    HybridSettings hs;
    hs.rest_speed = 0.01;  // sleepers next to the orifice lose their support as grains leave
    const RunResult<3> r = m == Method::Edm   ? run_edm<3>(sys, es, QueueKind::Calendar, {&rec})
                           : m == Method::Tdm ? run_tdm<3>(sys, ts, {&rec})
                                              : run_hybrid<3>(sys, es, hs, {&rec});
    EXPECT_EQ(r.status, "ok") << r.message;
    EXPECT_EQ(r.lists, mode == 1);
    // Grains do leave (the hole is 8 grain diameters wide).
    EXPECT_GT(rec.out.size(), 20u);
    // The hybrid removes soft grains too (the bed in the corner).
    if (m == Method::Hybrid) {
      EXPECT_GT(rec.out_soft, 0u);
    }
    // Every removed grain once, inside its outlet (the half space below the domain's floor, or the
    // corner box).
    std::set<std::uint32_t> gone;
    double mass_out = 0.0;
    std::size_t n_corner = 0;
    for (const auto& o : rec.out) {
      EXPECT_TRUE(gone.insert(o.id).second) << "grain " << o.id << " removed twice";
      ASSERT_LT(o.outlet, 2u);
      if (o.outlet == 0) {
        EXPECT_LE(o.x[2], -0.03 + 1e-12);
        EXPECT_LT(o.v[2], 0.0);
      } else {
        ++n_corner;
        const Vec<3> lo(0.0, 0.0, -0.01), hi(0.012, 0.012, 0.004);
        EXPECT_TRUE((o.x.array() >= lo.array() - 1e-12).all() && (o.x.array() <= hi.array() + 1e-12).all())
            << o.x.transpose();
      }
      EXPECT_NEAR(o.mass, sys.mass(o.id), 1e-18);
      mass_out += o.mass;
    }
    // Every row: present + removed = N, and the mass removed so far matches the records up to then.
    for (const auto& row : rec.rows) {
      EXPECT_EQ(row.grains + row.grains_out, N) << row.time;
      double m_then = 0.0;
      std::uint64_t n_then = 0;
      for (const auto& o : rec.out)
        if (o.time <= row.time) {
          m_then += o.mass;
          ++n_then;
        }
      EXPECT_EQ(row.grains_out, n_then) << row.time;
      EXPECT_NEAR(row.mass_out, m_then, 1e-12 * mass0) << row.time;
    }
    // The end: the final state holds exactly the grains not removed, each once, in increasing id.
    EXPECT_GT(n_corner, 0u);
    EXPECT_EQ(r.grains_out, rec.out.size());
    EXPECT_NEAR(r.mass_out, mass_out, 1e-12 * mass0);
    ASSERT_EQ(r.id.size(), N - gone.size());
    ASSERT_EQ(r.x.size(), r.id.size());
    double mass_left = 0.0;
    for (std::size_t k = 0; k < r.id.size(); ++k) {
      if (k > 0) {
        EXPECT_LT(r.id[k - 1], r.id[k]);
      }
      EXPECT_EQ(gone.count(r.id[k]), 0u);
      EXPECT_EQ(r.radius[k], sys.radius[r.id[k]]);
      EXPECT_GT(r.x[k][2], -0.03);
      mass_left += sys.mass(r.id[k]);
    }
    EXPECT_NEAR(mass_left + mass_out, mass0, 1e-12 * mass0);
    EXPECT_EQ(rec.rows.back().grains, r.id.size());
  }
}

}  // namespace
}  // namespace matep

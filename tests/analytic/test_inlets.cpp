// Inlets (engine/inlet.hpp) in the three engines: grains enter on schedule (EDM: at exactly
// start + k / rate; TDM and the hybrid at the first step from then), never overlapping a grain or
// a wall; a rate the region cannot take is reported as missed grains, never made up; every
// grain is accounted for: present = start + inserted - removed at every thermo row and at the end.
#include <gtest/gtest.h>

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

TEST(Inlets, SlotTimesAndCounts) {
  Inlet<3> in;
  in.rate = 10.0;
  in.start = 0.05;
  in.stop = 0.5;
  EXPECT_EQ(in.slots(1.0), 5u);  // 0.05, 0.15, ..., 0.45
  EXPECT_EQ(in.slots(0.3), 3u);  // 0.05, 0.15, 0.25
  EXPECT_EQ(in.slots(0.05), 0u);
  in.count = 3;
  EXPECT_EQ(in.slots(1.0), 3u);
  Inlet<3> every;
  every.rate = 4.0;
  EXPECT_EQ(every.slots(1.0), 4u);  // 0, 0.25, 0.5, 0.75: the end itself is not a slot
  EXPECT_DOUBLE_EQ(every.slot_time(3), 0.75);
  EXPECT_EQ(inlet_slots<3>({in, every}, 1.0), 7u);
}

// A periodic unit box without gravity; `n0` grains at rest in a row.
template <int D>
System<D> box(int n0) {
  System<D> s;
  s.lower = Vec<D>::Zero();
  s.upper = Vec<D>::Ones();
  s.periodic.fill(true);
  Material m;
  m.name = "glass";
  m.density = 2500.0;
  m.contact = "linear";
  m.stiffness = 1e4;
  m.restitution = Restitution::constant(1.0);
  s.materials.push_back(m);
  for (int i = 0; i < n0; ++i) {
    Vec<D> x = Vec<D>::Constant(0.05);
    x[0] = 0.05 + 0.1 * i;
    s.x.push_back(x);
    s.v.push_back(Vec<D>::Zero());
    s.w.push_back(Spin<D>::Zero());
    s.radius.push_back(0.02);
    s.material.push_back(0);
  }
  return s;
}

template <int D>
Inlet<D> box_inlet(const Vec<D>& lo, const Vec<D>& hi, double rate, double spread) {
  Inlet<D> in;
  in.name = "feed";
  in.lower = lo;
  in.upper = hi;
  in.rmin = 0.015;
  in.rmax = 0.02;
  in.rate = rate;
  in.spread = spread;
  in.seed = 7;
  return in;
}

// The largest overlap of any two grains of a final state, relative to their contact distance.
template <int D>
double worst_overlap(const RunResult<D>& r) {
  double worst = 0.0;
  for (std::size_t a = 0; a < r.x.size(); ++a)
    for (std::size_t b = a + 1; b < r.x.size(); ++b) {
      const double s = r.radius[a] + r.radius[b];
      worst = std::max(worst, (s - (r.x[a] - r.x[b]).norm()) / s);
    }
  return worst;
}

// EDM (and the hybrid's hard grains): every grain due enters at its slot time, with the next id,
// and the gas stays free of overlaps.
TEST(Inlets, EdmInsertsOnScheduleWithoutOverlap) {
  for (const int mode : {0, 1, 2}) {  // EDM with cells, EDM with neighbour lists, the hybrid
    const bool hybrid = mode == 2;
    SCOPED_TRACE(hybrid ? "hybrid" : mode == 1 ? "edm, lists" : "edm");
    System<3> s = box<3>(5);
    s.inlets = {box_inlet<3>(Vec<3>::Constant(0.1), Vec<3>::Constant(0.9), 200.0, 0.5)};
    s.inlets[0].start = 0.0125;  // no slot falls on a thermo row
    Recorder<3> rec;
    EdmSettings set;
    set.end_time = 0.5;
    set.thermo_interval = 0.05;
    set.lists = mode == 1;
    const RunResult<3> r = hybrid ? run_hybrid<3>(s, set, HybridSettings{}, {&rec})
                                  : run_edm<3>(s, set, QueueKind::Calendar, {&rec});
    EXPECT_EQ(r.status, "ok") << r.message;
    EXPECT_EQ(r.lists, mode == 1);
    ASSERT_EQ(r.inlets.size(), 1u);
    EXPECT_EQ(r.inlets[0].due, 98u);  // 0.0125 + k / 200 < 0.5
    EXPECT_EQ(r.inlets[0].inserted, 98u);
    EXPECT_EQ(r.inlets[0].missed, 0u);
    ASSERT_EQ(rec.in.size(), 98u);
    double mass = 0.0;
    for (std::size_t k = 0; k < rec.in.size(); ++k) {
      EXPECT_EQ(rec.in[k].time, 0.0125 + static_cast<double>(k) / 200.0);
      EXPECT_EQ(rec.in[k].id, 5u + k);
      EXPECT_GE(rec.in[k].radius, 0.015);
      EXPECT_LE(rec.in[k].radius, 0.02);
      EXPECT_NEAR(rec.in[k].mass, 2500.0 * 4.0 / 3.0 * std::acos(-1.0) * std::pow(rec.in[k].radius, 3), 1e-15);
      EXPECT_TRUE((rec.in[k].x.array() >= 0.1).all() && (rec.in[k].x.array() <= 0.9).all());
      mass += rec.in[k].mass;
    }
    EXPECT_EQ(r.x.size(), 103u);
    EXPECT_EQ(r.grains_in, 98u);
    EXPECT_NEAR(r.mass_in, mass, 1e-15);
    EXPECT_LT(worst_overlap(r), 1e-9);
    for (const auto& row : rec.rows) {
      const std::uint64_t due = row.time < 0.0125 ? 0 : static_cast<std::uint64_t>(std::floor((row.time - 0.0125) * 200.0)) + 1;
      EXPECT_EQ(row.grains_in, std::min<std::uint64_t>(due, 98u)) << row.time;
      EXPECT_EQ(row.grains, 5u + row.grains_in) << row.time;
    }
  }
}

// A region that fills up: the grains that find no free place are missed and reported, the rest
// never overlap (grains at rest, no gravity: they stay where they were put), in every method.
TEST(Inlets, AFullRegionReportsTheRateItCouldNotMeet) {
  for (const Method m : {Method::Edm, Method::Tdm, Method::Hybrid}) {
    SCOPED_TRACE(method_name(m));
    System<3> s = box<3>(0);
    s.inlets = {box_inlet<3>(Vec<3>(0.3, 0.3, 0.3), Vec<3>(0.42, 0.42, 0.42), 2000.0, 0.0)};
    Recorder<3> rec;
    EdmSettings es;
    es.end_time = 0.05;
    TdmSettings ts;
    ts.end_time = 0.05;
    const RunResult<3> r = m == Method::Edm   ? run_edm<3>(s, es, QueueKind::Heap, {&rec})
                           : m == Method::Tdm ? run_tdm<3>(s, ts, {&rec})
                                              : run_hybrid<3>(s, es, HybridSettings{}, {&rec});
    EXPECT_EQ(r.status, "ok") << r.message;
    ASSERT_EQ(r.inlets.size(), 1u);
    EXPECT_EQ(r.inlets[0].due, 100u);
    EXPECT_GT(r.inlets[0].missed, 0u);
    EXPECT_GT(r.inlets[0].inserted, 3u);
    EXPECT_EQ(r.inlets[0].inserted + r.inlets[0].missed, 100u);
    EXPECT_EQ(r.x.size(), r.inlets[0].inserted);
    EXPECT_EQ(rec.in.size(), r.inlets[0].inserted);
    EXPECT_LE(worst_overlap(r), 0.0);
    // The ids are given in order of entry, without gaps for the missed grains.
    for (std::size_t k = 0; k < r.id.size(); ++k) EXPECT_EQ(r.id[k], k);
  }
}


// The hopper of test::kFeed in TDM and the hybrid (an inelastic, frictional bed) and EDM (an
// elastic gas): the accounts balance.
TEST(Inlets, FedAndDrainedTheAccountsBalance) {
  for (const Method m : {Method::Edm, Method::Tdm, Method::Hybrid}) {
    SCOPED_TRACE(method_name(m));
    std::vector<std::string> set{std::string("run.method=") + method_name(m)};
    if (m == Method::Edm) {
      set.push_back("material.glass.restitution=1.0");
      set.push_back("material.glass.friction=0.0");
    }
    const Scene sc = load_scene_string(test::kFeed, "feed.toml", ".", set);
    const System<3>& sys = std::get<System<3>>(sc.system);
    const std::size_t N0 = sys.size();
    ASSERT_EQ(N0, 20u);
    Recorder<3> rec;
    EdmSettings es;
    es.end_time = sc.end_time;
    es.thermo_interval = 0.01;
    TdmSettings ts;
    ts.end_time = sc.end_time;
    ts.thermo_interval = 0.01;
    ts.threads = 2;
    const RunResult<3> r = m == Method::Edm   ? run_edm<3>(sys, es, QueueKind::Calendar, {&rec})
                           : m == Method::Tdm ? run_tdm<3>(sys, ts, {&rec})
                                              : run_hybrid<3>(sys, es, HybridSettings{}, {&rec});
    EXPECT_EQ(r.status, "ok") << r.message;
    EXPECT_EQ(r.inlets.at(0).due, 450u);
    EXPECT_EQ(r.inlets.at(0).missed, 0u);
    EXPECT_GT(rec.out.size(), 10u);  // grains do drain
    std::set<std::uint32_t> in, out;
    std::map<std::uint32_t, double> mass;
    for (const auto& g : rec.in) {
      EXPECT_TRUE(in.insert(g.id).second);
      EXPECT_GE(g.id, N0);
      mass[g.id] = g.mass;
    }
    for (std::uint32_t i = 0; i < N0; ++i) mass[i] = sys.mass(i);
    double mass_out = 0.0;
    for (const auto& g : rec.out) {
      EXPECT_TRUE(out.insert(g.id).second);
      EXPECT_TRUE(g.id < N0 || in.count(g.id)) << g.id;
      EXPECT_NEAR(g.mass, mass.at(g.id), 1e-18);
      mass_out += g.mass;
    }
    for (const auto& row : rec.rows) EXPECT_EQ(row.grains + row.grains_out, N0 + row.grains_in) << row.time;
    const auto& last = rec.rows.back();
    EXPECT_EQ(last.grains_in, in.size());
    EXPECT_EQ(last.grains_out, out.size());
    EXPECT_NEAR(last.mass_out, mass_out, 1e-12);
    // The final state: exactly the grains present, each once.
    ASSERT_EQ(r.id.size(), N0 + in.size() - out.size());
    double present = 0.0;
    for (std::size_t k = 0; k < r.id.size(); ++k) {
      EXPECT_EQ(out.count(r.id[k]), 0u);
      EXPECT_TRUE(r.id[k] < N0 || in.count(r.id[k]));
      present += mass.at(r.id[k]);
    }
    double start = 0.0;
    for (std::uint32_t i = 0; i < N0; ++i) start += mass[i];
    EXPECT_NEAR(present + mass_out, start + r.mass_in, 1e-12);
  }
}

}  // namespace
}  // namespace matep

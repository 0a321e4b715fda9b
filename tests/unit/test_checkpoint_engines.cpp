// Checkpoints at the engine level (engine/state_archive.hpp): a run stopped at a random moment, or
// checkpointed every interval, and continued from the saved state follows the uninterrupted run
// bit for bit: the same collisions and thermo samples after the checkpoint, the same final state.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "engine/edm.hpp"
#include "engine/hybrid.hpp"
#include "engine/state_archive.hpp"
#include "engine/tdm.hpp"
#include "io/run.hpp"
#include "io/scene.hpp"
#include "tests/support/cli.hpp"
#include "tests/support/systems.hpp"

namespace matep {
namespace {
using test::lattice_gas;

// Everything a run reports as it goes, as raw numbers; `cut` marks the length at each save.
template <int D>
class Trace final : public Observer<D> {
 public:
  explicit Trace(std::atomic<bool>* stop = nullptr, std::uint64_t stop_after = 0, bool by_collisions = true)
      : stop_(stop), stop_after_(stop_after), by_collisions_(by_collisions) {}
  bool wants_collisions() const override { return true; }
  void on_collision(const CollisionRecord<D>& c) override {
    put(c.time);
    put(static_cast<double>(c.i));
    put(static_cast<double>(c.j));
    for (int k = 0; k < D; ++k) {
      put(c.vi_after[k]);
      put(c.vj_after[k]);
    }
    if (++collisions_ == stop_after_ && stop_ && by_collisions_) stop_->store(true);
  }
  void on_sample(const ThermoSample& s) override {
    put(s.time);
    put(s.kinetic_energy);
    put(s.potential_energy);
    put(static_cast<double>(s.collisions));
    if (++samples_ == stop_after_ && stop_ && !by_collisions_) stop_->store(true);
  }
  void mark() { cuts.push_back(values.size()); }
  std::uint64_t collisions() const { return collisions_; }
  std::uint64_t samples() const { return samples_; }
  std::vector<double> values;
  std::vector<std::size_t> cuts;

 private:
  void put(double v) { values.push_back(v); }
  std::atomic<bool>* stop_;
  std::uint64_t stop_after_;
  bool by_collisions_;
  std::uint64_t collisions_ = 0, samples_ = 0;
};

template <int D>
void expect_same_result(const RunResult<D>& a, const RunResult<D>& b) {
  EXPECT_EQ(a.status, b.status);
  EXPECT_EQ(a.time, b.time);
  EXPECT_TRUE(test::same_bits(a.x, b.x)) << "final positions differ";
  EXPECT_TRUE(test::same_bits(a.v, b.v)) << "final velocities differ";
  EXPECT_EQ(a.counts.pair, b.counts.pair);
  EXPECT_EQ(a.counts.wall, b.counts.wall);
  EXPECT_EQ(a.soft.steps, b.soft.steps);
  EXPECT_EQ(a.hybrid.to_soft, b.hybrid.to_soft);
  EXPECT_EQ(a.hybrid.by_overlap, b.hybrid.by_overlap);
  EXPECT_EQ(a.mode, b.mode);
}

// Hooks that keep every state the run saves (every `interval`, at a stop, at the end), marking
// the trace at each.
template <int D>
struct Keeper {
  std::vector<std::vector<std::uint8_t>> states;
  CheckpointHooks hooks;
  Keeper(Trace<D>& trace, double interval) {
    hooks.interval = interval;
    hooks.save = [this, &trace](double, const auto& st) {
      states.push_back(archive_bytes(st));
      trace.mark();
    };
  }
  Keeper(const Keeper&) = delete;
};

// The first `cut` values of a run's reports, then those of the run that continued it.
std::vector<double> joined(const std::vector<double>& first, std::size_t cut, const std::vector<double>& rest) {
  std::vector<double> out(first.begin(), first.begin() + static_cast<std::ptrdiff_t>(cut));
  out.insert(out.end(), rest.begin(), rest.end());
  return out;
}

// A run of one method: `run(settings hooks, observers)`.
// Stopped after a random number of collisions (samples for TDM), at most 3/4 of the run's.
template <int D, class Run>
void check_resume(Run&& run, std::uint64_t seed, const char* what, int trials = 3) {
  // The uninterrupted run.
  Trace<D> whole;
  const RunResult<D> ref = run(nullptr, nullptr, &whole);
  ASSERT_EQ(ref.status, "ok") << ref.message;
  const bool by_collisions = whole.collisions() > 100;
  const std::uint64_t unit_max = std::max<std::uint64_t>(2, 3 * (by_collisions ? whole.collisions() : whole.samples()) / 4);
  std::mt19937_64 rng(seed);
  for (int trial = 0; trial < trials; ++trial) {
    SCOPED_TRACE(::testing::Message() << what << " trial " << trial);
    // Stopped after a random number of collisions (or samples): the state at the stop is saved.
    std::atomic<bool> stop{false};
    const std::uint64_t after = 1 + rng() % unit_max;
    Trace<D> first(&stop, after, by_collisions);
    Keeper<D> saved(first, 0.0);
    const RunResult<D> part = run(&saved.hooks, &stop, &first);
    ASSERT_EQ(part.status, "interrupted");
    ASSERT_EQ(saved.states.size(), 1u);
    ASSERT_FALSE(saved.states[0].empty());
    EXPECT_GT(part.time, 0.0);
    // Continued from it.
    Trace<D> rest;
    CheckpointHooks resume;
    resume.resume = &saved.states[0];
    const RunResult<D> cont = run(&resume, nullptr, &rest);
    const std::vector<double> both = joined(first.values, first.cuts[0], rest.values);
    ASSERT_EQ(both.size(), whole.values.size());
    EXPECT_EQ(std::memcmp(both.data(), whole.values.data(), both.size() * sizeof(double)), 0)
        << "the continued run's reports differ from the uninterrupted run's";
    expect_same_result(cont, ref);
  }
}

EdmSettings edm_set(double end, double thermo) {
  EdmSettings s;
  s.end_time = end;
  s.thermo_interval = thermo;
  return s;
}

TEST(CheckpointEngines, EdmGasResumesBitForBit) {
  const System<3> sys = lattice_gas<3>(6, 0.3, 1.0, 0.9, 11);
  for (const QueueKind q : {QueueKind::Calendar, QueueKind::Heap}) {
    auto run = [&](const CheckpointHooks* h, std::atomic<bool>* stop, Observer<3>* obs) {
      EdmSettings s = edm_set(20.0, 0.25);
      s.checkpoint = h;
      s.stop = stop;
      return run_edm<3>(sys, s, q, {obs});
    };
    check_resume<3>(run, q == QueueKind::Calendar ? 1 : 2, q == QueueKind::Calendar ? "edm 3D calendar" : "edm 3D heap");
  }
}

// A run that re-sorts its particles (EdmSettings::resort) saves their order and the map to the
// scene's ids; stopped between two re-sorts it continues on the same schedule of re-sorts.
TEST(CheckpointEngines, EdmReSortedGasResumesBitForBit) {
  System<3> sys = lattice_gas<3>(6, 0.3, 1.0, 0.9, 11);
  std::mt19937 rng(3);
  std::shuffle(sys.x.begin(), sys.x.end(), rng);
  for (const bool lists : {false, true}) {
    auto run = [&](const CheckpointHooks* h, std::atomic<bool>* stop, Observer<3>* obs) {
      EdmSettings s = edm_set(20.0, 0.25);
      s.resort = 1.5;
      s.lists = lists;
      s.checkpoint = h;
      s.stop = stop;
      return run_edm<3>(sys, s, QueueKind::Calendar, {obs});
    };
    check_resume<3>(run, lists ? 4 : 3, lists ? "edm re-sorted, lists" : "edm re-sorted, cells");
  }
  // Its state is refused by a run that does not re-sort (it reports in the engine's order, which
  // the saved map no longer is).
  std::vector<std::uint8_t> state;
  CheckpointHooks keep;
  keep.interval = 5.0;
  keep.save = [&](double, const auto& st) {
    if (state.empty()) state = archive_bytes(st);
  };
  EdmSettings s = edm_set(20.0, 0.25);
  s.resort = 1.5;
  s.checkpoint = &keep;
  ASSERT_GT(run_edm<3>(sys, s, QueueKind::Calendar).resorts, 2u);
  ASSERT_FALSE(state.empty());
  CheckpointHooks resume;
  resume.interval = keep.interval;
  resume.resume = &state;
  s.checkpoint = &resume;
  s.resort = 0.0;
  EXPECT_THROW(run_edm<3>(sys, s, QueueKind::Calendar), StateError);
}

TEST(CheckpointEngines, EdmIntervalCheckpointsDoNotChangeTheRun) {
  const System<2> sys = lattice_gas<2>(12, 0.4, 1.0, 0.8, 5);
  Trace<2> plain;
  EdmSettings s = edm_set(2.0, 0.1);
  const RunResult<2> ref = run_edm<2>(sys, s, QueueKind::Calendar, {&plain});
  // Every 0.3: six states; each continued gives the uninterrupted run.
  Trace<2> with;
  Keeper<2> every(with, 0.3);
  const auto& states = every.states;
  s.checkpoint = &every.hooks;
  const RunResult<2> r = run_edm<2>(sys, s, QueueKind::Calendar, {&with});
  ASSERT_EQ(states.size(), 7u);  // 0.3 ... 1.8, and the end
  EXPECT_EQ(with.values, plain.values);
  expect_same_result(r, ref);
  for (std::size_t k : {std::size_t{0}, std::size_t{3}, std::size_t{5}, std::size_t{6}}) {
    SCOPED_TRACE(::testing::Message() << "checkpoint " << k);
    Trace<2> rest;
    CheckpointHooks resume;  // with the interval of the run that saved it (its events are in the state)
    resume.interval = every.hooks.interval;
    resume.resume = &states[k];
    s.checkpoint = &resume;
    const RunResult<2> cont = run_edm<2>(sys, s, QueueKind::Calendar, {&rest});
    EXPECT_EQ(joined(plain.values, with.cuts[k], rest.values), plain.values);
    expect_same_result(cont, ref);
  }
}

TEST(CheckpointEngines, AStateOfAnotherSystemIsRefused) {
  const System<3> a = lattice_gas<3>(4, 0.3, 1.0, 0.9, 1);
  const System<3> b = lattice_gas<3>(5, 0.3, 1.0, 0.9, 1);
  std::vector<std::uint8_t> state;
  CheckpointHooks save;
  save.save = [&](double, const auto& st) { state = archive_bytes(st); };
  EdmSettings s = edm_set(0.5, 0.0);
  s.checkpoint = &save;
  run_edm<3>(a, s, QueueKind::Calendar);
  ASSERT_FALSE(state.empty());
  CheckpointHooks resume;
  resume.resume = &state;
  s.checkpoint = &resume;
  try {
    run_edm<3>(b, s, QueueKind::Calendar);
    FAIL() << "a state of 64 particles loaded into 125";
  } catch (const StateError& e) {
    EXPECT_NE(std::string(e.what()).find("64 particle slots, this scene 125"), std::string::npos) << e.what();
  }
  // Cut short anywhere: refused, never read past the end.
  for (std::size_t cut : {std::size_t{3}, state.size() / 2, state.size() - 1}) {
    std::vector<std::uint8_t> part(state.begin(), state.begin() + static_cast<std::ptrdiff_t>(cut));
    resume.resume = &part;
    EXPECT_THROW(run_edm<3>(a, s, QueueKind::Calendar), StateError) << cut;
  }
}

TEST(CheckpointEngines, TdmFrictionalGasResumesBitForBit) {
  System<3> sys = lattice_gas<3>(6, 0.35, 1.0, 0.7, 3);
  Material m = test::linear_material("grain", sys.materials[0].density, 2e4, 0.7);
  m.friction = 0.4;
  sys.materials[0] = m;
  auto run = [&](const CheckpointHooks* h, std::atomic<bool>* stop, Observer<3>* obs) {
    TdmSettings s;
    s.end_time = 2.0;
    s.thermo_interval = 0.01;
    s.threads = 1;
    s.checkpoint = h;
    s.stop = stop;
    return run_tdm<3>(sys, s, {obs});
  };
  check_resume<3>(run, 4, "tdm 3D friction");
}

// The shipped cases (shortened) through each engine: walls that move, gravity, inlets and
// outlets, rotation, the hybrid's soft set and sleepers.
template <int D>
RunResult<D> run_case(const Scene& sc, const System<D>& sys, const CheckpointHooks* h, std::atomic<bool>* stop,
                      Observer<D>* obs) {
  EdmSettings e;
  e.end_time = sc.end_time;
  e.tc = sc.tc;
  e.thermo_interval = sc.output.thermo_interval;
  e.collapse_decades = sc.collapse_decades;
  e.lists = sc.neighbours == "lists";
  e.shell = sc.shell;
  e.resort = sc.resort;
  e.checkpoint = h;
  e.stop = stop;
  if (sc.method == Method::Edm) return run_edm<D>(sys, e, QueueKind::Calendar, {obs});
  if (sc.method == Method::Hybrid) return run_hybrid<D>(sys, e, hybrid_settings(sc), {obs});
  TdmSettings t;
  t.end_time = sc.end_time;
  t.dt = sc.dt.value_or(0.0);
  t.threads = sc.threads.value_or(0);
  t.thermo_interval = sc.output.thermo_interval;
  t.checkpoint = h;
  t.stop = stop;
  return run_tdm<D>(sys, t, {obs});
}

void check_case(const std::string& name, const std::vector<std::string>& overrides, std::uint64_t seed,
                int trials = 3) {
  const Scene sc = load_scene(test::kCasesDir + name, overrides);
  std::visit(
      [&](const auto& sys) {
        constexpr int D = std::decay_t<decltype(sys)>::dimension;
        auto run = [&](const CheckpointHooks* h, std::atomic<bool>* stop, Observer<D>* obs) {
          return run_case<D>(sc, sys, h, stop, obs);
        };
        check_resume<D>(run, seed, name.c_str(), trials);
      },
      sc.system);
}

TEST(CheckpointEngines, TdmCasesResumeBitForBit) {
  check_case("heap.toml", {"run.end_time=0.8", "output.thermo_interval=0.01"}, 7);
  check_case("drum.toml", {"run.end_time=0.04", "output.thermo_interval=0.001"}, 8);
}

// The small pour of cases/pour_settle.toml: 300 beads land and begin to sleep by t = 0.5.
const std::vector<std::string> kSmallPour = {"run.end_time=0.5", "output.thermo_interval=0.01",
                                             "particles.beads.count=300",
                                             "particles.beads.region.upper=[0.15,0.15,0.25]"};

TEST(CheckpointEngines, HybridCasesResumeBitForBit) {
  // Settling under gravity; a bed on an oscillating floor; a 2D U-tube.
  check_case("pour_settle.toml", kSmallPour, 9);
  check_case("vibrated_bed.toml", {"run.end_time=0.6", "output.thermo_interval=0.01"}, 10);
  check_case("u_tube_2d.toml", {"run.end_time=0.15", "output.thermo_interval=0.005"}, 11);
}

// The hybrid's hard grains on neighbour lists: the pour (cube shells under gravity; soft grains
// leave their shells and get new ones, sleepers keep theirs) and a dense gas whose clusters go soft
// (ball shells, periodic wraps).
// The hybrid re-sorting its storage while no grain is soft (run.resort): a clustering gas of disks
// whose grains go soft and back, resumed from random stops with its map to the scene's ids, its
// renamed histories and the schedule of re-sorts. Twelve stops each: in the second run stops 7, 10
// and 11 are asked while the soft set coasts (or just before), which once made the stopping run
// step where the uninterrupted one coasted and end a round-off apart from it.
TEST(CheckpointEngines, HybridReSortedResumesBitForBit) {
  const std::vector<std::string> gas = {"run.end_time=8", "output.thermo_interval=0.5", "particles.gas.count=2000",
                                        "domain.upper=[60.0,60.0]", "material.grain.restitution=0.3",
                                        "run.resort=0.05"};
  check_case("cooling_clusters.toml", gas, 15, 12);
  std::vector<std::string> listed = gas;
  listed.push_back("run.neighbours=\"lists\"");
  check_case("cooling_clusters.toml", listed, 16, 12);
}

TEST(CheckpointEngines, HybridOnListsResumesBitForBit) {
  std::vector<std::string> pour = kSmallPour;
  pour.push_back("run.neighbours=\"lists\"");
  check_case("pour_settle.toml", pour, 13);
  check_case("cooling_clusters.toml",
             {"run.neighbours=\"lists\"", "run.end_time=8", "output.thermo_interval=0.5", "particles.gas.count=2000",
              "domain.upper=[60.0,60.0]", "material.grain.restitution=0.2"},
             14);
}

// The small pour to t = 0.3 s with its soft set split on two threads (down to 100 awake grains a
// thread): the derived split and owners are made again after a resume, and the run goes on bit
// for bit.
TEST(CheckpointEngines, HybridPourOnTwoThreadsResumesBitForBit) {
  std::vector<std::string> over = kSmallPour;
  over[0] = "run.end_time=0.3";
  const Scene sc = load_scene(test::kCasesDir + "pour_settle.toml", over);
  const auto& sys = std::get<System<3>>(sc.system);
  HybridSettings hs = hybrid_settings(sc);
  hs.threads = 2;
  hs.min_per_thread = 100;
  auto run = [&](const CheckpointHooks* h, std::atomic<bool>* stop, Observer<3>* obs) {
    EdmSettings e = edm_set(sc.end_time, sc.output.thermo_interval);
    e.checkpoint = h;
    e.stop = stop;
    return run_hybrid<3>(sys, e, hs, {obs});
  };
  Trace<3> probe;
  EXPECT_EQ(run(nullptr, nullptr, &probe).soft.threads, 2);  // the soft set was split
  check_resume<3>(run, 12, "hybrid pour, 2 threads");
}

// Checkpoints every interval in a pour: resumed mid-settling, the sleepers and springs carry on
// (the same switches, no grain turned soft again "by overlap", the same final modes).
TEST(CheckpointEngines, HybridPourResumedMidSettling) {
  const Scene sc = load_scene(test::kCasesDir + "pour_settle.toml", kSmallPour);
  const auto& sys = std::get<System<3>>(sc.system);
  Trace<3> plain;
  const RunResult<3> ref = run_case<3>(sc, sys, nullptr, nullptr, &plain);
  ASSERT_GT(ref.hybrid.slept, 0u);
  Trace<3> with;
  Keeper<3> every(with, 0.1);
  const auto& states = every.states;
  const RunResult<3> r = run_case<3>(sc, sys, &every.hooks, nullptr, &with);
  ASSERT_EQ(states.size(), 5u);  // 0.1 ... 0.4, and the end
  EXPECT_EQ(with.values, plain.values);
  expect_same_result(r, ref);
  for (std::size_t k : {std::size_t{2}, std::size_t{3}}) {
    SCOPED_TRACE(::testing::Message() << "checkpoint " << k);
    Trace<3> rest;
    CheckpointHooks resume;
    resume.interval = every.hooks.interval;
    resume.resume = &states[k];
    const RunResult<3> cont = run_case<3>(sc, sys, &resume, nullptr, &rest);
    EXPECT_EQ(joined(plain.values, with.cuts[k], rest.values), plain.values);
    expect_same_result(cont, ref);
    EXPECT_EQ(cont.hybrid.slept, ref.hybrid.slept);
    EXPECT_EQ(cont.hybrid.woken, ref.hybrid.woken);
  }
}

// A bed of 195 disks on a floor, every grain touching from the start (a triangular packing
// overlapping by a tenth of what gravity presses: nothing bounces), so that the hybrid runs
// substep after substep with no hard event between them: the closing pass of each substep then
// also drifts the soft set to the next one (engine/hybrid/hybrid.cpp, fuse_next). A stop asked
// for (after a random number of samples) must wait for a substep that leaves the soft set at the
// run's time: a state saved a substep ahead would continue with the drift done twice, and a stop
// that waited for good would end the run "ok" instead of "interrupted". (Checked: with the stop
// taken whatever the state, the continued run differs.)
TEST(CheckpointEngines, HybridSoftBedStopsBetweenWholeSubsteps) {
  System<2> s;
  const double d = 0.01, R = 0.5 * d, W = 20 * d;
  s.lower = Vec<2>(0.0, 0.0);
  s.upper = Vec<2>(W, 12 * d);
  s.gravity = Vec<2>(0.0, -9.81);
  s.materials.push_back(test::linear_material("glass", 2500.0, 2e7, 0.5));
  s.walls.push_back(plane_wall<2>("floor", Vec<2>(0.0, 0.0), Vec<2>(0.0, 1.0)));
  s.walls.push_back(plane_wall<2>("left", Vec<2>(0.0, 0.0), Vec<2>(1.0, 0.0)));
  s.walls.push_back(plane_wall<2>("right", Vec<2>(W, 0.0), Vec<2>(-1.0, 0.0)));
  const double a = (1.0 - 1e-6) * d;  // overlaps of 1e-6 d, a tenth of what gravity presses
  for (int row = 0; row < 10; ++row)  // a triangular packing: rows of 20 and 19
    for (int col = 0; col < 20 - row % 2; ++col) {
      s.x.push_back(Vec<2>(R + (col + 0.5 * (row % 2)) * a, (1.0 - 1e-6) * R + row * a * std::sqrt(0.75)));
      s.v.push_back(Vec<2>::Zero());
      s.radius.push_back(R);
      s.material.push_back(0);
    }
  auto run = [&](const CheckpointHooks* h, std::atomic<bool>* stop, Observer<2>* obs) {
    EdmSettings e = edm_set(0.03, 0.001);
    e.checkpoint = h;
    e.stop = stop;
    return run_hybrid<2>(s, e, HybridSettings{}, {obs});
  };
  Trace<2> probe;
  const RunResult<2> ref = run(nullptr, nullptr, &probe);
  ASSERT_EQ(ref.status, "ok") << ref.message;
  EXPECT_EQ(ref.counts.pair + ref.counts.wall, 0u);  // no hard collision: substeps only
  EXPECT_EQ(ref.hybrid.soft_at_end, 195u);
  check_resume<2>(run, 13, "soft bed");
}

TEST(CheckpointEngines, EdmCasesResumeBitForBit) {
  check_case("rough_gas.toml", {"run.end_time=20", "output.thermo_interval=1"}, 12);
}

}  // namespace
}  // namespace matep

namespace {
// Loads part "part" of `bytes` with load(reader) and expects it refused, the message naming `what`.
template <class Load>
void expect_refused(const std::vector<std::uint8_t>& bytes, Load&& load, const std::string& what) {
  matep::StateReader r(bytes);
  r.tag("part");
  try {
    load(r);
    ADD_FAILURE() << "loaded, where \"" << what << "\" was expected";
  } catch (const matep::StateError& e) {
    EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
  }
}
}  // namespace

// A flag of a saved state is one byte, 0 or 1; a corrupt byte is refused (found by the checkpoint
// fuzzer under UBSan: loading it into a bool was undefined behaviour).
TEST(CheckpointEngines, ACorruptFlagIsRefusedNotLoaded) {
  matep::StateWriter w;
  w.tag("part");
  bool on = true;
  w(on);
  std::vector<std::uint8_t> bytes = w.bytes;
  bool back = false;
  matep::StateReader good(bytes);
  good.tag("part");
  good(back);
  EXPECT_TRUE(back);
  bytes.back() = 7;
  expect_refused(bytes, [&](matep::StateReader& r) { r(back); }, "flag of value 7 in \"part\"");
}

// An array of equal elements is saved as one element with its length (kFill); it loads as the
// same array, an array with one element different is saved whole, and a filled length beyond any
// engine's (a corrupt state) is refused before anything is allocated.
TEST(CheckpointEngines, ArraysOfEqualElementsAreSavedOnce) {
  const std::vector<double> same(1000, -1.5);
  std::vector<double> one_off = same;
  one_off[517] = 2.0;
  const std::vector<matep::Vec<3>> vecs(300, matep::Vec<3>(1.0, -2.0, 3.0));
  const std::vector<int> single{4};
  matep::StateWriter w;
  w.tag("part");
  w(same);
  const std::size_t after_same = w.bytes.size();
  w(one_off);
  const std::size_t after_one_off = w.bytes.size();
  w(vecs);
  w(single);
  EXPECT_EQ(after_same, 4 + 4 + 8 + sizeof(double));  // tag, length, one element
  EXPECT_EQ(after_one_off - after_same, 8 + 1000 * sizeof(double));
  EXPECT_EQ(w.bytes.size() - after_one_off, 8 + sizeof(matep::Vec<3>) + 8 + sizeof(int));
  matep::StateWriter count;
  count.count_only = true;
  count.tag("part");
  count(same);
  count(one_off);
  count(vecs);
  count(single);
  EXPECT_EQ(count.size, w.bytes.size());

  std::vector<double> a, b;
  std::vector<matep::Vec<3>> c;
  std::vector<int> d;
  matep::StateReader r(w.bytes);
  r.tag("part");
  r(a);
  r(b);
  r(c);
  r(d);
  EXPECT_TRUE(r.done());
  EXPECT_EQ(a, same);
  EXPECT_EQ(b, one_off);
  EXPECT_EQ(c, vecs);
  EXPECT_EQ(d, single);

  // The test of equal elements, at each end of the array and inside an element.
  std::vector<matep::Vec<3>> last_off = vecs;
  last_off.back()[2] = 3.5;
  std::vector<matep::Vec<3>> first_off = vecs;
  first_off.front()[0] = 0.5;
  const auto equal = [](const auto& v) { return matep::uniform(v.data(), v.size(), sizeof(v[0])); };
  EXPECT_TRUE(equal(vecs));
  EXPECT_TRUE(equal(same));
  EXPECT_TRUE(equal(single));
  EXPECT_TRUE(equal(std::vector<int>{}));
  EXPECT_FALSE(equal(last_off));
  EXPECT_FALSE(equal(first_off));
  EXPECT_FALSE(equal(one_off));
  EXPECT_FALSE(equal(std::vector<std::uint8_t>{0, 0, 0, 1}));
  // Elements whose bytes repeat with a shorter period than the element are still compared whole.
  EXPECT_FALSE(equal(std::vector<std::uint16_t>{0x0101, 0x0101, 0x0102}));

  std::vector<std::uint8_t> bytes = w.bytes;
  const std::uint64_t huge = (std::uint64_t{1} << 63) | (std::uint64_t{1} << 50);
  std::memcpy(bytes.data() + 8, &huge, sizeof huge);  // the first array's length
  expect_refused(bytes, [&](matep::StateReader& r) { r(a); }, "array of 1125899906842624 elements in \"part\"");
}

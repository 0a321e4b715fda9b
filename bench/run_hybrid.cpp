// Hybrid against the pure methods on the same scene, wall time of whole runs (one core), each
// method alternated with its baseline in the same process and reported as medians of the ratios:
//  * dilute gas (e = 0.95, packing fraction 0.05, no gravity, 32 768 spheres): hybrid / EDM,
//    the issue's bound is 1.1 (the hybrid must stay hard and cost what EDM costs);
//  * pour and settle (cases/pour_settle.toml): hybrid / TDM at the same step, with the bed height
//    (2 <z>) and the kinetic-energy curve compared (the issue's bound on the time ratio is 1/3);
//  * soft set: a dense soft gas (32 768 grains, every one touching its neighbours at the start and
//    kept soft: releases off), the hybrid's soft particle-steps per second on 1 and `--threads` threads
//    against TDM's on the same gas and thread counts; with --shuffle the grains' ids are scattered
//    in space (a random permutation of the lattice), as in a scene placed at random or read from a
//    file (TDM sorts its storage in space at each list build; the hybrid renumbers the grains once,
//    engine/renumber.hpp).
// Usage: matep_bench_hybrid [--repeats N] [--only gas|pour|soft] [--threads T] [--steps S] [--shuffle] [--verbose]
//        [--one tdm|hybrid] (with --only soft: one run of that method on --threads threads, for a profiler)
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "engine/edm.hpp"
#include "engine/hybrid.hpp"
#include "engine/tdm.hpp"
#include "io/run.hpp"
#include "io/scene.hpp"

using namespace matep;

namespace {

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

struct KeCurve final : Observer<3> {
  std::vector<double> t, ke;
  void on_sample(const ThermoSample& s) override {
    t.push_back(s.time);
    ke.push_back(s.kinetic_energy);
  }
};

double bed_height(const RunResult<3>& r) {
  double z = 0.0;
  for (const auto& x : r.x) z += x[2];
  return 2.0 * z / static_cast<double>(r.x.size());
}

// A periodic cube of side L holding 32 768 unit-mass spheres of unit diameter on a lattice at T = 1,
// as a hybrid scene: `law` is the material's contact lines, `extra` further tables.
std::string lattice_gas_scene(double end_time, int seed, double L, double e, const std::string& law,
                              const std::string& extra) {
  return fmt::format(R"(
[run]
dimension = 3
method = "hybrid"
end_time = {}
seed = {}
[domain]
lower = [0.0, 0.0, 0.0]
upper = [{}, {}, {}]
periodic = [true, true, true]
[material.g]
density = 1.909859317102744
restitution = {}
{}
[particles.a]
material = "g"
radius = 0.5
count = 32768
arrangement = "lattice"
temperature = 1.0
{})",
                     end_time, seed, L, L, L, e, law, extra);
}

// The soft set alone: a 32^3 simple-cubic lattice of unit spheres compressed to a spacing of 0.99 d
// (packing fraction 0.534; every grain overlaps its six neighbours by 0.01 d, so all start soft)
// with Maxwellian velocities at T = 1, linear spring-dashpot (k = 9e4, e = 0.9, no friction, the
// TDM benchmark's gas law); the releases are switched off (cost_ratio 1e9, hysteresis 1e9) so the
// whole gas stays soft and melts into a dense soft fluid. Rates are soft particle-steps per second
// of the whole run (list builds included), medians of alternated runs: TDM 1 thread, hybrid 1
// thread, TDM T threads, hybrid T threads.
void soft_set(int repeats, int threads, double steps, bool shuffle, bool verbose, const std::string& one = {}) {
  const std::string text = lattice_gas_scene(1.0, 5, 32.0, 0.9, "contact = \"linear\"\nstiffness = 9.0e4",
                                              "[hybrid]\ncost_ratio = 1.0e9\nhysteresis = 1.0e9");
  const Scene scene = load_scene_string(text, "dense_soft_gas", "");
  System<3> sys = std::get<System<3>>(scene.system);
  const double s = 0.99;
  sys.upper *= s;
  for (auto& x : sys.x) x *= s;
  if (shuffle) {  // the same gas, its ids scattered in space
    std::mt19937 rng(3);
    std::vector<std::size_t> p(sys.x.size());
    for (std::size_t k = 0; k < p.size(); ++k) p[k] = k;
    std::shuffle(p.begin(), p.end(), rng);
    const System<3> a = sys;
    for (std::size_t k = 0; k < p.size(); ++k) {
      sys.x[k] = a.x[p[k]];
      sys.v[k] = a.v[p[k]];
    }
  }
  HybridSettings hs = hybrid_settings(scene);
  const SoftPlan plan = hybrid_preflight<3>(sys, hs);
  const double dt = plan.default_dt;
  EdmSettings es;
  es.end_time = steps * dt;
  TdmSettings ts;
  ts.end_time = es.end_time;
  ts.dt = dt;
  auto rate_h = [&](int th) {
    hs.threads = th;
    const RunResult<3> r = run_hybrid<3>(sys, es, hs);
    if (r.hybrid.to_hard != 0 || r.status != "ok") fmt::print("  (hybrid: {} releases, status {})\n", r.hybrid.to_hard, r.status);
    if (verbose) fmt::print("  hybrid {} threads: {:.3f} s, {} list builds\n", th, r.wall_seconds, r.hybrid.rebuilds);
    return static_cast<double>(r.hybrid.soft_particle_steps) / r.wall_seconds;
  };
  auto rate_t = [&](int th) {
    ts.threads = th;
    const RunResult<3> r = run_tdm<3>(sys, ts);
    if (verbose) fmt::print("  TDM {} threads: {:.3f} s, {} list builds\n", th, r.wall_seconds, r.soft.rebuilds);
    return static_cast<double>(r.soft.steps) * static_cast<double>(sys.x.size()) / r.wall_seconds;
  };
  if (!one.empty()) {  // --one METHOD: a single run, for a profiler
    const double r = one == "tdm" ? rate_t(threads) : rate_h(threads);
    fmt::print("{} {} threads: {:.2f} M particle-steps/s\n", one, threads, r / 1e6);
    return;
  }
  std::vector<double> t1, h1, tT, hT;
  for (int k = 0; k < repeats; ++k) {
    t1.push_back(rate_t(1));
    h1.push_back(rate_h(1));
    tT.push_back(rate_t(threads));
    hT.push_back(rate_h(threads));
  }
  fmt::print("\nSoft set: dense soft gas{}, N 32768, {} substeps of {:.4g}, M particle-steps/s (medians of {})\n", shuffle ? " (ids scattered)" : "", steps, dt, repeats);
  fmt::print("| threads | TDM | hybrid soft set | hybrid / TDM |\n|---:|---:|---:|---:|\n");
  fmt::print("| 1 | {:.2f} | {:.2f} | {:.3f} |\n", median(t1) / 1e6, median(h1) / 1e6, median(h1) / median(t1));
  fmt::print("| {} | {:.2f} | {:.2f} | {:.3f} |\n", threads, median(tT) / 1e6, median(hT) / 1e6, median(hT) / median(tT));
  fmt::print("hybrid {} threads / 1 thread: {:.3f}; TDM: {:.3f}\n", threads, median(hT) / median(h1), median(tT) / median(t1));
  // The same ratio within each round (its 1- and T-thread runs a few seconds apart, so under the
  // same load from the rest of the machine): the median and range over the rounds.
  std::vector<double> rh, rt;
  for (int k = 0; k < repeats; ++k) {
    rh.push_back(hT[k] / h1[k]);
    rt.push_back(tT[k] / t1[k]);
  }
  auto spread = [](const std::vector<double>& v) {
    const auto [lo, hi] = std::minmax_element(v.begin(), v.end());
    return fmt::format("{:.3f} ({:.3f}-{:.3f})", median(v), *lo, *hi);
  };
  fmt::print("per round, {} threads / 1 thread: hybrid {}, TDM {}\n", threads, spread(rh), spread(rt));
}

}  // namespace

int main(int argc, char** argv) {
  int repeats = 3, threads = 2;
  bool verbose = false, shuffle = false;
  double steps = 400.0;
  std::string only, one;
  for (int a = 1; a < argc; ++a) {
    if (!std::strcmp(argv[a], "--repeats") && a + 1 < argc) repeats = std::atoi(argv[++a]);
    else if (!std::strcmp(argv[a], "--only") && a + 1 < argc) only = argv[++a];
    else if (!std::strcmp(argv[a], "--threads") && a + 1 < argc) threads = std::atoi(argv[++a]);
    else if (!std::strcmp(argv[a], "--steps") && a + 1 < argc) steps = std::atof(argv[++a]);
    else if (!std::strcmp(argv[a], "--verbose")) verbose = true;
    else if (!std::strcmp(argv[a], "--shuffle")) shuffle = true;
    else if (!std::strcmp(argv[a], "--one") && a + 1 < argc) one = argv[++a];
  }
  const std::string src = MATEP_SOURCE_DIR;
  fmt::print("Hybrid against the pure methods, whole runs on one core, medians of {} alternated pairs.\n\n", repeats);
  fmt::print("| case | baseline | baseline s | hybrid s | hybrid / baseline | switches to soft | check |\n");
  fmt::print("|---|---|---:|---:|---:|---:|---|\n");
  if (only.empty() || only == "gas") {
    const std::string text =
        lattice_gas_scene(20.0, 9, 65.0, 0.95, "contact = \"hertz\"\nyoung = 1.0e7\npoisson = 0.3", "");
    const Scene scene = load_scene_string(text, "dilute_gas", "");
    const auto& sys = std::get<System<3>>(scene.system);
    EdmSettings es;
    es.end_time = scene.end_time;
    std::vector<double> te, th, ratio;
    std::uint64_t switches = 0, ce = 0, ch = 0;
    for (int k = 0; k < repeats; ++k) {
      const RunResult<3> re = run_edm<3>(sys, es, QueueKind::Calendar);
      const RunResult<3> rh = run_hybrid<3>(sys, es, hybrid_settings(scene));
      te.push_back(re.wall_seconds);
      th.push_back(rh.wall_seconds);
      ratio.push_back(rh.wall_seconds / re.wall_seconds);
      switches = rh.hybrid.to_soft;
      ce = re.counts.pair;
      ch = rh.counts.pair;
    }
    fmt::print("| dilute gas, e 0.95, phi 0.05, N 32768, t = 20 | EDM | {:.3f} | {:.3f} | {:.3f} | {} | pair collisions {} vs {} |\n",
               median(te), median(th), median(ratio), switches, ch, ce);
    std::fflush(stdout);
  }
  if (only.empty() || only == "pour") {
    const Scene scene = load_scene(src + "/cases/pour_settle.toml");
    const auto& sys = std::get<System<3>>(scene.system);
    EdmSettings es;
    es.end_time = scene.end_time;
    es.thermo_interval = 0.01;
    TdmSettings ts;
    ts.end_time = scene.end_time;
    ts.threads = 1;
    ts.thermo_interval = 0.01;
    std::vector<double> tt, th, ratio;
    double hh = 0.0, ht = 0.0, ke_err = 0.0;
    std::uint64_t switches = 0;
    for (int k = 0; k < repeats; ++k) {
      KeCurve ct, ch;
      const RunResult<3> rt = run_tdm<3>(sys, ts, {&ct});
      const RunResult<3> rh = run_hybrid<3>(sys, es, hybrid_settings(scene), {&ch});
      tt.push_back(rt.wall_seconds);
      th.push_back(rh.wall_seconds);
      ratio.push_back(rh.wall_seconds / rt.wall_seconds);
      hh = bed_height(rh);
      ht = bed_height(rt);
      // Kinetic-energy curves: the largest difference at the common sample times, relative to the
      // curve's peak.
      double peak = 0.0, worst = 0.0;
      for (double v : ct.ke) peak = std::max(peak, v);
      for (std::size_t a = 0; a < std::min(ct.ke.size(), ch.ke.size()); ++a)
        worst = std::max(worst, std::abs(ct.ke[a] - ch.ke[a]));
      ke_err = worst / peak;
      switches = rh.hybrid.to_soft;
    }
    fmt::print("| pour and settle (cases/pour_settle.toml), N 2000, t = {} | TDM | {:.2f} | {:.2f} | {:.3f} | {} | bed height {:.5g} vs {:.5g} ({:+.2f} %), KE curve max diff {:.2f} % of peak |\n",
               scene.end_time, median(tt), median(th), median(ratio), switches, hh, ht, 100.0 * (hh / ht - 1.0),
               100.0 * ke_err);
  }
  if (only.empty() || only == "soft") soft_set(repeats, threads, steps, shuffle, verbose, one);
  return 0;
}

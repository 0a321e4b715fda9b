// Whole-run EDM throughput: elastic hard spheres in 3D at number density 0.5 and 0.85, N from 4k
// to 1M, both schedulers. Prints collisions per second (collisions only, as DynamO counts them),
// ns per collision, other events beside, and peak memory per particle. Each configuration runs in
// its own process so that peak RSS belongs to it alone; each is repeated and the median is shown.
//
//   matep_bench_edm                  full table (N = 4k, 32k, 256k, 1M; a few minutes)
//   matep_bench_edm --quick          N = 4k and 32k only
//   matep_bench_edm --one N RHO QUEUE COLLISIONS_PER_PARTICLE [SHELL [ORDER [RESORT]]]   one measurement
//                    (internal; SHELL > 0: neighbour lists with shells of that size in diameters,
//                    else cells; ORDER: the particles' storage order at the start, lattice (default),
//                    shuffled or morton; RESORT: run.resort, auto (default), off, or the particle
//                    events per particle between two re-sorts)
#include <fmt/format.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <numbers>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include "bench/common.hpp"
#include "engine/edm.hpp"
#include "engine/renumber.hpp"

using namespace matep;

namespace {

using bench::current_rss_kb;
using bench::peak_rss_kb;

// n_side^3 unit spheres on a simple cubic lattice at number density rho, T = 1.
System<3> lattice(int n_side, double rho, std::uint64_t seed, const std::string& order) {
  System<3> s;
  const int N = n_side * n_side * n_side;
  const double L = std::cbrt(N / rho);
  s.upper = Vec<3>::Constant(L);
  s.periodic = {true, true, true};
  Material m;
  m.name = "hs";
  m.density = 6.0 / std::numbers::pi;
  s.materials.push_back(m);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g;
  s.x.reserve(N);
  s.v.reserve(N);
  const double a = L / n_side;
  Vec<3> p = Vec<3>::Zero();
  for (int i = 0; i < N; ++i) {
    s.x.emplace_back((i % n_side + 0.5) * a, ((i / n_side) % n_side + 0.5) * a, (i / n_side / n_side + 0.5) * a);
    s.v.emplace_back(g(rng), g(rng), g(rng));
    p += s.v.back();
  }
  for (auto& v : s.v) v -= p / N;
  s.radius.assign(N, 0.5);
  s.material.assign(N, 0);
  // The storage order (`order`): the lattice's rows (x fastest), a random permutation, or the
  // Morton (Z) order of the lattice sites, whose neighbours in space lie nearest in memory.
  if (order != "lattice") {
    std::vector<std::uint32_t> perm(N);
    std::iota(perm.begin(), perm.end(), 0u);
    if (order == "shuffled") {
      std::shuffle(perm.begin(), perm.end(), rng);
    } else {  // "morton": the bits of the site's three indices interleaved
      auto key = [&](std::uint32_t i) {
        const std::uint32_t c[3] = {i % n_side, (i / n_side) % n_side, i / n_side / n_side};
        std::uint64_t k = 0;
        for (int b = 0; b < 21; ++b)
          for (int d = 0; d < 3; ++d) k |= std::uint64_t((c[d] >> b) & 1u) << (3 * b + d);
        return k;
      };
      std::sort(perm.begin(), perm.end(), [&](std::uint32_t a, std::uint32_t b) { return key(a) < key(b); });
    }
    reorder(s, perm);  // engine/renumber.hpp
  }
  return s;
}

struct Timer final : Observer<3> {
  std::vector<double> wall;
  std::vector<std::uint64_t> coll;
  void on_sample(const ThermoSample& s) override {
    wall.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count());
    coll.push_back(s.collisions);
  }
};

int one(int n_side, double rho, const std::string& queue, double cpp, double shell, const std::string& order,
        double resort) {
  const long rss0 = current_rss_kb();
  System<3> sys = lattice(n_side, rho, 1, order);
  const double N = static_cast<double>(sys.size());
  // Enskog-CS collision rate per particle at T = 1 (docs/references.md §2.1) sets the run length;
  // the first sample (after ~3 collisions per particle) ends the melting of the lattice.
  const double phi = std::numbers::pi * rho / 6.0;
  const double g = (1 - phi / 2) / std::pow(1 - phi, 3);
  const double omega = 24 * phi * g / std::sqrt(std::numbers::pi);
  EdmSettings set;
  if (shell > 0.0) {  // neighbour lists, shells of this radius (in diameters)
    set.lists = true;
    set.shell = shell;
  }
  set.resort = resort;
  const double t_eq = 3.0 / omega;
  set.end_time = t_eq + cpp / omega;
  set.thermo_interval = t_eq;
  Timer timer;
  const auto res = run_edm<3>(std::move(sys), set, queue == "heap" ? QueueKind::Heap : QueueKind::Calendar, {&timer});
  // Samples: t = 0, t_eq, then possibly more every t_eq, and the end.
  const double dt = timer.wall.back() - timer.wall[1];
  const double dc = static_cast<double>(timer.coll.back() - timer.coll[1]);
  const double other = static_cast<double>(res.counts.cell + res.counts.stale) / res.counts.collisions();
  const double bytes = (peak_rss_kb() - rss0) * 1024.0 / N;
  std::printf("%d %.3f %s %.6g %.6g %.6g %.6g\n", static_cast<int>(N), rho, queue.c_str(), dc / dt,
              1e9 * dt / dc, other, bytes);
  return 0;
}

struct Row {
  int N;
  double rho;
  std::string queue;
  double rate, ns, other, bytes;
};

Row measure(const std::string& self, int n_side, double rho, const std::string& queue, double cpp, int reps) {
  std::vector<Row> rows;
  for (int r = 0; r < reps; ++r) {
    const std::string cmd = fmt::format("{} --one {} {} {} {}", self, n_side, rho, queue, cpp);
    std::unique_ptr<FILE, int (*)(FILE*)> p(popen(cmd.c_str(), "r"), pclose);
    Row row{};
    char q[32] = {};
    if (!p || std::fscanf(p.get(), "%d %lf %31s %lf %lf %lf %lf", &row.N, &row.rho, q, &row.rate, &row.ns,
                          &row.other, &row.bytes) != 7) {
      std::fprintf(stderr, "measurement failed: %s\n", cmd.c_str());
      std::exit(1);
    }
    row.queue = q;
    rows.push_back(row);
  }
  return bench::median_row(std::move(rows));
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> a(argv + 1, argv + argc);
  if (a.size() >= 5 && a.size() <= 8 && a[0] == "--one") {
    const std::string order = a.size() >= 7 ? a[6] : "lattice";
    const std::string rs = a.size() == 8 ? a[7] : "auto";
    const double resort = rs == "auto" ? -1.0 : rs == "off" ? 0.0 : std::stod(rs);
    if (order != "lattice" && order != "shuffled" && order != "morton") {
      std::fprintf(stderr, "matep_bench_edm: ORDER must be lattice, shuffled or morton, not \"%s\"\n", order.c_str());
      return 2;
    }
    return one(std::stoi(a[1]), std::stod(a[2]), a[3], std::stod(a[4]), a.size() >= 6 ? std::stod(a[5]) : 0.0, order,
               resort);
  }
  const bool quick = !a.empty() && a[0] == "--quick";
  const std::string self = "/proc/self/exe";
  char buf[4096];
  const ssize_t len = readlink(self.c_str(), buf, sizeof buf - 1);
  const std::string exe = len > 0 ? std::string(buf, len) : std::string(argv[0]);
  std::vector<int> sides = {16, 32, 64, 100};  // 4096, 32768, 262144, 1000000
  if (quick) sides = {16, 32};
  fmt::print("Elastic hard spheres, 3D, one core. Median of {} runs; collisions only in coll/s.\n", quick ? 3 : 3);
  fmt::print("{:>8} {:>5} {:>9} {:>12} {:>10} {:>14} {:>11} {:>16}\n", "N", "rho", "queue", "coll/s",
             "ns/coll", "other ev/coll", "bytes/part", "ns/coll vs 32k");
  for (double rho : {0.5, 0.85}) {
    for (const std::string queue : {"calendar", "heap"}) {
      double ns32 = 0.0;
      for (int s : sides) {
        const int N = s * s * s;
        const double cpp = N >= 1000000 ? 10.0 : 30.0;
        const Row r = measure(exe, s, rho, queue, cpp, 3);
        if (N == 32768) ns32 = r.ns;
        fmt::print("{:>8} {:>5.2f} {:>9} {:>12.4g} {:>10.1f} {:>14.2f} {:>11.0f} {:>16}\n", r.N, r.rho, r.queue, r.rate,
                   r.ns, r.other, r.bytes, ns32 > 0 ? fmt::format("{:.2f}", r.ns / ns32) : std::string("-"));
        std::fflush(stdout);
      }
    }
  }
  return 0;
}

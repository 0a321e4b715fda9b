// Whole-run TDM throughput in particle-steps per second (N x steps / wall seconds of run_tdm,
// RunResult::soft.particle_steps_per_second), on one core and on all cores, against the LAMMPS
// GRANULAR one-core reference figures. Two cases, 32^3 = 32768 equal spheres each:
//
//  gas  dilute granular gas: packing fraction 0.2, periodic box, linear spring-dashpot with
//       e = 0.9, no friction, the default step (0.02 t_c = t_c/50), skin 0.1 d (default).
//       Units d = m = 1, T = 1; k_n = m v^2/delta^2 with v = 3 sqrt(T/m), delta = 0.01 d, so that
//       a head-on impact at three thermal speeds compresses ~1 % of d. The lattice start is
//       melted once (about three collisions per particle), cached, and each measured run starts
//       from the melted state rescaled to T = 1.
//  bed  dense settled bed: glass-density beads (d = 1 cm, rho = 2500 kg/m^3) with a soft modulus
//       (E = 1e7 Pa, nu = 0.3; the usual reduced-E DEM choice: overlaps of order 1 % of d, the
//       largest ~4.5 %),
//       Hertz-Mindlin with friction 0.5 and e = 0.5, gravity 9.81 m/s^2, periodic sides and a
//       floor. Poured once (single thread, so the state is the same everywhere) from a loose
//       jittered lattice with run_tdm itself until the kinetic energy is small, cached in a
//       binary file next to the executable (build/tdm_bench_bed_32.bin; delete it to pour again,
//       ~20 min for 32k); each measured run is a fixed number of steps from the settled state (the
//       tangential springs restart at zero).
//
// Each measurement runs in its own process (peak RSS belongs to it alone) and is repeated; the
// table shows medians. Bytes per particle = (peak RSS - RSS before the system is built) / N.
//
//   matep_bench_tdm                 full table (N = 32768; prepares the cached states first)
//   matep_bench_tdm --quick         N = 4096 smoke test (fewer steps, one repeat)
//   matep_bench_tdm --one CASE NSIDE THREADS STEPS    one measurement (internal)
//   matep_bench_tdm --prepare CASE NSIDE              build the cached initial state (internal)
#include <fmt/format.h>
#include <omp.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "bench/common.hpp"
#include "engine/tdm.hpp"

using namespace matep;

namespace {

constexpr double kPi = std::numbers::pi;

// LAMMPS GRANULAR one-core reference figures (particle-steps per second), same 32k setups.
constexpr double kLammpsGas = 48e6;
constexpr double kLammpsBed = 4.2e6;

// ---- gas parameters (reduced units: d = 1, m = 1, T = 1) ----
constexpr double kGasPhi = 0.2;
constexpr double kGasE = 0.9;
constexpr double kGasT = 1.0;
double gas_stiffness() {
  const double m = 1.0, v = 3.0 * std::sqrt(kGasT / m), delta = 0.01;  // m v^2 = k delta^2
  return m * v * v / (delta * delta);
}

// ---- bed parameters (SI) ----
constexpr double kBedD = 0.01;      // m
constexpr double kBedRho = 2500.0;  // kg/m^3
constexpr double kBedYoung = 1e7;   // Pa
constexpr double kBedPoisson = 0.3;
constexpr double kBedMu = 0.5;
constexpr double kBedE = 0.5;
constexpr double kBedG = 9.81;       // m/s^2
constexpr double kBedSpacing = 1.1;  // lattice spacing of the loose start, in diameters

using bench::current_rss_kb;
using bench::peak_rss_kb;

double now() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }

// ---- the two systems (geometry and materials; particles from a lattice or from the cache) ----

System<3> gas_frame(int n_side) {
  System<3> s;
  const int N = n_side * n_side * n_side;
  const double L = std::cbrt(N * (kPi / 6.0) / kGasPhi);
  s.upper = Vec<3>::Constant(L);
  s.periodic = {true, true, true};
  Material m;
  m.name = "grain";
  m.density = 6.0 / kPi;  // unit mass for unit diameter
  m.contact = "linear";
  m.stiffness = gas_stiffness();
  m.restitution = Restitution::constant(kGasE);
  s.materials.push_back(m);
  return s;
}

System<3> gas_lattice(int n_side, std::uint64_t seed) {
  System<3> s = gas_frame(n_side);
  const int N = n_side * n_side * n_side;
  const double a = s.upper[0] / n_side;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g;
  Vec<3> p = Vec<3>::Zero();
  for (int i = 0; i < N; ++i) {
    s.x.emplace_back((i % n_side + 0.5) * a, ((i / n_side) % n_side + 0.5) * a, (i / n_side / n_side + 0.5) * a);
    s.v.emplace_back(g(rng), g(rng), g(rng));
    p += s.v.back();
  }
  for (auto& v : s.v) v -= p / N;
  s.radius.assign(N, 0.5);
  s.material.assign(N, 0);
  return s;
}

// Zero total momentum and T = (1/N) sum m v^2 / 3 = kGasT exactly (m = 1).
void rescale_gas(System<3>& s) {
  Vec<3> p = Vec<3>::Zero();
  for (const auto& v : s.v) p += v;
  p /= static_cast<double>(s.v.size());
  double mv2 = 0.0;
  for (auto& v : s.v) {
    v -= p;
    mv2 += v.squaredNorm();
  }
  const double f = std::sqrt(kGasT * 3.0 * s.v.size() / mv2);
  for (auto& v : s.v) v *= f;
}

// N m g d: the kinetic-energy scale of the bed.
double bed_energy_scale(int N) { return N * kBedRho * kPi / 6.0 * std::pow(kBedD, 3) * kBedG * kBedD; }

double bed_width(int n_side) { return n_side * kBedSpacing * kBedD; }
double bed_lattice_top(int n_side) { return (0.5 + (n_side - 1) * kBedSpacing + 0.5) * kBedD; }

System<3> bed_frame(int n_side) {
  System<3> s;
  const double W = bed_width(n_side);
  s.upper = Vec<3>(W, W, bed_lattice_top(n_side) + 5.0 * kBedD);
  s.periodic = {true, true, false};
  s.gravity = Vec<3>(0.0, 0.0, -kBedG);
  Material m;
  m.name = "glass";
  m.density = kBedRho;
  m.contact = "hertz";
  m.young = kBedYoung;
  m.poisson = kBedPoisson;
  m.friction = kBedMu;
  m.restitution = Restitution::constant(kBedE);
  s.materials.push_back(m);
  s.walls.push_back(plane_wall<3>("floor", Vec<3>::Zero(), Vec<3>(0.0, 0.0, 1.0), 0));
  return s;
}

// Loose simple cubic lattice (spacing 1.1 d) jittered by up to 0.04 d per axis, with small random
// velocities (0.05 m/s per component) so that the columns do not stack.
System<3> bed_lattice(int n_side, std::uint64_t seed) {
  System<3> s = bed_frame(n_side);
  const int N = n_side * n_side * n_side;
  const double a = kBedSpacing * kBedD;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g;
  std::uniform_real_distribution<double> u(-0.04 * kBedD, 0.04 * kBedD);
  Vec<3> p = Vec<3>::Zero();
  for (int i = 0; i < N; ++i) {
    const Vec<3> site((i % n_side + 0.5) * a, ((i / n_side) % n_side + 0.5) * a,
                      0.5 * kBedD + (i / n_side / n_side) * a);
    s.x.push_back(site + Vec<3>(u(rng), u(rng), u(rng)));
    s.v.emplace_back(0.05 * g(rng), 0.05 * g(rng), 0.05 * g(rng));
    p += s.v.back();
  }
  for (auto& v : s.v) v -= p / N;
  s.radius.assign(N, 0.5 * kBedD);
  s.material.assign(N, 0);
  return s;
}

// ---- cached states: positions, velocities, spins of every particle ----

std::string exe_dir() {
  char buf[4096];
  const ssize_t len = readlink("/proc/self/exe", buf, sizeof buf - 1);
  if (len <= 0) return ".";
  return std::filesystem::path(std::string(buf, len)).parent_path().string();
}

// The tag names every parameter the state depends on; a cache with another tag is rebuilt.
std::string cache_tag(const std::string& which, int n_side) {
  if (which == "gas")
    return fmt::format("tdm-bench-v1 gas n={} phi={} k={} e={} T={}", n_side, kGasPhi, gas_stiffness(), kGasE, kGasT);
  return fmt::format("tdm-bench-v1 bed n={} d={} rho={} E={} nu={} mu={} e={} g={} a={}", n_side, kBedD, kBedRho,
                     kBedYoung, kBedPoisson, kBedMu, kBedE, kBedG, kBedSpacing);
}

std::string cache_path(const std::string& which, int n_side) {
  return fmt::format("{}/tdm_bench_{}_{}.bin", exe_dir(), which, n_side);
}

void save_state(const std::string& path, const std::string& tag, const RunResult<3>& r) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp, std::ios::binary);
    const std::uint64_t tl = tag.size(), n = r.x.size();
    f.write(reinterpret_cast<const char*>(&tl), sizeof tl);
    f.write(tag.data(), static_cast<std::streamsize>(tl));
    f.write(reinterpret_cast<const char*>(&n), sizeof n);
    auto put = [&](const auto& vec) {
      f.write(reinterpret_cast<const char*>(vec.data()), static_cast<std::streamsize>(vec.size() * sizeof vec[0]));
    };
    put(r.x);
    put(r.v);
    std::vector<Spin<3>> w = r.w;
    w.resize(n, Spin<3>::Zero());
    put(w);
    if (!f) throw std::runtime_error("cannot write " + tmp);
  }
  std::filesystem::rename(tmp, path);
}

// Fills s.x, s.v, s.w, s.radius, s.material from the cache; false if absent or stale.
bool load_state(const std::string& path, const std::string& tag, System<3>& s, double radius) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return false;
  std::uint64_t tl = 0, n = 0;
  f.read(reinterpret_cast<char*>(&tl), sizeof tl);
  if (!f || tl != tag.size()) return false;
  std::string t(tl, '\0');
  f.read(t.data(), static_cast<std::streamsize>(tl));
  if (!f || t != tag) return false;
  f.read(reinterpret_cast<char*>(&n), sizeof n);
  if (!f || n == 0 || n > (1u << 26)) return false;
  s.x.resize(n);
  s.v.resize(n);
  s.w.resize(n);
  auto get = [&](auto& vec) {
    f.read(reinterpret_cast<char*>(vec.data()), static_cast<std::streamsize>(vec.size() * sizeof vec[0]));
  };
  get(s.x);
  get(s.v);
  get(s.w);
  if (!f) return false;
  s.radius.assign(n, radius);
  s.material.assign(n, 0);
  return true;
}

// ---- structure of a state: contacts and packing fraction ----

struct Contacts {
  std::uint64_t pairs = 0, walls = 0;
};

// Pairs closer than R_i + R_j (periodic images included) and particles touching a wall.
Contacts count_contacts(const System<3>& s, const std::vector<Vec<3>>& x) {
  Contacts c;
  const std::size_t N = x.size();
  double dmax = 0.0;
  for (double r : s.radius) dmax = std::max(dmax, 2.0 * r);
  const Vec<3> L = s.upper - s.lower;
  std::array<int, 3> nc{};
  for (int k = 0; k < 3; ++k) nc[k] = std::max(1, static_cast<int>(L[k] / dmax));
  auto cell = [&](const Vec<3>& p, int k) {
    return std::clamp(static_cast<int>((p[k] - s.lower[k]) / L[k] * nc[k]), 0, nc[k] - 1);
  };
  std::vector<std::vector<std::uint32_t>> cells(static_cast<std::size_t>(nc[0]) * nc[1] * nc[2]);
  auto idx = [&](int a, int b, int d) { return (static_cast<std::size_t>(d) * nc[1] + b) * nc[0] + a; };
  for (std::size_t i = 0; i < N; ++i) cells[idx(cell(x[i], 0), cell(x[i], 1), cell(x[i], 2))].push_back(i);
  for (std::size_t i = 0; i < N; ++i) {
    const int ci[3] = {cell(x[i], 0), cell(x[i], 1), cell(x[i], 2)};
    std::vector<std::size_t> seen;
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          int cc[3] = {ci[0] + dx, ci[1] + dy, ci[2] + dz};
          bool ok = true;
          for (int k = 0; k < 3; ++k) {
            if (cc[k] < 0 || cc[k] >= nc[k]) {
              if (!s.periodic[k]) ok = false;
              cc[k] = (cc[k] + nc[k]) % nc[k];
            }
          }
          if (!ok) continue;
          const std::size_t id = idx(cc[0], cc[1], cc[2]);
          if (std::find(seen.begin(), seen.end(), id) != seen.end()) continue;
          seen.push_back(id);
          for (std::uint32_t j : cells[id]) {
            if (j <= i) continue;
            Vec<3> d = x[i] - x[j];
            for (int k = 0; k < 3; ++k)
              if (s.periodic[k]) d[k] -= L[k] * std::round(d[k] / L[k]);
            const double rs = s.radius[i] + s.radius[j];
            if (d.squaredNorm() < rs * rs) ++c.pairs;
          }
        }
    for (const auto& w : s.walls)
      if (w.geometry().at(x[i], s.radius[i], 0.0).gap < 0.0) ++c.walls;
  }
  return c;
}

// Volume of the sphere (centre height zc, radius R) between heights a < b.
double slab_volume(double zc, double R, double a, double b) {
  const double lo = std::max(a, zc - R), hi = std::min(b, zc + R);
  if (hi <= lo) return 0.0;
  auto F = [&](double z) { return R * R * z - (z - zc) * (z - zc) * (z - zc) / 3.0; };
  return kPi * (F(hi) - F(lo));
}

struct BedShape {
  double phi = 0.0;  // packing fraction of the bulk slab
  double slab_lo = 0.0, slab_hi = 0.0;
  double height = 0.0;  // solid volume / (area x phi)
  double z_max = 0.0;   // highest particle centre
};

// Bulk packing fraction between 2 d above the floor and 4 d below the highest centre.
BedShape bed_shape(const System<3>& s, const std::vector<Vec<3>>& x) {
  BedShape b;
  double solid = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    b.z_max = std::max(b.z_max, x[i][2]);
    solid += 4.0 / 3.0 * kPi * std::pow(s.radius[i], 3);
  }
  b.slab_lo = 2.0 * kBedD;
  b.slab_hi = b.z_max - 4.0 * kBedD;
  const double area = (s.upper[0] - s.lower[0]) * (s.upper[1] - s.lower[1]);
  double v = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i) v += slab_volume(x[i][2], s.radius[i], b.slab_lo, b.slab_hi);
  b.phi = b.slab_hi > b.slab_lo ? v / (area * (b.slab_hi - b.slab_lo)) : 0.0;
  b.height = b.phi > 0.0 ? solid / (area * b.phi) : 0.0;
  return b;
}

double kinetic_energy(const System<3>& s, const std::vector<Vec<3>>& v) {
  double e = 0.0;
  for (std::size_t i = 0; i < v.size(); ++i) e += 0.5 * s.mass(i) * v[i].squaredNorm();
  return e;
}

int all_threads() { return std::max(1, omp_get_num_procs()); }

// The 1, 5 and 15 minute load averages (other work on the machine skews the multi-thread rows).
std::string load_average() {
  std::string s;
  if (std::FILE* f = std::fopen("/proc/loadavg", "r")) {
    double a = 0, b = 0, c = 0;
    if (std::fscanf(f, "%lf %lf %lf", &a, &b, &c) == 3) s = fmt::format("{:.2f} {:.2f} {:.2f}", a, b, c);
    std::fclose(f);
  }
  return s.empty() ? "?" : s;
}

struct KeLogger final : Observer<3> {
  double t0 = 0.0, scale = 1.0;
  void on_sample(const ThermoSample& s) override {
    std::fprintf(stderr, "  t = %.4f  KE/(N m g d) = %.3e\n", t0 + s.time, s.kinetic_energy / scale);
  }
};

// ---- preparation (once, cached) ----

int prepare(const std::string& which, int n_side) {
  const std::string path = cache_path(which, n_side), tag = cache_tag(which, n_side);
  const double w0 = now();
  if (which == "gas") {
    System<3> s = gas_lattice(n_side, 1);
    // Melt: about three collisions per particle (Enskog-CS collision rate at T = 1).
    const double g = (1 - kGasPhi / 2) / std::pow(1 - kGasPhi, 3);
    const double omega = 24 * kGasPhi * g / std::sqrt(kPi);
    TdmSettings set;
    set.end_time = 3.0 / omega;
    set.threads = 1;  // the cached state is the same on every machine
    const RunResult<3> r = run_tdm<3>(std::move(s), set);
    if (r.status != "ok") {
      std::fprintf(stderr, "gas preparation stopped: %s: %s\n", r.status.c_str(), r.message.c_str());
      return 1;
    }
    save_state(path, tag, r);
    std::fprintf(stderr, "prepared gas N=%zu: %llu steps of dt=%.4g in %.1f s, max overlap %.4g d -> %s\n", r.x.size(),
                 static_cast<unsigned long long>(r.soft.steps), r.soft.dt, now() - w0, r.max_overlap_relative,
                 path.c_str());
    return 0;
  }
  // Bed: pour from the loose lattice, then keep going in passes until the kinetic energy per
  // particle is below 1e-5 m g d, or four passes (~2 s). The structure is at rest long before
  // that; what is left is the bed ringing in its fundamental vertical mode (period ~0.07 s for
  // 32k, amplitude < 0.01 d), which viscous contact damping damps only weakly (the damping
  // ratio of a mode scales with its frequency over the contact frequency, ~0.01 here).
  System<3> s = bed_lattice(n_side, 1);
  const int N = n_side * n_side * n_side;
  const double scale = bed_energy_scale(N);
  const double h_est = N * kPi / 6.0 * kBedD * kBedD * kBedD / (0.59 * std::pow(bed_width(n_side), 2));
  // First pass: the fall plus 1 s of settling in one run; then, if needed, passes of 0.3 s. A
  // restart drops the tangential springs, which sets off small slips in a deep bed, so the passes
  // are long and few.
  double t = 0.0, chunk = std::sqrt(2.0 * (bed_lattice_top(n_side) - h_est) / kBedG) + 1.0;
  KeLogger log;
  log.scale = scale;
  RunResult<3> r;
  for (int pass = 0; pass < 4; ++pass) {
    TdmSettings set;
    set.end_time = chunk;
    set.threads = 1;  // the cached state is the same on every machine
    set.thermo_interval = 0.1;
    log.t0 = t;
    System<3> in = bed_frame(n_side);
    if (pass == 0) {
      in = s;
    } else {
      in.x = r.x;
      in.v = r.v;
      in.w = r.w;
      in.radius = r.radius;
      in.material.assign(N, 0);
    }
    r = run_tdm<3>(std::move(in), set, {&log});
    if (r.status != "ok") {
      std::fprintf(stderr, "bed preparation stopped: %s: %s\n", r.status.c_str(), r.message.c_str());
      return 1;
    }
    t += r.time;
    const double ke = kinetic_energy(s, r.v) / scale;
    if (ke < 1e-5) break;
    chunk = 0.3;
  }
  save_state(path, tag, r);
  const BedShape b = bed_shape(s, r.x);
  const Contacts c = count_contacts(s, r.x);
  std::fprintf(stderr,
               "prepared bed N=%d: poured for %.3f s (dt=%.4g) in %.1f s; KE/(N m g d) = %.2e, phi = %.4f, "
               "Z = %.3f, max overlap %.4g d -> %s\n",
               N, t, r.soft.dt, now() - w0, kinetic_energy(s, r.v) / scale, b.phi, 2.0 * c.pairs / N,
               r.max_overlap_relative, path.c_str());
  return 0;
}

// ---- one measurement ----

int one(const std::string& which, int n_side, int threads, std::uint64_t steps) {
  const long rss0 = current_rss_kb();
  const bool gas = which == "gas";
  System<3> s = gas ? gas_frame(n_side) : bed_frame(n_side);
  if (!load_state(cache_path(which, n_side), cache_tag(which, n_side), s, gas ? 0.5 : 0.5 * kBedD)) {
    std::fprintf(stderr, "no cached state %s; run --prepare %s %d\n", cache_path(which, n_side).c_str(), which.c_str(),
                 n_side);
    return 1;
  }
  if (gas) rescale_gas(s);
  const System<3> frame = gas ? gas_frame(n_side) : bed_frame(n_side);  // radii for the analysis
  TdmSettings set;
  set.threads = threads;
  const SoftPlan plan = tdm_preflight<3>(s, set);
  set.dt = plan.default_dt;
  set.end_time = static_cast<double>(steps) * plan.default_dt;
  const double N = static_cast<double>(s.size());
  const double ke0 = kinetic_energy(s, s.v);
  const RunResult<3> r = run_tdm<3>(std::move(s), set);
  const double bytes = (peak_rss_kb() - rss0) * 1024.0 / N;
  if (r.status != "ok") {
    std::fprintf(stderr, "run stopped: %s: %s\n", r.status.c_str(), r.message.c_str());
    return 1;
  }
  System<3> a = frame;
  a.radius.assign(r.x.size(), gas ? 0.5 : 0.5 * kBedD);
  a.material.assign(r.x.size(), 0);
  const Contacts c = count_contacts(a, r.x);
  const double phi = gas ? kGasPhi : bed_shape(a, r.x).phi;
  // rate dt steps rebuilds threads bytes max_overlap_rel Z_pair walls_per_particle phi wall_s KE0 KE1 contact_time
  std::printf("%.9g %.9g %llu %llu %d %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g\n", r.soft.particle_steps_per_second,
              r.soft.dt, static_cast<unsigned long long>(r.soft.steps),
              static_cast<unsigned long long>(r.soft.rebuilds), r.soft.threads, bytes, r.max_overlap_relative,
              2.0 * c.pairs / N, c.walls / N, phi, r.wall_seconds, ke0, kinetic_energy(a, r.v),
              std::min(plan.contact_time, plan.rayleigh_time));
  return 0;
}

struct Row {
  double rate = 0, dt = 0;
  unsigned long long steps = 0, rebuilds = 0;
  int threads = 0;
  double bytes = 0, overlap = 0, Z = 0, walls = 0, phi = 0, wall_s = 0, ke0 = 0, ke1 = 0, tc = 0;
};

Row measure(const std::string& exe, const std::string& which, int n_side, int threads, std::uint64_t steps, int reps) {
  std::vector<Row> rows;
  for (int k = 0; k < reps; ++k) {
    const std::string cmd = fmt::format("{} --one {} {} {} {}", exe, which, n_side, threads, steps);
    std::unique_ptr<FILE, int (*)(FILE*)> p(popen(cmd.c_str(), "r"), pclose);
    Row r;
    if (!p || std::fscanf(p.get(), "%lf %lf %llu %llu %d %lf %lf %lf %lf %lf %lf %lf %lf %lf", &r.rate, &r.dt, &r.steps,
                          &r.rebuilds, &r.threads, &r.bytes, &r.overlap, &r.Z, &r.walls, &r.phi, &r.wall_s, &r.ke0,
                          &r.ke1, &r.tc) != 14) {
      std::fprintf(stderr, "measurement failed: %s\n", cmd.c_str());
      std::exit(1);
    }
    std::fprintf(stderr, "  %s N=%d threads=%d: %.4g particle-steps/s (%.2f s, %llu rebuilds)\n", which.c_str(),
                 n_side * n_side * n_side, r.threads, r.rate, r.wall_s, r.rebuilds);
    rows.push_back(r);
  }
  return bench::median_row(std::move(rows));
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> a(argv + 1, argv + argc);
  try {
    if (a.size() == 5 && a[0] == "--one") return one(a[1], std::stoi(a[2]), std::stoi(a[3]), std::stoull(a[4]));
    if (a.size() == 3 && a[0] == "--prepare") return prepare(a[1], std::stoi(a[2]));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
  const bool quick = a.size() == 1 && a[0] == "--quick";
  if (!a.empty() && !quick) {
    std::fprintf(stderr,
                 "usage: matep_bench_tdm [--quick]\n"
                 "       matep_bench_tdm --one gas|bed NSIDE THREADS STEPS\n"
                 "       matep_bench_tdm --prepare gas|bed NSIDE\n");
    return 2;
  }
  // As the CLI does: OpenMP threads that spin at every barrier lose a scheduler quantum per step
  // when another process shares the cores, so the measurements run with passive waiting unless
  // the caller chose a policy (libgomp reads it at start-up; the child processes inherit it).
  if (std::getenv("OMP_WAIT_POLICY") == nullptr) setenv("OMP_WAIT_POLICY", "passive", 1);
  const std::string policy = std::getenv("OMP_WAIT_POLICY");
  const std::string exe = exe_dir() + "/" + std::filesystem::path(argv[0]).filename().string();
  const int n_side = quick ? 16 : 32;
  const int reps = quick ? 1 : 3;
  const std::uint64_t gas_steps = quick ? 1000 : 5000, bed_steps = quick ? 500 : 2000;
  std::vector<int> threads = {1};
  if (all_threads() > 1) threads.push_back(all_threads());

  for (const std::string which : {"gas", "bed"}) {
    System<3> probe = which == "gas" ? gas_frame(n_side) : bed_frame(n_side);
    if (!load_state(cache_path(which, n_side), cache_tag(which, n_side), probe, 1.0)) {
      std::fprintf(stderr, "preparing the %s state (once; cached in %s)\n", which.c_str(),
                   cache_path(which, n_side).c_str());
      const std::string cmd = fmt::format("{} --prepare {} {}", exe, which, n_side);
      if (std::system(cmd.c_str()) != 0) {
        std::fprintf(stderr, "preparation failed: %s\n", cmd.c_str());
        return 1;
      }
    }
  }

  const std::string load_before = load_average();
  struct Line {
    std::string name;
    int N, threads;
    Row r;
    double speedup, ref;
  };
  std::vector<Line> lines;
  Row gas1, bed1;
  for (const std::string which : {"gas", "bed"}) {
    double base = 0.0;
    for (int t : threads) {
      const Row r = measure(exe, which, n_side, t, which == "gas" ? gas_steps : bed_steps, reps);
      if (t == 1) base = r.rate;
      if (t == 1) (which == "gas" ? gas1 : bed1) = r;
      lines.push_back({which, n_side * n_side * n_side, r.threads, r, base > 0 ? r.rate / base : 0.0,
                       which == "gas" ? kLammpsGas : kLammpsBed});
    }
  }

  const int N = n_side * n_side * n_side;
  fmt::print("TDM whole-run throughput, N = {} ({}), {} cores; median of {} run{} per row, each in its own process.\n",
             N, quick ? "--quick" : "full", all_threads(), reps, reps > 1 ? "s" : "");
  fmt::print(
      "gas: phi = {}, linear k_n = {:.4g} (= m v^2/delta^2, v = 3 sqrt(T/m), delta = 0.01 d; units m = d = T = 1), e = "
      "{}, no friction, dt = {:.4g} = t_c/{:.0f}, "
      "skin 0.1 d, {} steps from a melted state at T = 1 (KE {:.4g} -> {:.4g}); largest overlap {:.4f} d; "
      "{} list builds.\n",
      kGasPhi, gas_stiffness(), kGasE, gas1.dt, gas1.tc / gas1.dt, gas1.steps, gas1.ke0, gas1.ke1, gas1.overlap,
      gas1.rebuilds);
  fmt::print(
      "bed: d = {} m, rho = {}, Hertz-Mindlin E = {:.3g} Pa, nu = {}, mu = {}, e = {}, g = {}, periodic sides + "
      "floor, dt = {:.4g} = t_Rayleigh/{:.0f}, skin 0.1 d, {} steps from the settled state; bulk phi = {:.4f}, "
      "contacts per particle Z = {:.3f} (+ {:.3f} floor contacts per particle); largest overlap {:.4f} of the "
      "contact distance (d; R at the floor); KE/(N m g d) {:.3g} -> {:.3g} (the tangential springs restart at "
      "zero); {} list builds.\n",
      kBedD, kBedRho, kBedYoung, kBedPoisson, kBedMu, kBedE, kBedG, bed1.dt, bed1.tc / bed1.dt, bed1.steps, bed1.phi,
      bed1.Z, bed1.walls, bed1.overlap, bed1.ke0 / bed_energy_scale(N), bed1.ke1 / bed_energy_scale(N), bed1.rebuilds);
  fmt::print("OMP_WAIT_POLICY={}; load average (1, 5, 15 min) before the measurements {}, after {}.\n\n", policy,
             load_before, load_average());
  fmt::print(
      "| case | N | threads | particle-steps/s (median) | speed-up vs 1 thread | bytes/particle | vs LAMMPS 1 core "
      "|\n");
  fmt::print("|---|---:|---:|---:|---:|---:|---:|\n");
  for (const auto& l : lines)
    fmt::print("| {} | {} | {} | {:.4g} | {:.2f} | {:.0f} | {:.3f} (ref {:.3g}) |\n",
               l.name == "gas" ? "dilute gas, linear, phi 0.2" : "settled bed, Hertz-Mindlin mu 0.5", l.N, l.threads,
               l.r.rate, l.speedup, l.r.bytes, l.r.rate / l.ref, l.ref);
  return 0;
}

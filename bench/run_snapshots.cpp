// Snapshot writing: bytes and time per grain per frame of each format (io/snapshots.hpp), on one
// frame of N grains in 3D with spins (a TDM run's snapshot: positions, velocities, spins, radii,
// two groups, one material, mode 1), every value a full-precision double as a run makes them.
// Each format writes the frame `repeats` times with one writer (as a run writes its series); the
// median time is shown, with the ratio to the ASCII VTK of the same run (the baseline measured
// alongside). The times include the .pvd rewritten after each VTK snapshot.
//
//   matep_bench_snapshots [N] [repeats] [FILTER]   default N = 200000, 5 repeats; FILTER: only the
//                                                  formats whose name contains it (besides the baseline)
#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "io/snapshots.hpp"

using namespace matep;
namespace fs = std::filesystem;

int main(int argc, char** argv) {
  const std::size_t n = argc > 1 ? std::strtoull(argv[1], nullptr, 10) : 200000;
  const int repeats = argc > 2 ? std::atoi(argv[2]) : 5;
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> pos(0.0, 0.5), vel(-1.0, 1.0), rad(0.004, 0.006);
  Snapshot<3> snap;
  snap.time = 0.123456789;
  for (std::size_t i = 0; i < n; ++i) {
    snap.x.emplace_back(pos(rng), pos(rng), pos(rng));
    snap.v.emplace_back(vel(rng), vel(rng), vel(rng));
    snap.w.emplace_back(100 * vel(rng), 100 * vel(rng), 100 * vel(rng));
    snap.radius.push_back(rad(rng));
  }
  snap.mode.assign(n, 1);
  StateLabels labels;
  labels.group_names = {"bed", "inlet.feed"};
  labels.materials = {"glass"};
  for (std::size_t i = 0; i < n; ++i) {
    labels.group.push_back(i % 7 == 0 ? 1 : 0);
    labels.material.push_back(0);
  }
  const fs::path root = fs::temp_directory_path() / ("matep_bench_snapshots_" + std::to_string(::getpid()));
  struct Row {
    const char* name;
    SnapshotFormats f;
    const char* ext;
  };
  auto fmt_of = [](bool vtk, bool ascii, bool xyz, bool lammps, bool single) {
    SnapshotFormats f;
    f.vtk = vtk, f.vtk_ascii = ascii, f.xyz = xyz, f.lammps = lammps, f.single = single;
    return f;
  };
  const Row rows[] = {
      {"vtk_ascii (float64)", fmt_of(false, true, false, false, false), "vtp"},
      {"vtk binary (float64)", fmt_of(true, false, false, false, false), "vtp"},
      {"vtk binary (float32)", fmt_of(true, false, false, false, true), "vtp"},
      {"vtk_ascii (single)", fmt_of(false, true, false, false, true), "vtp"},
      {"xyz (double)", fmt_of(false, false, true, false, false), "xyz"},
      {"xyz (single)", fmt_of(false, false, true, false, true), "xyz"},
      {"lammps (double)", fmt_of(false, false, false, true, false), "lammpstrj"},
      {"lammps (single)", fmt_of(false, false, false, true, true), "lammpstrj"},
  };
  fmt::print("snapshot of {} grains (3D, with spins), median of {} writes\n", n, repeats);
  fmt::print("{:<22} {:>12} {:>10} {:>12} {:>10} {:>10}\n", "format", "bytes/grain", "vs ascii", "ns/grain",
             "vs ascii", "MB/s");
  double base_bytes = 0, base_ns = 0;
  const std::string filter = argc > 3 ? argv[3] : "";
  for (const Row& r : rows) {
    if (&r != &rows[0] && std::string(r.name).find(filter) == std::string::npos) continue;
    // One writer writes the frame `repeats` times (as a run writes its series), after one warm-up
    // write; each write is timed.
    std::vector<double> secs;
    std::uintmax_t bytes = 0;
    const fs::path dir = root / "run";
    fs::remove_all(dir);
    fs::create_directories(dir);
    SnapshotWriter<3> w(dir.string(), r.f, labels, {}, Vec<3>::Zero(), Vec<3>::Constant(0.5), {false, false, false});
    w.on_snapshot(snap);
    for (int k = 1; k <= repeats; ++k) {
      const auto t0 = std::chrono::steady_clock::now();
      w.on_snapshot(snap);
      secs.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
      bytes = fs::file_size(dir / fmt::format("snapshots/snap_{:06d}.{}", k, r.ext));
    }
    std::sort(secs.begin(), secs.end());
    const double t = secs[secs.size() / 2];
    const double bpg = static_cast<double>(bytes) / static_cast<double>(n), ns = 1e9 * t / static_cast<double>(n);
    if (base_bytes == 0) base_bytes = bpg, base_ns = ns;
    fmt::print("{:<22} {:>12.1f} {:>10.3f} {:>12.1f} {:>10.3f} {:>10.0f}\n", r.name, bpg, bpg / base_bytes, ns,
               ns / base_ns, static_cast<double>(bytes) / t / 1e6);
  }
  fs::remove_all(root);
  return 0;
}

// Snapshots: the grains (and walls) at t = 0, every output.snapshot_interval and the end, in the
// formats of output.format (README "Outputs"):
//   vtk        DIR/snapshots/snap_NNNNNN.vtp, VTK XML PolyData with appended raw binary arrays, and
//              the series DIR/snapshots.pvd (ParaView), walls as DIR/snapshots/wall_*.vtp
//   vtk_ascii  the same files with ASCII arrays
//   xyz        DIR/snapshots/snap_NNNNNN.xyz, extended XYZ (OVITO, ASE)
//   lammps     DIR/snapshots/snap_NNNNNN.lammpstrj, a LAMMPS "dump custom" frame (OVITO, ASE)
// with output.precision = "double" (default: float64 arrays, 17 significant digits) or "single"
// (float32, 9 digits). With output.contacts, every snapshot also writes
// DIR/snapshots/contacts_NNNNNN.csv: one row per contact (engine/observer.hpp ContactRow). Every
// grain carries its id, group and material (indices into the legend in summary.json and in each
// file) and its mode.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "engine/observer.hpp"
#include "engine/system.hpp"
#include "io/vec3.hpp"

namespace matep {

// Each particle id's group and material: group[id] indexes group_names, material[id] materials
// (an inlet's grains: the group "inlet.NAME", the ids after the initial ones; io/run.cpp).
struct StateLabels {
  std::vector<std::string> group_names;
  std::vector<int> group;
  std::vector<std::string> materials;
  std::vector<int> material;
};

struct SnapshotFormats {
  bool vtk = true, vtk_ascii = false, xyz = false, lammps = false;
  bool single = false;  // output.precision = "single"
  bool contacts = false;  // output.contacts: the contacts at each snapshot (contacts_NNNNNN.csv)
};

// Bytes a grain in one snapshot, for the output plan (io/run.cpp): generous upper bounds of the
// measured sizes (bench/README.md, "Snapshots"), summed over the formats.
inline double snapshot_bytes_per_grain(const SnapshotFormats& f) {
  const double vtk = f.single ? 70.0 : 120.0, text = f.single ? 180.0 : 280.0;
  // Contacts: up to about four rows a grain (half of a dense packing's coordination, and walls).
  const double contacts = f.contacts ? 4.0 * (f.single ? 160.0 : 240.0) : 0.0;
  return (f.vtk ? vtk : 0.0) + (f.vtk_ascii ? text : 0.0) + (f.xyz ? text : 0.0) + (f.lammps ? text : 0.0) + contacts;
}

// What a snapshot series held at a checkpoint: each snapshot's time and files, and each wall's
// file once written (walls at rest).
struct SnapshotSeriesMark {
  std::vector<double> times;
  std::vector<std::vector<std::string>> files;
  std::vector<std::string> static_files;
  template <class A>
  void archive(A& a) {
    a(times);
    a(files);
    a(static_files);
  }
};

// The binary VTK writer's buffers, reused from one snapshot to the next.
struct VtkBuffers {
  std::vector<char> raw;
  std::vector<float> f32;
  std::vector<double> f64;
};

template <int D>
class SnapshotWriter final : public Observer<D> {
 public:
  // With walls (and the domain box that clips unbounded ones), every snapshot time of a VTK series
  // also shows each wall's surface: DIR/snapshots/wall_NAME.vtp once for a wall at rest,
  // DIR/snapshots/wall_NAME_NNNNNN.vtp at every snapshot for a moving one; the .pvd lists the grains
  // as part 0 and wall k as part k + 1. `labels` must outlive the writer. Without `spins` (a run
  // whose grains never turn) no angular velocity is written.
  SnapshotWriter(const std::string& dir, const SnapshotFormats& formats, const StateLabels& labels,
                 const std::vector<Wall<D>>& walls, const Vec<D>& lower, const Vec<D>& upper,
                 const std::array<bool, D>& periodic, bool spins = true);
  bool wants_snapshots() const override { return true; }
  void on_snapshot(const Snapshot<D>& snap) override;
  bool wants_contacts() const override { return formats_.contacts; }
  // The series so far (a checkpoint's), and continuing one: the files it names are in place.
  using Mark = SnapshotSeriesMark;
  Mark mark() const;
  void resume(const Mark& m);

 private:
  void write_vtk(const std::string& path, const Snapshot<D>& snap, bool binary);
  void write_xyz(const std::string& path, const Snapshot<D>& snap) const;
  void write_lammps(const std::string& path, const Snapshot<D>& snap, std::size_t frame) const;
  void write_contacts(const std::string& path, const Snapshot<D>& snap) const;
  std::string wall_file(std::size_t w, double t);  // writes it when needed; the relative path
  // The domain box in three components (2D: z from -0.5 to 0.5, as LAMMPS takes a 2D box).
  void box3(double* lo, double* hi) const {
    to3<D>(lower_, lo);
    to3<D>(upper_, hi);
    if (D == 2) lo[2] = -0.5, hi[2] = 0.5;
  }
  void write_pvd();
  std::uint32_t id_of(const Snapshot<D>& snap, std::size_t row) const {
    return snap.id.empty() ? static_cast<std::uint32_t>(row) : snap.id[row];
  }
  std::string dir_;
  SnapshotFormats formats_;
  const StateLabels& labels_;
  std::vector<Wall<D>> walls_;
  Vec<D> lower_, upper_;
  std::array<bool, D> periodic_;
  bool spins_;
  VtkBuffers buffers_;
  std::vector<std::string> static_file_;  // per wall: its file once written (walls at rest)
  // (time, files relative to dir_: the grains' in each format, then each wall's)
  std::vector<std::pair<double, std::vector<std::string>>> written_;
};

}  // namespace matep

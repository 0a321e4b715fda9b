#include "io/snapshots.hpp"

#include <fmt/format.h>

#include <cctype>
#include <cstring>
#include <filesystem>

#include "io/checked_file.hpp"
#include "io/io_error.hpp"
#include "io/vec3.hpp"

namespace matep {

namespace {

// A name as one token of a text format: characters other than [A-Za-z0-9_.-] become _.
std::string token(std::string s) {
  for (char& ch : s)
    if (!(std::isalnum(static_cast<unsigned char>(ch)) || ch == '_' || ch == '-' || ch == '.')) ch = '_';
  return s.empty() ? std::string("_") : s;
}

std::string legend(const std::vector<std::string>& names) {
  std::string s;
  for (std::size_t k = 0; k < names.size(); ++k) s += fmt::format("{}{} {}", k ? ", " : "", k, token(names[k]));
  return s;
}

// The smallest unsigned VTK integer type that holds 0..n-1.
// One number of a text format, after a space: 17 significant digits, or float(v) with 9.
void put_number(CheckedFile& f, double v, bool single) {
  if (single) f.print(" {:.9g}", static_cast<float>(v));
  else f.print(" {:.17g}", v);
}

const char* index_type(std::size_t n) { return n <= 256 ? "UInt8" : n <= 65536 ? "UInt16" : "UInt32"; }

// The arrays of one VTK piece, written either inline as ASCII or into the appended raw block (each
// array there: a UInt64 byte count, then the little-endian values; VTK XML file format, "Appended
// Data Section"; this build runs on little-endian machines only, checked in io/output.cpp).
class VtkArrays {
 public:
  // `raw` (the appended block) and the scratch vectors are the writer's, kept from one snapshot to
  // the next: fresh buffers of tens of MB would cost page faults at every snapshot.
  VtkArrays(CheckedFile& f, bool binary, bool single, VtkBuffers& buf)
      : f_(f), binary_(binary), single_(single), raw_(buf.raw), f32_(buf.f32), f64_(buf.f64) {
    raw_.clear();
  }
  // Floating-point arrays: n tuples of `comps` components, get(i, double* out).
  template <class Get>
  void reals(const char* name, std::size_t n, int comps, Get get) {
    open(single_ ? "Float32" : "Float64", name, comps);
    double c[3];
    if (binary_) {
      if (single_) {
        std::vector<float>& b = begin_block<float>(n * comps);
        for (std::size_t i = 0; i < n; ++i) {
          get(i, c);
          for (int k = 0; k < comps; ++k) b.push_back(static_cast<float>(c[k]));
        }
        end_block(b);
      } else {
        std::vector<double>& b = begin_block<double>(n * comps);
        for (std::size_t i = 0; i < n; ++i) {
          get(i, c);
          for (int k = 0; k < comps; ++k) b.push_back(c[k]);
        }
        end_block(b);
      }
    } else {
      for (std::size_t i = 0; i < n; ++i) {
        get(i, c);
        for (int k = 0; k < comps; ++k) {
          if (single_) f_.print("{:.9g}", static_cast<float>(c[k]));
          else f_.print("{:.17g}", c[k]);
          f_.puts(k + 1 < comps ? " " : "\n");
        }
      }
      f_.puts("        </DataArray>\n");
    }
  }
  // Integer arrays of the VTK type `type` (UInt8, UInt16, UInt32, Int32), get(i) -> value.
  template <class Get>
  void ints(const char* type, const char* name, std::size_t n, Get get) {
    open(type, name, 1);
    if (binary_) {
      const std::string t = type;
      if (t == "UInt8") put_ints<std::uint8_t>(n, get);
      else if (t == "UInt16") put_ints<std::uint16_t>(n, get);
      else if (t == "UInt32") put_ints<std::uint32_t>(n, get);
      else put_ints<std::int32_t>(n, get);
    } else {
      for (std::size_t i = 0; i < n; ++i) f_.print("{}\n", static_cast<std::int64_t>(get(i)));
      f_.puts("        </DataArray>\n");
    }
  }
  // After the XML: the appended block (binary only).
  void finish() {
    if (!binary_) return;
    f_.puts("  <AppendedData encoding=\"raw\">\n   _");
    f_.write(raw_.data(), raw_.size());
    f_.puts("\n  </AppendedData>\n");
  }

 private:
  void open(const char* type, const char* name, int comps) {
    if (binary_)
      f_.print("        <DataArray type=\"{}\" Name=\"{}\" NumberOfComponents=\"{}\" format=\"appended\" offset=\"{}\"/>\n",
               type, name, comps, raw_.size());
    else
      f_.print("        <DataArray type=\"{}\" Name=\"{}\" NumberOfComponents=\"{}\" format=\"ascii\">\n", type, name,
               comps);
  }
  template <class T>
  std::vector<T>& begin_block(std::size_t n) {
    auto& b = scratch<T>();
    b.clear();
    b.reserve(n);
    return b;
  }
  template <class T>
  void end_block(const std::vector<T>& b) {
    const std::uint64_t bytes = b.size() * sizeof(T);
    const std::size_t at = raw_.size();
    raw_.resize(at + 8 + bytes);
    std::memcpy(raw_.data() + at, &bytes, 8);
    if (bytes > 0) std::memcpy(raw_.data() + at + 8, b.data(), bytes);
  }
  template <class T, class Get>
  void put_ints(std::size_t n, Get get) {
    const std::uint64_t bytes = n * sizeof(T);
    const std::size_t at = raw_.size();
    raw_.resize(at + 8 + bytes);
    std::memcpy(raw_.data() + at, &bytes, 8);
    for (std::size_t i = 0; i < n; ++i) {
      const T v = static_cast<T>(get(i));
      std::memcpy(raw_.data() + at + 8 + i * sizeof(T), &v, sizeof(T));
    }
  }
  template <class T>
  std::vector<T>& scratch() {
    if constexpr (sizeof(T) == 4) return f32_;
    else return f64_;
  }
  CheckedFile& f_;
  bool binary_, single_;
  std::vector<char>& raw_;
  std::vector<float>& f32_;
  std::vector<double>& f64_;
};

}  // namespace

template <int D>
SnapshotWriter<D>::SnapshotWriter(const std::string& dir, const SnapshotFormats& formats, const StateLabels& labels,
                                  const std::vector<Wall<D>>& walls, const Vec<D>& lower, const Vec<D>& upper,
                                  const std::array<bool, D>& periodic, bool spins)
    : dir_(dir),
      formats_(formats),
      labels_(labels),
      walls_(walls),
      lower_(lower),
      upper_(upper),
      periodic_(periodic),
      spins_(spins),
      static_file_(walls.size()) {
  std::filesystem::create_directories(dir_ + "/snapshots");
}

// One wall's surface at time t as VTK PolyData (polygons in 3D, lines in 2D).
template <int D>
std::string SnapshotWriter<D>::wall_file(std::size_t w, double t) {
  const WallShape<D>& shape = walls_[w].geometry();
  const bool moving = shape.moving();
  if (!moving && !static_file_[w].empty()) return static_file_[w];
  const std::string name = token(walls_[w].name);
  const std::string rel = moving ? fmt::format("snapshots/wall_{}_{:06d}.vtp", name, written_.size())
                                 : fmt::format("snapshots/wall_{}.vtp", name);
  SurfaceMesh m;
  shape.tessellate(t, lower_, upper_, m);
  CheckedFile f(dir_ + "/" + rel, "w");
  const char* kind = D == 3 ? "Polys" : "Lines";
  f.print("<?xml version=\"1.0\"?>\n<VTKFile type=\"PolyData\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
          "  <PolyData>\n    <Piece NumberOfPoints=\"{}\" NumberOfVerts=\"0\" NumberOfLines=\"{}\" "
          "NumberOfStrips=\"0\" NumberOfPolys=\"{}\">\n      <Points>\n"
          "        <DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n",
          m.points.size(), D == 2 ? m.cells.size() : 0, D == 3 ? m.cells.size() : 0);
  for (const auto& p : m.points) f.print("{:.17g} {:.17g} {:.17g}\n", p[0], p[1], p[2]);
  f.print("        </DataArray>\n      </Points>\n      <{}>\n"
          "        <DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">\n",
          kind);
  for (const auto& c : m.cells)
    for (const auto k : c) f.print("{}\n", k);
  f.print("        </DataArray>\n        <DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">\n");
  std::size_t off = 0;
  for (const auto& c : m.cells) f.print("{}\n", off += c.size());
  f.print("        </DataArray>\n      </{}>\n    </Piece>\n  </PolyData>\n</VTKFile>\n", kind);
  f.close();
  if (!moving) static_file_[w] = rel;
  return rel;
}

// The grains as one PolyData piece: the points, their data, and one poly-vertex cell holding them
// all (so that ParaView draws them without a filter).
template <int D>
void SnapshotWriter<D>::write_vtk(const std::string& path, const Snapshot<D>& snap, bool binary) {
  CheckedFile f(path, "w");
  const std::size_t n = snap.x.size();
  f.print("<?xml version=\"1.0\"?>\n<VTKFile type=\"PolyData\" version=\"1.0\" byte_order=\"LittleEndian\"{}>\n"
          "  <!-- matep snapshot at t = {:.17g}; group: {}; material: {} -->\n"
          "  <PolyData>\n    <FieldData>\n"
          "      <DataArray type=\"Float64\" Name=\"TimeValue\" NumberOfTuples=\"1\" format=\"ascii\">{:.17g}</DataArray>\n"
          "    </FieldData>\n"
          "    <Piece NumberOfPoints=\"{}\" NumberOfVerts=\"{}\" NumberOfLines=\"0\" NumberOfStrips=\"0\" "
          "NumberOfPolys=\"0\">\n      <Points>\n",
          binary ? " header_type=\"UInt64\"" : "", snap.time, legend(labels_.group_names), legend(labels_.materials),
          snap.time, n, n > 0 ? 1 : 0);
  VtkArrays a(f, binary, formats_.single, buffers_);
  a.reals("position", n, 3, [&](std::size_t i, double* c) { to3<D>(snap.x[i], c); });
  f.puts("      </Points>\n      <PointData Scalars=\"radius\" Vectors=\"velocity\">\n");
  a.reals("radius", n, 1, [&](std::size_t i, double* c) { c[0] = snap.radius[i]; });
  a.reals("velocity", n, 3, [&](std::size_t i, double* c) { to3<D>(snap.v[i], c); });
  if (spins_ && !snap.w.empty()) a.reals("angular_velocity", n, 3, [&](std::size_t i, double* c) { spin3<D>(snap.w[i], c); });
  a.ints("UInt32", "id", n, [&](std::size_t i) { return id_of(snap, i); });
  a.ints(index_type(labels_.group_names.size()), "group", n,
         [&](std::size_t i) { return labels_.group.at(id_of(snap, i)); });
  a.ints(index_type(labels_.materials.size()), "material", n,
         [&](std::size_t i) { return labels_.material.at(id_of(snap, i)); });
  a.ints("UInt8", "mode", n, [&](std::size_t i) { return snap.mode.empty() ? 0 : snap.mode[i]; });
  if (!snap.cluster.empty()) a.ints("Int32", "cluster", n, [&](std::size_t i) { return snap.cluster[i]; });
  f.puts("      </PointData>\n      <Verts>\n");
  if (n > 0) {
    a.ints("Int32", "connectivity", n, [](std::size_t i) { return i; });
    a.ints("Int32", "offsets", 1, [&](std::size_t) { return n; });
  } else {
    f.puts("        <DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\"></DataArray>\n"
           "        <DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\"></DataArray>\n");
  }
  f.puts("      </Verts>\n    </Piece>\n  </PolyData>\n");
  a.finish();
  f.puts("</VTKFile>\n");
  f.close();
}

// Extended XYZ (the format of ASE and OVITO, "extxyz"): the count, a line of key=value pairs
// naming the box and the columns, then one line per grain. species is "X" (ASE takes only element
// symbols there); the group and material are named columns.
template <int D>
void SnapshotWriter<D>::write_xyz(const std::string& path, const Snapshot<D>& snap) const {
  CheckedFile f(path, "w");
  const std::size_t n = snap.x.size();
  const bool spins = spins_ && !snap.w.empty();
  double lo[3], hi[3];
  box3(lo, hi);
  auto pbc = [&](int k) { return k < D && periodic_[static_cast<std::size_t>(k)] ? 'T' : 'F'; };
  f.print("{}\nLattice=\"{:.17g} 0 0 0 {:.17g} 0 0 0 {:.17g}\" Origin=\"{:.17g} {:.17g} {:.17g}\" pbc=\"{} {} {}\" "
          "Time={:.17g} Properties=species:S:1:pos:R:3:radius:R:1:velocity:R:3{}:id:I:1:group:S:1:material:S:1:"
          "mode:I:1\n",
          n, hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], lo[0], lo[1], lo[2], pbc(0), pbc(1), pbc(2), snap.time,
          spins ? ":angular_velocity:R:3" : "");
  std::vector<std::string> groups, materials;
  for (const auto& g : labels_.group_names) groups.push_back(token(g));
  for (const auto& m : labels_.materials) materials.push_back(token(m));
  auto num = [&](double v) { put_number(f, v, formats_.single); };
  double c[3];
  for (std::size_t i = 0; i < n; ++i) {
    f.puts("X");
    to3<D>(snap.x[i], c);
    num(c[0]), num(c[1]), num(c[2]);
    num(snap.radius[i]);
    to3<D>(snap.v[i], c);
    num(c[0]), num(c[1]), num(c[2]);
    if (spins) {
      spin3<D>(snap.w[i], c);
      num(c[0]), num(c[1]), num(c[2]);
    }
    const std::uint32_t id = id_of(snap, i);
    f.print(" {} {} {} {}\n", id, groups.at(static_cast<std::size_t>(labels_.group.at(id))),
            materials.at(static_cast<std::size_t>(labels_.material.at(id))), snap.mode.empty() ? 0 : snap.mode[i]);
  }
  f.close();
}

// A LAMMPS "dump custom" frame (LAMMPS manual, dump command; the columns of the granular atom
// style): type is the group index + 1 (LAMMPS types start at 1), TIMESTEP the snapshot's number,
// ITEM: TIME the simulated time (as dump_modify time yes writes it).
template <int D>
void SnapshotWriter<D>::write_lammps(const std::string& path, const Snapshot<D>& snap, std::size_t frame) const {
  CheckedFile f(path, "w");
  const std::size_t n = snap.x.size();
  const bool spins = spins_ && !snap.w.empty();
  double lo[3], hi[3];
  box3(lo, hi);
  auto bc = [&](int k) { return k < D && periodic_[static_cast<std::size_t>(k)] ? "pp" : "ff"; };
  f.print("ITEM: TIMESTEP\n{}\nITEM: TIME\n{:.17g}\nITEM: NUMBER OF ATOMS\n{}\nITEM: BOX BOUNDS {} {} {}\n"
          "{:.17g} {:.17g}\n{:.17g} {:.17g}\n{:.17g} {:.17g}\n"
          "ITEM: ATOMS id type x y z vx vy vz{} radius material mode\n",
          frame, snap.time, n, bc(0), bc(1), bc(2), lo[0], hi[0], lo[1], hi[1], lo[2], hi[2],
          spins ? " omegax omegay omegaz" : "");
  auto num = [&](double v) { put_number(f, v, formats_.single); };
  double c[3];
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t id = id_of(snap, i);
    f.print("{} {}", id, labels_.group.at(id) + 1);
    to3<D>(snap.x[i], c);
    num(c[0]), num(c[1]), num(c[2]);
    to3<D>(snap.v[i], c);
    num(c[0]), num(c[1]), num(c[2]);
    if (spins) {
      spin3<D>(snap.w[i], c);
      num(c[0]), num(c[1]), num(c[2]);
    }
    num(snap.radius[i]);
    f.print(" {} {}\n", labels_.material.at(id), snap.mode.empty() ? 0 : snap.mode[i]);
  }
  f.close();
}

// The contacts of one snapshot as CSV (engine/observer.hpp ContactRow): a comment line with the
// time, a header, then one row per contact. 2D: two components per vector.
template <int D>
void SnapshotWriter<D>::write_contacts(const std::string& path, const Snapshot<D>& snap) const {
  CheckedFile f(path, "w");
  f.print("# time = {:.17g}\n", snap.time);
  if constexpr (D == 3)
    f.puts("kind,i,j,wall,x,y,z,fn_x,fn_y,fn_z,ft_x,ft_y,ft_z,overlap,collisions\n");
  else
    f.puts("kind,i,j,wall,x,y,fn_x,fn_y,ft_x,ft_y,overlap,collisions\n");
  auto num = [&](double v) {
    if (formats_.single) f.print(",{:.9g}", static_cast<float>(v));
    else f.print(",{:.17g}", v);
  };
  for (const ContactRow<D>& r : snap.contacts) {
    f.print("{},{},{},{}", r.kind, r.i, r.j, r.wall);
    for (const Vec<D>* v : {&r.point, &r.fn, &r.ft})
      for (int k = 0; k < D; ++k) num((*v)[k]);
    num(r.overlap);
    f.print(",{}\n", r.collisions);
  }
  f.close();
}

template <int D>
void SnapshotWriter<D>::on_snapshot(const Snapshot<D>& snap) {
  const std::size_t k = written_.size();
  std::vector<std::string> files;
  auto add = [&](const char* ext) {
    files.push_back(fmt::format("snapshots/snap_{:06d}.{}", k, ext));
    return dir_ + "/" + files.back();
  };
  if (formats_.vtk || formats_.vtk_ascii) write_vtk(add("vtp"), snap, formats_.vtk);
  if (formats_.xyz) write_xyz(add("xyz"), snap);
  if (formats_.lammps) write_lammps(add("lammpstrj"), snap, k);
  if (formats_.contacts && snap.with_contacts) {
    files.push_back(fmt::format("snapshots/contacts_{:06d}.csv", k));
    write_contacts(dir_ + "/" + files.back(), snap);
  }
  if (formats_.vtk || formats_.vtk_ascii)
    for (std::size_t w = 0; w < walls_.size(); ++w) files.push_back(wall_file(w, snap.time));
  written_.emplace_back(snap.time, std::move(files));
  if (formats_.vtk || formats_.vtk_ascii) write_pvd();
}

// The collection (the .vtp files of each time) is rewritten whole (to a temporary, then renamed)
// after every snapshot.
template <int D>
void SnapshotWriter<D>::write_pvd() {
  const std::string pvd = dir_ + "/snapshots.pvd", tmp = pvd + ".tmp";
  CheckedFile c(tmp, "w");
  c.print("<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
          "  <Collection>\n");
  for (const auto& [t, files] : written_) {
    std::size_t part = 0;
    for (const std::string& file : files)
      if (file.ends_with(".vtp"))
        c.print("    <DataSet timestep=\"{:.17g}\" group=\"\" part=\"{}\" file=\"{}\"/>\n", t, part++, file);
  }
  c.print("  </Collection>\n</VTKFile>\n");
  c.close();
  std::error_code ec;
  std::filesystem::rename(tmp, pvd, ec);
  if (ec) throw WriteError(fmt::format("{}: cannot rename into place: {}", pvd, ec.message()));
}

template <int D>
typename SnapshotWriter<D>::Mark SnapshotWriter<D>::mark() const {
  Mark m;
  for (const auto& [t, files] : written_) {
    m.times.push_back(t);
    m.files.push_back(files);
  }
  m.static_files = static_file_;
  return m;
}

template <int D>
void SnapshotWriter<D>::resume(const Mark& m) {
  if (m.static_files.size() != walls_.size() || m.times.size() != m.files.size())
    throw IoError(fmt::format("{}: the checkpoint's snapshot series does not fit this scene's walls", dir_));
  written_.clear();
  for (std::size_t k = 0; k < m.times.size(); ++k) written_.emplace_back(m.times[k], m.files[k]);
  static_file_ = m.static_files;
  if (!written_.empty() && (formats_.vtk || formats_.vtk_ascii)) write_pvd();
}

template class SnapshotWriter<2>;
template class SnapshotWriter<3>;

}  // namespace matep

#include "io/log_tools.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <functional>
#include <array>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <iterator>
#include <limits>
#include <memory>
#include <new>
#include <optional>
#include <stdexcept>
#include <unordered_map>
#include <variant>

#include "engine/rough_rules.hpp"
#include "io/scene.hpp"

namespace matep {

namespace fs = std::filesystem;

// ---- kinds, id lists --------------------------------------------------------------------------

const char* event_kind_name(std::uint8_t kind) {
  switch (kind) {
    case 1: return "pair";
    case 2: return "wall";
    case 3: return "cell";
    case 4: return "soft";
    case 5: return "hard";
    case 6: return "outflow";
    case 7: return "inflow";
    default: return "unknown";
  }
}

std::uint8_t parse_event_kind(std::string_view word) {
  if (word == "pair") return static_cast<std::uint8_t>(EventKind::PairCollision);
  if (word == "wall") return static_cast<std::uint8_t>(EventKind::WallCollision);
  if (word == "soft") return static_cast<std::uint8_t>(EventKind::ToSoft);
  if (word == "hard") return static_cast<std::uint8_t>(EventKind::ToHard);
  if (word == "outflow") return static_cast<std::uint8_t>(EventKind::Outflow);
  if (word == "inflow") return static_cast<std::uint8_t>(EventKind::Inflow);
  throw std::invalid_argument(
      fmt::format("--kind: unknown event kind '{}' (expected pair, wall, soft, hard, outflow or inflow)", word));
}

std::vector<std::uint32_t> parse_id_list(std::string_view list) {
  std::vector<std::uint32_t> ids;
  std::size_t pos = 0;
  while (pos <= list.size()) {
    const std::size_t comma = std::min(list.find(',', pos), list.size());
    std::string_view item = list.substr(pos, comma - pos);
    while (!item.empty() && item.front() == ' ') item.remove_prefix(1);
    while (!item.empty() && item.back() == ' ') item.remove_suffix(1);
    std::uint32_t v = 0;
    const auto [end, ec] = std::from_chars(item.data(), item.data() + item.size(), v);
    if (item.empty() || ec != std::errc() || end != item.data() + item.size())
      throw std::invalid_argument(fmt::format(
          "--ids: '{}' is not a particle id in '{}' (expected ids >= 0 separated by commas)", item,
          list));
    ids.push_back(v);
    pos = comma + 1;
  }
  std::sort(ids.begin(), ids.end());
  ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
  return ids;
}

// ---- opening ----------------------------------------------------------------------------------

namespace {

LogFile log_file(const EventLogReader& reader) {
  LogFile lf;
  lf.header = reader.header();
  lf.file_size = reader.file_size();
  lf.records = reader.records();
  return lf;
}

bool is_collision(std::uint8_t kind) {
  return kind == static_cast<std::uint8_t>(EventKind::PairCollision) ||
         kind == static_cast<std::uint8_t>(EventKind::WallCollision);
}
bool is_pair(std::uint8_t kind) { return kind == static_cast<std::uint8_t>(EventKind::PairCollision); }

double dot3(const double* a, const double* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
double norm3(const double* a) { return std::sqrt(dot3(a, a)); }
void cross3(const double* a, const double* b, double* out) {
  out[0] = a[1] * b[2] - a[2] * b[1];
  out[1] = a[2] * b[0] - a[0] * b[2];
  out[2] = a[0] * b[1] - a[1] * b[0];
}

const char* file_type(mode_t m) {
  if (S_ISDIR(m)) return "a directory";
  if (S_ISCHR(m)) return "a character device";
  if (S_ISBLK(m)) return "a block device";
  if (S_ISFIFO(m)) return "a FIFO";
  if (S_ISSOCK(m)) return "a socket";
  return "not a regular file";
}

// The output of filter and export --out. It is written to a new hidden file in the folder of `out`
// (.NAME.matep-XXXXXX, mkstemp) and renamed onto `out` by commit() only; on any failure just that
// temporary is removed, so whatever was at `out` before stays as it was. An `out` that exists and
// is not a regular file, or that is the input log (same device and inode), is refused before
// anything is created.
class AtomicOutput {
 public:
  AtomicOutput(const std::string& out, const std::string& in) : out_(out) {
    struct stat so {};
    mode_t mode = 0;
    if (::stat(out.c_str(), &so) == 0) {
      if (!S_ISREG(so.st_mode))
        throw IoError(fmt::format("{}: is {}, not a regular file: refusing to write the output there", out,
                                  file_type(so.st_mode)));
      struct stat si {};
      if (::stat(in.c_str(), &si) == 0 && si.st_dev == so.st_dev && si.st_ino == so.st_ino)
        throw IoError(fmt::format("{}: is the input log {} itself: refusing to overwrite it", out, in));
      mode = so.st_mode & 07777;  // a replaced file keeps its permissions
    } else {
      mode = ::umask(0);
      ::umask(mode);
      mode = 0666 & ~mode;
    }
    const fs::path p(out);
    const std::string dir = p.parent_path().empty() ? std::string(".") : p.parent_path().string();
    std::string name = (fs::path(dir) / ("." + p.filename().string() + ".matep-XXXXXX")).string();
    const int fd = ::mkostemp(name.data(), O_CLOEXEC);
    if (fd < 0)
      throw IoError(fmt::format("{}: cannot create a temporary file in {}: {}", out, dir, std::strerror(errno)));
    tmp_ = name;
    if (::fchmod(fd, mode) != 0 || !(f_ = ::fdopen(fd, "wb"))) {
      const int err = errno;
      ::close(fd);
      ::unlink(tmp_.c_str());
      throw IoError(fmt::format("{}: cannot write the temporary file {}: {}", out, tmp_, std::strerror(err)));
    }
    buffer_.resize(1 << 20);
    std::setvbuf(f_, buffer_.data(), _IOFBF, buffer_.size());
  }
  ~AtomicOutput() {
    if (f_) std::fclose(f_);
    if (!committed_) ::unlink(tmp_.c_str());
  }
  AtomicOutput(const AtomicOutput&) = delete;
  AtomicOutput& operator=(const AtomicOutput&) = delete;
  std::FILE* get() const { return f_; }
  const std::string& path() const { return out_; }
  void write(const void* p, std::size_t n) {
    if (n && std::fwrite(p, 1, n, f_) != n) fail("write failed");
  }
  // Flushes, syncs and closes the temporary, then renames it onto `out`.
  void commit() {
    if (std::fflush(f_) != 0) fail("write failed");
    if (::fsync(::fileno(f_)) != 0) fail("write failed");
    std::FILE* f = f_;
    f_ = nullptr;
    if (std::fclose(f) != 0) fail("write failed");
    if (std::rename(tmp_.c_str(), out_.c_str()) != 0) fail(fmt::format("cannot rename {} onto it", tmp_));
    committed_ = true;
  }

 private:
  [[noreturn]] void fail(const std::string& what) {
    throw WriteError(fmt::format("{}: {}: {}", out_, what, std::strerror(errno)));
  }
  std::string out_, tmp_;
  std::FILE* f_ = nullptr;
  bool committed_ = false;
  std::vector<char> buffer_;
};

void write_all(std::FILE* f, const std::string& s, const std::string& what) {
  if (!s.empty() && std::fwrite(s.data(), 1, s.size(), f) != s.size())
    throw WriteError(fmt::format("{}: write failed: {}", what, std::strerror(errno)));
}

// Collisions per particle id, in memory bounded by the log's size, not by the header's particle
// count: a vector for ids below max(2^16, 4 x records) that grows with the largest id seen, a hash
// map for larger ids (at most two per record).
class IdCounts {
 public:
  explicit IdCounts(std::uint64_t records) : dense_limit_(std::max<std::uint64_t>(1 << 16, 4 * records)) {}
  void add(std::uint32_t id) {
    if (id < dense_limit_) {
      if (id >= dense_.size())
        dense_.resize(static_cast<std::size_t>(
            std::min<std::uint64_t>(dense_limit_, std::max<std::uint64_t>(id + std::uint64_t{1}, 2 * dense_.size()))));
      ++dense_[id];
    } else {
      ++sparse_[id];
    }
  }
  // Particles counted, and the one with the most (lowest id on a tie).
  void summarize(std::uint64_t& collided, std::uint32_t& busiest, std::uint64_t& most) const {
    collided = 0;
    most = 0;
    busiest = 0;
    auto see = [&](std::uint32_t id, std::uint64_t n) {
      if (!n) return;
      ++collided;
      if (n > most || (n == most && id < busiest)) {
        most = n;
        busiest = id;
      }
    };
    for (std::size_t p = 0; p < dense_.size(); ++p) see(static_cast<std::uint32_t>(p), dense_[p]);
    for (const auto& [id, n] : sparse_) see(id, n);
  }

 private:
  std::uint64_t dense_limit_;
  std::vector<std::uint64_t> dense_;
  std::unordered_map<std::uint32_t, std::uint64_t> sparse_;
};

}  // namespace

LogFile inspect_log(const std::string& path) {
  EventLogReader reader(path);
  return log_file(reader);
}

// ---- stats ------------------------------------------------------------------------------------

LogStats compute_log_stats(const std::string& path, std::size_t nbins) {
  if (nbins == 0) throw std::invalid_argument("--bins must be at least 1");
  EventLogReader reader(path);
  LogStats s;
  s.path = path;
  s.file = log_file(reader);
  if (s.file.records == 0) {
    EventRecord none;
    reader.next(none);  // checks the (empty) last block
    return s;
  }

  EventRecord rec;
  reader.next(rec);  // the first record (records > 0)
  s.t_first = rec.time;
  s.t_last = reader.record_at(s.file.records - 1).time;
  const double span = s.t_last - s.t_first;
  s.bins.resize(nbins);
  for (std::size_t k = 0; k < nbins; ++k) {
    s.bins[k].t0 = s.t_first + span * static_cast<double>(k) / static_cast<double>(nbins);
    s.bins[k].t1 = k + 1 == nbins ? s.t_last
                                  : s.t_first + span * static_cast<double>(k + 1) / static_cast<double>(nbins);
  }
  const double bins_per_time = span > 0.0 ? static_cast<double>(nbins) / span : 0.0;

  // Per-particle counts: grown with the ids the records name (each < the header's count: the
  // reader checks it), never sized from the header.
  IdCounts per_particle(s.file.records);
  double e_sum = 0.0, e_comp = 0.0;
  std::uint64_t index = 0;
  do {
    s.by_kind[rec.kind] += 1;
    if (is_collision(rec.kind)) {
      const bool pair = is_pair(rec.kind);
      per_particle.add(rec.i);
      if (pair) per_particle.add(rec.j);

      double k = std::floor((rec.time - s.t_first) * bins_per_time);
      if (!(k >= 0.0)) k = 0.0;  // also NaN
      const std::size_t b = std::min(static_cast<std::size_t>(std::min(k, 1e18)), nbins - 1);
      (pair ? s.bins[b].pair : s.bins[b].wall) += 1;

      double g[3];
      for (int c = 0; c < 3; ++c) g[c] = rec.vi_before[c] - rec.vj_before[c];
      const double u = std::abs(dot3(g, rec.normal));
      if (s.collisions == 0 || u > s.max_impact) {
        s.max_impact = u;
        s.max_impact_index = index;
        s.max_impact_time = rec.time;
        s.max_impact_kind = rec.kind;
        s.max_impact_i = rec.i;
        s.max_impact_j = rec.j;
      }
      if (s.collisions == 0 || rec.e < s.e_min) {
        s.e_min = rec.e;
        s.e_min_index = index;
      }
      if (s.collisions == 0 || rec.e > s.e_max) {
        s.e_max = rec.e;
        s.e_max_index = index;
      }
      const double t = e_sum + rec.e;  // Neumaier-compensated sum (1e8 records keep all digits)
      e_comp += std::abs(e_sum) >= std::abs(rec.e) ? (e_sum - t) + rec.e : (rec.e - t) + e_sum;
      e_sum = t;
      ++s.collisions;
    }
    ++index;
  } while (reader.next(rec));

  if (s.collisions) s.e_mean = (e_sum + e_comp) / static_cast<double>(s.collisions);
  for (auto& b : s.bins) {
    const double w = b.t1 - b.t0;
    b.rate = w > 0.0 ? static_cast<double>(b.pair + b.wall) / w : 0.0;
  }
  per_particle.summarize(s.particles_collided, s.busiest, s.busiest_count);
  return s;
}

std::string format_log_stats(const LogStats& s) {
  std::string out;
  auto o = std::back_inserter(out);
  const auto& h = s.file.header;
  fmt::format_to(o, "event log   {}\n", s.path);
  fmt::format_to(o, "format      version {}{}, {}D, {} particles, {} bytes\n", h.version,
                 h.fixed_grains() ? " (fixed grains)" : "", h.dimension, h.particles, s.file.file_size);
  fmt::format_to(o, "records     {}\n", s.file.records);
  if (s.file.records == 0) {
    fmt::format_to(o, "(no records)\n");
    return out;
  }
  fmt::format_to(o, "time span   {:.10g} .. {:.10g}  ({:.6g})\n\n", s.t_first, s.t_last,
                 s.t_last - s.t_first);

  fmt::format_to(o, "{:<22}{:>14}\n", "kind", "records");
  fmt::format_to(o, "{:<22}{:>14}\n", "pair collisions", s.by_kind[1]);
  fmt::format_to(o, "{:<22}{:>14}\n", "wall collisions", s.by_kind[2]);
  if (s.by_kind[3]) fmt::format_to(o, "{:<22}{:>14}\n", "cell crossings", s.by_kind[3]);
  fmt::format_to(o, "{:<22}{:>14}\n", "switches to soft", s.by_kind[4]);
  fmt::format_to(o, "{:<22}{:>14}\n", "switches to hard", s.by_kind[5]);
  if (s.by_kind[6]) fmt::format_to(o, "{:<22}{:>14}\n", "grains out (outflow)", s.by_kind[6]);
  if (s.by_kind[7]) fmt::format_to(o, "{:<22}{:>14}\n", "grains in (inflow)", s.by_kind[7]);
  fmt::format_to(o, "\n");

  fmt::format_to(o, "collision rate (pair + wall collisions per unit time), {} bins\n", s.bins.size());
  fmt::format_to(o, "{:>16} {:>16} {:>12} {:>12} {:>14}\n", "t from", "t to", "pair", "wall", "rate");
  for (const auto& b : s.bins) {
    if (b.t1 > b.t0)
      fmt::format_to(o, "{:>16.9g} {:>16.9g} {:>12} {:>12} {:>14.6g}\n", b.t0, b.t1, b.pair, b.wall,
                     b.rate);
    else
      fmt::format_to(o, "{:>16.9g} {:>16.9g} {:>12} {:>12} {:>14}\n", b.t0, b.t1, b.pair, b.wall, "-");
  }
  fmt::format_to(o, "\n");

  if (s.collisions == 0) {
    fmt::format_to(o, "no collisions\n");
    return out;
  }
  fmt::format_to(o, "{:<22}particle {} ({} collision{})\n", "most collisions", s.busiest,
                 s.busiest_count, s.busiest_count == 1 ? "" : "s");
  fmt::format_to(o, "{:<22}{} of {}\n", "particles collided", s.particles_collided, h.particles);
  if (is_pair(s.max_impact_kind))
    fmt::format_to(o, "{:<22}{:.10g}  (record {}, t = {:.10g}, pair {}-{})\n", "largest impact u_n",
                   s.max_impact, s.max_impact_index, s.max_impact_time, s.max_impact_i, s.max_impact_j);
  else
    fmt::format_to(o, "{:<22}{:.10g}  (record {}, t = {:.10g}, particle {} on wall {})\n",
                   "largest impact u_n", s.max_impact, s.max_impact_index, s.max_impact_time,
                   s.max_impact_i, s.max_impact_j);
  fmt::format_to(o, "{:<22}min {:.10g} (record {}), max {:.10g} (record {}), mean {:.10g}\n",
                 "restitution e", s.e_min, s.e_min_index, s.e_max, s.e_max_index, s.e_mean);
  return out;
}

// ---- filter / export --------------------------------------------------------------------------

bool LogFilter::matches(const EventRecord& r) const {
  if (from && !(r.time >= *from)) return false;
  if (to && !(r.time <= *to)) return false;
  if (!kinds.empty() && std::find(kinds.begin(), kinds.end(), r.kind) == kinds.end()) return false;
  if (!ids.empty()) {
    const bool hit_i = std::binary_search(ids.begin(), ids.end(), r.i);
    const bool hit_j = is_pair(r.kind) && std::binary_search(ids.begin(), ids.end(), r.j);
    if (!hit_i && !hit_j) return false;
  }
  return true;
}

std::string csv_header() {
  std::string h = "time,kind,i,j,mi,mj,e";
  const char* vecs[] = {"n", "vi_b", "vj_b", "vi_a", "vj_a", "wi_b", "wj_b", "wi_a", "wj_a"};
  for (const char* v : vecs)
    for (const char* c : {"x", "y", "z"}) h += fmt::format(",{}{}", v, c);
  return h;
}

void append_csv_row(std::string& buf, const EventRecord& r) {
  auto o = std::back_inserter(buf);
  fmt::format_to(o, "{},{},{},{},{},{},{}", r.time, event_kind_name(r.kind), r.i, r.j, r.mi, r.mj, r.e);
  for (const double* v : {r.normal, r.vi_before, r.vj_before, r.vi_after, r.vj_after, r.wi_before,
                          r.wj_before, r.wi_after, r.wj_after})
    fmt::format_to(o, ",{},{},{}", v[0], v[1], v[2]);
  buf += '\n';
}

FilterResult filter_log(const std::string& in, const std::string& out, const LogFilter& filter,
                        bool csv) {
  EventLogReader reader(in);  // a bad header or a cut file is refused before any output exists
  AtomicOutput o(out, in);
  const EventLogHeader& h = reader.header();
  std::optional<EventLogEncoder> enc;
  std::string text;
  if (csv)
    text = csv_header() + "\n";
  else
    enc.emplace(o.get(), out, h.dimension, h.particles, h.fixed_grains(), kEventLogBlockRecords,
                h.version >= kEventLogVersionIdentity ? &reader.identity() : nullptr);

  FilterResult res;
  EventRecord rec;
  while (reader.next(rec)) {
    ++res.read;
    if (!filter.matches(rec)) continue;
    ++res.written;
    if (csv) {
      append_csv_row(text, rec);
      if (text.size() > (1u << 20)) {
        o.write(text.data(), text.size());
        text.clear();
      }
    } else {
      enc->add(rec);
    }
  }
  if (enc) enc->finish();
  o.write(text.data(), text.size());
  o.commit();
  return res;
}

namespace {
std::uint64_t export_to(const std::string& in, std::FILE* out, const std::string& name) {
  EventLogReader reader(in);
  std::string text = csv_header() + "\n";
  std::uint64_t rows = 0;
  EventRecord rec;
  while (reader.next(rec)) {
    append_csv_row(text, rec);
    ++rows;
    if (text.size() > (1u << 20)) {
      write_all(out, text, name);
      text.clear();
    }
  }
  write_all(out, text, name);
  return rows;
}
}  // namespace

std::uint64_t export_csv(const std::string& in, std::FILE* out) { return export_to(in, out, "CSV output"); }

std::uint64_t export_csv(const std::string& in, const std::string& out_path) {
  if (out_path.empty()) {
    const std::uint64_t n = export_csv(in, stdout);
    if (std::fflush(stdout) != 0) throw WriteError(fmt::format("CSV output: write failed: {}", std::strerror(errno)));
    return n;
  }
  { EventLogReader check(in); }  // a bad header or a cut file is refused before any output exists
  AtomicOutput o(out_path, in);
  const std::uint64_t n = export_to(in, o.get(), out_path);
  o.commit();
  return n;
}

// ---- verify -----------------------------------------------------------------------------------

namespace {

// What verify needs from a scene, independent of the dimension.
struct SceneView {
  std::string path;
  double tc = 0.0;
  std::vector<Material> materials;
  std::vector<int> material;   // per particle
  std::vector<double> mass;    // per particle
  std::vector<int> wall_material;
  // Per wall: whether a unit vector (3 components; 2D uses the first two) is the wall's normal
  // somewhere on its surface, and the wall's description for messages.
  std::vector<std::function<bool(const double*, double)>> wall_has_normal;
  std::vector<std::string> wall_text;
  std::vector<double> radius;  // per particle (rough collisions)
  std::vector<std::uint8_t> fixed;  // per particle: a fixed grain (empty: none)
  std::vector<int> inlet_material;  // per inlet: the material of its grains (their mass and radius come
                                    // from the log's inflow records)
  RoughRules rough;            // which material pairs are rough, and their rule
};

template <int D>
void fill_view(SceneView& v, const System<D>& sys, const Scene& scene, const EventLogHeader& h,
               const std::string& log) {
  if (static_cast<std::uint32_t>(D) != h.dimension)
    throw IoError(fmt::format("{}: the scene is {}D but the event log {} is {}D", scene.path, D, log,
                              h.dimension));
  const std::uint64_t slots = inlet_slots(sys.inlets, scene.end_time);
  if (sys.size() + slots != h.particles)
    throw IoError(fmt::format("{}: the scene has {} particles{} but the event log {} has {}", scene.path,
                              sys.size() + slots,
                              slots > 0 ? fmt::format(" ({} at the start, {} ids for its inlets)", sys.size(), slots)
                                        : std::string(),
                              log, h.particles));
  // The inlets' grains get their mass and radius from the inflow records (0 until then: a collision
  // of a grain not yet inserted fails the mass check).
  v.materials = sys.materials;
  v.material = sys.material;
  v.material.resize(h.particles, 0);
  v.mass.assign(h.particles, 0.0);
  for (std::size_t p = 0; p < sys.size(); ++p) v.mass[p] = sys.mass(p);
  v.radius = sys.radius;
  v.radius.resize(h.particles, 0.0);
  v.fixed = sys.fixed;
  if (!v.fixed.empty()) v.fixed.resize(h.particles, 0);
  for (const auto& in : sys.inlets) v.inlet_material.push_back(in.material);
  try {
    v.rough = make_rough_rules(sys.materials);
  } catch (const std::invalid_argument& e) {
    throw IoError(fmt::format("{}: {}", scene.path, e.what()));
  }
  for (const auto& w : sys.walls) {
    v.wall_material.push_back(w.material);
    v.wall_has_normal.push_back([shape = w.shape](const double* n, double tol) {
      Vec<D> m;
      for (int k = 0; k < D; ++k) m[k] = n[k];
      // A 2D record's third component must be zero.
      return (D == 3 || std::abs(n[2]) <= tol) && shape->has_normal(m, tol);
    });
    v.wall_text.push_back(fmt::format("{} ({})", w.name, w.geometry().describe()));
  }
}

SceneView view_scene(const Scene& scene, const EventLogHeader& h, const std::string& log) {
  SceneView v;
  v.path = scene.path;
  v.tc = scene.tc;
  std::visit([&](const auto& sys) { fill_view(v, sys, scene, h, log); }, scene.system);
  return v;
}

struct Violation {
  std::string check;
  std::string detail;
};

// A fixed partner's mass is +infinity (version 2 logs only); everything else must be finite.
bool all_finite(const EventRecord& r, bool fixed_partner) {
  const bool mj_ok = std::isfinite(r.mj) || fixed_partner;
  if (!std::isfinite(r.time) || !std::isfinite(r.mi) || !mj_ok || !std::isfinite(r.e)) return false;
  for (const double* v : {r.normal, r.vi_before, r.vj_before, r.vi_after, r.vj_after, r.wi_before,
                          r.wj_before, r.wi_after, r.wj_after})
    for (int c = 0; c < 3; ++c)
      if (!std::isfinite(v[c])) return false;
  return true;
}

// The checks of a rough collision (contact/rough.hpp), after the normal-velocity check:
// angular momentum of each body about the contact point, the tangential contact-point velocity
// reversed by a scalar beta in [-1, 1] (with a scene: the scene's tangential rule at this impact),
// and the energy bookkeeping of translation + rotation. The radii come from the scene; without
// one each body's radius is the one its angular-momentum balance implies (R = |n x dv|/(q |dw|)),
// which still tests the direction of the spin change, the tangential rule and the energy.
std::optional<Violation> check_rough(const EventRecord& r, const EventLogHeader& h, const SceneView* sv,
                                     double tol, double ub, double V, int mat_i, int mat_j) {
  auto fail = [](std::string check, std::string detail) {
    return std::optional<Violation>(Violation{std::move(check), std::move(detail)});
  };
  const bool pair = is_pair(r.kind);
  const bool two = pair && !std::isinf(r.mj);  // a fixed partner is infinitely heavy, like a wall
  const double q = h.dimension == 2 ? 0.5 : 0.4;  // I/(m R^2): solid disk, solid sphere
  const double* n = r.normal;
  double dvi[3], dvj[3], dwi[3], dwj[3];
  for (int c = 0; c < 3; ++c) {
    dvi[c] = r.vi_after[c] - r.vi_before[c];
    dvj[c] = pair ? r.vj_after[c] - r.vj_before[c] : 0.0;
    dwi[c] = r.wi_after[c] - r.wi_before[c];
    dwj[c] = pair ? r.wj_after[c] - r.wj_before[c] : 0.0;
  }
  // Angular impulse on each body about its centre: I dw = -R n x J_t, J_t = m_i dv_i = -m_j dv_j
  // (contact/rough.hpp), i.e. q R dw_i = -n x dv_i and q R dw_j = +n x dv_j.
  double ti[3], tj[3];
  cross3(n, dvi, ti);
  cross3(n, dvj, tj);
  for (int c = 0; c < 3; ++c) tj[c] = -tj[c];
  double Ri = 0.0, Rj = 0.0;
  if (sv) {
    Ri = sv->radius[r.i];
    Rj = pair ? sv->radius[r.j] : 0.0;
  } else {
    auto infer = [&](const double* t, const double* dw) {
      const double a = norm3(dw);
      return a > 0.0 ? norm3(t) / (q * a) : 0.0;
    };
    Ri = infer(ti, dwi);
    Rj = pair ? infer(tj, dwj) : 0.0;
  }
  const double W = Ri * norm3(r.wi_before) + (pair ? Rj * norm3(r.wj_before) : 0.0);
  const double Vs = V + W;  // contact-point velocity scale
  if (!std::isfinite(Vs))
    return fail("range", fmt::format("the contact-point velocity scale overflows a double: |v| {:.6g} + R |w| {:.6g} "
                                     "(R_i = {:.6g}, R_j = {:.6g})",
                                     V, W, Ri, Rj));
  for (int b = 0; b < (pair ? 2 : 1); ++b) {
    const double R = b == 0 ? Ri : Rj;
    const double* t = b == 0 ? ti : tj;
    const double* dw = b == 0 ? dwi : dwj;
    double res[3];
    for (int c = 0; c < 3; ++c) res[c] = q * R * dw[c] + t[c];
    // Both sides are velocities: compare with the contact-point velocity scale.
    // Without a scene, a spin change needs a tangential impulse to imply a radius.
    const bool unbalanced = !sv && ((norm3(t) > tol * Vs && R == 0.0) || (norm3(dw) > 0.0 && !(norm3(t) > tol * Vs)));
    if (!(norm3(res) <= tol * Vs) || unbalanced)
      return fail("angular momentum",
                  fmt::format("particle {}: the spin change {:.6g} does not balance the tangential impulse about "
                              "the contact point: |q R dw + n x dv| = {:.6g} > tol x {:.6g} (R = {:.17g}{})",
                              b == 0 ? r.i : r.j, norm3(dw), norm3(res), Vs, R,
                              sv ? " from the scene" : ", implied by the record"));
  }
  // Contact-point relative velocity, before and after: v_i - v_j - (R_i w_i + R_j w_j) x n.
  auto contact = [&](const double* vi, const double* vj, const double* wi, const double* wj, double* out) {
    double w[3], wxn[3];
    for (int c = 0; c < 3; ++c) w[c] = Ri * wi[c] + (pair ? Rj * wj[c] : 0.0);
    cross3(w, n, wxn);
    for (int c = 0; c < 3; ++c) out[c] = vi[c] - vj[c] - wxn[c];
  };
  double cb[3], ca[3], tb[3], ta[3];
  contact(r.vi_before, r.vj_before, r.wi_before, r.wj_before, cb);
  contact(r.vi_after, r.vj_after, r.wi_after, r.wj_after, ca);
  const double cnb = dot3(cb, n), cna = dot3(ca, n);
  for (int c = 0; c < 3; ++c) {
    tb[c] = cb[c] - cnb * n[c];
    ta[c] = ca[c] - cna * n[c];
  }
  const double vt = norm3(tb);
  // Tangential restitution: v_t' = -beta v_t with beta in [-1, 1] (the scene's rule, or implied).
  const double mi = r.mi, mj = pair ? r.mj : std::numeric_limits<double>::infinity();
  const double mstar = two ? mi * mj / (mi + mj) : mi;
  const double mt = rough_tangential_mass(mi, q, mj, q);
  double beta = vt > 0.0 ? -dot3(ta, tb) / (vt * vt) : -1.0;
  std::string rule = "implied by the record";
  if (sv) {
    beta = rough_beta(sv->rough.rule(mat_i, mat_j), r.e, std::abs(cnb), vt, mstar / mt).beta;
    rule = "the scene's tangential rule";
  }
  {
    double res[3];
    for (int c = 0; c < 3; ++c) res[c] = ta[c] + beta * tb[c];
    if (!(norm3(res) <= tol * Vs) || !(beta >= -1.0 - tol && beta <= 1.0 + tol))
      return fail("tangential restitution",
                  fmt::format("contact-point tangential velocity after |v_t'| = {:.17g}, before |v_t| = {:.17g}: "
                              "v_t' + beta v_t = {:.6g} > tol x {:.6g} with beta = {:.17g} ({})",
                              norm3(ta), vt, norm3(res), Vs, beta, rule));
  }
  // Energy: lost = (1 - e^2) m* v_n^2/2 + m_t (|v_t|^2 - |v_t'|^2)/2 (contact/rough.hpp), the kinetic
  // energy counting rotation (I = q m R^2); a wall collision in the wall's frame.
  auto ke = [&](const double* vi, const double* vj, const double* wi, const double* wj) {
    double gi[3];
    for (int c = 0; c < 3; ++c) gi[c] = pair ? vi[c] : vi[c] - vj[c];
    double k = 0.5 * mi * dot3(gi, gi) + 0.5 * q * mi * Ri * Ri * dot3(wi, wi);
    if (two) k += 0.5 * r.mj * dot3(vj, vj) + 0.5 * q * r.mj * Rj * Rj * dot3(wj, wj);
    return k;
  };
  const double ke_b = ke(r.vi_before, r.vj_before, r.wi_before, r.wj_before);
  const double ke_a = ke(r.vi_after, r.vj_after, r.wi_after, r.wj_after);
  if (!std::isfinite(ke_b) || !std::isfinite(ke_a))
    return fail("range", fmt::format("the kinetic energy with rotation overflows a double: before {:.6g}, after {:.6g} "
                                     "(R_i = {:.6g}, R_j = {:.6g})",
                                     ke_b, ke_a, Ri, Rj));
  const double expected = 0.5 * (1.0 - r.e * r.e) * mstar * ub * ub + 0.5 * mt * (vt * vt - dot3(ta, ta));
  const double lost = ke_b - ke_a;
  if (!(std::abs(lost - expected) <= tol * ke_b) || !(lost >= -tol * ke_b))
    return fail("energy", fmt::format("kinetic energy (translation + rotation) lost {:.17g} but (1 - e^2) m* v_n^2/2 + "
                                      "m_t (v_t^2 - v_t'^2)/2 = {:.17g} (|diff| {:.3g} > tol x KE {:.6g}; e = {:.17g}, "
                                      "m* = {:.17g}, m_t = {:.17g}, |v_t| = {:.17g}, |v_t'| = {:.17g})",
                                      lost, expected, std::abs(lost - expected), ke_b, r.e, mstar, mt, vt,
                                      norm3(ta)));
  return std::nullopt;
}

std::optional<Violation> check_record(const EventRecord& r, const EventLogHeader& h,
                                      const SceneView* sv, double tol, bool& rough_out) {
  const bool pair = is_pair(r.kind);
  auto fail = [](std::string check, std::string detail) {
    return std::optional<Violation>(Violation{std::move(check), std::move(detail)});
  };
  // A fixed partner (version 2): mj = +infinity, at rest; the collision is checked as one with a
  // wall at rest whose normal is the pair's.
  const bool fixed = pair && h.fixed_grains() && r.mj == std::numeric_limits<double>::infinity();
  const bool two = pair && !fixed;
  if (!all_finite(r, fixed)) return fail("finite values", "a field is NaN or infinite");
  if (fixed) {
    const double rest = std::max({norm3(r.vj_before), norm3(r.vj_after), norm3(r.wj_before), norm3(r.wj_after)});
    if (rest != 0.0)
      return fail("fixed partner", fmt::format("particle {} has mj = infinity (a fixed grain) but moves or spins "
                                               "(largest |vj|, |wj| {:.6g})",
                                               r.j, rest));
  }
  if (r.i >= h.particles || (pair && (r.j >= h.particles || r.j == r.i)))
    return fail("particle index",
                fmt::format("i = {}, j = {} in a log of {} particles", r.i, r.j, h.particles));
  if (!pair && sv && r.j >= sv->wall_has_normal.size())
    return fail("wall index", fmt::format("wall {} but the scene has {} walls", r.j, sv->wall_has_normal.size()));
  const double ntol = std::max(tol, 1e-14);
  const double nlen = norm3(r.normal);
  if (!(std::abs(nlen - 1.0) <= ntol))
    return fail("unit normal", fmt::format("|n| = {:.17g}", nlen));
  if (!(r.mi > 0.0) || (pair && !(r.mj > 0.0)))
    return fail("mass", fmt::format("mi = {:.17g}, mj = {:.17g}", r.mi, r.mj));
  if (sv) {
    const double m = sv->mass[r.i];
    if (std::abs(r.mi - m) > tol * m)
      return fail("mass", fmt::format("mi = {:.17g} but the scene gives particle {} mass {:.17g}", r.mi,
                                      r.i, m));
    const bool scene_fixed = pair && !sv->fixed.empty() && sv->fixed[r.j];
    if (pair && scene_fixed != fixed)
      return fail("mass", fmt::format("mj = {:.17g} but particle {} is {}fixed in the scene", r.mj, r.j,
                                      scene_fixed ? "" : "not "));
    if (two && std::abs(r.mj - sv->mass[r.j]) > tol * sv->mass[r.j])
      return fail("mass", fmt::format("mj = {:.17g} but the scene gives particle {} mass {:.17g}", r.mj,
                                      r.j, sv->mass[r.j]));
    if (!pair) {
      if (!sv->wall_has_normal[r.j](r.normal, ntol))
        return fail("wall normal", fmt::format("n = ({:.10g}, {:.10g}, {:.10g}) is not the normal of wall {} ({}) "
                                               "at any point of its surface",
                                               r.normal[0], r.normal[1], r.normal[2], r.j, sv->wall_text[r.j]));
    }
  }
  if (!(r.e >= 0.0 && r.e <= 1.0)) return fail("restitution", fmt::format("e = {:.17g} outside [0, 1]", r.e));

  // Relative velocity (a wall's vj is its own velocity: zero for a static wall, u(t) for an
  // oscillating one; mj is not used).
  double gb[3], ga[3], dvi[3], dvj[3];
  for (int c = 0; c < 3; ++c) {
    const double vjb = r.vj_before[c], vja = r.vj_after[c];
    gb[c] = r.vi_before[c] - vjb;
    ga[c] = r.vi_after[c] - vja;
    dvi[c] = r.vi_after[c] - r.vi_before[c];
    dvj[c] = vja - vjb;
  }
  const double vib = norm3(r.vi_before), vjb = norm3(r.vj_before);
  const double V = vib + vjb;  // velocity scale
  // Every comparison below is relative to a scale (V, momentum, kinetic energy, spin): one that
  // overflows to infinity would let it pass, so a record whose scales overflow a double fails here.
  {
    auto ke = [&](const double* vi, const double* vj) {
      return 0.5 * r.mi * dot3(vi, vi) + (two ? 0.5 * r.mj * dot3(vj, vj) : 0.0);
    };
    const double P = r.mi * vib + (two ? r.mj * vjb : 0.0);
    const double Kb = ke(r.vi_before, r.vj_before), Ka = ke(r.vi_after, r.vj_after);
    const double Kw = 0.5 * r.mi * std::max(dot3(gb, gb), dot3(ga, ga));  // in the partner's frame
    const double W = std::max({dot3(r.wi_before, r.wi_before), dot3(r.wi_after, r.wi_after),
                               dot3(r.wj_before, r.wj_before), dot3(r.wj_after, r.wj_after)});
    if (!std::isfinite(V) || !std::isfinite(P) || !std::isfinite(Kb) || !std::isfinite(Ka) || !std::isfinite(Kw) ||
        !std::isfinite(W))
      return fail("range", fmt::format("a scale overflows a double: |vi| + |vj| = {:.6g}, momentum {:.6g}, kinetic "
                                       "energy before {:.6g}, after {:.6g}, largest |w|^2 {:.6g}",
                                       V, P, Kb, Ka, W));
  }
  const double ub = dot3(gb, r.normal), ua = dot3(ga, r.normal);
  if (ub > tol * V)
    return fail("approach", fmt::format("normal relative velocity before (vi - vj).n = {:.17g} > 0: the "
                                        "particles were separating",
                                        ub));

  // A rough collision (friction: spins change): with a scene, the scene's rule for the material
  // pair decides; without one, a record whose spins changed is taken as rough.
  const int mat_i = sv ? sv->material[r.i] : -1;
  const int mat_j = sv ? (pair ? sv->material[r.j] : sv->wall_material[r.j]) : -1;
  bool rough = false;
  if (sv) {
    rough = sv->rough.is_rough(mat_i, mat_j);
  } else {
    double di[3], dj[3];
    for (int c = 0; c < 3; ++c) {
      di[c] = r.wi_after[c] - r.wi_before[c];
      dj[c] = pair ? r.wj_after[c] - r.wj_before[c] : 0.0;
    }
    rough = std::max(norm3(di), norm3(dj)) > tol * (norm3(r.wi_before) + (pair ? norm3(r.wj_before) : 0.0));
  }

  // Momentum: pair mi dvi + mj dvj = 0; wall or fixed partner: the impulse is along n (tangential
  // velocity kept).
  if (two) {
    double dp[3];
    for (int c = 0; c < 3; ++c) dp[c] = r.mi * dvi[c] + r.mj * dvj[c];
    const double P = r.mi * vib + r.mj * vjb;
    const double res = norm3(dp);
    if (!(res <= tol * P))
      return fail("momentum", fmt::format("|mi dvi + mj dvj| = {:.6g} > tol x (mi |vi| + mj |vj|) = "
                                          "{:.6g} x {:.6g} (relative {:.3g})",
                                          res, tol, P, res / P));
  } else if (!rough) {
    const double dn = dot3(dvi, r.normal);
    double dt[3];
    for (int c = 0; c < 3; ++c) dt[c] = dvi[c] - dn * r.normal[c];
    const double res = norm3(dt);
    if (!(res <= tol * V))
      return fail("momentum", fmt::format("wall collision changed the tangential velocity by {:.6g} > tol "
                                          "x |vi| = {:.6g} x {:.6g} (relative {:.3g})",
                                          res, tol, V, res / V));
  }

  // Normal relative velocity after = -e x before.
  const double nres = std::abs(ua + r.e * ub);
  if (!(nres <= tol * V))
    return fail("normal velocity", fmt::format("(vi - vj).n after = {:.17g} but -e x before = {:.17g} "
                                               "(e = {:.17g}; |diff| {:.3g} > tol x {:.6g})",
                                               ua, -r.e * ub, r.e, nres, V));

  rough_out = rough;
  if (rough) {
    if (auto v = check_rough(r, h, sv, tol, ub, V, mat_i, mat_j)) return v;
  } else {
  // Tangential relative velocity unchanged.
  double dtan[3];
  for (int c = 0; c < 3; ++c) dtan[c] = (ga[c] - ua * r.normal[c]) - (gb[c] - ub * r.normal[c]);
  const double tres = norm3(dtan);
  if (!(tres <= tol * V))
    return fail("tangential velocity",
                fmt::format("tangential relative velocity changed by {:.6g} > tol x {:.6g} (relative {:.3g})",
                            tres, V, tres / V));

  // Smooth spheres: spins unchanged.
  {
    double di[3], dj[3];
    for (int c = 0; c < 3; ++c) {
      di[c] = r.wi_after[c] - r.wi_before[c];
      dj[c] = pair ? r.wj_after[c] - r.wj_before[c] : 0.0;
    }
    const double W = norm3(r.wi_before) + (pair ? norm3(r.wj_before) : 0.0);
    const double sres = std::max(norm3(di), norm3(dj));
    if (!(sres <= tol * W))
      return fail("spin", fmt::format("a spin changed by {:.6g} in a smooth collision (spin scale {:.6g})",
                                      sres, W));
  }

  // Energy: KE lost = (1 - e^2) m* u_n^2 / 2 (a wall collision: in the wall's frame).
  {
    const double ke_b = two ? 0.5 * r.mi * dot3(r.vi_before, r.vi_before) +
                                  0.5 * r.mj * dot3(r.vj_before, r.vj_before)
                            : 0.5 * r.mi * dot3(gb, gb);
    const double ke_a = two ? 0.5 * r.mi * dot3(r.vi_after, r.vi_after) +
                                  0.5 * r.mj * dot3(r.vj_after, r.vj_after)
                            : 0.5 * r.mi * dot3(ga, ga);
    const double mstar = two ? r.mi * r.mj / (r.mi + r.mj) : r.mi;
    const double expected = 0.5 * (1.0 - r.e * r.e) * mstar * ub * ub;
    const double lost = ke_b - ke_a;
    const double eres = std::abs(lost - expected);
    if (!(eres <= tol * ke_b))
      return fail("energy", fmt::format("kinetic energy lost {:.17g} but (1 - e^2) m* u_n^2 / 2 = {:.17g} "
                                        "(|diff| {:.3g} > tol x KE {:.6g}; e = {:.17g}, m* = {:.17g}, u_n = {:.17g})",
                                        lost, expected, eres, ke_b, r.e, mstar, -ub));
  }
  }  // smooth

  // The scene's restitution model at the impact speed (mixed as the engine does).
  if (sv) {
    const double u = -ub;
    const int ma = sv->material[r.i];
    const int mb = pair ? sv->material[r.j] : sv->wall_material[r.j];
    const Restitution& ra = sv->materials[static_cast<std::size_t>(ma)].restitution;
    const Restitution& rb = sv->materials[static_cast<std::size_t>(mb)].restitution;
    const double model = ma == mb ? ra(u) : mixed_restitution(ra, rb, u);
    const bool tc_elastic = sv->tc > 0.0 && r.e == 1.0;
    if (!(std::abs(r.e - model) <= tol) && !tc_elastic) {
      const std::string mats =
          ma == mb ? fmt::format("the model of material '{}' gives", sv->materials[static_cast<std::size_t>(ma)].name)
                   : fmt::format("the mean of the models of materials '{}' and '{}' gives",
                                 sv->materials[static_cast<std::size_t>(ma)].name,
                                 sv->materials[static_cast<std::size_t>(mb)].name);
      return fail("restitution model",
                  fmt::format("e = {:.17g} but at u_n = {:.17g} {} {:.17g} (|diff| {:.3g} > tol {:.3g}{})",
                              r.e, u, mats, model, std::abs(r.e - model), tol,
                              sv->tc > 0.0 ? "; e = 1 would be accepted under the TC model" : ""));
    }
  }
  return std::nullopt;
}

}  // namespace

VerifyResult verify_log(const std::string& path, const Scene* scene, double tol) {
  if (!(tol >= 0.0)) throw std::invalid_argument(fmt::format("--tol must be >= 0 (got {})", tol));
  EventLogReader reader(path);
  const LogFile lf = log_file(reader);
  std::optional<SceneView> sv;
  if (scene) sv = view_scene(*scene, lf.header, path);

  VerifyResult res;
  res.model_checked = scene != nullptr;
  EventRecord rec;
  std::uint64_t index = 0;
  while (reader.next(rec)) {
    ++res.records;
    if (sv && rec.kind == static_cast<std::uint8_t>(EventKind::Inflow) && rec.i < lf.header.particles &&
        rec.j < sv->inlet_material.size()) {
      sv->mass[rec.i] = rec.mi;
      sv->radius[rec.i] = rec.mj;
      sv->material[rec.i] = sv->inlet_material[rec.j];
    }
    if (!is_collision(rec.kind)) {
      ++res.skipped;
      ++index;
      continue;
    }
    bool rough = false;
    if (auto v = check_record(rec, lf.header, sv ? &*sv : nullptr, tol, rough)) {
      res.ok = false;
      res.index = index;
      res.offset = record_offset(lf.header, index);
      res.time = rec.time;
      res.kind = rec.kind;
      res.i = rec.i;
      res.j = rec.j;
      res.check = v->check;
      res.detail = v->detail;
      const std::string who =
          is_pair(rec.kind) ? fmt::format("pair collision of particles {} and {}", rec.i, rec.j)
                            : fmt::format("wall collision of particle {} with wall {}", rec.i, rec.j);
      res.message = fmt::format("{}: record {} at byte offset {} (t = {:.17g}, {}) fails the {} check: {}",
                                path, index, res.offset, rec.time, who, res.check, res.detail);
      return res;
    }
    if (rough) ++res.rough;
    if (is_pair(rec.kind))
      ++res.pair;
    else
      ++res.wall;
    ++index;
  }
  return res;
}

}  // namespace matep

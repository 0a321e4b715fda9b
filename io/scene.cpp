// Scene files -> validated Scene. See io/scene.hpp and README.md for the schema.
#include "io/scene.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <random>
#include <numbers>
#include <sstream>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "contact/cone.hpp"
#include "contact/cylinder.hpp"
#include "contact/mesh.hpp"
#include "contact/pipe.hpp"
#include "contact/plane_patch.hpp"
#include "contact/rotating.hpp"
#include "io/placement.hpp"
#include "io/scene_csv.hpp"
#include "io/scene_limits.hpp"
#include "io/scene_toml.hpp"
#include "io/stl.hpp"

namespace matep {

namespace {

using namespace scene_detail;
namespace fs = std::filesystem;

template <int D>
std::string vec_str(const Vec<D>& v) {
  std::string s = "(";
  for (int k = 0; k < D; ++k) s += fmt::format("{}{}", k ? ", " : "", v[k]);
  return s + ")";
}

template <int D>
Vec<D> to_vec(const std::vector<double>& a) {
  Vec<D> v;
  for (int k = 0; k < D; ++k) v[k] = a[static_cast<std::size_t>(k)];
  return v;
}

constexpr const char* kAxis[] = {"x", "y", "z"};

// A radius the cell grids can hold: a normal float, and the domain's widest axis at most
// kMaxDomainToDiameter diameters. Empty when it can; else the problem.
template <int D>
std::string radius_problem(double r, const System<D>& sys) {
  if (!std::isnormal(r) || r < 0.0)
    return fmt::format("radius {} is not a normal positive number (too small to compute with)", r);
  const double L = (sys.upper - sys.lower).maxCoeff(), ratio = L / (2.0 * r);
  if (ratio > kMaxDomainToDiameter)
    return fmt::format("radius {} is too small for the domain: its widest axis ({}) is {:.3g} diameters, more than "
                       "the limit of {:.0e}",
                       r, L, ratio, kMaxDomainToDiameter);
  return {};
}

// Refuses a planned number of grains (so far, with `more` added at key k) that the engines cannot
// number or this machine's memory cannot hold (kBytesPerParticle each, a generous estimate).
void check_grains(const TableReader& t, std::string_view k, std::uint64_t so_far, double more,
                  std::string_view what) {
  const double total = static_cast<double>(so_far) + more;
  const std::string whose = so_far > 0 ? fmt::format(", {} in all with the grains before", total) : std::string();
  if (total > static_cast<double>(kMaxParticles))
    t.fail(k, fmt::format("{} {:.0f} grains{}, more than the limit of {} grains a run can number", what, more, whose,
                          kMaxParticles),
           t.need(k));
  const double mem = physical_memory_bytes(), need = total * kBytesPerParticle;
  if (mem > 0.0 && need > mem)
    t.fail(k, fmt::format("{} {:.0f} grains{}; they would need about {} of memory ({:.0f} bytes each), more than this "
                          "machine's {}",
                          what, more, whose, show_bytes(need), kBytesPerParticle, show_bytes(mem)),
           t.need(k));
}

// The [NAME] sub-tables of a top-level table such as [material], in file order.
std::vector<std::pair<std::string, TableReader>> named_tables(const TableReader& top, std::string_view k) {
  std::vector<std::pair<std::string, TableReader>> out;
  if (!top.has(k)) return out;
  const TableReader parent = top.sub(k);
  std::vector<std::pair<std::string, const toml::node*>> items;
  for (const auto& [name, node] : parent.table()) items.emplace_back(std::string(name.str()), &node);
  std::stable_sort(items.begin(), items.end(), [](const auto& a, const auto& b) {
    return source_order(*a.second) < source_order(*b.second);
  });
  for (const auto& [name, node] : items) {
    if (!node->is_table()) {
      parent.fail(name,
                  fmt::format("expected a table ([{}.{}]) but found {}", k, name, type_name(*node)), *node);
    }
    out.emplace_back(name, TableReader(top.file(), *node->as_table(), parent.key(name)));
  }
  return out;
}

// -------------------------------------------------------------------------------- materials

Restitution read_restitution(const TableReader& m) {
  const toml::node* n = m.find("restitution");
  if (n == nullptr) return Restitution::constant(1.0);
  if (n->is_number()) return Restitution::constant(m.as_number(*n, "restitution", kUnit));
  if (!n->is_table()) {
    m.fail("restitution",
           fmt::format("expected a number in [0, 1] or a table {{model = ...}} but found {}", type_name(*n)), *n);
  }
  const TableReader t = m.sub("restitution");
  const std::string model = t.string("model", {"constant", "power", "schwager", "exponential"});
  Restitution r;
  if (model == "constant") {
    t.allow({"model", "e"});
    r = Restitution::constant(t.number("e", kUnit));
  } else if (model == "power") {
    t.allow({"model", "B", "b"});
    r.model = Restitution::Model::Power;
    r.B = t.number("B", kPositive);
    r.b = t.number("b", kNonNegative);
  } else if (model == "schwager") {
    t.allow({"model", "e0", "u0", "n"});
    r.model = Restitution::Model::Schwager;
    r.e0 = t.number("e0", kUnit);
    r.u0 = t.number("u0", kPositive);
    r.n = t.number_or("n", 0.2, kPositive);
  } else {
    t.allow({"model", "C", "a"});
    r.model = Restitution::Model::Exponential;
    r.C = t.number("C", Range{0.0, 1.0, true, false});
    r.a = t.number("a", kNonNegative);
  }
  return r;
}

Material read_material(const std::string& name, const TableReader& m) {
  m.allow({"density", "restitution", "young", "poisson", "friction", "contact", "stiffness", "dissipation",
           "tangential_restitution", "tangential", "rolling_friction", "rolling", "rolling_damping"});
  Material mat;
  mat.name = name;
  mat.density = m.number("density", kPositive);
  mat.restitution = read_restitution(m);
  mat.young = m.number_opt("young", kPositive);
  mat.poisson = m.number_opt("poisson", Range{-1.0, 0.5, true, false});
  mat.friction = m.number_opt("friction", kNonNegative);
  mat.contact = m.string_opt("contact", {"linear", "hertz", "viscoelastic"}).value_or("");
  mat.stiffness = m.number_opt("stiffness", kPositive);
  mat.dissipation = m.number_opt("dissipation", kNonNegative);
  mat.tangential_restitution = m.number_opt("tangential_restitution", Range{-1.0, 1.0});
  mat.tangential = m.string_opt("tangential", {"walton", "constant", "fem_fit"}).value_or("");
  mat.rolling_friction = m.number_opt("rolling_friction", kNonNegative);
  mat.rolling = m.string_opt("rolling", {"constant", "epsd"}).value_or("");
  mat.rolling_damping = m.number_opt("rolling_damping", Range{0.0, 1.0});
  return mat;
}

int material_index(const TableReader& t, const std::vector<Material>& materials) {
  const std::string name = t.string("material");
  for (std::size_t i = 0; i < materials.size(); ++i) {
    if (materials[i].name == name) return static_cast<int>(i);
  }
  std::string known;
  for (const auto& m : materials) known += (known.empty() ? "" : ", ") + m.name;
  t.fail("material",
         known.empty() ? std::string("no such material: the scene defines no [material.NAME] tables")
                       : fmt::format("no such material (defined: {})", known),
         t.need("material"));
}

// -------------------------------------------------------------------------------- particles

template <int D>
struct Group {
  Group(std::string n, TableReader t) : name(std::move(n)), table(std::move(t)) {}
  std::string name;
  TableReader table;
  int material = 0;         // -1: a file group whose material column gives each grain's
  std::vector<int> mat;     // then: per particle (empty: all `material`)
  bool from_file = false;
  std::string file_value;   // as written in the scene
  std::string file_path;    // resolved
  std::optional<std::string> file_group;  // file_group: the rows of this group only
  // Generated groups.
  double rmin = 0.0, rmax = 0.0;
  std::uint64_t count = 0;
  bool lattice = false;
  Vec<D> region_lower = Vec<D>::Zero(), region_upper = Vec<D>::Zero();
  bool region_given = false;
  std::optional<double> temperature;
  Vec<D> velocity = Vec<D>::Zero();
  bool fixed = false;  // immovable grains (at rest; a file's velocities and spins are dropped)
  // Particles.
  std::vector<Vec<D>> x, v;
  std::vector<Spin<D>> w;
  std::vector<double> r;
  std::vector<std::size_t> line;  // file groups: CSV line of each particle

  int material_of(std::size_t i) const { return mat.empty() ? material : mat[i]; }
};

template <int D>
struct Builder {
  const std::string& file;
  fs::path base_dir;
  System<D>& sys;
  std::vector<Group<D>> groups;
  std::vector<std::pair<std::size_t, std::size_t>> owner;  // grid tag -> (group, index)
  // Overlap allowed between particles read from files, as a fraction of the contact distance:
  // round-off for hard spheres; kSoftFileOverlap for soft spheres (a settled TDM state).
  double file_overlap = 1e-12;
  std::uint64_t planned = 0;  // grains of the groups read so far and the inlets' slots

  std::string who(std::size_t g, std::size_t i) const {
    std::string s = fmt::format("particles.{}[{}]", groups[g].name, i);
    if (groups[g].from_file && i < groups[g].line.size()) {
      s += fmt::format(" ({} line {})", groups[g].file_value, groups[g].line[i]);
    }
    return s;
  }

  void read_group(const std::string& name, const TableReader& t) {
    t.allow({"material", "file", "file_group", "radius", "count", "arrangement", "region", "temperature",
             "velocity", "fixed"});
    Group<D> g(name, t);
    // A file with a material column may give each grain's material (read_file).
    g.material = t.has("file") && !t.has("material") ? -1 : material_index(t, sys.materials);
    if (t.has("file_group") && !t.has("file"))
      t.fail("file_group", "needs file (it picks the rows of a particle file by its group column)", t.need("file_group"));
    g.fixed = t.boolean_or("fixed", false);
    if (g.fixed) {
      for (const char* k : {"velocity", "temperature"}) {
        if (t.has(k)) t.fail(k, "cannot be combined with fixed = true (a fixed grain does not move)", t.need(k));
      }
    }
    if (t.has("file")) {
      for (const char* k : {"radius", "count", "arrangement", "region", "temperature", "velocity"}) {
        if (t.has(k)) t.fail(k, "cannot be combined with file (the file gives every particle)", t.need(k));
      }
      g.from_file = true;
      g.file_value = t.string("file");
      fs::path p(g.file_value);
      if (p.is_relative()) p = base_dir / p;
      g.file_path = p.lexically_normal().string();
      if (t.has("file_group")) g.file_group = t.string("file_group");
      read_file(g);
      if (g.fixed) {  // the file's velocity and spin columns describe motion a fixed grain has not
        g.v.assign(g.v.size(), Vec<D>::Zero());
        g.w.assign(g.w.size(), Spin<D>::Zero());
      }
    } else {
      read_generated(g, t);
    }
    planned += g.from_file ? g.r.size() : g.count;
    groups.push_back(std::move(g));
  }

  void read_file(Group<D>& g) {
    const TableReader& t = g.table;
    CsvTable csv;
    std::error_code ec;
    const auto bytes = fs::file_size(g.file_path, ec);
    if (!ec) {  // reading holds about 16 bytes per byte of text (rows of doubles)
      const double mem = physical_memory_bytes();
      if (mem > 0.0 && 16.0 * static_cast<double>(bytes) > mem)
        fail_got(file, t.key("file"),
                 fmt::format("{}: the file is {}; reading it would need about {} of memory, more than this machine's {}",
                             g.file_path, show_bytes(static_cast<double>(bytes)),
                             show_bytes(16.0 * static_cast<double>(bytes)), show_bytes(mem)),
                 quote(g.file_value));
    }
    try {
      csv = read_csv(g.file_path, {"group", "material"});
    } catch (const CsvError& e) {
      fail_got(file, t.key("file"), fmt::format("{}: {}", g.file_path, e.what()), quote(g.file_value));
    }
    const auto bad = [&](std::string_view problem) {
      fail_got(file, t.key("file"), fmt::format("{}: {}", g.file_path, problem), quote(g.file_value));
    };
    std::vector<std::string> required, optional;
    for (int k = 0; k < D; ++k) required.emplace_back(kAxis[k]);
    for (int k = 0; k < D; ++k) required.push_back(fmt::format("v{}", kAxis[k]));
    required.emplace_back("radius");
    if (D == 2) {
      optional = {"w"};
    } else {
      optional = {"wx", "wy", "wz"};
    }
    std::map<std::string, std::size_t> col;
    for (std::size_t c = 0; c < csv.columns.size(); ++c) {
      const std::string& name = csv.columns[c];
      // "id" (as written in final_state.csv) is accepted and ignored: ids follow the file order;
      // "group" and "material" are words (below).
      const bool known = std::find(required.begin(), required.end(), name) != required.end() ||
                         std::find(optional.begin(), optional.end(), name) != optional.end() || name == "id" ||
                         csv.text.count(name);
      if (!known) {
        std::string allowed;
        for (const auto& a : required) allowed += (allowed.empty() ? "" : ",") + a;
        for (const auto& a : optional) allowed += "," + a;
        allowed += ",id,group,material";
        bad(fmt::format("unknown column '{}' (columns of a {}D particle file: {})", name, D, allowed));
      }
      col[name] = c;
    }
    for (const auto& name : required) {
      if (!col.count(name)) bad(fmt::format("missing column '{}'", name));
    }
    if (csv.rows.empty()) bad("no particles (the file has a header but no rows)");
    // The rows read: all, or those whose group is file_group (a final_state.csv of a multi-group run).
    std::vector<std::size_t> rows;
    const auto groups_col = csv.text.find("group");
    if (g.file_group) {
      if (groups_col == csv.text.end())
        t.fail("file_group", fmt::format("{} has no group column to pick rows by", g.file_value), t.need("file_group"));
      std::vector<std::string> seen;
      for (std::size_t i = 0; i < csv.rows.size(); ++i) {
        const std::string& w = groups_col->second[i];
        if (w == *g.file_group) rows.push_back(i);
        if (seen.size() < 8 && std::find(seen.begin(), seen.end(), w) == seen.end()) seen.push_back(w);
      }
      if (rows.empty())
        t.fail("file_group", fmt::format("no row of {} has this group (it has: {})", g.file_value, fmt::join(seen, ", ")),
               t.need("file_group"));
    } else {
      rows.resize(csv.rows.size());
      for (std::size_t i = 0; i < rows.size(); ++i) rows[i] = i;
    }
    // Materials: a material column must agree with the table's material, or gives each grain's when
    // the table has none.
    const auto mats_col = csv.text.find("material");
    if (g.material < 0 && mats_col == csv.text.end()) g.material = material_index(t, sys.materials);  // missing key
    if (mats_col != csv.text.end()) {
      std::map<std::string, int, std::less<>> index;
      for (std::size_t m = 0; m < sys.materials.size(); ++m) index.emplace(sys.materials[m].name, static_cast<int>(m));
      if (g.material < 0) g.mat.resize(rows.size());
      for (std::size_t i = 0; i < rows.size(); ++i) {
        const std::string& w = mats_col->second[rows[i]];
        const auto it = index.find(w);
        const auto row = [&] {
          return fmt::format("particles.{}[{}] ({} line {})", g.name, i, g.file_value, csv.lines[rows[i]]);
        };
        if (it == index.end()) {
          std::string known;
          for (const auto& m : sys.materials) known += (known.empty() ? "" : ", ") + m.name;
          bad(fmt::format("{} has material '{}': no such material (defined: {})", row(), w, known));
        }
        if (g.material >= 0 && it->second != g.material)
          bad(fmt::format("{} has material '{}' but {} is '{}'", row(), w, t.key("material"),
                          sys.materials[static_cast<std::size_t>(g.material)].name));
        if (g.material < 0) g.mat[i] = it->second;
      }
      if (g.material < 0) g.material = g.mat[0];
    }
    const std::size_t n = rows.size();
    check_grains(t, "file", planned, static_cast<double>(n), "the file gives");
    g.x.resize(n);
    g.v.resize(n);
    g.w.assign(n, Spin<D>::Zero());
    g.r.resize(n);
    g.line.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      const auto& row = csv.rows[rows[i]];
      g.line[i] = csv.lines[rows[i]];
      for (int k = 0; k < D; ++k) {
        g.x[i][k] = row[col.at(kAxis[k])];
        g.v[i][k] = row[col.at(fmt::format("v{}", kAxis[k]))];
      }
      for (std::size_t s = 0; s < optional.size(); ++s) {
        const auto it = col.find(optional[s]);
        if (it != col.end()) g.w[i][static_cast<Eigen::Index>(s)] = row[it->second];
      }
      g.r[i] = row[col.at("radius")];
      if (!(g.r[i] > 0.0)) {
        fail_got(file, t.key("file"),
                 fmt::format("particles.{}[{}] ({} line {}) has radius {} (must be > 0)", g.name, i, g.file_value,
                             g.line[i], g.r[i]),
                 quote(g.file_value));
      }
      if (const std::string p = radius_problem<D>(g.r[i], sys); !p.empty())
        fail_got(file, t.key("file"),
                 fmt::format("particles.{}[{}] ({} line {}): {}", g.name, i, g.file_value, g.line[i], p),
                 quote(g.file_value));
      for (int k = 0; k < D; ++k) {
        const double lo = sys.lower[k], hi = sys.upper[k], xk = g.x[i][k];
        const double slack = file_overlap * g.r[i];  // a soft particle may press into a wall at the edge
        const bool inside = sys.periodic[k] ? (xk >= lo && xk <= hi)
                                            : (xk - g.r[i] >= lo - slack && xk + g.r[i] <= hi + slack);
        if (!inside) {
          fail_got(file, t.key("file"),
                   fmt::format("particles.{}[{}] ({} line {}) at {} with radius {} is outside the domain along {} "
                               "(domain [{}, {}]{})",
                               g.name, i, g.file_value, g.line[i], vec_str<D>(g.x[i]), g.r[i], kAxis[k], lo, hi,
                               sys.periodic[k] ? ", periodic: the centre must lie inside"
                                               : ": the particle must lie entirely inside"),
                   quote(g.file_value));
        }
      }
    }
  }

  void read_generated(Group<D>& g, const TableReader& t) {
    // radius = r or [rmin, rmax]
    const toml::node& rn = t.need("radius");
    if (rn.is_number()) {
      g.rmin = g.rmax = t.as_number(rn, "radius", kPositive);
    } else if (const toml::array* a = rn.as_array()) {
      if (a->size() != 2) t.fail("radius", fmt::format("expected [rmin, rmax] but the array has {} elements", a->size()), rn);
      const auto rr = t.numbers("radius", 2);
      if (!(rr[0] > 0.0)) t.fail("radius", "rmin must be > 0", rn);
      if (!(rr[1] >= rr[0])) t.fail("radius", "rmax must be >= rmin", rn);
      g.rmin = rr[0];
      g.rmax = rr[1];
    } else {
      t.fail("radius", fmt::format("expected a number or [rmin, rmax] but found {}", type_name(rn)), rn);
    }
    if (const std::string p = radius_problem<D>(g.rmin, sys); !p.empty()) t.fail("radius", p, rn);
    g.count = static_cast<std::uint64_t>(t.integer("count", Range{1.0}));
    check_grains(t, "count", planned, static_cast<double>(g.count), "asks for");
    g.lattice = t.string_opt("arrangement", {"random", "lattice"}).value_or("random") == "lattice";
    g.region_lower = sys.lower;
    g.region_upper = sys.upper;
    if (t.has("region")) {
      g.region_given = true;
      const TableReader reg = t.sub("region");
      reg.allow({"lower", "upper"});
      g.region_lower = to_vec<D>(reg.numbers("lower", D));
      g.region_upper = to_vec<D>(reg.numbers("upper", D));
      for (int k = 0; k < D; ++k) {
        if (!(g.region_upper[k] > g.region_lower[k])) {
          reg.fail("upper", fmt::format("must exceed region.lower along {} ({} <= {})", kAxis[k],
                                        g.region_upper[k], g.region_lower[k]),
                   reg.need("upper"));
        }
        if (g.region_lower[k] < sys.lower[k]) {
          reg.fail("lower", fmt::format("lies outside the domain along {} (domain.lower = {})", kAxis[k], sys.lower[k]),
                   reg.need("lower"));
        }
        if (g.region_upper[k] > sys.upper[k]) {
          reg.fail("upper", fmt::format("lies outside the domain along {} (domain.upper = {})", kAxis[k], sys.upper[k]),
                   reg.need("upper"));
        }
      }
    }
    for (int k = 0; k < D; ++k) {
      const double L = g.region_upper[k] - g.region_lower[k];
      if (!sys.periodic[k] && L < 2.0 * g.rmax) {
        t.fail(g.region_given ? "region" : "radius",
               fmt::format("the {} is {} wide along {}, less than the largest particle diameter {}",
                           g.region_given ? "region" : "domain", L, kAxis[k], 2.0 * g.rmax),
               t.need(g.region_given ? "region" : "radius"));
      }
    }
    if (t.has("temperature") && t.has("velocity")) {
      t.fail("velocity", "cannot be combined with temperature (give one of them)", t.need("velocity"));
    }
    g.temperature = t.number_opt("temperature", kNonNegative);
    if (t.has("velocity")) g.velocity = to_vec<D>(t.numbers("velocity", D));
  }

  void check_and_insert(placement::OverlapGrid<D>& grid, std::size_t gi, std::size_t i) {
    const Group<D>& g = groups[gi];
    const TableReader& t = g.table;
    const Vec<D>& x = g.x[i];
    const double r = g.r[i];
    const std::string key = t.key(g.from_file ? "file" : "arrangement");
    const std::string got = g.from_file ? quote(g.file_value) : quote(g.lattice ? "lattice" : "random");
    const double tol = g.from_file ? file_overlap : 1e-12;
    if (const auto w = placement::wall_overlap<D>(sys.walls, x, r, tol)) {
      fail_got(file, key,
               fmt::format("{} at {} with radius {} overlaps wall.{} by {:.6g} (signed distance {:.6g} < radius)",
                           who(gi, i), vec_str<D>(x), r, sys.walls[w->first].name, r - w->second, w->second),
               got);
    }
    if (const auto hit = grid.first_overlap(x, r, tol)) {
      const auto [og, oi] = owner[hit->tag];
      fail_got(file, key,
               fmt::format("{} at {} with radius {} overlaps {} at {} with radius {} by {:.6g}", who(gi, i),
                           vec_str<D>(x), r, who(og, oi), vec_str<D>(hit->x), hit->r, r + hit->r - hit->distance),
               got);
    }
    grid.insert(x, r, owner.size());
    owner.emplace_back(gi, i);
  }

  std::vector<double> masses(const Group<D>& g) const {
    std::vector<double> m(g.r.size());
    for (std::size_t i = 0; i < m.size(); ++i) m[i] = sys.materials[g.material_of(i)].density * ball_volume<D>(g.r[i]);
    return m;
  }

  void generate(placement::OverlapGrid<D>& grid, std::size_t gi, std::uint64_t seed) {
    Group<D>& g = groups[gi];
    const TableReader& t = g.table;
    const toml::node& count_node = t.need("count");
    const std::string rdesc = g.rmax > g.rmin ? fmt::format("radius in [{}, {}]", g.rmin, g.rmax)
                                              : fmt::format("radius {}", g.rmin);
    double vol = 1.0;
    for (int k = 0; k < D; ++k) vol *= g.region_upper[k] - g.region_lower[k];
    const double close_packing =
        D == 2 ? std::numbers::pi / std::sqrt(12.0) : std::numbers::pi / std::sqrt(18.0);
    // Hopeless requests fail at once, before anything is allocated: even the smallest radii
    // would fill more of the region than the densest packing of equal spheres.
    const auto too_full = [&](double fill) {
      t.fail("count",
             fmt::format("could not place {} particles of {} in the region: they would fill {:.3g}% of its "
                         "volume, more than the densest packing ({:.3g}%); lower the count or the radius",
                         g.count, rdesc, 100.0 * fill, 100.0 * close_packing),
             count_node);
    };
    if (static_cast<double>(g.count) * ball_volume<D>(g.rmin) / vol > close_packing) {
      too_full(static_cast<double>(g.count) * ball_volume<D>(g.rmin) / vol);
    }
    placement::Rng rng(seed, gi);
    g.r.resize(g.count);
    for (auto& r : g.r) r = (g.rmax > g.rmin) ? rng.uniform(g.rmin, g.rmax) : g.rmin;
    double fill = 0.0;
    for (const double r : g.r) fill += ball_volume<D>(r);
    fill /= vol;
    if (fill > close_packing) too_full(fill);
    if (g.lattice) {
      const auto lat = placement::lattice_for<D>(g.region_lower, g.region_upper, g.count);
      if (lat.spacing < 2.0 * g.rmax * (1.0 - 1e-12)) {
        t.fail("count",
               fmt::format("a lattice of {} particles with {} does not fit in the region: the largest spacing "
                           "giving {} sites is {:.6g}, less than the diameter {}; lower the count or the radius",
                           g.count, rdesc, g.count, lat.spacing, 2.0 * g.rmax),
               count_node);
      }
      g.x.resize(g.count);
      for (std::uint64_t i = 0; i < g.count; ++i) {
        g.x[i] = lat.site(g.region_lower, g.region_upper, i);
        check_and_insert(grid, gi, i);
      }
    } else {
      // Random sequential placement of equal spheres jams at a known packing fraction (Feder 1980;
      // Torquato, Uche & Stillinger 2006); large monodisperse requests above it fail at once.
      const double jamming = D == 2 ? 0.547 : 0.3841;
      if (g.rmin == g.rmax && g.count >= 500 && fill > jamming) {
        t.fail("count",
               fmt::format("could not place {} particles of {} in the region: they would fill {:.3g}% of its "
                           "volume, more than random placement can reach (about {:.3g}%); lower the count or "
                           "use arrangement = \"lattice\"",
                           g.count, rdesc, 100.0 * fill, 100.0 * jamming),
               count_node);
      }
      const std::uint64_t cap = std::numeric_limits<std::uint64_t>::max() / 400;
      const std::uint64_t max_attempts = 200 * std::min(g.count, cap) + 10000;
      const std::size_t first_tag = owner.size();
      for (std::size_t i = 0; i < g.count; ++i) owner.emplace_back(gi, i);
      const auto res = placement::place_random<D>(grid, sys.walls, g.region_lower, g.region_upper, sys.periodic,
                                                  g.r, first_tag, max_attempts, rng, g.x);
      if (res.placed < g.count) {
        t.fail("count",
               fmt::format("could not place {} particles of {} in the region (placed {} after {} attempts{}; "
                           "they would fill {:.3g}% of its volume); lower the count or use "
                           "arrangement = \"lattice\"",
                           g.count, rdesc, res.placed, res.attempts,
                           res.gave_up_early
                               ? fmt::format(", stopped early: at the current success rate the rest would need "
                                             "more than the limit of {} attempts",
                                             max_attempts)
                               : std::string(),
                           100.0 * fill),
               count_node);
      }
    }
    // Velocities.
    if (g.temperature) {
      placement::thermal_velocities<D>(masses(g), *g.temperature, rng, g.v);
    } else {
      g.v.assign(g.count, g.velocity);
    }
    g.w.assign(g.count, Spin<D>::Zero());
  }
};

// A nonzero direction at key k (made unit).
template <int D>
Vec<D> read_direction(const TableReader& t, std::string_view k) {
  const Vec<D> n = to_vec<D>(t.numbers(k, D));
  if (!(n.norm() > 0.0) || !n.allFinite()) t.fail(k, "must be a nonzero vector", t.need(k));
  return n / n.norm();
}

// rotation = {angular_velocity = w}: rad/s about the shape's own axis (2D: about its centre), for
// the shapes of revolution. With `point` (and in 3D `axis`) the rotation is about that axis
// instead, for any bounded shape (contact/rotating.hpp, applied by read_wall_shape): the shape is
// then read at rest (0 here).
template <int D>
bool about_given_axis(const TableReader& t) {
  if (!t.has("rotation")) return false;
  const TableReader r = t.sub("rotation");
  if (D == 2) r.allow({"angular_velocity", "point"});
  else r.allow({"angular_velocity", "point", "axis"});
  return r.has("point") || r.has("axis");
}
template <int D>
double read_rotation(const TableReader& t) {
  if (!t.has("rotation") || about_given_axis<D>(t)) return 0.0;
  return t.sub("rotation").number("angular_velocity");
}

// type = "pipe": point (the centreline's start), direction, radius, and pieces, an array of
// ["straight", length] and ["arc", bend_radius, angle_degrees(, [axis])] (contact/pipe.hpp).
template <int D>
std::shared_ptr<const WallShape<D>> read_pipe(const TableReader& t) {
  t.allow({"type", "point", "direction", "radius", "pieces", "material", "rotation"});
  if (t.has("rotation") && !about_given_axis<D>(t))
    t.fail("rotation", D == 3 ? "a pipe turns only about a given axis: add point and axis to rotation"
                              : "a 2D pipe turns only about a given point: add point to rotation",
           t.need("rotation"));
  const Vec<D> point = to_vec<D>(t.numbers("point", D));
  const Vec<D> dir = read_direction<D>(t, "direction");
  const double radius = t.number("radius", kPositive);
  const toml::node& node = t.need("pieces");
  const toml::array* a = node.as_array();
  if (a == nullptr || a->empty())
    t.fail("pieces", "expected a non-empty array of pieces such as [\"straight\", 0.3] or [\"arc\", 0.1, 180.0]",
           node);
  std::vector<PipePiece<D>> pieces;
  for (std::size_t k = 0; k < a->size(); ++k) {
    const toml::array* p = a->get(k)->as_array();
    auto bad = [&](std::string_view why) {
      t.fail("pieces", fmt::format("piece {}: {}", k, why), node);
    };
    if (p == nullptr || p->empty() || !p->get(0)->is_string()) bad("expected [\"straight\", length] or [\"arc\", ...]");
    const std::string kind = p->get(0)->value<std::string>().value_or("");
    auto num = [&](std::size_t i, std::string_view what) {
      if (i >= p->size() || !p->get(i)->is_number()) bad(fmt::format("{} must be a number", what));
      const double v = p->get(i)->value<double>().value_or(0.0);
      if (!std::isfinite(v)) bad(fmt::format("{} must be finite", what));
      return v;
    };
    if (kind == "straight") {
      if (p->size() != 2) bad("a straight piece is [\"straight\", length]");
      const double L = num(1, "the length");
      if (!(L > 0.0)) bad(fmt::format("the length must be > 0 (got {})", L));
      pieces.push_back(PipePiece<D>::straight(L));
    } else if (kind == "arc") {
      const std::size_t want = D == 3 ? 4 : 3;
      if (p->size() != want)
        bad(D == 3 ? "an arc is [\"arc\", bend_radius, angle_degrees, [axis]] (it turns about axis)"
                   : "an arc is [\"arc\", bend_radius, angle_degrees] (> 0 turns left)");
      const double Rb = num(1, "the bend radius"), deg = num(2, "the angle");
      if (!(Rb > radius)) bad(fmt::format("the bend radius {} must exceed the pipe's radius {}", Rb, radius));
      if (!(deg != 0.0) || std::abs(deg) > 360.0) bad(fmt::format("the angle must be nonzero, at most 360 degrees (got {})", deg));
      Vec<D> axis = Vec<D>::Zero();
      if constexpr (D == 3) {
        const toml::array* ax = p->get(3)->as_array();
        if (ax == nullptr || ax->size() != 3) bad("the axis must be an array of 3 numbers");
        for (int i = 0; i < 3; ++i) {
          if (!ax->get(static_cast<std::size_t>(i))->is_number()) bad("the axis must be an array of 3 numbers");
          axis[i] = ax->get(static_cast<std::size_t>(i))->value<double>().value_or(0.0);
        }
      }
      pieces.push_back(PipePiece<D>::arc(Rb, deg * std::numbers::pi / 180.0, axis));
    } else {
      bad(fmt::format("unknown kind \"{}\" (expected \"straight\" or \"arc\")", kind));
    }
  }
  try {
    return std::make_shared<PipeWall<D>>(point, dir, radius, pieces);
  } catch (const std::invalid_argument& e) {  // e.g. an arc's axis along the pipe's direction
    t.fail("pieces", e.what(), node);
  }
}

// type = "mesh": file (an STL file, relative to the scene's folder), scale (a factor, e.g. 0.001
// for a CAD file in millimetres), translate (added after scaling) (contact/mesh.hpp, io/stl.hpp).
template <int D>
std::shared_ptr<const WallShape<D>> read_mesh(const TableReader& t, const fs::path& base_dir) {
  t.allow({"type", "file", "scale", "translate", "material", "rotation"});
  if (t.has("rotation") && !about_given_axis<D>(t))
    t.fail("rotation", "a mesh turns only about a given axis: add point and axis to rotation", t.need("rotation"));
  if constexpr (D == 2) {
    t.fail("type", "a mesh wall is a 3D triangle surface (STL); a 2D scene uses planes, patches and pipes",
           t.need("type"));
  } else {
    const std::string value = t.string("file");
    fs::path p(value);
    if (p.is_relative()) p = base_dir / p;
    const std::string path = p.lexically_normal().string();
    const double scale = t.number_or("scale", 1.0, kPositive);
    const Vec<3> shift = t.has("translate") ? to_vec<3>(t.numbers("translate", 3)) : Vec<3>::Zero();
    StlMesh m;
    try {
      m = read_stl(path);
    } catch (const std::runtime_error& e) {
      t.fail("file", fmt::format("{}: {}", path, e.what()), t.need("file"));
    }
    for (Vec<3>& x : m.vertices) x = scale * x + shift;
    if (m.triangles.size() >= kMaxFeatures)
      t.fail("file", fmt::format("{}: {} triangles, more than a mesh wall holds ({})", path, m.triangles.size(),
                                 kMaxFeatures - 1),
             t.need("file"));
    try {
      return std::make_shared<MeshWall>(std::move(m.vertices), std::move(m.triangles));
    } catch (const std::invalid_argument& e) {
      t.fail("file", fmt::format("{}: {}", path, e.what()), t.need("file"));
    }
  }
}

// The shape of a [wall.NAME] table (contact/plane.hpp, plane_patch.hpp, cylinder.hpp, cone.hpp,
// pipe.hpp, mesh.hpp).
template <int D>
std::shared_ptr<const WallShape<D>> read_shape_itself(const TableReader& t, const fs::path& base_dir);

// A shape, turning about a given axis if rotation has a point (contact/rotating.hpp).
template <int D>
std::shared_ptr<const WallShape<D>> read_wall_shape(const TableReader& t, const fs::path& base_dir) {
  std::shared_ptr<const WallShape<D>> shape = read_shape_itself<D>(t, base_dir);
  if (!about_given_axis<D>(t)) return shape;
  const TableReader r = t.sub("rotation");
  const double omega = r.number("angular_velocity");
  const Vec<D> point = to_vec<D>(r.numbers("point", D));
  Vec<D> axis = Vec<D>::Zero();
  if constexpr (D == 3) axis = read_direction<D>(r, "axis");
  try {
    return std::make_shared<RotatingWall<D>>(std::move(shape), point, axis, omega);
  } catch (const std::invalid_argument& e) {
    t.fail("rotation", e.what(), t.need("rotation"));
  }
}

template <int D>
std::shared_ptr<const WallShape<D>> read_shape_itself(const TableReader& t, const fs::path& base_dir) {
  const std::string type = t.string("type", {"plane", "cylinder", "cone", "pipe", "mesh"});
  if (type == "pipe") return read_pipe<D>(t);
  if (type == "mesh") return read_mesh<D>(t, base_dir);
  if (type == "plane") {
    t.allow({"type", "point", "normal", "material", "oscillation", "patch", "hole", "rotation"});
    const Vec<D> point = to_vec<D>(t.numbers("point", D));
    const Vec<D> n = read_direction<D>(t, "normal");
    if (t.has("patch") && t.has("hole"))
      t.fail("hole", "a plane is either a patch or has a hole, not both (remove patch or hole)", t.need("hole"));
    const char* region_key = t.has("patch") ? "patch" : (t.has("hole") ? "hole" : nullptr);
    if (!region_key) {
      if (t.has("rotation"))
        t.fail("rotation", "an infinite plane cannot rotate (a turntable is a disk patch)", t.need("rotation"));
      auto plane = std::make_shared<PlaneWall<D>>(point, n);
      if (t.has("oscillation")) {  // p(t) = point + amplitude sin(2 pi frequency t)
        const TableReader o = t.sub("oscillation");
        o.allow({"amplitude", "frequency"});
        plane->amplitude = to_vec<D>(o.numbers("amplitude", D));
        plane->frequency = o.number("frequency", kPositive);
      }
      return plane;
    }
    if (t.has("oscillation"))
      t.fail("oscillation", fmt::format("a plane with a {} cannot oscillate (only an infinite plane can)", region_key),
             t.need("oscillation"));
    const bool hole = std::string_view(region_key) == "hole";
    const TableReader r = t.sub(region_key);
    const double omega = read_rotation<D>(t);
    const std::string shape = r.string("shape", D == 3 ? std::initializer_list<std::string_view>{"disk", "rectangle"}
                                                     : std::initializer_list<std::string_view>{"segment"});
    if (shape == "rectangle") {
      r.allow({"shape", "size", "direction"});
      const auto size = r.numbers("size", 2);
      if (!(size[0] > 0.0) || !(size[1] > 0.0)) r.fail("size", "must be two lengths > 0", r.need("size"));
      const Vec<D> u = read_direction<D>(r, "direction");
      if (std::abs(u.dot(n)) > 1.0 - 1e-9)
        r.fail("direction", "must not be parallel to the plane's normal", r.need("direction"));
      if (omega != 0.0)
        t.fail("rotation", "a rectangle turns only about a given axis: add point and axis to rotation",
               t.need("rotation"));
      return std::make_shared<BoundedPlane<D>>(point, n, u, 0.5 * size[0], 0.5 * size[1], hole);
    }
    // A disk (3D) or a segment (2D) around `point`.
    r.allow({"shape", D == 3 ? "radius" : "length"});
    const double radius = D == 3 ? r.number("radius", kPositive) : 0.5 * r.number("length", kPositive);
    if (omega != 0.0 && (D == 2 || hole))
      t.fail("rotation",
             D == 2 ? "a segment turns only about a given point: add point to rotation"
                    : "only a 3D disk patch turns about its own normal; a holed plane is unbounded and cannot turn",
             t.need("rotation"));
    return std::make_shared<BoundedPlane<D>>(point, n, radius, hole, omega);
  }
  if (type == "cylinder") {
    if constexpr (D == 3) t.allow({"type", "point", "axis", "radius", "length", "side", "material", "rotation"});
    else t.allow({"type", "point", "radius", "side", "material", "rotation"});
    const Vec<D> point = to_vec<D>(t.numbers("point", D));
    Vec<D> axis = Vec<D>::Zero();
    if constexpr (D == 3) axis = read_direction<D>(t, "axis");
    const double radius = t.number("radius", kPositive);
    const double length = D == 3 ? t.number_or("length", 0.0, kPositive) : 0.0;
    if (t.has("length") && t.has("side"))
      t.fail("side", "a finite cylinder (length given) is an open tube touched from both sides; side applies to an "
                     "infinite one",
             t.need("side"));
    const bool inside = t.string_opt("side", {"inside", "outside"}).value_or("inside") == "inside";
    return std::make_shared<CylinderWall<D>>(point, axis, radius, length, inside, read_rotation<D>(t));
  }
  // cone
  t.allow({"type", "point", "axis", "radii", "length", "material", "rotation"});
  const Vec<D> point = to_vec<D>(t.numbers("point", D));
  const Vec<D> axis = read_direction<D>(t, "axis");
  const auto radii = t.numbers("radii", 2);
  if (!(radii[0] >= 0.0) || !(radii[1] >= 0.0) || !(radii[0] + radii[1] > 0.0))
    t.fail("radii", "must be two radii >= 0, not both 0", t.need("radii"));
  const double length = t.number("length", kPositive);
  return std::make_shared<ConeWall<D>>(point, axis, radii[0], radii[1], length, read_rotation<D>(t));
}

// An [outlet.NAME] table (contact/outlet.hpp): an open face of the domain, a plane, a box or a
// cylinder (2D: a disk).
template <int D>
Outlet<D> read_outlet(const std::string& name, const TableReader& t, const System<D>& sys) {
  Outlet<D> o;
  o.name = name;
  const std::string type = t.string("type", {"face", "plane", "box", "cylinder"});
  try {
    if (type == "face") {
      t.allow({"type", "face"});
      const std::string f = D == 3 ? t.string("face", {"x-", "x+", "y-", "y+", "z-", "z+"})
                                   : t.string("face", {"x-", "x+", "y-", "y+"});
      const int k = f[0] - 'x';
      const bool up = f[1] == '+';
      if (sys.periodic[k])
        t.fail("face", fmt::format("the domain is periodic along {}: that axis has no open face", kAxis[k]),
               t.need("face"));
      Vec<D> p = sys.lower, n = Vec<D>::Zero();
      p[k] = up ? sys.upper[k] : sys.lower[k];
      n[k] = up ? -1.0 : 1.0;  // towards the grains: removed beyond the face
      o.region = OutletRegion<D>::half_space(p, n);
      o.face = 2 * k + (up ? 1 : 0);
    } else if (type == "plane") {
      t.allow({"type", "point", "normal"});
      o.region = OutletRegion<D>::half_space(to_vec<D>(t.numbers("point", D)), read_direction<D>(t, "normal"));
    } else if (type == "box") {
      t.allow({"type", "lower", "upper"});
      const Vec<D> lo = to_vec<D>(t.numbers("lower", D)), hi = to_vec<D>(t.numbers("upper", D));
      for (int k = 0; k < D; ++k)
        if (!(hi[k] > lo[k]))
          t.fail("upper", fmt::format("must exceed lower along {} ({} <= {})", kAxis[k], hi[k], lo[k]), t.need("upper"));
      o.region = OutletRegion<D>::box(lo, hi);
    } else {
      if constexpr (D == 3) t.allow({"type", "point", "axis", "radius", "length"});
      else t.allow({"type", "point", "radius"});
      const Vec<D> p = to_vec<D>(t.numbers("point", D));
      const double r = t.number("radius", kPositive);
      Vec<D> a = Vec<D>::Zero();
      double L = 0.0;
      if constexpr (D == 3) {
        a = read_direction<D>(t, "axis");
        L = t.number("length", kPositive);
      }
      o.region = OutletRegion<D>::cylinder(p, a, r, L);
    }
  } catch (const std::invalid_argument& e) {
    fail(t.file(), t.path(), e.what());
  }
  return o;
}

// An [inlet.NAME] table (engine/inlet.hpp): where, what, how fast. Checks the region against the
// domain and the walls.
template <int D>
Inlet<D> read_inlet(const std::string& name, const TableReader& t, const System<D>& sys, std::uint64_t seed) {
  Inlet<D> in;
  in.name = name;
  in.seed = seed;
  const std::string type = t.string("type", {"box", "cylinder", "disk"});
  t.allow({"type", "lower", "upper", "point", "axis", "normal", "radius", "length", "material", "grain_radius",
           "rate", "mass_rate", "velocity", "spread", "count", "start", "stop"});
  // Where.
  auto forbid = [&](std::initializer_list<const char*> keys) {
    for (const char* k : keys)
      if (t.has(k)) t.fail(k, fmt::format("not a key of an inlet of type \"{}\"", type), t.need(k));
  };
  Vec<D> lo, hi;  // the region's bounding box
  if (type == "box") {
    forbid({"point", "axis", "normal", "radius", "length"});
    in.shape = Inlet<D>::Shape::Box;
    in.lower = to_vec<D>(t.numbers("lower", D));
    in.upper = to_vec<D>(t.numbers("upper", D));
    for (int k = 0; k < D; ++k)
      if (!(in.upper[k] >= in.lower[k]))
        t.fail("upper", fmt::format("must not be below lower along {} ({} < {})", kAxis[k], in.upper[k], in.lower[k]),
               t.need("upper"));
    lo = in.lower;
    hi = in.upper;
  } else {
    in.shape = Inlet<D>::Shape::Cylinder;
    in.point = to_vec<D>(t.numbers("point", D));
    in.radius = t.number("radius", kPositive);
    if (type == "cylinder") {
      forbid({"lower", "upper", "normal"});
      in.axis = read_direction<D>(t, "axis");
      in.length = t.number("length", kPositive);
    } else {
      forbid({"lower", "upper", "axis", "length"});
      in.axis = read_direction<D>(t, "normal");
    }
    for (int k = 0; k < D; ++k) {
      const double e = in.radius * std::sqrt(std::max(0.0, 1.0 - in.axis[k] * in.axis[k]));
      lo[k] = std::min(in.point[k], in.point[k] + in.length * in.axis[k]) - e;
      hi[k] = std::max(in.point[k], in.point[k] + in.length * in.axis[k]) + e;
    }
  }
  for (int k = 0; k < D; ++k)
    if (lo[k] < sys.lower[k] - 1e-12 * (sys.upper[k] - sys.lower[k]) ||
        hi[k] > sys.upper[k] + 1e-12 * (sys.upper[k] - sys.lower[k]))
      fail(t.file(), t.path(),
           fmt::format("the region reaches {} along {}, outside the domain [{}, {}]; move the inlet into the domain",
                       lo[k] < sys.lower[k] ? lo[k] : hi[k], kAxis[k], sys.lower[k], sys.upper[k]));
  // What: the grains' material and radius (a value or [rmin, rmax], drawn uniformly).
  in.material = material_index(t, sys.materials);
  const toml::node& rn = t.need("grain_radius");
  if (rn.is_number()) {
    in.rmin = in.rmax = t.as_number(rn, "grain_radius", kPositive);
  } else {
    const auto rr = t.numbers("grain_radius", 2);
    if (!(rr[0] > 0.0)) t.fail("grain_radius", "rmin must be > 0", rn);
    if (!(rr[1] >= rr[0])) t.fail("grain_radius", "rmax must be >= rmin", rn);
    in.rmin = rr[0];
    in.rmax = rr[1];
  }
  if (const std::string p = radius_problem<D>(in.rmin, sys); !p.empty()) t.fail("grain_radius", p, rn);
  // How fast: grains/s, or kg/s over the mean grain mass of the radius distribution.
  if (t.has("rate") == t.has("mass_rate"))
    fail(t.file(), t.path(), "give exactly one of rate (grains/s) and mass_rate (kg/s)");
  if (t.has("rate")) {
    in.rate = t.number("rate", kPositive);
  } else {
    const double a = in.rmin, b = in.rmax;
    // <R^D> of R uniform in [a, b].
    const double mean_rd = b > a ? (std::pow(b, D + 1) - std::pow(a, D + 1)) / ((D + 1) * (b - a)) : std::pow(a, D);
    const double mean_mass = sys.materials[static_cast<std::size_t>(in.material)].density * ball_volume<D>(1.0) * mean_rd;
    in.rate = t.number("mass_rate", kPositive) / mean_mass;
  }
  if (t.has("velocity")) in.velocity = to_vec<D>(t.numbers("velocity", D));
  in.spread = t.number_or("spread", 0.0, kNonNegative);
  if (const auto c = t.integer_opt("count", Range{1.0})) in.count = static_cast<std::uint64_t>(*c);
  in.start = t.number_or("start", 0.0, kNonNegative);
  if (const auto s = t.number_opt("stop", kPositive)) {
    if (!(*s > in.start)) t.fail("stop", fmt::format("must be after start = {}", in.start), t.need("stop"));
    in.stop = *s;
  }
  // The region must leave room for a grain: not wholly inside a wall (sampled), each sample's
  // nearest wall remembered for the message.
  std::mt19937_64 rng(seed);
  std::vector<int> blocked(sys.walls.size(), 0);
  int free = 0;
  for (int s = 0; s < 256 && free == 0; ++s) {
    const Vec<D> x = in.sample_point(rng);
    bool ok = true;
    for (std::size_t w = 0; w < sys.walls.size(); ++w)
      if (!(sys.walls[w].geometry().at(x, in.rmin, 0.0).gap > 0.0)) {
        ++blocked[w];
        ok = false;
      }
    free += ok;
  }
  if (free == 0 && !sys.walls.empty()) {
    const auto w = static_cast<std::size_t>(std::max_element(blocked.begin(), blocked.end()) - blocked.begin());
    fail(t.file(), t.path(), fmt::format("the region lies inside wall.{}: no grain of radius {} fits anywhere in it",
                                         sys.walls[w].name, in.rmin));
  }
  return in;
}

// A bounded wall must lie within the domain (it would otherwise stand where no grain can be).
template <int D>
void check_walls_fit(const std::string& file, const System<D>& sys) {
  for (const auto& w : sys.walls) {
    Vec<D> lo, hi;
    if (!w.geometry().bounds(lo, hi)) continue;
    // Round-off, and a binary STL file's float coordinates (relative 6e-8): a mesh made to the
    // domain's size reaches beyond it by that much.
    const double tol = 1e-9 * (sys.upper - sys.lower).norm() +
                       2e-7 * std::max(sys.upper.cwiseAbs().maxCoeff(), sys.lower.cwiseAbs().maxCoeff());
    for (int k = 0; k < D; ++k)
      if (lo[k] < sys.lower[k] - tol || hi[k] > sys.upper[k] + tol)
        fail(file, fmt::format("wall.{}", w.name),
             fmt::format("the {} reaches {} along {}, outside the domain [{}, {}]; enlarge the domain or move the "
                         "wall",
                         w.geometry().kind(), lo[k] < sys.lower[k] - tol ? lo[k] : hi[k], kAxis[k], sys.lower[k],
                         sys.upper[k]));
  }
}

template <int D>
void build_system(const TableReader& top, const TableReader& run, const fs::path& base_dir, Scene& scene) {
  System<D>& sys = scene.system.template emplace<System<D>>();
  const std::string& file = scene.path;

  // [run] gravity.
  if (run.has("gravity")) sys.gravity = to_vec<D>(run.numbers("gravity", D));

  // [domain]
  const TableReader dom = top.sub("domain");
  dom.allow({"lower", "upper", "periodic"});
  sys.lower = to_vec<D>(dom.numbers("lower", D));
  sys.upper = to_vec<D>(dom.numbers("upper", D));
  for (int k = 0; k < D; ++k) {
    if (!(sys.upper[k] > sys.lower[k])) {
      dom.fail("upper",
               fmt::format("must exceed domain.lower along {} ({} <= {})", kAxis[k], sys.upper[k], sys.lower[k]),
               dom.need("upper"));
    }
    if (!std::isfinite(sys.upper[k] - sys.lower[k]))
      dom.fail("upper", fmt::format("the domain is wider along {} than a number can hold", kAxis[k]), dom.need("upper"));
  }
  if (dom.has("periodic")) {
    const auto p = dom.booleans("periodic", D);
    for (int k = 0; k < D; ++k) sys.periodic[k] = p[static_cast<std::size_t>(k)];
  }

  // [material.NAME]
  for (const auto& [name, t] : named_tables(top, "material")) sys.materials.push_back(read_material(name, t));

  // [wall.NAME]
  for (const auto& [name, t] : named_tables(top, "wall")) {
    std::shared_ptr<const WallShape<D>> shape;
    try {
      shape = read_wall_shape<D>(t, base_dir);
    } catch (const std::invalid_argument& e) {  // a shape's own check of its parameters
      fail(file, fmt::format("wall.{}", name), e.what());
    }
    sys.walls.push_back(Wall<D>{name, 0, std::move(shape)});
    sys.walls.back().material = material_index(t, sys.materials);
  }
  if (sys.walls.size() > kMaxWalls)
    fail(file, "wall", fmt::format("{} walls; a scene holds at most {} (join planes into a mesh)", sys.walls.size(),
                                   kMaxWalls));
  check_walls_fit<D>(file, sys);

  // [inlet.NAME] (each its own random stream: the scene's seed and its index)
  std::uint64_t inlet_grains = 0;  // the engines reserve a particle per grain due
  {
    std::uint64_t k = 0;
    for (const auto& [name, t] : named_tables(top, "inlet")) {
      sys.inlets.push_back(read_inlet<D>(name, t, sys, scene.seed * 1000003ULL + 17 * ++k));
      const std::uint64_t due = sys.inlets.back().slots(scene.end_time);
      const char* key = t.has("count") && sys.inlets.back().count == due ? "count"
                        : t.has("rate")                                   ? "rate"
                                                                          : "mass_rate";
      check_grains(t, key, inlet_grains, static_cast<double>(due), "has due by run.end_time");
      inlet_grains += due;
    }
  }

  // [outlet.NAME]
  for (const auto& [name, t] : named_tables(top, "outlet")) {
    sys.outlets.push_back(read_outlet<D>(name, t, sys));
    const Outlet<D>& o = sys.outlets.back();
    if (o.face < 0 && !o.region.meets_box(sys.lower, sys.upper))
      scene.warnings.push_back(fmt::format(
          "{}: outlet.{}: the region lies outside the domain, so no grain can reach it{}", file, name,
          o.region.kind() == OutletRegion<D>::Kind::HalfSpace ? " (for an open face of the domain use type = \"face\")"
                                                               : ""));
  }

  // [particles.NAME]: read and validate every group, then place the groups with fixed positions
  // first (file groups, checked against each other; then lattice groups), then the random groups
  // around everything placed so far. Within each kind groups go in file order; particle ids
  // always follow the file order of the groups.
  const auto group_tables = named_tables(top, "particles");
  if (group_tables.empty() && sys.inlets.empty())
    fail(file, "particles", "missing (a scene needs at least one [particles.NAME] table, or an inlet)");
  Builder<D> b{file, base_dir, sys, {}, {}};
  b.planned = inlet_grains;
  if (scene.method != Method::Edm) b.file_overlap = kSoftFileOverlap;
  for (std::size_t gi = 0; gi < group_tables.size(); ++gi) {
    b.read_group(group_tables[gi].first, group_tables[gi].second);
  }
  double rmax = 0.0;
  std::size_t total = 0;
  for (const auto& g : b.groups) {
    if (g.from_file) {
      for (const double r : g.r) rmax = std::max(rmax, r);
      total += g.r.size();
    } else {
      rmax = std::max(rmax, g.rmax);
      total += g.count;
    }
  }
  placement::OverlapGrid<D> grid(sys.lower, sys.upper, sys.periodic, 2.0 * rmax, total);
  b.owner.reserve(total);
  for (std::size_t gi = 0; gi < b.groups.size(); ++gi) {
    if (!b.groups[gi].from_file) continue;
    for (std::size_t i = 0; i < b.groups[gi].r.size(); ++i) b.check_and_insert(grid, gi, i);
  }
  for (std::size_t gi = 0; gi < b.groups.size(); ++gi) {
    if (!b.groups[gi].from_file && b.groups[gi].lattice) b.generate(grid, gi, scene.seed);
  }
  for (std::size_t gi = 0; gi < b.groups.size(); ++gi) {
    if (!b.groups[gi].from_file && !b.groups[gi].lattice) b.generate(grid, gi, scene.seed);
  }

  // Assemble in group order.
  sys.x.reserve(total);
  sys.v.reserve(total);
  sys.w.reserve(total);
  sys.radius.reserve(total);
  sys.material.reserve(total);
  scene.group.reserve(total);
  bool any_fixed = false;
  for (const auto& g : b.groups) any_fixed = any_fixed || g.fixed;
  if (any_fixed) sys.fixed.reserve(total);
  for (std::size_t gi = 0; gi < b.groups.size(); ++gi) {
    const Group<D>& g = b.groups[gi];
    scene.group_names.push_back(g.name);
    for (std::size_t i = 0; i < g.r.size(); ++i) {
      for (const Outlet<D>& o : sys.outlets)
        if (o.region.inside(g.x[i]))
          fail(file, fmt::format("particles.{}", g.name),
               fmt::format("particle {} of the group at {} starts inside outlet.{} (it would leave at t = 0); move the "
                           "outlet or the grains",
                           i, vec_str<D>(g.x[i]), o.name));
      sys.x.push_back(g.x[i]);
      sys.v.push_back(g.v[i]);
      sys.w.push_back(g.w[i]);
      sys.radius.push_back(g.r[i]);
      sys.material.push_back(g.material_of(i));
      if (any_fixed) sys.fixed.push_back(g.fixed ? 1 : 0);
      scene.group.push_back(static_cast<int>(gi));
    }
  }
}

Scene build_scene(toml::table& root, const std::string& file, const fs::path& base_dir,
                  const std::vector<std::string>& overrides) {
  apply_overrides(root, overrides, file);
  Scene scene;
  scene.path = file;
  {
    std::ostringstream canon;  // what a checkpoint compares (io/checkpoint.hpp)
    canon << toml::toml_formatter(root);
    scene.canonical = canon.str();
  }
  const TableReader top(scene.path, root, "");
  top.allow({"run", "domain", "material", "particles", "wall", "inlet", "outlet", "output", "hybrid"});

  // [run]
  const TableReader run = top.sub("run");
  for (const char* gone : {"collapse_count", "collapse_window"})
    if (run.has(gone))
      run.fail(gone, "is no longer a key: the collapse watch judges a particle's collision intervals against "
                     "its own recent ones, set by run.collapse_decades (README \"Inelastic collapse\")");
  run.allow({"dimension", "method", "start_time", "end_time", "seed", "gravity", "queue", "tc", "collapse_decades",
             "max_events", "dt", "threads", "neighbours", "shell", "resort"});
  const std::int64_t dim = run.integer("dimension");
  if (dim != 2 && dim != 3) run.fail("dimension", "must be 2 or 3", run.need("dimension"));
  scene.dimension = static_cast<int>(dim);
  scene.method = parse_method(run.string_opt("method", {"edm", "tdm", "hybrid"}).value_or("edm")).value_or(Method::Edm);
  scene.end_time = run.number("end_time", kPositive);
  scene.start_time = run.number_or("start_time", 0.0, kNonNegative);
  if (!(scene.start_time < scene.end_time))
    run.fail("start_time", fmt::format("must be before run.end_time = {} (got {})", scene.end_time, scene.start_time));
  scene.seed = static_cast<std::uint64_t>(run.integer_or("seed", 1, kNonNegative));
  scene.queue = run.string_opt("queue", {"calendar", "heap"}).value_or("calendar");
  scene.tc = run.number_or("tc", 0.0, kNonNegative);
  scene.collapse_decades = run.number_or("collapse_decades", EdmSettings{}.collapse_decades, Range{0.0, 30.0});
  if (scene.collapse_decades > 0.0 && scene.collapse_decades < 1.0)
    run.fail("collapse_decades", fmt::format("must be 0 (off) or at least 1 (got {})", scene.collapse_decades));
  scene.max_events = static_cast<std::uint64_t>(run.integer_or("max_events", 0, kNonNegative));
  // Read and checked whatever run.method is; used by pure EDM only (the hybrid keeps its cells).
  scene.neighbours = run.string_opt("neighbours", {"cells", "lists", "auto"}).value_or("cells");
  scene.shell = run.number_or("shell", EdmSettings{}.shell, Range{1e-3, 2.0});
  // resort: "auto", "off", or the particle events per particle between two re-sorts.
  if (const toml::node* r = run.find("resort"); r && r->is_string()) {
    const std::string v = r->as_string()->get();
    if (v != "auto" && v != "off") run.fail("resort", "expected a number > 0, \"auto\" or \"off\"", *r);
    scene.resort = v == "off" ? 0.0 : -1.0;
  } else {
    scene.resort = run.number_opt("resort", kPositive).value_or(-1.0);
  }
  scene.dt = run.number_opt("dt", kPositive);
  if (const auto th = run.integer_opt("threads", Range{1.0, 1048576.0})) scene.threads = static_cast<int>(*th);

  // [hybrid]
  if (top.has("hybrid")) {
    const TableReader hy = top.sub("hybrid");
    hy.allow({"stability", "repeats", "speed_fall", "lookahead", "hysteresis", "skin", "cost_ratio", "rest_speed",
              "rest_time", "coast"});
    // Read and checked whatever run.method is (so that --set run.method=tdm compares a hybrid
    // scene with the pure methods); used only by the hybrid engine.
    HybridSpec& h = scene.hybrid;
    h.stability = hy.number_opt("stability", kPositive);
    if (const auto r = hy.integer_opt("repeats", Range{1.0, 1000.0})) h.repeats = static_cast<int>(*r);
    h.speed_fall = hy.number_opt("speed_fall", Range{1.0});
    h.lookahead = hy.number_opt("lookahead", kNonNegative);
    h.hysteresis = hy.number_opt("hysteresis", kPositive);
    h.skin = hy.number_opt("skin", kPositive);
    // cost_ratio: a number, or "measured" (the crossover follows the costs the run measures).
    if (const toml::node* c = hy.find("cost_ratio"); c && c->is_string()) {
      if (c->as_string()->get() != "measured") hy.fail("cost_ratio", "expected a number > 0 or \"measured\"", *c);
      h.cost_measured = true;
    } else {
      h.cost_ratio = hy.number_opt("cost_ratio", kPositive);
    }
    h.rest_speed = hy.number_opt("rest_speed", kNonNegative);
    h.rest_time = hy.number_opt("rest_time", kPositive);
    h.coast = hy.boolean_or("coast", true);
  }

  // [output]
  if (top.has("output")) {
    const TableReader out = top.sub("output");
    out.allow({"dir", "thermo_interval", "events", "snapshot_interval", "wall_loads", "max_bytes",
               "checkpoint_interval", "format", "precision", "contacts"});
    scene.output.dir = out.string_opt("dir").value_or(scene.output.dir);
    scene.output.thermo_interval = out.number_or("thermo_interval", 0.0, kNonNegative);
    scene.output.events = out.boolean_or("events", false);
    scene.output.snapshot_interval = out.number_or("snapshot_interval", 0.0, kNonNegative);
    scene.output.wall_loads = out.boolean_or("wall_loads", false);
    scene.output.max_bytes = out.number_or("max_bytes", scene.output.max_bytes, kPositive);
    scene.output.checkpoint_interval = out.number_or("checkpoint_interval", 0.0, kNonNegative);
    // output.format: one name or a list of them (io/snapshots.hpp).
    if (const toml::node* f = out.find("format")) {
      SnapshotFormats& sf = scene.output.formats;
      sf.vtk = false;
      std::vector<const toml::node*> names;
      if (const toml::array* a = f->as_array()) {
        if (a->empty()) out.fail("format", "names no format", *f);
        for (const toml::node& e : *a) names.push_back(&e);
      } else {
        names.push_back(f);
      }
      for (const toml::node* e : names) {
        const std::string v = e->is_string() ? e->as_string()->get() : std::string();
        bool* flag = v == "vtk" ? &sf.vtk : v == "vtk_ascii" ? &sf.vtk_ascii : v == "xyz" ? &sf.xyz
                   : v == "lammps" ? &sf.lammps : nullptr;
        if (!flag)
          out.fail("format", "must be \"vtk\", \"vtk_ascii\", \"xyz\" or \"lammps\", or a list of them", *e);
        if (*flag) out.fail("format", fmt::format("names \"{}\" twice", v), *f);
        *flag = true;
      }
      if (sf.vtk && sf.vtk_ascii)
        out.fail("format", "\"vtk\" and \"vtk_ascii\" write the same files; name one of them", *f);
    }
    scene.output.formats.single = out.string_opt("precision", {"double", "single"}).value_or("double") == "single";
    scene.output.formats.contacts = out.boolean_or("contacts", false);
    if (scene.output.formats.contacts && scene.output.snapshot_interval == 0.0)
      out.fail("contacts", "the contacts are written with the snapshots: set output.snapshot_interval too",
               *out.find("contacts"));
  }

  if (!top.has("domain")) top.need("domain");
  if (scene.dimension == 2) {
    build_system<2>(top, run, base_dir, scene);
  } else {
    build_system<3>(top, run, base_dir, scene);
  }
  // A run that starts later (run.start_time): each inlet begins then at the earliest.
  std::visit(
      [&](auto& sys) {
        for (auto& in : sys.inlets) in.start = std::max(in.start, scene.start_time);
      },
      scene.system);
  return scene;
}

}  // namespace

Scene load_scene(const std::string& path, const std::vector<std::string>& overrides) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) throw SceneError(fmt::format("{}: cannot read scene file: it is a directory", path));
  if (const auto bytes = fs::file_size(path, ec); !ec && bytes > kMaxSceneBytes)
    throw SceneError(fmt::format("{}: the scene is {} bytes, more than the limit of {} (give particles in a CSV file: "
                                 "particles.NAME.file)",
                                 path, bytes, show_bytes(static_cast<double>(kMaxSceneBytes))));
  std::ifstream in(path, std::ios::binary);
  if (!in) throw SceneError(fmt::format("{}: cannot read scene file: {}", path, std::strerror(errno)));
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) throw SceneError(fmt::format("{}: cannot read scene file: read error", path));
  fs::path base = fs::path(path).parent_path();
  if (base.empty()) base = ".";
  toml::table root = parse_toml(ss.str(), path);
  return build_scene(root, path, base, overrides);
}

Scene load_scene_string(const std::string& toml_text, const std::string& name, const std::string& base_dir,
                        const std::vector<std::string>& overrides) {
  toml::table root = parse_toml(toml_text, name);
  return build_scene(root, name, base_dir.empty() ? fs::path(".") : fs::path(base_dir), overrides);
}

}  // namespace matep

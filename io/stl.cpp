// STL reading (io/stl.hpp).
#include "io/stl.hpp"

#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include <fmt/format.h>

namespace matep {

namespace {

struct Merge {
  StlMesh& m;
  std::map<std::array<double, 3>, std::uint32_t> index;
  std::uint32_t add(double x, double y, double z) {
    auto [it, fresh] = index.try_emplace({x, y, z}, static_cast<std::uint32_t>(m.vertices.size()));
    if (fresh) m.vertices.emplace_back(x, y, z);
    return it->second;
  }
};

void read_binary(const std::string& bytes, StlMesh& m) {
  std::uint32_t n = 0;
  std::memcpy(&n, bytes.data() + 80, 4);
  Merge merge{m, {}};
  for (std::uint32_t k = 0; k < n; ++k) {
    const char* rec = bytes.data() + 84 + 50 * static_cast<std::size_t>(k);
    float f[12];
    std::memcpy(f, rec, sizeof f);
    std::array<std::uint32_t, 3> tri{};
    for (int j = 0; j < 3; ++j) {
      const float* p = f + 3 + 3 * j;
      for (int c = 0; c < 3; ++c)
        if (!std::isfinite(p[c]))
          throw std::runtime_error(fmt::format("triangle {}: vertex {} has a non-finite coordinate", k + 1, j + 1));
      tri[static_cast<std::size_t>(j)] = merge.add(p[0], p[1], p[2]);
    }
    m.triangles.push_back(tri);
  }
}

void read_ascii(const std::string& bytes, StlMesh& m) {
  std::istringstream in(bytes);
  std::string line;
  int lineno = 0;
  Merge merge{m, {}};
  // Start -> Solid (between facets) -> Facet (after "facet") -> Loop (after "outer loop") ->
  // Closed (after "endloop") -> Solid (after "endfacet") ... -> Done (after "endsolid").
  enum class At { Start, Solid, Facet, Loop, Closed, Done } at = At::Start;
  std::array<std::uint32_t, 3> tri{};
  int nv = 0;
  auto bad = [&](const std::string& what) {
    throw std::runtime_error(fmt::format("line {}: {} (\"{}\")", lineno, what, line.substr(0, 80)));
  };
  while (std::getline(in, line)) {
    ++lineno;
    std::istringstream ls(line);
    std::string word;
    if (!(ls >> word)) continue;
    switch (at) {
      case At::Start:
      case At::Done:
        if (word != "solid") bad(at == At::Start ? "expected \"solid\" at the start of an ASCII STL file"
                                                 : "expected \"solid\" or the end of the file after \"endsolid\"");
        at = At::Solid;
        break;
      case At::Solid:
        if (word == "endsolid") at = At::Done;
        else if (word == "facet") at = At::Facet;
        else bad("expected \"facet\" or \"endsolid\"");
        break;
      case At::Facet:
        if (word != "outer") bad("expected \"outer loop\"");
        at = At::Loop;
        nv = 0;
        break;
      case At::Loop:
        if (word == "vertex") {
          double x, y, z;
          if (!(ls >> x >> y >> z)) bad("a vertex needs three numbers");
          if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z)) bad("a vertex has a non-finite coordinate");
          if (nv == 3) bad("a facet with more than three vertices (STL facets are triangles)");
          tri[static_cast<std::size_t>(nv++)] = merge.add(x, y, z);
        } else if (word == "endloop") {
          if (nv != 3) bad(fmt::format("a facet with {} vertices (STL facets are triangles)", nv));
          m.triangles.push_back(tri);
          at = At::Closed;
        } else {
          bad("expected \"vertex\" or \"endloop\"");
        }
        break;
      case At::Closed:
        if (word != "endfacet") bad("expected \"endfacet\"");
        at = At::Solid;
        break;
    }
  }
  if (at == At::Start) throw std::runtime_error("empty file (no \"solid\")");
  if (at != At::Done)
    throw std::runtime_error(fmt::format("line {}: the file ends before \"endsolid\" (truncated?)", lineno));
}

}  // namespace

StlMesh read_stl(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw std::runtime_error("no such file");
  std::ifstream f(path, std::ios::binary);
  if (!f) throw std::runtime_error(fmt::format("cannot be read ({})", std::strerror(errno)));
  std::ostringstream buf;
  buf << f.rdbuf();
  const std::string bytes = buf.str();
  StlMesh m;
  if (bytes.empty()) throw std::runtime_error("empty file (no triangles)");
  bool binary = false;
  if (bytes.size() >= 84) {
    std::uint32_t n = 0;
    std::memcpy(&n, bytes.data() + 80, 4);
    binary = bytes.size() == 84 + 50 * static_cast<std::uint64_t>(n);
    if (!binary && bytes.compare(0, 5, "solid") != 0)
      throw std::runtime_error(fmt::format(
          "a binary STL file of {} bytes, but its header counts {} triangles ({} bytes): truncated or corrupt",
          bytes.size(), n, 84 + 50 * static_cast<std::uint64_t>(n)));
  } else if (bytes.compare(0, 5, "solid") != 0) {
    throw std::runtime_error(fmt::format("{} bytes: too short for a binary STL file and not ASCII STL", bytes.size()));
  }
  m.binary = binary;
  if (binary) read_binary(bytes, m);
  else read_ascii(bytes, m);
  if (m.triangles.empty()) throw std::runtime_error("the file holds no triangles");
  return m;
}

}  // namespace matep

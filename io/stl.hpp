// STL triangle meshes (the CAD exchange format; 3D Systems, "StereoLithography Interface
// Specification", 1989): ASCII ("solid ... facet normal ... outer loop vertex x y z ... endsolid")
// and binary (an 80-byte header, a little-endian uint32 triangle count, then per triangle 12
// float32 (normal, three vertices) and a uint16 attribute). A file whose size is exactly
// 84 + 50 n for the count n in its header is binary, any other ASCII (some binary files begin with
// "solid" too). The facet normals are not used (the triangle's vertex order and cross product
// give it). Vertices with identical coordinates are merged, so triangles share them by index.
#pragma once

#include <array>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "contact/vec.hpp"

namespace matep {

struct StlMesh {
  std::vector<Vec<3>> vertices;
  std::vector<std::array<std::uint32_t, 3>> triangles;
  bool binary = false;
};

// Reads an STL file; throws std::runtime_error naming the problem (and, for ASCII, the line):
// a missing or unreadable file, a truncated binary file, a malformed ASCII file, no triangles.
StlMesh read_stl(const std::string& path);

}  // namespace matep

// Triangle meshes for the tests (contact/mesh.hpp): a box, a randomly turned octahedron, a random
// height field; and STL writers (ASCII, binary) for the reader's tests.
#pragma once

#include <array>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "contact/mesh.hpp"
#include "tests/support/shape_check.hpp"

namespace matep::test {

using MeshTris = std::vector<std::array<std::uint32_t, 3>>;

// The box [lo, hi], each side two triangles (outward normals); closed = false leaves the lid
// (z = hi) open.
inline void box_triangles(const Vec<3>& lo, const Vec<3>& hi, bool closed, std::vector<Vec<3>>& v, MeshTris& t) {
  v.clear();
  t.clear();
  for (int k = 0; k < 8; ++k) v.emplace_back(k & 1 ? hi[0] : lo[0], k & 2 ? hi[1] : lo[1], k & 4 ? hi[2] : lo[2]);
  const std::vector<std::array<std::uint32_t, 4>> quads{
      {0, 2, 3, 1}, {0, 1, 5, 4}, {0, 4, 6, 2}, {1, 3, 7, 5}, {2, 6, 7, 3}, {4, 5, 7, 6}};
  for (std::size_t q = 0; q < quads.size(); ++q) {
    if (!closed && q == 5) continue;
    const auto& c = quads[q];
    t.push_back({c[0], c[1], c[2]});
    t.push_back({c[0], c[2], c[3]});
  }
}
inline std::shared_ptr<const MeshWall> box_mesh(const Vec<3>& lo, const Vec<3>& hi, bool closed) {
  std::vector<Vec<3>> v;
  MeshTris t;
  box_triangles(lo, hi, closed, v, t);
  return std::make_shared<MeshWall>(v, t);
}

// A regular octahedron of circumradius a about c, turned at random.
inline std::shared_ptr<const MeshWall> octahedron(const Vec<3>& c, double a, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> nd(0.0, 1.0);
  const Eigen::Quaterniond q = Eigen::Quaterniond(nd(rng), nd(rng), nd(rng), nd(rng)).normalized();
  std::vector<Vec<3>> v;
  for (int k = 0; k < 3; ++k)
    for (const double s : {1.0, -1.0}) {
      Vec<3> e = Vec<3>::Zero();
      e[k] = s * a;
      v.push_back(c + q * e);
    }
  // vertices: 0 +x, 1 -x, 2 +y, 3 -y, 4 +z, 5 -z
  const MeshTris t{{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4}, {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
  return std::make_shared<MeshWall>(v, t);
}

// A 3 x 3 grid of vertices over [-h, h]^2 at random heights in [-amp, amp]: 8 triangles, open,
// with convex and concave edges.
inline std::shared_ptr<const MeshWall> height_field(double h, double amp, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Vec<3>> v;
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 3; ++i) v.emplace_back(h * (i - 1), h * (j - 1), amp * u(rng));
  MeshTris t;
  for (std::uint32_t j = 0; j < 2; ++j)
    for (std::uint32_t i = 0; i < 2; ++i) {
      const std::uint32_t a = 3 * j + i, b = a + 1, c = a + 3, d = a + 4;
      t.push_back({a, b, d});
      t.push_back({a, d, c});
    }
  return std::make_shared<MeshWall>(v, t);
}

inline void write_stl_ascii(const std::string& path, const std::vector<Vec<3>>& v, const MeshTris& t) {
  std::ofstream f(path);
  f << "solid test\n";
  for (const auto& tr : t) {
    f << "  facet normal 0 0 0\n    outer loop\n";
    for (const auto k : tr) {
      char buf[128];
      std::snprintf(buf, sizeof buf, "      vertex %.17g %.17g %.17g\n", v[k][0], v[k][1], v[k][2]);
      f << buf;
    }
    f << "    endloop\n  endfacet\n";
  }
  f << "endsolid test\n";
}

inline void write_stl_binary(const std::string& path, const std::vector<Vec<3>>& v, const MeshTris& t) {
  std::ofstream f(path, std::ios::binary);
  const std::string header(80, ' ');
  f.write(header.data(), 80);
  const auto n = static_cast<std::uint32_t>(t.size());
  f.write(reinterpret_cast<const char*>(&n), 4);
  for (const auto& tr : t) {
    float rec[12] = {0, 0, 0};
    for (int j = 0; j < 3; ++j)
      for (int c = 0; c < 3; ++c) rec[3 + 3 * j + c] = static_cast<float>(v[tr[static_cast<std::size_t>(j)]][c]);
    f.write(reinterpret_cast<const char*>(rec), sizeof rec);
    const std::uint16_t attr = 0;
    f.write(reinterpret_cast<const char*>(&attr), 2);
  }
}

// Long-double distance from x to triangle (a, b, c).
inline long double triangle_distance(const VecL<3>& x, const VecL<3>& a, const VecL<3>& b, const VecL<3>& c) {
  const VecL<3> n = (b - a).cross(c - a).normalized();
  const long double h = (x - a).dot(n);
  const VecL<3> p = x - h * n;
  auto side = [&](const VecL<3>& u, const VecL<3>& w) { return n.dot((w - u).cross(p - u)) >= 0.0L; };
  if (side(a, b) && side(b, c) && side(c, a)) return std::abs(h);
  auto seg = [&](const VecL<3>& u, const VecL<3>& w) {
    const VecL<3> d = w - u;
    const long double s = std::clamp((x - u).dot(d) / d.squaredNorm(), 0.0L, 1.0L);
    return (x - u - s * d).norm();
  };
  return std::min({seg(a, b), seg(b, c), seg(c, a)});
}

inline long double mesh_gap_ld(const MeshWall& m, const VecL<3>& x, long double R) {
  long double d = std::numeric_limits<long double>::infinity();
  for (const auto& t : m.triangle_list())
    d = std::min(d, triangle_distance(x, to_ld<3>(m.vertices()[t[0]]), to_ld<3>(m.vertices()[t[1]]),
                                      to_ld<3>(m.vertices()[t[2]])));
  return d - R;
}

// The engine's view of impact_time for a flight starting at time 0: a checkpoint (a search
// horizon, the gap still open) is a point to predict again from, at its absolute time (a turning
// wall's position depends on it).
template <int D>
double impact_following_checkpoints(const WallShape<D>& m, const Vec<D>& x0, const Vec<D>& v0, const Vec<D>& g, double R,
                                    double limit) {
  double t0 = 0.0;
  Vec<D> x = x0, v = v0;
  for (int k = 0; k < 100000; ++k) {
    const double dt = m.impact_time(x, v, g, R, t0, limit - t0);
    if (!(dt < kNever)) return kNever;
    // Positions from the start, as the reference computes them.
    const double t = t0 + dt;
    const Vec<D> xt = x0 + t * v0 + (0.5 * t * t) * g;
    if (m.at(xt, R, t).gap <= 1e-9 * R) return t;
    if (!(dt > 0.0)) return t;  // stalled: report it (the test fails)
    t0 = t;
    x = xt;
    v = v0 + t * g;
  }
  return -1.0;
}

}  // namespace matep::test

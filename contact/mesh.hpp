// The triangle-mesh wall (3D): a surface read from an STL file (io/stl.cpp), as CAD brings a hopper,
// a mixer or a chute: WallShape<3> (contact/wall.hpp).
//   MeshWall(vertices, triangles)    vertices shared by index; every triangle three distinct indices
// The mesh is a thin sheet touched from both sides: the gap of a particle with one of its parts is
// the distance from the sphere's centre to the nearest point of that part minus R, the normal from
// that point towards the centre (a face gives +-its normal, an edge or a corner any direction: the
// sphere-triangle contact of DEM codes, e.g. Kremmer, Favier, Powder Technol. 2001; LIGGGHTS'
// tri_mesh). Checked at construction: no degenerate triangle (zero area, a repeated vertex), no
// edge shared by more than two triangles (non-manifold). Open meshes (a funnel, a chute) are fine.
//
// Features (one contact each): the triangles are grouped into facets, the connected sets of
// coplanar triangles (a box's side of two triangles is one facet, so a grain rolling across the
// diagonal keeps its contact and its spring). A particle touches a facet at the facet's nearest
// point c to its centre x. Where c lies on a facet's border (an edge or corner shared with other
// facets), the contact is the border's, not the face's: it counts once, for the lowest-numbered
// facet at that border, and only where every neighbouring triangle at the border has the same
// nearest point c (x lies in the border's own Voronoi region; otherwise the grain sees a face of
// the neighbour, which makes the contact). So a grain against a convex edge gets one edge contact,
// a grain in a concave corner one face contact per face, and a grain on a flat facet one contact,
// whatever the triangulation. (The "edge/vertex contact only if no face owns it" rule of mesh
// contact in DEM: Hu, Hu, Jin, Zhao, Powder Technol. 2013; Smith & Hanley, Comput. Part. Mech. 2019.)
// The engines ask features_near() for the facets within their list reach and at_feature() for
// each one's contact.
//
// Impact times (contact/shape_features.hpp): per triangle the two offset planes of its face
// (linear in t, quadratic under gravity) where the foot point lies in the triangle, per edge an
// offset cylinder around the segment, per vertex an offset sphere (quadratic / quartic); the
// earliest accepted root over the triangles the flight's swept box (padded by R) meets in the
// mesh's cell grid, refined on the gap of at(). The flight is searched up to the engine's earliest
// event (bracketed()) and at most `horizon` (a few grid cells) ahead: beyond it the shape returns a
// checkpoint (the gap still open), which the engine re-predicts from, so a prediction never visits
// more than the triangles near the flight.
#pragma once

#include <fmt/format.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "contact/predict.hpp"
#include "contact/shape_features.hpp"
#include "contact/wall.hpp"

namespace matep {

// The nearest point of triangle (a, b, c) to p and its Voronoi region: 0 the face, 1 + k the edge
// k (from vertex k to vertex k + 1 mod 3), 4 + k the vertex k (Ericson, "Real-Time Collision
// Detection", 2005, sec. 5.1.5: the regions tested by barycentric coordinates).
struct TriangleFoot {
  Vec<3> point;
  int region = 0;
};

inline TriangleFoot nearest_on_triangle(const Vec<3>& p, const Vec<3>& a, const Vec<3>& b, const Vec<3>& c) {
  const Vec<3> ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) return {a, 4};
  const Vec<3> bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) return {b, 5};
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) return {Vec<3>(a + (d1 / (d1 - d3)) * ab), 1};
  const Vec<3> cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) return {c, 6};
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) return {Vec<3>(a + (d2 / (d2 - d6)) * ac), 3};
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0)
    return {Vec<3>(b + ((d4 - d3) / ((d4 - d3) + (d5 - d6))) * (c - b)), 2};
  const double den = 1.0 / (va + vb + vc);
  return {Vec<3>(a + (vb * den) * ab + (vc * den) * ac), 0};
}

class MeshWall final : public WallShape<3> {
 public:
  using V3 = Vec<3>;
  using Tri = std::array<std::uint32_t, 3>;
  static constexpr std::uint32_t kNone = 0xffffffffu;

  MeshWall(std::vector<V3> vertices, std::vector<Tri> triangles)
      : v_(std::move(vertices)), t_(std::move(triangles)) {
    if (t_.empty()) throw std::invalid_argument("mesh: no triangles");
    for (const V3& p : v_)
      if (!p.allFinite()) throw std::invalid_argument("mesh: a vertex has a non-finite coordinate");
    lo_ = hi_ = v_[t_[0][0]];
    for (const Tri& tr : t_)
      for (const auto k : tr) {
        if (k >= v_.size()) throw std::invalid_argument("mesh: a triangle refers to a missing vertex");
        lo_ = lo_.cwiseMin(v_[k]);
        hi_ = hi_.cwiseMax(v_[k]);
      }
    scale_ = (hi_ - lo_).norm();
    check_and_link();
    make_facets();
    make_grid();
  }

  std::size_t triangles() const { return t_.size(); }
  std::size_t facets() const { return facet_normal_.size(); }
  const std::vector<V3>& vertices() const { return v_; }
  const std::vector<Tri>& triangle_list() const { return t_; }
  std::uint32_t facet_of(std::size_t tri) const { return tri_facet_[tri]; }

  const char* kind() const override { return "mesh"; }
  std::string describe() const override {
    return fmt::format("mesh of {} triangles ({} flat facets, {} vertices) in [({}), ({})], touched from both sides",
                       t_.size(), facets(), v_.size(), fmt::join(lo_, ", "), fmt::join(hi_, ", "));
  }

  // The nearest valid contact over all facets (the one an engine without a feature list sees).
  WallPoint<3> at(const V3& x, double R, double) const override {
    double r = std::max(cell_, R);
    std::vector<std::uint32_t> tris, fs;
    for (;;) {
      const bool all = covers_grid(x, r + R);
      tris.clear();
      if (all) {
        fs.resize(facets());
        for (std::uint32_t f = 0; f < fs.size(); ++f) fs[f] = f;
      } else {
        query(V3(x.array() - (r + R)), V3(x.array() + (r + R)), tris);
        facets_of(tris, fs);
      }
      WallPoint<3> best;
      best.gap = kNever;
      for (const std::uint32_t f : fs) {
        const WallPoint<3> c = contact(x, R, f);
        if (c.gap < best.gap) best = c;
      }
      if (all || best.gap + R <= r) {
        if (!(best.gap < kNever)) best = unconditioned_nearest(x, R);  // a tie no facet owns
        return best;
      }
      r *= 4.0;
    }
  }

  bool multi_contact() const override { return true; }
  void features_near(const V3& x, double R, double reach, double, std::vector<std::uint32_t>& out) const override {
    std::vector<std::uint32_t> tris, fs;
    const double span = R + std::max(reach, 0.0);
    query(V3(x.array() - span), V3(x.array() + span), tris);
    facets_of(tris, fs);
    for (const std::uint32_t f : fs)
      if (facet_nearest(x, f).dist - R < reach) out.push_back(f);
  }
  WallPoint<3> at_feature(const V3& x, double R, double, std::uint32_t f) const override { return contact(x, R, f); }
  Vec<3> feature_velocity(const V3&, double, double, std::uint32_t) const override { return V3::Zero(); }

  // At an impact the particle may touch several facets within round-off (a concave corner): the
  // one it approaches fastest.
  WallPoint<3> at_impact(const V3& x, const V3& v, double R, double t) const override {
    const WallPoint<3> c0 = at(x, R, t);
    const double tol = 1e-9 * (R + scale_);
    std::vector<std::uint32_t> tris, fs;
    const double span = R + std::max(c0.gap, 0.0) + tol;
    query(V3(x.array() - span), V3(x.array() + span), tris);
    facets_of(tris, fs);
    WallPoint<3> best = c0;
    double un = v.dot(c0.normal);
    for (const std::uint32_t f : fs) {
      const WallPoint<3> c = contact(x, R, f);
      if (!(c.gap <= c0.gap + tol)) continue;
      const double u = v.dot(c.normal);
      if (u < un) {
        un = u;
        best = c;
      }
    }
    return best;
  }

  double impact_time(const V3& x, const V3& v, const V3& g, double R, double, double limit) const override {
    const WallPoint<3> c0 = at(x, R, 0.0);
    const bool approaching = closing_now(v, g, c0.normal);
    if (c0.gap <= 0.0 && approaching) return 0.0;
    if (out_of_reach(c0.gap, v, g, limit)) return kNever;
    // Where the flight is in the mesh's box (padded by a little more than R): outside it no
    // triangle can be touched, so the search starts at the entry (a checkpoint there) and stops at
    // the exit (a checkpoint, the flight may come back under gravity).
    double t_in = 0.0, t_out = kNever;
    if (!flight_box_window<3>(x, v, g, lo_, hi_, R * (1.0 + 1e-6) + 1e-9 * scale_, t_in, t_out)) return kNever;
    if (t_in > 0.0) return t_in < limit ? t_in : kNever;
    // The search horizon: the time in which the centre travels `horizon_` (or the limit).
    double T = std::min(limit, t_out);
    bool checkpoint = t_out < limit;
    const double sv = v.norm(), sg = g.norm();
    const double reach = c0.gap + horizon_;
    const double Th = sg > 0.0 ? 2.0 * reach / (sv + std::sqrt(sv * sv + 2.0 * sg * reach)) : (sv > 0.0 ? reach / sv : kNever);
    if (Th < T) {
      T = Th;
      checkpoint = true;
    }
    if (!(T < kNever)) return kNever;  // at rest, no gravity: never
    // The flight's box over [0, T] (a parabola's extremes per axis), padded by R.
    V3 blo = x, bhi = x;
    auto pos = [&](double s) { return V3(x + s * v + (0.5 * s * s) * g); };
    const V3 xe = pos(T);
    blo = blo.cwiseMin(xe);
    bhi = bhi.cwiseMax(xe);
    for (int k = 0; k < 3; ++k)
      if (g[k] != 0.0) {
        const double s = -v[k] / g[k];
        if (s > 0.0 && s < T) {
          const double xk = pos(s)[k];
          blo[k] = std::min(blo[k], xk);
          bhi[k] = std::max(bhi[k], xk);
        }
      }
    const double pad = R * (1.0 + 1e-9) + 1e-12 * scale_;
    std::vector<std::uint32_t> tris;
    query(V3(blo.array() - pad), V3(bhi.array() + pad), tris);
    double t = kNever;
    const double lim = std::min(T, limit);
    std::vector<std::uint32_t> edges, verts;
    for (const std::uint32_t k : tris) {
      const Tri& tr = t_[k];
      const V3& a = v_[tr[0]];
      const Flight<3> f(x, v, g, a);
      const V3 e1 = v_[tr[1]] - a, e2 = v_[tr[2]] - a;
      auto in_tri = [&](const V3& r) { return inside(r, e1, e2, tri_n_[k]); };
      t = std::min(t, feature::face(f, tri_n_[k], +1, R, std::min(t, lim), approaching, in_tri));
      t = std::min(t, feature::face(f, tri_n_[k], -1, R, std::min(t, lim), approaching, in_tri));
      for (int j = 0; j < 3; ++j) {
        edges.push_back(tri_edge_[k][j]);
        verts.push_back(tr[j]);
      }
    }
    unique(edges);
    unique(verts);
    for (const std::uint32_t e : edges) {
      const V3& a = v_[edge_[e].a];
      const V3 d = v_[edge_[e].b] - a;
      const double L = d.norm();
      t = std::min(t, feature::edge(Flight<3>(x, v, g, a), V3(d / L), 0.0, L, R, std::min(t, lim), approaching));
    }
    for (const std::uint32_t p : verts)
      t = std::min(t, feature::point(Flight<3>(x, v, g, v_[p]), R, std::min(t, lim), approaching));
    if (t < lim) {
      t = refine_on_gap([&](double s) { return at(pos(s), R, 0.0).gap; }, t);
      return t < limit ? t : kNever;
    }
    return checkpoint && T < limit ? T : kNever;
  }

  bool bracketed() const override { return true; }
  double reach_from_axis(const V3& p, const V3& a) const override {
    double r = 0.0;
    for (const V3& x : v_) r = std::max(r, (x - p - (x - p).dot(a) * a).norm());
    return r;
  }
  bool bounds(V3& lo, V3& hi) const override {
    lo = lo_;
    hi = hi_;
    return true;
  }
  // Faces give +-their normals, edges and corners every other direction.
  bool has_normal(const V3& n, double tol) const override { return std::abs(n.norm() - 1.0) <= tol; }
  V3 anchor() const override { return 0.5 * (lo_ + hi_); }
  void tessellate(double, const V3&, const V3&, SurfaceMesh& out) const override {
    const auto base = static_cast<std::uint32_t>(out.points.size());
    for (const V3& p : v_) out.points.push_back({p[0], p[1], p[2]});
    for (const Tri& tr : t_) out.cells.push_back({base + tr[0], base + tr[1], base + tr[2]});
  }

  // The distance from x to the nearest point of facet f and that point (no ownership rule).
  struct Foot {
    V3 point;
    double dist = 0.0;
    std::uint32_t tri = kNone;
    int region = 0;
  };
  Foot facet_nearest(const V3& x, std::uint32_t f) const {
    Foot best;
    best.dist = kNever;
    for (std::uint32_t k = facet_start_[f]; k < facet_start_[f + 1]; ++k) {
      const std::uint32_t tr = facet_tris_[k];
      const TriangleFoot q = foot(x, tr);
      const double d = (x - q.point).norm();
      if (d < best.dist) best = {q.point, d, tr, q.region};
    }
    return best;
  }

 private:
  struct Edge {
    std::uint32_t a, b;             // vertex indices, a < b
    std::uint32_t t0, t1 = kNone;   // the one or two triangles
  };

  TriangleFoot foot(const V3& x, std::uint32_t tr) const {
    return nearest_on_triangle(x, v_[t_[tr][0]], v_[t_[tr][1]], v_[t_[tr][2]]);
  }

  // The contact of a particle (centre x, radius R) with facet f under the ownership rule above;
  // gap = kNever where the facet does not own it.
  WallPoint<3> contact(const V3& x, double R, std::uint32_t f) const {
    WallPoint<3> out;
    out.gap = kNever;
    const Foot q = facet_nearest(x, f);
    if (q.region != 0 && !owns(x, f, q)) return out;
    const V3 d = x - q.point;
    out.gap = q.dist - R;
    out.normal = q.dist > 0.0 ? V3(d / q.dist) : facet_normal_[f];
    return out;
  }

  // Whether facet f owns the border contact at q (region != 0).
  bool owns(const V3& x, std::uint32_t f, const Foot& q) const {
    const double eps = 1e-9 * scale_;
    auto same = [&](std::uint32_t u) {
      if (tri_facet_[u] == f) return true;
      if (tri_facet_[u] < f) return false;
      return (foot(x, u).point - q.point).norm() <= eps;
    };
    if (q.region <= 3) {
      const Edge& e = edge_[tri_edge_[q.tri][q.region - 1]];
      const std::uint32_t o = e.t0 == q.tri ? e.t1 : e.t0;
      return o == kNone || same(o);
    }
    const std::uint32_t p = t_[q.tri][q.region - 4];
    for (std::uint32_t k = vert_start_[p]; k < vert_start_[p + 1]; ++k)
      if (!same(vert_tris_[k])) return false;
    return true;
  }

  WallPoint<3> unconditioned_nearest(const V3& x, double R) const {
    WallPoint<3> out;
    out.gap = kNever;
    for (std::uint32_t f = 0; f < facets(); ++f) {
      const Foot q = facet_nearest(x, f);
      if (q.dist - R < out.gap) {
        out.gap = q.dist - R;
        out.normal = q.dist > 0.0 ? V3((x - q.point) / q.dist) : facet_normal_[f];
      }
    }
    return out;
  }

  // Whether r (from the triangle's first vertex) projects into the triangle spanned by e1, e2.
  static bool inside(const V3& r, const V3& e1, const V3& e2, const V3& n) {
    const double tol = -1e-12;
    return n.dot(e1.cross(r)) >= tol * e1.squaredNorm() && n.dot(r.cross(e2)) >= tol * e2.squaredNorm() &&
           n.dot((e2 - e1).cross(r - e1)) >= tol * (e2 - e1).squaredNorm();
  }

  static void unique(std::vector<std::uint32_t>& v) {
    std::sort(v.begin(), v.end());
    v.erase(std::unique(v.begin(), v.end()), v.end());
  }

  void facets_of(const std::vector<std::uint32_t>& tris, std::vector<std::uint32_t>& fs) const {
    fs.clear();
    for (const std::uint32_t k : tris) fs.push_back(tri_facet_[k]);
    unique(fs);
  }

  // Degenerate triangles, non-manifold edges; the edge table and each vertex's triangles.
  void check_and_link() {
    std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> index;
    tri_n_.resize(t_.size());
    tri_edge_.resize(t_.size());
    for (std::uint32_t k = 0; k < t_.size(); ++k) {
      const Tri& tr = t_[k];
      const V3 &a = v_[tr[0]], &b = v_[tr[1]], &c = v_[tr[2]];
      const V3 n = (b - a).cross(c - a);
      const double longest = std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
      if (tr[0] == tr[1] || tr[1] == tr[2] || tr[0] == tr[2] || !(n.norm() > 1e-12 * longest * longest))
        throw std::invalid_argument(fmt::format(
            "triangle {} is degenerate (zero area: vertices ({}), ({}), ({})); remove it or repair the mesh", k + 1,
            fmt::join(a, ", "), fmt::join(b, ", "), fmt::join(c, ", ")));
      tri_n_[k] = n.normalized();
      for (int j = 0; j < 3; ++j) {
        std::uint32_t p = tr[j], q = tr[(j + 1) % 3];
        if (p > q) std::swap(p, q);
        auto [it, fresh] = index.try_emplace({p, q}, static_cast<std::uint32_t>(edge_.size()));
        if (fresh) {
          edge_.push_back({p, q, k});
        } else {
          Edge& e = edge_[it->second];
          if (e.t1 != kNone)
            throw std::invalid_argument(fmt::format(
                "the edge from ({}) to ({}) is shared by more than two triangles (triangles {}, {} and {}): the mesh "
                "is non-manifold",
                fmt::join(v_[p], ", "), fmt::join(v_[q], ", "), e.t0 + 1, e.t1 + 1, k + 1));
          e.t1 = k;
        }
        tri_edge_[k][j] = it->second;
      }
    }
    vert_start_.assign(v_.size() + 1, 0);
    for (const Tri& tr : t_)
      for (const auto p : tr) ++vert_start_[p + 1];
    for (std::size_t p = 0; p < v_.size(); ++p) vert_start_[p + 1] += vert_start_[p];
    vert_tris_.resize(vert_start_.back());
    std::vector<std::uint32_t> fill(vert_start_.begin(), vert_start_.end() - 1);
    for (std::uint32_t k = 0; k < t_.size(); ++k)
      for (const auto p : t_[k]) vert_tris_[fill[p]++] = k;
  }

  // Facets: triangles joined across an edge when coplanar (normals parallel or antiparallel, the
  // far vertex in the plane within round-off of the mesh's size).
  void make_facets() {
    std::vector<std::uint32_t> parent(t_.size());
    for (std::uint32_t k = 0; k < parent.size(); ++k) parent[k] = k;
    auto root = [&](std::uint32_t k) {
      while (parent[k] != k) k = parent[k] = parent[parent[k]];
      return k;
    };
    for (const Edge& e : edge_) {
      if (e.t1 == kNone) continue;
      const V3 &n0 = tri_n_[e.t0], &n1 = tri_n_[e.t1];
      if (std::abs(n0.dot(n1)) < 1.0 - 1e-12) continue;
      bool flat = true;
      for (const auto p : t_[e.t1]) flat = flat && std::abs((v_[p] - v_[e.a]).dot(n0)) <= 1e-12 * scale_;
      if (flat) parent[root(e.t0)] = root(e.t1);
    }
    tri_facet_.assign(t_.size(), kNone);
    std::vector<std::uint32_t> id(t_.size(), kNone);
    for (std::uint32_t k = 0; k < t_.size(); ++k) {
      const std::uint32_t r = root(k);
      if (id[r] == kNone) {
        id[r] = static_cast<std::uint32_t>(facet_normal_.size());
        facet_normal_.push_back(tri_n_[k]);
      }
      tri_facet_[k] = id[r];
    }
    facet_start_.assign(facets() + 1, 0);
    for (const auto f : tri_facet_) ++facet_start_[f + 1];
    for (std::size_t f = 0; f < facets(); ++f) facet_start_[f + 1] += facet_start_[f];
    facet_tris_.resize(t_.size());
    std::vector<std::uint32_t> fill(facet_start_.begin(), facet_start_.end() - 1);
    for (std::uint32_t k = 0; k < t_.size(); ++k) facet_tris_[fill[tri_facet_[k]]++] = k;
  }

  // A uniform grid over the mesh's box, each cell listing the triangles whose box meets it: cells
  // about the mean triangle size, at most 32 per triangle.
  void make_grid() {
    double mean = 0.0;
    for (const Tri& tr : t_) {
      V3 a = v_[tr[0]], b = a;
      for (const auto p : tr) {
        a = a.cwiseMin(v_[p]);
        b = b.cwiseMax(v_[p]);
      }
      mean += (b - a).maxCoeff();
    }
    cell_ = std::max(mean / static_cast<double>(t_.size()), 1e-6 * scale_);
    auto count = [&] {
      double c = 1.0;
      for (int k = 0; k < 3; ++k) c *= std::floor((hi_[k] - lo_[k]) / cell_) + 1.0;
      return c;
    };
    while (count() > 32.0 * static_cast<double>(t_.size()) + 64.0) cell_ *= 1.25;
    for (int k = 0; k < 3; ++k) n_[k] = static_cast<int>(std::floor((hi_[k] - lo_[k]) / cell_)) + 1;
    horizon_ = 4.0 * cell_;
    const std::size_t cells = static_cast<std::size_t>(n_[0]) * n_[1] * n_[2];
    std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;  // (cell, triangle)
    for (std::uint32_t k = 0; k < t_.size(); ++k) {
      V3 a = v_[t_[k][0]], b = a;
      for (const auto p : t_[k]) {
        a = a.cwiseMin(v_[p]);
        b = b.cwiseMax(v_[p]);
      }
      std::array<int, 3> c0 = cell_of(a), c1 = cell_of(b);
      for (int i = c0[0]; i <= c1[0]; ++i)
        for (int j = c0[1]; j <= c1[1]; ++j)
          for (int l = c0[2]; l <= c1[2]; ++l) pairs.push_back({flat(i, j, l), k});
    }
    std::sort(pairs.begin(), pairs.end());
    cell_start_.assign(cells + 1, 0);
    for (const auto& p : pairs) ++cell_start_[p.first + 1];
    for (std::size_t c = 0; c < cells; ++c) cell_start_[c + 1] += cell_start_[c];
    cell_tris_.resize(pairs.size());
    for (std::size_t k = 0; k < pairs.size(); ++k) cell_tris_[k] = pairs[k].second;
  }
  std::array<int, 3> cell_of(const V3& p) const {
    std::array<int, 3> c;
    for (int k = 0; k < 3; ++k) {
      double s = std::floor((p[k] - lo_[k]) / cell_);
      if (!(s >= 0.0)) s = 0.0;  // below the grid, or NaN (a lost particle: no crash)
      c[k] = static_cast<int>(std::min(s, static_cast<double>(n_[k] - 1)));
    }
    return c;
  }
  std::uint32_t flat(int i, int j, int l) const {
    return static_cast<std::uint32_t>((static_cast<std::size_t>(l) * n_[1] + j) * n_[0] + i);
  }
  bool covers_grid(const V3& x, double span) const {
    return ((x.array() - span) <= lo_.array()).all() && ((x.array() + span) >= hi_.array()).all();
  }
  // The triangles listed in the cells that the box [a, b] meets (each once).
  void query(const V3& a, const V3& b, std::vector<std::uint32_t>& out) const {
    out.clear();
    if ((b.array() < lo_.array()).any() || (a.array() > hi_.array()).any()) return;
    const std::array<int, 3> c0 = cell_of(a), c1 = cell_of(b);
    for (int l = c0[2]; l <= c1[2]; ++l)
      for (int j = c0[1]; j <= c1[1]; ++j)
        for (int i = c0[0]; i <= c1[0]; ++i) {
          const std::uint32_t c = flat(i, j, l);
          out.insert(out.end(), cell_tris_.begin() + cell_start_[c], cell_tris_.begin() + cell_start_[c + 1]);
        }
    unique(out);
  }

  std::vector<V3> v_;
  std::vector<Tri> t_;
  std::vector<V3> tri_n_;
  std::vector<std::array<std::uint32_t, 3>> tri_edge_;
  std::vector<Edge> edge_;
  std::vector<std::uint32_t> vert_start_, vert_tris_;
  std::vector<std::uint32_t> tri_facet_, facet_start_, facet_tris_;
  std::vector<V3> facet_normal_;
  V3 lo_, hi_;
  double scale_ = 1.0, cell_ = 1.0, horizon_ = 1.0;
  std::array<int, 3> n_{1, 1, 1};
  std::vector<std::uint32_t> cell_start_, cell_tris_;
};

}  // namespace matep

// The pipe wall (a bent tube, the U-tube): WallShape<D> (contact/wall.hpp).
//   PipeWall<D>(start, direction, radius, pieces)
// The centreline starts at `start` heading along `direction` (any nonzero vector, normalized) and
// is a chain of pieces, each starting where the previous one ends and tangent to it:
//   PipePiece<D>::straight(length)                 length > 0: a straight run along the current
//                                                  direction;
//   PipePiece<D>::arc(bend_radius, angle, axis)    a circular bend of radius bend_radius > radius
//                                                  (else the tube would cut itself at the bend)
//                                                  through |angle| radians, 0 < |angle| <= 2 pi.
//     3D: the direction turns by `angle` about `axis` (right-handed; nonzero, perpendicular to the
//         current direction within 1e-9 relative, normalized): angle > 0 bends towards
//         axis x direction, where the bend's centre lies.
//     2D: `axis` is unused (omit it): angle > 0 turns left (counter-clockwise), < 0 right.
// Scene-file form (suggested): pieces = [["straight", L], ["arc", Rb, angle, [ax, ay, az]], ...];
// the U-tube rising along z and coming back down: start (0, 0, 0), direction (0, 0, 1),
// [["straight", H], ["arc", Rb, pi, (0, 1, 0)], ["straight", H]] (turns towards (0, 1, 0) x
// (0, 0, 1) = +x: the second leg descends at x = 2 Rb). 2D: [["straight", H], ["arc", Rb, -pi],
// ["straight", H]] turns right, to +x.
// 3D: a tube of radius `radius` around the centreline (torus sections in the bends); 2D: a channel
// of half-width `radius` (the two curves offset from the centreline). The grains live inside, and
// the gap is one-sided and signed: gap = radius - R - d, d the distance from the particle's centre to
// the nearest point q of the whole centreline (a grain outside the tube has a negative gap); the
// normal is (q - x) / d, from the wall towards the particle (towards the centreline); on the
// centreline itself (d = 0) any direction across it.
// The ends: since d is measured to the nearest centreline point, end points included, beyond an end
// the surface is a hemispherical cap of radius `radius` (2D: a half-circle) centred on the end
// point: the shape is a closed vessel and the gap is continuous everywhere. The caps lie beyond the
// end cross-sections, so a scene that wants open ends closes them with planes (through start()
// with normal direction(), through end_point() with normal -end_direction(), both pointing into the
// pipe) or lets the domain end at those cross-sections (bounds() covers the tube up to its end
// cross-sections and not the caps); the pictures show the tube without caps. Pieces that come back close to one another (not checked) make the union of
// their tubes (d is the distance to the nearest of them).
// Impact times (contact/shape_features.hpp): the grain touches the wall when its centre reaches
// distance A = radius - R from the centreline. Per piece, the offset surface is the cylinder
// |r_perp|^2 = A^2 around the straight's line (quadratic in t for a straight flight, quartic under
// gravity) or the torus (|r|^2 + Rb^2 - A^2)^2 = 4 Rb^2 rho^2 around the bend's circle (quartic, octic
// under gravity; (d_near^2 - A^2)(d_far^2 - A^2), the second factor >= Rb^2 - A^2 > 0: its sign is
// that of the first), plus the spheres |r|^2 = A^2 around the two end points. Each polynomial only cuts
// time into monotone pieces; the feature's own distance locates the root (closing_on_pieces), and a
// root counts only where the whole pipe's gap (at()) is closed there to round-off: the particle is
// at the pipe's wall, not merely outside the line of one straight while inside the next bend. The
// first closing of the pipe's gap happens at the nearest piece, at a root of that piece's feature
// (the pieces join tangentially, so a point nearest to a joint lies in the common cross-section and
// both pieces see it as an interior point), hence the earliest accepted root is the impact; it is
// refined on the gap of at() evaluated in long double, on the pieces' long-double frames (place).
// "Closed to round-off" is gap <= 1e-12 (radius + the size of the pipe's box): a flight that passes
// the wall closer than that counts as touching it.
// bracketed() is true: the engine passes its earliest event so far as the limit, and a flight that
// cannot reach the surface before it (gap > |v| limit + |g| limit^2 / 2) costs one at() call.
// has_normal: every unit vector (the caps and bends give all directions).
#pragma once

#include <fmt/format.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "contact/predict.hpp"
#include "contact/shape_features.hpp"
#include "contact/wall.hpp"

namespace matep {

template <int D>
struct PipePiece {
  enum class Kind { Straight, Arc };
  Kind kind = Kind::Straight;
  double length = 0.0;       // straight
  double bend_radius = 0.0;  // arc
  double angle = 0.0;        // arc, radians (sign: see the header)
  Vec<D> axis = Vec<D>::Zero();  // arc, 3D: the turning axis

  static PipePiece straight(double length) {
    PipePiece p;
    p.kind = Kind::Straight;
    p.length = length;
    return p;
  }
  static PipePiece arc(double bend_radius, double angle, const Vec<D>& axis = Vec<D>::Zero()) {
    PipePiece p;
    p.kind = Kind::Arc;
    p.bend_radius = bend_radius;
    p.angle = angle;
    p.axis = axis;
    return p;
  }
};

template <int D>
class PipeWall final : public WallShape<D> {
 public:
  PipeWall(const Vec<D>& start, const Vec<D>& direction, double radius, const std::vector<PipePiece<D>>& pieces)
      : start_(start), radius_(radius), pieces_(pieces) {
    if (!(radius > 0.0) || !std::isfinite(radius)) throw std::invalid_argument("pipe: radius must be finite and > 0");
    const double dn = direction.norm();
    if (!(dn > 0.0) || !std::isfinite(dn)) throw std::invalid_argument("pipe: direction must be a nonzero vector");
    if (pieces.empty()) throw std::invalid_argument("pipe: at least one piece is needed");
    dir0_ = direction / dn;
    std::vector<Frame<double>> fd;
    place<double>(direction, fd);
    place<long double>(direction, framesx_);
    for (std::size_t i = 0; i < pieces.size(); ++i) {
      Seg s;
      static_cast<Frame<double>&>(s) = fd[i];
      s.arc = pieces[i].kind == PipePiece<D>::Kind::Arc;
      if (!s.arc) {
        s.L = pieces[i].length;
      } else {
        s.Rb = pieces[i].bend_radius;
        s.phi = std::abs(pieces[i].angle);
        if constexpr (D == 3) s.n = s.e0.cross(s.e1);
        s.L = s.Rb * s.phi;
      }
      segs_.push_back(s);
    }
    end_ = segs_.back().p1;
    dir1_ = segs_.back().d1;
    Vec<D> lo, hi;
    bounds(lo, hi);
    tol_ = 1e-12 * (radius_ + (hi - lo).maxCoeff());
  }

  const Vec<D>& start() const { return start_; }
  const Vec<D>& direction() const { return dir0_; }  // unit, at the start
  const Vec<D>& end_point() const { return end_; }
  const Vec<D>& end_direction() const { return dir1_; }  // unit, at the end (pointing out of the pipe)
  double radius() const { return radius_; }
  const std::vector<PipePiece<D>>& pieces() const { return pieces_; }
  // The centreline's length.
  double length() const {
    double s = 0.0;
    for (const Seg& g : segs_) s += g.L;
    return s;
  }

  const char* kind() const override { return "pipe"; }
  std::string describe() const override {
    std::string s = fmt::format("pipe of radius {} from ({}) along ({}) to ({}), {} pieces:", radius_,
                                fmt::join(start_, ", "), fmt::join(dir0_, ", "), fmt::join(end_, ", "), segs_.size());
    for (const PipePiece<D>& p : pieces_) {
      if (p.kind == PipePiece<D>::Kind::Straight) s += fmt::format(" straight {};", p.length);
      else s += fmt::format(" arc radius {} angle {};", p.bend_radius, p.angle);
    }
    s.pop_back();
    return s + " (grains inside, hemispherical caps beyond the ends)";
  }

  // The distance from x to the centreline and its nearest point q, with the centreline's tangent
  // there; in the precision T of x.
  template <class T>
  T distance(const Eigen::Matrix<T, D, 1>& x, Eigen::Matrix<T, D, 1>& q, Eigen::Matrix<T, D, 1>& tangent) const {
    T best = std::numeric_limits<T>::infinity();
    for (std::size_t i = 0; i < segs_.size(); ++i) {
      Eigen::Matrix<T, D, 1> qs, ts;
      T d;
      if constexpr (std::is_same_v<T, double>) d = segs_[i].nearest(static_cast<const Frame<double>&>(segs_[i]), x, qs, ts);
      else d = segs_[i].nearest(framesx_[i], x, qs, ts);
      if (d < best) {
        best = d;
        q = qs;
        tangent = ts;
      }
    }
    return best;
  }
  double distance(const Vec<D>& x) const {
    Vec<D> q = Vec<D>::Zero(), t = Vec<D>::Zero();
    return distance(x, q, t);
  }

  WallPoint<D> at(const Vec<D>& x, double R, double) const override {
    Vec<D> q = Vec<D>::Zero(), tg = Vec<D>::Zero();
    const double d = distance(x, q, tg);
    WallPoint<D> c;
    c.gap = radius_ - R - d;
    if (d > 0.0) {
      c.normal = (q - x) / d;
    } else {  // on the centreline: any direction across it
      if constexpr (D == 2) {
        c.normal = Vec<D>(-tg[1], tg[0]);
      } else {
        const Vec<D> e = std::abs(tg[0]) < 0.9 ? Vec<D>(1, 0, 0) : Vec<D>(0, 1, 0);
        c.normal = (e - e.dot(tg) * tg).normalized();
      }
    }
    return c;
  }

  double impact_time(const Vec<D>& x, const Vec<D>& v, const Vec<D>& g, double R, double,
                     double limit) const override {
    // Now: an approaching particle within round-off of the wall (or outside it).
    const WallPoint<D> c0 = at(x, R, 0.0);
    const bool approaching = closing_now(v, g, c0.normal);
    if (c0.gap <= 0.0 && approaching) return 0.0;
    if (out_of_reach(c0.gap, v, g, limit)) return kNever;
    const double A = radius_ - R;
    if (!(A > 0.0)) return kNever;  // the particle does not fit: always overlapping
    // A root counts where the whole pipe's gap is closed (to round-off): at the wall.
    auto valid = [&](double t) {
      const Vec<D> xt = x + t * (v + (0.5 * t) * g);
      return A - distance(xt) <= tol_;
    };
    double t = kNever;
    for (const Seg& s : segs_) {
      const double lim = std::min(t, limit);
      if (!s.arc) {
        const Flight<D> f = Flight<D>(x, v, g, s.p0).perp(s.d0);
        const Poly p = Poly{A * A} - f.norm2();
        t = std::min(t, closing_on_pieces(p, [&](double u) { return A - f.at(u).norm(); }, valid, lim, approaching));
      } else {
        const Flight<D> f(x, v, g, s.c);
        const Poly r2 = f.norm2();
        Poly rho2 = r2;
        if constexpr (D == 3) rho2 = f.perp(s.n).norm2();
        const Poly q = r2 + Poly{s.Rb * s.Rb - A * A};
        const Poly p = rho2 * (4.0 * s.Rb * s.Rb) - q * q;
        auto h = [&](double u) {  // A minus the distance to the bend's full circle
          const Vec<D> r = f.at(u);
          double z = 0.0;
          if constexpr (D == 3) z = r.dot(s.n);
          const double rho = D == 3 ? (r - z * s.n).norm() : r.norm();
          return A - std::hypot(rho - s.Rb, z);
        };
        t = std::min(t, closing_on_pieces(p, h, valid, lim, approaching));
      }
    }
    for (const Vec<D>& e : {start_, end_}) {  // the caps
      const Flight<D> f(x, v, g, e);
      const Poly p = Poly{A * A} - f.norm2();
      t = std::min(t, closing_on_pieces(p, [&](double u) { return A - f.at(u).norm(); }, valid,
                                        std::min(t, limit), approaching));
    }
    if (!(t < limit)) return kNever;
    // The grazing touches of the bends need the gap in long double (flight_point_x).
    t = refine_on_gap(
        [&](double s) {
          VecX<D> q, tg;
          return static_cast<long double>(radius_) - static_cast<long double>(R) -
                 distance<long double>(flight_point_x<D>(x, v, g, s, Vec<D>::Zero()), q, tg);
        },
        t);
    return t < limit ? t : kNever;
  }

  // The engine passes the earliest event found so far as `limit`: most flights are rejected by
  // out_of_reach without a root search.
  bool bracketed() const override { return true; }

  // The box of the tube up to its end cross-sections (the caps beyond them are left out: a domain
  // may end at an end cross-section). A straight: its end discs, coordinate k reaching
  // radius sqrt(1 - d_k^2) across the axis d. A bend: the torus section's coordinate k,
  // c_k + (Rb + radius cos psi) u_k + radius sin psi n_k (u(theta) the in-plane unit radius), is
  // largest over psi at c_k + Rb u_k + radius hypot(u_k, n_k), which grows with u_k (its derivative
  // Rb + radius u_k / hypot >= Rb - radius > 0): its extremes are those of u_k over the arc's angles,
  // at the end points or at the in-plane direction of e_k if that lies within the arc.
  bool bounds(Vec<D>& lo, Vec<D>& hi) const override {
    lo = Vec<D>::Constant(std::numeric_limits<double>::infinity());
    hi = -lo;
    for (const Seg& s : segs_) {
      for (int k = 0; k < D; ++k) {
        if (!s.arc) {
          const double ext = radius_ * std::sqrt(std::max(0.0, 1.0 - s.d0[k] * s.d0[k]));
          lo[k] = std::min({lo[k], s.p0[k] - ext, s.p1[k] - ext});
          hi[k] = std::max({hi[k], s.p0[k] + ext, s.p1[k] + ext});
        } else {
          const double nk = D == 3 ? s.n[k] : 0.0;
          auto reach = [&](double th, double sign) {
            const double uk = std::cos(th) * s.e0[k] + std::sin(th) * s.e1[k];
            return s.c[k] + s.Rb * uk + sign * radius_ * std::hypot(uk, nk);
          };
          double ths[4] = {0.0, s.phi, 0.0, 0.0};
          int m = 2;
          const double th_max = std::atan2(s.e1[k], s.e0[k]);  // u_k largest (if e_k has an in-plane part)
          for (double th : {th_max, th_max + 3.14159265358979323846}) {
            th = std::fmod(th + 4.0 * 3.14159265358979323846, 2.0 * 3.14159265358979323846);
            if (th <= s.phi) ths[m++] = th;
          }
          for (int j = 0; j < m; ++j) {
            lo[k] = std::min(lo[k], reach(ths[j], -1.0));
            hi[k] = std::max(hi[k], reach(ths[j], 1.0));
          }
        }
      }
    }
    return true;
  }
  bool has_normal(const Vec<D>& n, double tol) const override { return std::abs(n.norm() - 1.0) <= tol; }

  Vec<D> anchor() const override { return start_; }

  // 3D: rings of 24 points around the centreline, at both ends of a straight and every 7.5 degrees
  // along a bend, joined by quads within each piece. 2D: the two walls as polylines (sampled the same
  // way along the bends). The caps are not drawn.
  void tessellate(double, const Vec<D>&, const Vec<D>&, SurfaceMesh& out) const override {
    constexpr double kPi = 3.14159265358979323846;
    auto push = [&](const Vec<D>& x) {
      out.points.push_back({x[0], x[1], D == 3 ? x[D - 1] : 0.0});
      return static_cast<std::uint32_t>(out.points.size() - 1);
    };
    // Centreline samples (point, tangent) of one piece.
    auto samples = [&](const Seg& s, std::vector<Vec<D>>& pts, std::vector<Vec<D>>& tan) {
      pts.clear();
      tan.clear();
      if (!s.arc) {
        pts = {s.p0, s.p1};
        tan = {s.d0, s.d0};
        return;
      }
      const int n = std::max(2, static_cast<int>(std::ceil(s.phi / (kPi / 24.0))));
      for (int j = 0; j <= n; ++j) {
        const double th = s.phi * j / n;
        pts.push_back(s.c + s.Rb * (std::cos(th) * s.e0 + std::sin(th) * s.e1));
        tan.push_back(-std::sin(th) * s.e0 + std::cos(th) * s.e1);
      }
    };
    std::vector<Vec<D>> pts, tan;
    if constexpr (D == 2) {
      for (const double side : {-1.0, 1.0}) {
        std::vector<std::uint32_t> cell;
        for (std::size_t i = 0; i < segs_.size(); ++i) {
          samples(segs_[i], pts, tan);
          for (std::size_t j = (i == 0 ? 0 : 1); j < pts.size(); ++j)
            cell.push_back(push(Vec<D>(pts[j] + side * radius_ * Vec<D>(-tan[j][1], tan[j][0]))));
        }
        out.cells.push_back(std::move(cell));
      }
    } else {
      const int ring = 24;
      for (const Seg& s : segs_) {
        samples(s, pts, tan);
        std::vector<std::uint32_t> prev;
        for (std::size_t j = 0; j < pts.size(); ++j) {
          // A frame across the tangent: the bend's plane normal, or any direction across a straight.
          Vec<D> u = s.arc ? Vec<D>(s.n) : (std::abs(tan[j][0]) < 0.9 ? Vec<D>(1, 0, 0) : Vec<D>(0, 1, 0));
          u = (u - u.dot(tan[j]) * tan[j]).normalized();
          const Vec<D> w = tan[j].cross(u);
          std::vector<std::uint32_t> cur;
          for (int k = 0; k < ring; ++k) {
            const double a = 2.0 * kPi * k / ring;
            cur.push_back(push(Vec<D>(pts[j] + radius_ * (std::cos(a) * u + std::sin(a) * w))));
          }
          if (!prev.empty())
            for (int k = 0; k < ring; ++k) {
              const int k1 = (k + 1) % ring;
              out.cells.push_back({prev[k], cur[k], cur[k1], prev[k1]});
            }
          prev = std::move(cur);
        }
      }
    }
  }

 private:
  // Where one piece of the centreline lies, in the precision T: its ends p0, p1 and unit tangents
  // there d0, d1; a bend's centre c and the unit vectors e0 (centre -> start) and e1 (the tangent
  // at the start), its points c + Rb (cos th e0 + sin th e1), 0 <= th <= phi.
  template <class T>
  struct Frame {
    using VT = Eigen::Matrix<T, D, 1>;
    VT p0 = VT::Zero(), p1 = VT::Zero(), d0 = VT::Zero(), d1 = VT::Zero();
    VT c = VT::Zero(), e0 = VT::Zero(), e1 = VT::Zero();
  };

  // The pieces placed one after the other from start_ along `direction`, in the precision T (the
  // parameters are checked in the double pass, which comes first). The long-double frames serve
  // the refinement of impact times (a grazing root moves by ~1e-9 relative per 1e-16 of shift of
  // the wall: the double frames, rounded along the chain, are 1e-16 off the pipe the pieces
  // define).
  template <class T>
  void place(const Vec<D>& direction, std::vector<Frame<T>>& out) const {
    using VT = Eigen::Matrix<T, D, 1>;
    constexpr bool check = std::is_same_v<T, double>;
    constexpr T kPi = T(3.14159265358979323846L);
    const VT dir = direction.template cast<T>();
    VT p = start_.template cast<T>(), d = dir / dir.norm();
    out.clear();
    for (std::size_t i = 0; i < pieces_.size(); ++i) {
      const PipePiece<D>& pc = pieces_[i];
      Frame<T> s;
      s.p0 = p;
      s.d0 = d;
      if (pc.kind == PipePiece<D>::Kind::Straight) {
        if (check && (!(pc.length > 0.0) || !std::isfinite(pc.length)))
          throw std::invalid_argument(fmt::format("pipe: piece {}: a straight's length must be finite and > 0", i));
        p = p + T(pc.length) * d;
      } else {
        if (check && (!(pc.bend_radius > radius_) || !std::isfinite(pc.bend_radius)))
          throw std::invalid_argument(fmt::format(
              "pipe: piece {}: the bend radius ({}) must be finite and > the pipe's radius ({})", i, pc.bend_radius,
              radius_));
        if (check && (!(pc.angle != 0.0) || !(std::abs(pc.angle) <= 2.0 * kPi)))
          throw std::invalid_argument(fmt::format("pipe: piece {}: an arc's angle must be nonzero, |angle| <= 2 pi", i));
        VT towards;  // unit, from the arc's start towards its centre
        if constexpr (D == 2) {
          towards = VT(-d[1], d[0]) * T(pc.angle > 0.0 ? 1 : -1);
        } else {
          const VT ax = pc.axis.template cast<T>();
          const T an = ax.norm();
          if (check && (!(an > 0.0) || !std::isfinite(an)))
            throw std::invalid_argument(fmt::format("pipe: piece {}: an arc's axis must be a nonzero vector", i));
          VT a = ax / an;
          if (check && std::abs(a.dot(d)) > 1e-9)
            throw std::invalid_argument(
                fmt::format("pipe: piece {}: an arc's axis must be perpendicular to the direction there ({})", i,
                            fmt::join(d, ", ")));
          a = (a - a.dot(d) * d).normalized();
          towards = a.cross(d) * T(pc.angle > 0.0 ? 1 : -1);
        }
        const T Rb = pc.bend_radius, phi = std::abs(T(pc.angle));
        s.c = p + Rb * towards;
        s.e0 = -towards;
        s.e1 = d;
        p = s.c + Rb * (std::cos(phi) * s.e0 + std::sin(phi) * s.e1);
        d = (-std::sin(phi) * s.e0 + std::cos(phi) * s.e1).normalized();
      }
      s.p1 = p;
      s.d1 = d;
      out.push_back(s);
    }
  }

  // One piece of the centreline, placed (its double frame; the plane normal n = e0 x e1 of a 3D
  // bend, its radius Rb and angle phi > 0).
  struct Seg : Frame<double> {
    bool arc = false;
    double L = 0.0;  // length (a straight's; a bend's arc length)
    Vec<D> n = Vec<D>::Zero();
    double Rb = 0.0, phi = 0.0;

    // The nearest point q of this piece to x (a straight: the clamped projection; a bend: the point
    // of the circle in x's direction when that lies within the arc, else the nearer end point, as the
    // distance to the circle's point at angle th grows with |th - the direction's angle|), its
    // distance and the tangent there.
    // In the precision T of x (double, or long double for refining impact times), on the frame f
    // of this piece in that precision.
    template <class T>
    T nearest(const Frame<T>& f, const Eigen::Matrix<T, D, 1>& x, Eigen::Matrix<T, D, 1>& q,
              Eigen::Matrix<T, D, 1>& t) const {
      if (!arc) {
        const T s = std::clamp(T((x - f.p0).dot(f.d0)), T(0), T(L));
        q = f.p0 + s * f.d0;
        t = f.d0;
        return (x - q).norm();
      }
      const Eigen::Matrix<T, D, 1> r = x - f.c;
      const T a = r.dot(f.e0), b = r.dot(f.e1);
      T th = (a == T(0) && b == T(0)) ? T(0) : std::atan2(b, a);
      if (th < T(0)) th += T(2) * T(3.14159265358979323846L);
      if (th <= T(phi)) {
        q = f.c + T(Rb) * (std::cos(th) * f.e0 + std::sin(th) * f.e1);
        t = -std::sin(th) * f.e0 + std::cos(th) * f.e1;
        return (x - q).norm();
      }
      const T da = (x - f.p0).norm(), db = (x - f.p1).norm();
      if (da <= db) {
        q = f.p0;
        t = f.d0;
        return da;
      }
      q = f.p1;
      t = f.d1;
      return db;
    }
  };

  Vec<D> start_, dir0_, end_, dir1_;
  double radius_ = 0.0, tol_ = 0.0;
  std::vector<PipePiece<D>> pieces_;
  std::vector<Seg> segs_;
  std::vector<Frame<long double>> framesx_;  // the pieces' frames in long double (place)
};

}  // namespace matep

// Outlet regions: where a grain whose centre enters is taken out of the run (the open-flow issue:
// a silo's orifice, the end of a chute). A region is the set of points where every one of its
// constraints c_k(x) < 0 holds:
//   half space (point p, unit normal n towards the side the grains come from):  (x - p).n < 0
//     (a domain face is the half space beyond it);
//   box [lo, hi]:                      lo_k - x_k < 0 and x_k - hi_k < 0 for every axis k;
//   cylinder (3D: point p, unit axis a, radius r, length L > 0; 2D: a disk of radius r about p):
//                                      |x - p|_perp^2 - r^2 < 0, -z < 0, z - L < 0, z = (x - p).a.
// Along a flight x(t) = x0 + v t + g t^2 / 2 each constraint is a polynomial in t (degree 2, or 4
// for the cylinder's radius under gravity), so the entry time, the earliest t >= 0 at which all
// hold, is found exactly: the sign changes of every constraint in (0, limit) (contact/poly.hpp)
// cut time into pieces on which each constraint keeps its sign; the region is entered at the start
// of the first piece whose midpoint is inside.
#pragma once

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "contact/poly.hpp"
#include "contact/shape_features.hpp"
#include "contact/vec.hpp"

namespace matep {

template <int D>
class OutletRegion {
 public:
  enum class Kind { HalfSpace, Box, Cylinder };

  // Grains are removed on the side of the plane through p opposite to the unit normal n.
  static OutletRegion half_space(const Vec<D>& p, const Vec<D>& n) {
    const double nn = n.norm();
    if (!(nn > 0.0) || !std::isfinite(nn)) throw std::invalid_argument("outlet: normal must be a nonzero vector");
    OutletRegion o;
    o.kind_ = Kind::HalfSpace;
    o.p_ = p;
    o.a_ = n / nn;
    return o;
  }
  static OutletRegion box(const Vec<D>& lo, const Vec<D>& hi) {
    for (int k = 0; k < D; ++k)
      if (!(lo[k] < hi[k])) throw std::invalid_argument("outlet: a box needs lower < upper on every axis");
    OutletRegion o;
    o.kind_ = Kind::Box;
    o.p_ = lo;
    o.q_ = hi;
    return o;
  }
  // 3D: the finite cylinder from p along axis a (normalized) for length L; 2D: the disk of radius r
  // about p (axis and length unused).
  static OutletRegion cylinder(const Vec<D>& p, const Vec<D>& a, double r, double L) {
    if (!(r > 0.0) || !std::isfinite(r)) throw std::invalid_argument("outlet: a cylinder's radius must be > 0");
    OutletRegion o;
    o.kind_ = Kind::Cylinder;
    o.p_ = p;
    o.r_ = r;
    if constexpr (D == 3) {
      const double an = a.norm();
      if (!(an > 0.0) || !std::isfinite(an)) throw std::invalid_argument("outlet: a cylinder's axis must be nonzero");
      if (!(L > 0.0) || !std::isfinite(L)) throw std::invalid_argument("outlet: a cylinder's length must be > 0");
      o.a_ = a / an;
      o.L_ = L;
    }
    return o;
  }

  Kind kind() const { return kind_; }

  std::string describe() const {
    switch (kind_) {
      case Kind::HalfSpace:
        return fmt::format("grains removed beyond the plane through ({}) with normal ({})", fmt::join(p_, ", "),
                           fmt::join(a_, ", "));
      case Kind::Box:
        return fmt::format("grains removed inside the box ({}) .. ({})", fmt::join(p_, ", "), fmt::join(q_, ", "));
      case Kind::Cylinder:
        if constexpr (D == 3)
          return fmt::format("grains removed inside the cylinder from ({}) along ({}), radius {}, length {}",
                             fmt::join(p_, ", "), fmt::join(a_, ", "), r_, L_);
        return fmt::format("grains removed inside the disk about ({}), radius {}", fmt::join(p_, ", "), r_);
    }
    return "";
  }

  // Whether the point x lies inside (every constraint < 0).
  bool inside(const Vec<D>& x) const {
    switch (kind_) {
      case Kind::HalfSpace:
        return (x - p_).dot(a_) < 0.0;
      case Kind::Box:
        for (int k = 0; k < D; ++k)
          if (!(x[k] > p_[k] && x[k] < q_[k])) return false;
        return true;
      case Kind::Cylinder: {
        const Vec<D> r = x - p_;
        if constexpr (D == 3) {
          const double z = r.dot(a_);
          if (!(z > 0.0 && z < L_)) return false;
          return (r - z * a_).squaredNorm() < r_ * r_;
        }
        return r.squaredNorm() < r_ * r_;
      }
    }
    return false;
  }

  // Whether the region meets the open box (lo, hi): a grain inside the box can reach it (for a
  // cylinder: its bounding box meets the box, a conservative answer).
  bool meets_box(const Vec<D>& lo, const Vec<D>& hi) const {
    switch (kind_) {
      case Kind::HalfSpace: {
        double m = 0.0;  // the least (x - p).n over the box
        for (int k = 0; k < D; ++k) m += a_[k] * ((a_[k] > 0.0 ? lo[k] : hi[k]) - p_[k]);
        return m < 0.0;
      }
      case Kind::Box:
        for (int k = 0; k < D; ++k)
          if (!(p_[k] < hi[k] && q_[k] > lo[k])) return false;
        return true;
      case Kind::Cylinder:
        for (int k = 0; k < D; ++k) {
          double a = p_[k] - r_, b = p_[k] + r_;
          if constexpr (D == 3) {
            const double e = r_ * std::sqrt(std::max(0.0, 1.0 - a_[k] * a_[k]));
            a = std::min(p_[k], p_[k] + L_ * a_[k]) - e;
            b = std::max(p_[k], p_[k] + L_ * a_[k]) + e;
          }
          if (!(a < hi[k] && b > lo[k])) return false;
        }
        return true;
    }
    return false;
  }

  // The earliest t in [0, limit) at which the centre of the flight x + v t + g t^2 / 2 is inside
  // (0 if it is inside now); infinity if it does not enter before limit.
  double entry_time(const Vec<D>& x, const Vec<D>& v, const Vec<D>& g, double limit) const {
    constexpr double inf = std::numeric_limits<double>::infinity();
    if (inside(x)) return 0.0;
    std::array<Poly, 2 * D + 1> c;
    int m = 0;
    const Flight<D> f(x, v, g, p_);
    switch (kind_) {
      case Kind::HalfSpace:
        c[m++] = f.along(a_);
        break;
      case Kind::Box:
        for (int k = 0; k < D; ++k) {
          Vec<D> e = Vec<D>::Zero();
          e[k] = 1.0;
          c[m++] = f.along(e) * -1.0;                       // lo_k - x_k (p_ = lo)
          c[m++] = f.along(e) - Poly{q_[k] - p_[k]};         // x_k - hi_k
        }
        break;
      case Kind::Cylinder:
        if constexpr (D == 3) {
          c[m++] = f.perp(a_).norm2() - Poly{r_ * r_};
          c[m++] = f.along(a_) * -1.0;
          c[m++] = f.along(a_) - Poly{L_};
        } else {
          c[m++] = f.norm2() - Poly{r_ * r_};
        }
        break;
    }
    // The times where some constraint changes sign, in (0, limit); beyond the largest root bound
    // (contact/poly.hpp) no constraint changes sign any more, so the search stops there (a search
    // over (0, 1e30) would lose a quartic's roots to round-off).
    double bound = 0.0;
    for (int k = 0; k < m; ++k) {
      c[k].trim();
      if (c[k].n > 0) bound = std::max(bound, root_bound(c[k]));
    }
    const double hi = std::min(limit, std::max(bound * 1.0000001, 1.0));
    if (!(hi > 0.0)) return inf;
    double cuts[(2 * D + 1) * Poly::kMax + 2];
    int n = 0;
    for (int k = 0; k < m; ++k) n += poly_detail::sign_changes(c[k], 0.0, hi, cuts + n);
    std::sort(cuts, cuts + n);
    double a = 0.0;
    for (int i = 0; i <= n; ++i) {
      const double b = i < n ? cuts[i] : hi;
      if (b > a) {
        const double mid = std::isfinite(b) ? 0.5 * (a + b) : a + 1.0;
        bool in = true;
        for (int k = 0; k < m && in; ++k) in = c[k](mid) < 0.0;
        if (in) return a < limit ? a : inf;
      }
      a = std::max(a, b);
    }
    return inf;
  }

 private:
  Kind kind_ = Kind::HalfSpace;
  Vec<D> p_ = Vec<D>::Zero(), q_ = Vec<D>::Zero(), a_ = Vec<D>::Zero();
  double r_ = 0.0, L_ = 0.0;
};

}  // namespace matep

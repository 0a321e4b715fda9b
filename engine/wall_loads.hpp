// The load the grains put on each wall: the force and the torque about the wall's anchor point
// (contact/wall.hpp anchor(): a plane's point, a drum's axis point), accumulated as impulses
// (EDM: m dv of each wall collision; soft contacts: F h per step) and reported as their means over
// each thermo interval. The torque of an impulse J applied at the contact point c is
// (c - anchor) x J (2D: the scalar (c - a)_x J_y - (c - a)_y J_x); on a drum its component
// along the axis times the angular velocity is the power the drive supplies.
#pragma once

#include <cstddef>
#include <vector>

#include <Eigen/Geometry>

#include "contact/vec.hpp"

namespace matep {

template <int D>
struct WallLoads {
  std::vector<Vec<D>> impulse;   // on each wall, since the last report
  std::vector<Spin<D>> angular;  // about each wall's anchor

  // Checkpoints (engine/state_archive.hpp).
  template <class A>
  void archive(A& a) {
    a.same(impulse, "walls");
    a.same(angular, "walls");
  }
  void resize(std::size_t walls) {
    impulse.assign(walls, Vec<D>::Zero());
    angular.assign(walls, Spin<D>::Zero());
  }
  // The wall w receives the impulse J at the point c (its anchor at a).
  void add(std::size_t w, const Vec<D>& a, const Vec<D>& c, const Vec<D>& J) {
    impulse[w] += J;
    const Vec<D> r = c - a;
    if constexpr (D == 2) {
      angular[w][0] += r[0] * J[1] - r[1] * J[0];
    } else {
      angular[w] += r.cross(J);
    }
  }
  void add(const WallLoads& o) {
    for (std::size_t w = 0; w < impulse.size(); ++w) {
      impulse[w] += o.impulse[w];
      angular[w] += o.angular[w];
    }
  }
  void clear() { resize(impulse.size()); }
  // Means over an interval of length dt, six numbers per wall (force x y z, torque x y z; 2D: z
  // force and x, y torque are zero), appended to out; then cleared.
  void report(double dt, std::vector<double>& out) {
    const double s = dt > 0.0 ? 1.0 / dt : 0.0;
    for (std::size_t w = 0; w < impulse.size(); ++w) {
      for (int k = 0; k < 3; ++k) out.push_back(k < D ? s * impulse[w][k] : 0.0);
      if constexpr (D == 2) {
        out.push_back(0.0);
        out.push_back(0.0);
        out.push_back(s * angular[w][0]);
      } else {
        for (int k = 0; k < 3; ++k) out.push_back(s * angular[w][k]);
      }
    }
    clear();
  }
};

}  // namespace matep

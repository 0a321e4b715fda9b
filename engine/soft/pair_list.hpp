// A half neighbour list in rows that can grow and shrink between rebuilds (the hybrid's soft set:
// rows are appended when particles join or wake, and entries leave when both ends fall asleep).
// Row r holds the entries off[r] .. off[r + 1] of particle owner[r]; an entry is the partner, the
// index of the periodic image shift (x_owner - x_partner + shift is their separation), the index of
// the contact constants, the touching flag and the tangential spring oriented for the owner (with
// Epsd rolling resistance, set_rolling(true), also the rolling spring torque).
// as_rows() hands it to the soft path's loop (engine/soft/forces.hpp).
#pragma once

#include <cstdint>
#include <vector>

#include "contact/vec.hpp"
#include "engine/soft/forces.hpp"

namespace matep::soft {

template <int D>
struct PairEntry {
  std::uint32_t i, j;  // owner, partner
  std::uint32_t c;     // contact constants
  std::uint8_t sh;     // image shift index
  std::uint8_t touch;
  Vec<D> xi;           // spring, oriented for i
  Spin<D> mr = Spin<D>::Zero();  // rolling spring torque on i (Epsd; else unused)
};

template <int D>
class PairList {
 public:
  std::vector<std::uint32_t> owner, off{0}, nb, c;
  std::vector<std::uint8_t> sh, touch;
  std::vector<Vec<D>> xi;
  std::vector<Spin<D>> mr;  // only with set_rolling(true)

  // Whether the entries carry rolling spring torques (call on an empty list).
  void set_rolling(bool on) { rolling_ = on; }

  void clear() {
    ++layout_;
    owner.clear();
    off.assign(1, 0);
    nb.clear();
    c.clear();
    sh.clear();
    touch.clear();
    xi.clear();
    mr.clear();
  }
  std::size_t rows() const { return owner.size(); }
  // Changes whenever rows are added or removed (a caller may keep what it derived from the rows,
  // such as the hybrid's thread owners, until then).
  std::uint64_t layout() const { return layout_; }
  std::size_t size() const { return nb.size(); }

  // Entries are added to the open row of `i` (a row with no entries is dropped by end_row).
  void begin_row(std::uint32_t i) { open_ = i; }
  void add(const PairEntry<D>& e) {
    nb.push_back(e.j);
    c.push_back(e.c);
    sh.push_back(e.sh);
    touch.push_back(e.touch);
    xi.push_back(e.xi);
    if (rolling_) mr.push_back(e.mr);
  }
  void end_row() {
    if (nb.size() == off.back()) return;
    ++layout_;
    owner.push_back(open_);
    off.push_back(static_cast<std::uint32_t>(nb.size()));
  }
  // A row of one entry.
  void push(const PairEntry<D>& e) {
    begin_row(e.i);
    add(e);
    end_row();
  }

  // Appends the rows of o (a list built apart, e.g. by another thread) after these.
  void append(const PairList& o) {
    ++layout_;
    const std::uint32_t base = static_cast<std::uint32_t>(nb.size());
    owner.insert(owner.end(), o.owner.begin(), o.owner.end());
    for (std::size_t r = 1; r < o.off.size(); ++r) off.push_back(base + o.off[r]);
    nb.insert(nb.end(), o.nb.begin(), o.nb.end());
    c.insert(c.end(), o.c.begin(), o.c.end());
    sh.insert(sh.end(), o.sh.begin(), o.sh.end());
    touch.insert(touch.end(), o.touch.begin(), o.touch.end());
    xi.insert(xi.end(), o.xi.begin(), o.xi.end());
    if (rolling_) mr.insert(mr.end(), o.mr.begin(), o.mr.end());
  }

  PairEntry<D> entry(std::size_t r, std::size_t e) const {
    return {owner[r], nb[e], c[e], sh[e], touch[e], xi[e], rolling_ ? mr[e] : Spin<D>(Spin<D>::Zero())};
  }

  // f(entry) for every entry, in row order.
  template <class F>
  void for_each(F&& f) const {
    for (std::size_t r = 0; r < rows(); ++r)
      for (std::size_t e = off[r]; e < off[r + 1]; ++e) f(entry(r, e));
  }
  // Keeps the entries for which keep(entry) is true, in order; rows left empty are dropped.
  template <class Keep>
  void filter(Keep&& keep) {
    ++layout_;
    std::size_t w = 0, rw = 0;
    std::size_t begin = 0;
    for (std::size_t r = 0; r < rows(); ++r) {
      const std::size_t end = off[r + 1];
      const std::size_t row_start = w;
      for (std::size_t e = begin; e < end; ++e) {
        if (!keep(entry(r, e))) continue;
        nb[w] = nb[e];
        c[w] = c[e];
        sh[w] = sh[e];
        touch[w] = touch[e];
        xi[w] = xi[e];
        if (rolling_) mr[w] = mr[e];
        ++w;
      }
      begin = end;
      if (w > row_start) {
        owner[rw] = owner[r];
        off[rw + 1] = static_cast<std::uint32_t>(w);
        ++rw;
      }
    }
    owner.resize(rw);
    off.resize(rw + 1);
    nb.resize(w);
    c.resize(w);
    sh.resize(w);
    touch.resize(w);
    xi.resize(w);
    if (rolling_) mr.resize(w);
  }

  PairRows<D> as_rows(const Vec<D>* shifts) {
    return PairRows<D>::of(owner.data(), off.data(), nb.data(), sh.data(), touch.data(), xi.data(), shifts,
                           rolling_ ? mr.data() : nullptr);
  }

  // Checkpoints (engine/state_archive.hpp).
  template <class A>
  void archive(A& a) {
    a(owner);
    a(off);
    a(nb);
    a(c);
    a(sh);
    a(touch);
    a(xi);
    a(mr);
    a(open_);
  }

 private:
  std::uint32_t open_ = 0;
  bool rolling_ = false;
  std::uint64_t layout_ = 0;
};

}  // namespace matep::soft

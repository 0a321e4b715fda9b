// The soft contacts' memory across list rebuilds (engine/soft/springs.hpp): every remembered
// contact is recalled with its own springs, oriented for the grain that asks, whatever the order
// they were remembered in; the rolling spring torques only where kept.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <random>
#include <vector>

#include "engine/soft/springs.hpp"

using namespace matep;

namespace {

struct Pair {
  std::uint32_t a, b, w;  // a pair (a, b), or a wall contact of a with wall slot w
  Vec<3> xi;
  Spin<3> mr;
};

std::vector<Pair> contacts(std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Pair> c;
  for (std::uint32_t a = 0; a < 40; ++a)
    for (std::uint32_t b = a + 1; b < a + 5; ++b)
      c.push_back({(a * 7 + b) % 3 == 0 ? b : a, (a * 7 + b) % 3 == 0 ? a : b, a % 4, Vec<3>(u(rng), u(rng), u(rng)),
                   Spin<3>(u(rng), u(rng), u(rng))});
  std::shuffle(c.begin(), c.end(), rng);
  return c;
}

}  // namespace

TEST(SpringMemory, EveryContactIsRecalledWithItsOwnSprings) {
  for (const bool rolling : {true, false}) {
    SCOPED_TRACE(rolling);
    soft::SpringMemory<3> mem;
    mem.set_rolling(rolling);
    const std::vector<Pair> c = contacts(3);
    mem.reserve(c.size(), c.size());
    for (const Pair& p : c) {
      mem.remember_pair(p.a, p.b, p.xi, p.mr);
      mem.remember_wall(p.a, p.w + 100 * p.b, p.xi, p.mr);
    }
    mem.sort();
    for (const Pair& p : c) {
      Vec<3> xi;
      Spin<3> mr;
      // Asked by either grain: the spring and torque oriented for the one that asks.
      ASSERT_TRUE(mem.recall_pair(p.a, p.b, xi, &mr));
      EXPECT_EQ(xi, p.xi);
      EXPECT_EQ(mr, rolling ? p.mr : Spin<3>(Spin<3>::Zero()));
      ASSERT_TRUE(mem.recall_pair(p.b, p.a, xi, &mr));
      EXPECT_EQ(xi, Vec<3>(-p.xi));
      EXPECT_EQ(mr, rolling ? Spin<3>(-p.mr) : Spin<3>(Spin<3>::Zero()));
      ASSERT_TRUE(mem.recall_wall(p.a, p.w + 100 * p.b, xi, &mr));
      EXPECT_EQ(xi, p.xi);
      EXPECT_EQ(mr, rolling ? p.mr : Spin<3>(Spin<3>::Zero()));
    }
    Vec<3> xi;
    EXPECT_FALSE(mem.recall_pair(0, 39, xi));  // never touching
    EXPECT_FALSE(mem.recall_wall(0, 3, xi));
    mem.release();
    EXPECT_TRUE(mem.empty());
  }
}

// Contacts as data (Snapshot::contacts, output.contacts) against closed forms:
//  - soft contacts (TDM, the hybrid's soft set): a column of disks at rest on a floor carries the
//    weight above each contact, (K - k) m g, normal to it, with no tangential part; a sphere
//    sliding on a floor feels the Coulomb force mu m g against the slip until it rolls at
//    t* = 2 v0 / (7 mu g) (a uniform sphere), and none once it rolls;
//  - hard collisions (EDM and the hybrid's hard grains): the mean forces over each interval times
//    its length are the impulses, which the change of momentum of every grain balances exactly
//    (impulse-momentum: m (v(t_b) - v(t_a)) = sum of impulses + m g (t_b - t_a)).
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <vector>

#include "engine/edm.hpp"
#include "engine/hybrid.hpp"
#include "engine/tdm.hpp"
#include "tests/support/systems.hpp"

using namespace matep;

namespace {

// Keeps every snapshot (with its contacts).
template <int D>
struct Frames : Observer<D> {
  std::vector<Snapshot<D>> s;
  bool wants_snapshots() const override { return true; }
  bool wants_contacts() const override { return true; }
  void on_snapshot(const Snapshot<D>& snap) override { s.push_back(snap); }
};

constexpr double kG = 9.81;

// K disks of radius R stacked on a floor at x = 0 (linear law, k = 1e5 N/m, e = 0.1, frictionless),
// each placed touching the one below; they settle into the static column.
System<2> disk_column(int K, double R) {
  System<2> s;
  s.lower = Vec<2>(-0.05, 0.0);
  s.upper = Vec<2>(0.05, 2.0 * R * K + 0.05);
  s.gravity = Vec<2>(0.0, -kG);
  s.materials = {test::linear_material("grain", 2500.0, 1e5, 0.1)};
  s.walls = {plane_wall<2>("floor", Vec<2>::Zero(), Vec<2>(0.0, 1.0))};
  for (int k = 0; k < K; ++k) {
    s.x.push_back(Vec<2>(0.0, R + 2.0 * R * k));
    s.v.push_back(Vec<2>::Zero());
    s.radius.push_back(R);
    s.material.push_back(0);
  }
  return s;
}

// The column's last frame: the floor carries K m g, the contact of disks k and k + 1 (ids in
// height order) pushes k down with the weight of the K - 1 - k disks above it.
void expect_static_column(const Snapshot<2>& last, int K, double m) {
  ASSERT_TRUE(last.with_contacts);
  ASSERT_EQ(last.contacts.size(), static_cast<std::size_t>(K));  // K - 1 pairs and the floor
  int pairs = 0, walls = 0;
  for (const ContactRow<2>& c : last.contacts) {
    EXPECT_EQ(c.kind, 1);
    EXPECT_GT(c.overlap, 0.0);
    EXPECT_EQ(c.ft.norm(), 0.0);  // frictionless
    EXPECT_EQ(c.fn[0], 0.0);
    if (c.wall >= 0) {
      ++walls;
      EXPECT_EQ(c.i, 0u);
      EXPECT_EQ(c.j, -1);
      EXPECT_NEAR(c.fn[1], K * m * kG, 1e-6 * K * m * kG);
      EXPECT_NEAR(c.point[1], 0.0, 1e-12);  // on the floor's surface
    } else {
      ++pairs;
      ASSERT_EQ(c.j, c.i + 1);
      const double above = (K - 1 - static_cast<int>(c.i)) * m * kG;
      EXPECT_NEAR(c.fn[1], -above, 1e-6 * K * m * kG) << c.i;
      // The point lies between the two centres.
      EXPECT_GT(c.point[1], last.x[c.i][1]);
      EXPECT_LT(c.point[1], last.x[c.i + 1][1]);
    }
  }
  EXPECT_EQ(walls, 1);
  EXPECT_EQ(pairs, K - 1);
}

}  // namespace

TEST(ContactOutput, TdmColumnCarriesTheWeightAboveEachContact) {
  const int K = 5;
  const double R = 0.005, m = 2500.0 * ball_volume<2>(R);
  TdmSettings set;
  set.end_time = 0.5;
  set.snapshot_interval = 0.25;
  set.threads = 1;
  Frames<2> f;
  const RunResult<2> r = run_tdm<2>(disk_column(K, R), set, {&f});
  ASSERT_EQ(r.status, "ok") << r.message;
  ASSERT_EQ(f.s.size(), 3u);
  expect_static_column(f.s.back(), K, m);
}

TEST(ContactOutput, HybridSoftColumnCarriesTheWeightAboveEachContact) {
  // Placed at its static overlaps, the column starts soft (grains overlapping at t = 0 do) and
  // stays at rest.
  const int K = 5;
  const double R = 0.005, m = 2500.0 * ball_volume<2>(R), k = 1e5;
  System<2> s = disk_column(K, R);
  double y = R - K * m * kG / k;
  for (int i = 0; i < K; ++i) {
    s.x[i][1] = y;
    y += 2.0 * R - (K - 1 - i) * m * kG / k;
  }
  EdmSettings edm;
  edm.end_time = 0.3;
  edm.snapshot_interval = 0.1;
  Frames<2> f;
  const RunResult<2> r = run_hybrid<2>(s, edm, HybridSettings{}, {&f});
  ASSERT_EQ(r.status, "ok") << r.message;
  ASSERT_GE(f.s.size(), 4u);
  for (const std::uint8_t mode : f.s.back().mode) EXPECT_EQ(mode, 1);
  expect_static_column(f.s.back(), K, m);
}

TEST(ContactOutput, TdmSlidingSphereFeelsCoulombFrictionUntilItRolls) {
  // A sphere (R = 5 mm, linear law, k = 1e5, mu = 0.3) resting on a floor at its static overlap and
  // sliding at v0 = 0.5 m/s without spin: friction -mu m g x until t* = 2 v0 / (7 mu g) = 48.5 ms.
  const double R = 0.005, mu = 0.3, v0 = 0.5, k = 1e5;
  System<3> s;
  s.lower = Vec<3>(-0.1, -0.05, -0.05);
  s.upper = Vec<3>(0.4, 0.05, 0.05);
  s.gravity = Vec<3>(0.0, 0.0, -kG);
  Material mat = test::linear_material("grain", 2500.0, k, 0.5);
  mat.friction = mu;
  s.materials = {mat};
  s.walls = {plane_wall<3>("floor", Vec<3>::Zero(), Vec<3>(0.0, 0.0, 1.0))};
  const double m = 2500.0 * ball_volume<3>(R);
  s.x = {Vec<3>(0.0, 0.0, R - m * kG / k)};
  s.v = {Vec<3>(v0, 0.0, 0.0)};
  s.w = {Spin<3>::Zero()};
  s.radius = {R};
  s.material = {0};
  TdmSettings set;
  set.end_time = 0.3;
  set.snapshot_interval = 0.01;
  set.threads = 1;
  Frames<3> f;
  const RunResult<3> r = run_tdm<3>(s, set, {&f});
  ASSERT_EQ(r.status, "ok") << r.message;
  const double t_roll = 2.0 * v0 / (7.0 * mu * kG);
  int sliding = 0, rolling = 0;
  for (const Snapshot<3>& snap : f.s) {
    ASSERT_EQ(snap.contacts.size(), 1u) << snap.time;
    const ContactRow<3>& c = snap.contacts[0];
    EXPECT_EQ(c.wall, 0);
    EXPECT_NEAR(c.fn[2], m * kG, 1e-3 * m * kG) << snap.time;
    if (snap.time > 0.0 && snap.time < 0.8 * t_roll) {  // sliding: the Coulomb force against the slip
      ++sliding;
      EXPECT_NEAR(c.ft[0], -mu * c.fn[2], 1e-9 * m * kG) << snap.time;
      EXPECT_NEAR(c.ft[1], 0.0, 1e-12);
      EXPECT_NEAR(c.point[0], snap.x[0][0], 1e-15);
    } else if (snap.time > 2.0 * t_roll) {  // rolling on a flat floor needs no force
      ++rolling;
      EXPECT_LT(c.ft.norm(), 0.05 * mu * m * kG) << snap.time;
    }
  }
  EXPECT_EQ(sliding, 3);
  EXPECT_GT(rolling, 15);
}

namespace {

// Impulse-momentum over every interval between two snapshots: for each grain present in both,
// m (v_b - v_a) - m g dt equals the sum of the kind-0 rows' mean forces times dt on it (+ as i,
// - as j). Returns the number of rows checked.
template <int D>
int check_impulses(const std::vector<Snapshot<D>>& s, const std::vector<double>& mass, const Vec<D>& g,
                   double scale) {
  int rows = 0;
  for (std::size_t k = 1; k < s.size(); ++k) {
    const double dt = s[k].time - s[k - 1].time;
    std::vector<Vec<D>> J(mass.size(), Vec<D>::Zero());
    for (const ContactRow<D>& c : s[k].contacts) {
      EXPECT_EQ(c.kind, 0);
      EXPECT_GT(c.collisions, 0u);
      const Vec<D> f = c.fn + c.ft;
      J[c.i] += f * dt;
      if (c.j >= 0) {
        EXPECT_LT(static_cast<std::int64_t>(c.i), c.j);
        J[static_cast<std::size_t>(c.j)] -= f * dt;
      }
      ++rows;
    }
    for (std::size_t i = 0; i < mass.size(); ++i) {
      const Vec<D> dp = mass[i] * (s[k].v[i] - s[k - 1].v[i]) - mass[i] * g * dt;
      EXPECT_LT((dp - J[i]).norm(), 1e-9 * scale) << "grain " << i << " interval " << k;
    }
  }
  return rows;
}

}  // namespace

TEST(ContactOutput, EdmImpulsesBalanceEachGrainsMomentum) {
  // A freely cooling gas (e = 0.8, 64 disks, periodic): pair rows only.
  System<2> s = test::lattice_gas<2>(8, 0.3, 1.0, 0.8, 7);
  EdmSettings set;
  set.end_time = 2.0;
  set.snapshot_interval = 0.5;
  Frames<2> f;
  const RunResult<2> r = run_edm<2>(s, set, QueueKind::Calendar, {&f});
  ASSERT_EQ(r.status, "ok") << r.message;
  ASSERT_EQ(f.s.size(), 5u);
  std::vector<double> mass(s.size(), 1.0);
  EXPECT_GT(check_impulses<2>(f.s, mass, Vec<2>::Zero(), 1.0), 50);
}

TEST(ContactOutput, BouncingBallImpulsesBalanceGravityInEdmAndTheHybrid) {
  // A ball (R = 1 cm) dropped from 0.5 m onto a floor, e = 0.8, snapshots every 0.1 s up to
  // t = 2 s (hard all along in the hybrid: its bounces are still long apart): the floor's impulse
  // in each interval is m (v_b - v_a) - m g dt, with the count of bounces of the closed form.
  for (const bool hybrid : {false, true}) {
    System<3> s;
    s.lower = Vec<3>(-0.1, -0.1, 0.0);
    s.upper = Vec<3>(0.1, 0.1, 1.0);
    s.gravity = Vec<3>(0.0, 0.0, -kG);
    s.materials = {test::linear_material("ball", 1000.0, 1e5, 0.8)};
    s.walls = {plane_wall<3>("floor", Vec<3>::Zero(), Vec<3>(0.0, 0.0, 1.0))};
    const double R = 0.01, h = 0.5, m = 1000.0 * ball_volume<3>(R);
    s.x = {Vec<3>(0.0, 0.0, R + h)};
    s.v = {Vec<3>::Zero()};
    s.radius = {R};
    s.material = {0};
    EdmSettings set;
    set.end_time = 2.0;
    set.snapshot_interval = 0.1;
    Frames<3> f;
    const RunResult<3> r = hybrid ? run_hybrid<3>(s, set, HybridSettings{}, {&f})
                                  : run_edm<3>(s, set, QueueKind::Calendar, {&f});
    ASSERT_EQ(r.status, "ok") << r.message;
    ASSERT_EQ(f.s.size(), 21u);
    EXPECT_EQ(check_impulses<3>(f.s, {m}, s.gravity, m * 10.0), 5);  // one bounce in each of 5 intervals
    // Bounce times: t1 = sqrt(2h/g), then intervals 2 e^k v1 / g.
    const double v1 = std::sqrt(2.0 * kG * h);
    std::vector<double> bounces{std::sqrt(2.0 * h / kG)};
    for (int k = 1; bounces.back() < 2.0; ++k) bounces.push_back(bounces.back() + 2.0 * std::pow(0.8, k) * v1 / kG);
    for (std::size_t k = 1; k < f.s.size(); ++k) {
      std::uint32_t expected = 0;
      for (const double tb : bounces) expected += tb > f.s[k - 1].time && tb <= f.s[k].time ? 1u : 0u;
      const std::uint32_t got = f.s[k].contacts.empty() ? 0u : f.s[k].contacts[0].collisions;
      EXPECT_EQ(got, expected) << (hybrid ? "hybrid" : "edm") << " interval ending " << f.s[k].time;
      for (const ContactRow<3>& c : f.s[k].contacts) {
        EXPECT_EQ(c.wall, 0);
        EXPECT_EQ(c.j, -1);
        EXPECT_NEAR(c.point[2], 0.0, 1e-9);
        EXPECT_NEAR(c.ft.norm(), 0.0, 1e-12 * c.fn.norm());
        EXPECT_GT(c.fn[2], 0.0);
      }
    }
  }
}

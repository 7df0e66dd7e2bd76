// The octree of the pipeline (src/index/octree.hpp) against brute force: the neighbourhood moments of
// a ball and the cylinder offsets. And its promise: the moments of a neighbourhood, and the order
// of a cylinder's offsets, depend only on the neighbours (and their relative input order), never
// on the other points the index holds, which is what makes tiled runs bit-identical.

#include "test_support.hpp"

#include "index/octree.hpp"

#include <algorithm>
#include <cstring>
#include <random>

namespace m3c2::test {
namespace {

using detail::Moments;
using detail::Octree;
using detail::OctreeGrid;
using detail::OctreeOptions;
using detail::OctreeScratch;

/// An index with the node moments that normals read.
const OctreeOptions kWithMoments{.node_moments = true};

/// Moments of the points of `cloud` within `radius` of `c`, two-pass in input order (the oracle).
Moments brute_moments(const Cloud& cloud, const Vec3& c, double radius) {
  std::vector<Vec3> in;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Vec3 d = cloud[i] - c;
    if (d.x() * d.x() + d.y() * d.y() + d.z() * d.z() <= radius * radius) in.push_back(d);
  }
  Moments m;
  m.count = double(in.size());
  if (in.empty()) return m;
  Vec3 mean = Vec3::Zero();
  for (const Vec3& v : in) mean += v;
  mean /= m.count;
  for (const Vec3& v0 : in) {
    const Vec3 v = v0 - mean;
    m.comoment[0] += v.x() * v.x(), m.comoment[1] += v.x() * v.y(), m.comoment[2] += v.x() * v.z();
    m.comoment[3] += v.y() * v.y(), m.comoment[4] += v.y() * v.z(), m.comoment[5] += v.z() * v.z();
  }
  return m;
}

bool same_bits(const Moments& a, const Moments& b) {
  return a.count == b.count && std::memcmp(a.comoment.data(), b.comoment.data(), sizeof(a.comoment)) == 0;
}

/// A rough surface with duplicates and a dense cluster, shifted to UTM-sized coordinates.
Cloud test_cloud(std::uint64_t seed, std::size_t n, const Vec3& offset) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 6.0), noise(-0.02, 0.02);
  Cloud c;
  for (std::size_t i = 0; i < n; ++i) {
    const double x = u(rng), y = u(rng);
    c.add(Vec3(x, y, 0.3 * std::sin(x) * std::cos(1.3 * y) + noise(rng)) + offset);
    if (i % 97 == 0) c.add(c[c.size() - 1]);                                    // an exact duplicate
    if (i % 211 == 0) c.add(Vec3(3.0 + 1e-4 * noise(rng), 3.0, 0.1) + offset);  // a tight cluster
  }
  return c;
}

void expect_moments_match_brute_force(const Vec3& offset) {
  const Cloud cloud = test_cloud(7, 20000, offset);
  const std::vector<double> radii = {0.15, 0.4, 0.75};
  const OctreeGrid grid = detail::octree_grid(0.3, 1.5);
  const Octree tree(cloud.view(), grid, kWithMoments);
  OctreeScratch scratch;
  std::vector<Moments> out;
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(0.0, 6.0);
  for (int q = 0; q < 150; ++q) {
    const Vec3 core = q % 10 == 0 ? cloud[std::size_t(q) * 37] : Vec3(u(rng), u(rng), 0.0) + offset;
    tree.ball_moments(core, radii, scratch, out);
    for (std::size_t k = 0; k < radii.size(); ++k) {
      const Moments want = brute_moments(cloud, core, radii[k]);
      ASSERT_EQ(out[k].count, want.count) << "query " << q << " radius " << radii[k];
      const double scale = want.comoment[0] + want.comoment[3] + want.comoment[5];
      for (int j = 0; j < 6; ++j) EXPECT_NEAR(out[k].comoment[j], want.comoment[j], 1e-11 * scale + 1e-300) << q;
    }
  }
}

TEST(Octree, BallMomentsMatchBruteForce) { expect_moments_match_brute_force(Vec3::Zero()); }

TEST(Octree, BallMomentsMatchBruteForceAtUtmCoordinates) {
  expect_moments_match_brute_force(Vec3(512345.25, 5412345.75, 812.5));
}

TEST(Octree, InclusiveSphereBoundaryOnQuantisedPoints) {
  // Coordinates on a 1/8 grid: many points lie exactly at distance r, and must be counted.
  Cloud cloud;
  for (int i = 0; i <= 32; ++i)
    for (int j = 0; j <= 32; ++j) cloud.add(0.125 * i, 0.125 * j, 0.125 * ((i * j) % 3));
  const Octree tree(cloud.view(), detail::octree_grid(0.5, 1.0), kWithMoments);
  OctreeScratch scratch;
  std::vector<Moments> out;
  for (const Vec3& c : {Vec3(2.0, 2.0, 0.0), Vec3(1.5, 2.25, 0.125), Vec3(0.0, 0.0, 0.0)}) {
    const std::vector<double> radii = {0.25, 0.5};
    tree.ball_moments(c, radii, scratch, out);
    for (std::size_t k = 0; k < 2; ++k) EXPECT_EQ(out[k].count, brute_moments(cloud, c, radii[k]).count);
  }
}

TEST(Octree, MomentsAddedAfterTheBuildAreTheBuildsBits) {
  // compute() builds two indexes side by side without moments, then adds them on every thread.
  const Cloud cloud = test_cloud(5, 30000, Vec3(600000.0, 4200000.0, 50.0));
  const std::vector<double> radii = {0.2, 0.5, 1.5};
  const OctreeGrid grid = detail::octree_grid(0.4, 3.0);
  const Octree built(cloud.view(), grid, kWithMoments);
  for (const int threads : {1, 2}) {
    Octree added(cloud.view(), grid);
    added.add_moments(threads);
    added.add_moments(threads);  // a second call changes nothing
    OctreeScratch scratch;
    std::vector<Moments> a, b;
    for (int q = 0; q < 200; ++q) {
      const Vec3 core = cloud[std::size_t(q) * 149 % cloud.size()] + Vec3(0.01, -0.02, 0.0);
      built.ball_moments(core, radii, scratch, a);
      added.ball_moments(core, radii, scratch, b);
      for (std::size_t k = 0; k < radii.size(); ++k) {
        ASSERT_GT(a[k].count, 0.0);
        EXPECT_TRUE(same_bits(a[k], b[k])) << threads << " threads, query " << q << " radius " << radii[k];
      }
    }
  }
}

/// The index of a tile holds the neighbours of its core points plus an arbitrary subset of the
/// rest, in the same relative order: the moments must be the same bits. Trials alternate between
/// keeping 60 %, 5 % and none of the other points (the last: the neighbours' own index, whose
/// queries start at its root, while the whole cloud's start deep inside the tree).
void expect_moments_independent_of_other_points(const Vec3& offset) {
  const Cloud cloud = test_cloud(3, 30000, offset);
  const std::vector<double> radii = {0.2, 0.5};
  const OctreeGrid grid = detail::octree_grid(0.4, 1.0);
  const Octree whole(cloud.view(), grid, kWithMoments);
  std::mt19937_64 rng(5);
  OctreeScratch scratch;
  std::vector<Moments> a, b;
  for (int trial = 0; trial < 60; ++trial) {
    const Vec3 core = cloud[std::size_t(trial) * 701 % cloud.size()] + Vec3(0.01, -0.02, 0.0);
    std::bernoulli_distribution keep(trial % 3 == 0 ? 0.6 : trial % 3 == 1 ? 0.05 : 0.0);
    Cloud part;
    for (std::size_t i = 0; i < cloud.size(); ++i)
      if ((cloud[i] - core).norm() <= 0.5 + 1e-9 || keep(rng)) part.add(cloud[i]);
    const Octree tile(part.view(), grid, kWithMoments);
    whole.ball_moments(core, radii, scratch, a);
    tile.ball_moments(core, radii, scratch, b);
    for (std::size_t k = 0; k < radii.size(); ++k) {
      EXPECT_GT(a[k].count, 0.0);
      EXPECT_TRUE(same_bits(a[k], b[k])) << "trial " << trial << " radius " << radii[k];
    }
  }
}

TEST(Octree, NeighbourhoodMomentsDoNotDependOnTheOtherPoints) {
  expect_moments_independent_of_other_points(Vec3(600000.0, 4200000.0, 50.0));
}

TEST(Octree, NeighbourhoodMomentsDoNotDependOnTheOtherPointsAcrossBlocks) {
  // Blocks are 1024 m wide here (1024 diameters of 1, a power of two): the cloud straddles the
  // boundary at x = 1024 * 586, so nodes span blocks and move their children's moments.
  expect_moments_independent_of_other_points(Vec3(1024.0 * 586 - 3.0, 4200000.0, 50.0));
}

TEST(Octree, NeighbourhoodMomentsDoNotDependOnTheOtherPointsAroundTheOrigin) {
  // A cloud around the grid's origin varies in every key bit (its index sorts 128-bit keys
  // split at the origin), a tile of neighbours on one side of it in a few (64-bit keys).
  expect_moments_independent_of_other_points(Vec3(-3.0, -3.0, 0.0));
}

TEST(Octree, EachScaleOfAMultiScaleQueryEqualsItsSingleScaleQuery) {
  const Cloud cloud = test_cloud(9, 20000, Vec3(1000.0, 2000.0, 0.0));
  const OctreeGrid grid = detail::octree_grid(0.2, 1.6);
  const Octree tree(cloud.view(), grid, kWithMoments);
  const std::vector<double> radii = {0.1, 0.25, 0.4, 0.8};
  OctreeScratch scratch;
  std::vector<Moments> all, one;
  for (int q = 0; q < 60; ++q) {
    const Vec3 core = cloud[std::size_t(q) * 301];
    tree.ball_moments(core, radii, scratch, all);
    for (std::size_t k = 0; k < radii.size(); ++k) {
      tree.ball_moments(core, std::span<const double>(&radii[k], 1), scratch, one);
      EXPECT_TRUE(same_bits(all[k], one[0])) << q << " " << k;
    }
  }
}

TEST(Octree, CylinderOffsetsMatchBruteForceAndKeepTheirOrderInASubset) {
  const Cloud cloud = test_cloud(13, 30000, Vec3(300000.0, 5000000.0, 100.0));
  const OctreeGrid grid = detail::octree_grid(0.3, 0.0);
  const Octree whole(cloud.view(), grid);
  std::mt19937_64 rng(17);
  std::vector<double> t_whole, t_tile;
  for (int q = 0; q < 40; ++q) {
    const Vec3 core = cloud[std::size_t(q) * 577 % cloud.size()];
    const Vec3 n = Vec3(0.3 * std::sin(q), 0.2 * std::cos(q), 1.0).normalized();
    const detail::Cylinder cyl{core, n, 0.15, -0.6, 0.6};
    whole.cylinder(cyl, t_whole);
    EXPECT_EQ(t_whole.size(), brute_cylinder_count(cloud, core, n, 0.15, -0.6, 0.6)) << q;
    std::bernoulli_distribution keep(0.3);
    Cloud part;
    for (std::size_t i = 0; i < cloud.size(); ++i)
      if ((cloud[i] - core).norm() <= 0.7 || keep(rng)) part.add(cloud[i]);
    const Octree tile(part.view(), grid);
    tile.cylinder(cyl, t_tile);
    EXPECT_EQ(t_whole, t_tile) << q;  // the same values in the same order
  }
}

TEST(Octree, RejectsCoordinatesBeyondTheGridRange) {
  Cloud cloud;
  cloud.add(0.0, 0.0, 0.0);
  cloud.add(1e12, 0.0, 0.0);
  EXPECT_THROW(Octree(cloud.view(), detail::octree_grid(0.01, 0.01)), InvalidArgument);
}

TEST(Octree, ComputeRefusesAFarOutlierNamingTheCloud) {
  Cloud ref = test_cloud(1, 500, Vec3::Zero()), cmp = ref;
  cmp.add(0.0, 8e10, 0.0);  // beyond 2^40 cells of 2^-5 = 2^35 (D = 0.5)
  Params p;
  p.normal_diameters = {0.5};
  p.projection_diameter = 0.3;
  p.max_depth = 0.5;
  EXPECT_EQ(max_abs_coordinate(p), std::ldexp(1.0, 35));
  try {
    compute(ref.view(), cmp.view(), ref.view(), p);
    FAIL() << "no error";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("the compared cloud has a coordinate"), std::string::npos) << e.what();
  }
}

TEST(Octree, GridIsAPowerOfTwoFromTheScalesAlone) {
  const OctreeGrid g = detail::octree_grid(1.0, 2.5);
  EXPECT_EQ(g.cell, 1.0 / 16.0);  // the largest power of two <= 1/16
  EXPECT_EQ(detail::octree_grid(0.9, 2.5).cell, 1.0 / 32.0);
  EXPECT_GE(std::ldexp(g.cell, g.block_level), 2.5);
  EXPECT_GE(std::ldexp(g.cell, g.block_level), 1024 * 2.5);  // blocks: 1024 diameters at least
  EXPECT_LT(std::ldexp(g.cell, g.block_level - 1), 1024 * 2.5);
}

// Octree's order_in_place: while the index lives, row s of the cloud's array is the point of
// original index original_index(s); destroyed, it leaves the array as it found it.
TEST(Octree, OrderedInPlaceHoldsTheSlotsRowsAndPutsThemBack) {
  std::mt19937_64 rng(31);
  std::uniform_real_distribution<double> u(-5.0, 5.0);
  std::vector<double> original(3 * 5000);
  for (double& x : original) x = u(rng);
  std::vector<double> own = original;
  const OctreeGrid grid = detail::octree_grid(0.2, 0.4);
  {
    const Octree copied(PointsView(original.data(), 5000), grid, kWithMoments);
    const Octree ordered(PointsView(own.data(), 5000), grid, {.node_moments = true, .order_cloud_in_place = true});
    ASSERT_EQ(ordered.size(), 5000u);
    bool moved = false;
    for (std::size_t s = 0; s < 5000; ++s) {
      const std::uint32_t i = ordered.original_index(s);
      ASSERT_EQ(i, copied.original_index(s));
      ASSERT_EQ(std::memcmp(&own[3 * s], &original[3 * i], 3 * sizeof(double)), 0) << "slot " << s;
      moved |= i != s;
    }
    EXPECT_TRUE(moved);  // non-vacuity: the key order is not the input order
  }
  EXPECT_EQ(std::memcmp(own.data(), original.data(), own.size() * sizeof(double)), 0);
}

}  // namespace
}  // namespace m3c2::test

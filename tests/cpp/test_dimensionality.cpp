// Multi-scale dimensionality (Brodu & Lague 2012): the octree's features against a brute-force
// eigen-decomposition of each neighbourhood, the analytic 1D / 2D / 3D vertices, CANUPO's rule for
// scales with too few points, and the same bits for any thread count and any tile.

#include "test_support.hpp"

#include "index/distance.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>

namespace m3c2::test {
namespace {

/// Brute force: the neighbours within D/2 (the engine's squared_distance test), their covariance
/// about their mean in long double, Eigen's solver, the proportions descending.
std::array<double, 3> brute_proportions(const Cloud& cloud, const Vec3& core, double diameter, std::uint32_t* count) {
  const double r2 = 0.25 * diameter * diameter;
  std::vector<Vec3> kept;
  for (std::size_t j = 0; j < cloud.size(); ++j)
    if (detail::squared_distance(&cloud.xyz[3 * j], core) <= r2) kept.push_back(cloud[j]);
  *count = std::uint32_t(kept.size());
  long double mean[3] = {0, 0, 0};
  for (const auto& v : kept)
    for (int a = 0; a < 3; ++a) mean[a] += v(a);
  for (auto& m : mean) m /= (long double)kept.size();
  long double c[3][3] = {};
  for (const auto& v : kept)
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) c[a][b] += (v(a) - mean[a]) * (v(b) - mean[b]);
  Eigen::Matrix3d m;
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b) m(a, b) = double(c[a][b]);
  const Eigen::Vector3d e = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(m).eigenvalues().cwiseMax(0.0);
  return {e(2) / e.sum(), e(1) / e.sum(), e(0) / e.sum()};
}

/// A scene of the three dimensionalities: a rough plane, a line of points and a volume blob,
/// shifted to UTM-sized coordinates (the moments must not lose the offset's digits).
Cloud mixed_scene(const Vec3& offset) {
  std::mt19937_64 rng(18);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> g(0.0, 1.0);
  Cloud cloud;
  for (int i = 0; i < 3000; ++i) cloud.add(offset + Vec3(4 * u(rng), 4 * u(rng), 0.02 * g(rng)));
  for (int i = 0; i < 300; ++i) cloud.add(offset + Vec3(1 + 2 * u(rng), 2 + 0.01 * g(rng), 0.5 + 0.01 * g(rng)));
  for (int i = 0; i < 1500; ++i) cloud.add(offset + Vec3(3 + 0.4 * g(rng), 3 + 0.4 * g(rng), 1 + 0.4 * g(rng)));
  return cloud;
}

TEST(Dimensionality, EqualsBruteForceEigenvaluesAtUtmCoordinates) {
  const Vec3 offset(512345.0, 5123456.0, 250.0);
  const Cloud cloud = mixed_scene(offset);
  const Cloud cores = cloud.every_nth(17);
  const std::vector<double> diameters = {0.6, 0.2, 1.5};  // not sorted: outputs follow this order
  const DimensionalityResult r = dimensionality(cloud.view(), cores.view(), diameters, 3);
  ASSERT_EQ(r.size(), cores.size());
  std::size_t compared = 0;
  for (std::size_t i = 0; i < cores.size(); ++i) {
    ASSERT_EQ(r.status[i], PointStatus::kOk) << i;  // every core point is a point of its cloud
    for (std::size_t k = 0; k < diameters.size(); ++k) {
      std::uint32_t n = 0;
      const auto p = brute_proportions(cloud, cores[i], diameters[k], &n);
      ASSERT_EQ(r.count[i * 3 + k], n) << i << " " << k;
      if (n < 3) continue;  // filled from a larger scale: tested below
      ++compared;
      const double* got = &r.proportions[(i * 3 + k) * 3];
      const double* abc = &r.barycentric[(i * 3 + k) * 3];
      for (int j = 0; j < 3; ++j) EXPECT_NEAR(got[j], p[j], 1e-9) << i << " " << k << " " << j;
      EXPECT_NEAR(abc[0], p[0] - p[1], 1e-9);
      EXPECT_NEAR(abc[1], 2 * (p[1] - p[2]), 1e-9);
      EXPECT_NEAR(abc[2], 3 * p[2], 1e-9);
      EXPECT_NEAR(abc[0] + abc[1] + abc[2], 1.0, 1e-12);
    }
  }
  EXPECT_GT(compared, 3 * cores.size() * 9 / 10);
}

TEST(Dimensionality, TightClusterFarFromTheCorePointEqualsBruteForce) {
  // The shells' sums are taken about each shell's first point (dimensionality.cpp): two tight
  // clusters (1e-4 and 1e-5 wide, one flat, one linear) 0.9 and 0.36 from a core point that is
  // not a cloud point, at UTM-sized coordinates, where sums about the core point lose ~8 digits
  // (this test fails with them).
  const Vec3 offset(512345.0, 5123456.0, 250.0);
  std::mt19937_64 rng(7);
  std::normal_distribution<double> g(0.0, 1.0);
  Cloud cloud;
  for (int i = 0; i < 400; ++i) cloud.add(offset + Vec3(0.9 + 1e-4 * g(rng), 1e-4 * g(rng), 1e-6 * g(rng)));
  for (int i = 0; i < 100; ++i) cloud.add(offset + Vec3(0.2 + 1e-5 * g(rng), 0.3 + 3e-5 * g(rng), 2e-6 * g(rng)));
  Cloud core;
  core.add(offset);
  const std::vector<double> diameters = {0.8, 2.0};
  const DimensionalityResult r = dimensionality(cloud.view(), core.view(), diameters, 3);
  ASSERT_EQ(r.status[0], PointStatus::kOk);
  for (std::size_t k = 0; k < diameters.size(); ++k) {
    std::uint32_t n = 0;
    const auto p = brute_proportions(cloud, core[0], diameters[k], &n);
    ASSERT_EQ(r.count[k], n);
    for (int j = 0; j < 3; ++j) EXPECT_NEAR(r.proportions[k * 3 + j], p[j], 1e-9) << k << " " << j;
  }
  EXPECT_GT(r.proportions[2 * 0 + 2], 0.0);  // the flat cluster keeps its small third share
}

TEST(Dimensionality, LatticeLinePlaneAndVolumeAreTheTriangleVertices) {
  // Centred on a lattice point, a ball of a line, square or cubic lattice has the lattice's
  // symmetry: one, two equal or three equal eigenvalues, so (a, b, c) is (1,0,0), (0,1,0), (0,0,1).
  Cloud line, plane, volume;
  for (int i = -10; i <= 10; ++i) {
    line.add(i * 0.1, 0, 0);
    for (int j = -10; j <= 10; ++j) {
      plane.add(i * 0.1, j * 0.1, 0);
      for (int k = -10; k <= 10; ++k) volume.add(i * 0.1, j * 0.1, k * 0.1);
    }
  }
  Cloud core;
  core.add(0, 0, 0);
  const std::vector<double> diameters = {1.0, 1.9};
  const Cloud* clouds[3] = {&line, &plane, &volume};
  for (int dim = 0; dim < 3; ++dim) {
    const DimensionalityResult r = dimensionality(clouds[dim]->view(), core.view(), diameters);
    ASSERT_EQ(r.status[0], PointStatus::kOk);
    for (std::size_t k = 0; k < 2; ++k)
      for (int j = 0; j < 3; ++j) EXPECT_NEAR(r.barycentric[k * 3 + j], j == dim ? 1.0 : 0.0, 1e-12) << dim << k << j;
  }
}

TEST(Dimensionality, ScaleWithTooFewPointsTakesTheNextLargerScale) {
  // A sparse line (spacing 1) and a dense blob far from it: at the core point on the line, the
  // 0.5 scale holds only the point itself, the 1.5 scale 1 point too, the 10 scale a line of 9.
  Cloud cloud;
  for (int i = -4; i <= 4; ++i) cloud.add(i, 0, 0);
  Cloud core;
  core.add(0, 0, 0);
  core.add(100, 100, 100);  // nothing within any scale
  const DimensionalityResult r = dimensionality(cloud.view(), core.view(), {0.5, 10.0, 1.5}, 3);
  EXPECT_EQ(r.count[0], 1u);
  EXPECT_EQ(r.count[1], 9u);
  EXPECT_EQ(r.count[2], 1u);
  ASSERT_EQ(r.status[0], PointStatus::kOk);
  for (int j = 0; j < 3; ++j) {
    EXPECT_EQ(r.barycentric[0 * 3 + j], r.barycentric[1 * 3 + j]);
    EXPECT_EQ(r.barycentric[2 * 3 + j], r.barycentric[1 * 3 + j]);
  }
  EXPECT_NEAR(r.barycentric[3], 1.0, 1e-12);  // a line
  EXPECT_EQ(r.status[1], PointStatus::kTooFewNormalPoints);
  for (std::size_t q = 9; q < 18; ++q) EXPECT_TRUE(std::isnan(r.proportions[q]) && std::isnan(r.barycentric[q]));
  EXPECT_EQ(r.count[3], 0u);
}

TEST(Dimensionality, CoincidentPointsAreDegenerate) {
  Cloud cloud;
  for (int i = 0; i < 10; ++i) cloud.add(1, 2, 3);
  Cloud core;
  core.add(1, 2, 3);
  const DimensionalityResult r = dimensionality(cloud.view(), core.view(), {1.0});
  EXPECT_EQ(r.status[0], PointStatus::kDegenerateNormal);
  EXPECT_EQ(r.count[0], 10u);
  EXPECT_TRUE(std::isnan(r.proportions[0]));
}

TEST(Dimensionality, SameBitsForAnyThreadCountAndTile) {
  const Cloud cloud = mixed_scene(Vec3(300000.0, 4000000.0, 0.0));
  const Cloud cores = cloud.every_nth(7);
  const std::vector<double> diameters = {0.3, 0.8, 0.1, 1.2};
  RunOptions one, two;
  one.threads = 1;
  two.threads = 2;
  const DimensionalityResult a = dimensionality(cloud.view(), cores.view(), diameters, 3, one);
  const DimensionalityResult b = dimensionality(cloud.view(), cores.view(), diameters, 3, two);
  EXPECT_TRUE(BitIdentical(a.proportions, b.proportions));
  EXPECT_TRUE(BitIdentical(a.barycentric, b.barycentric));
  EXPECT_EQ(a.count, b.count);
  // A tile: the core points with x below the middle, the cloud points within the largest radius
  // of the tile's core points (its halo), in their relative input order (the octree's sums are a
  // function of the neighbour set and that order: octree.hpp; tiles keep it).
  const double mid = 300002.0;
  Cloud tile_cores, tile;
  std::vector<std::size_t> kept_cores;
  for (std::size_t i = 0; i < cores.size(); ++i)
    if (cores[i].x() < mid) tile_cores.add(cores[i]), kept_cores.push_back(i);
  std::vector<std::size_t> idx;
  for (std::size_t j = 0; j < cloud.size(); ++j)
    if (cloud[j].x() < mid + 0.6 + 1e-6) idx.push_back(j);
  for (const std::size_t j : idx) tile.add(cloud[j]);
  const DimensionalityResult t = dimensionality(tile.view(), tile_cores.view(), diameters, 3, two);
  std::size_t differing = 0;
  for (std::size_t q = 0; q < kept_cores.size(); ++q) {
    const std::size_t i = kept_cores[q];
    for (std::size_t v = 0; v < 12; ++v) {
      const double x = a.barycentric[i * 12 + v], y = t.barycentric[q * 12 + v];
      differing += std::memcmp(&x, &y, sizeof x) != 0;
    }
  }
  EXPECT_EQ(differing, 0u);
}

TEST(Dimensionality, BadInputsAreRefusedByName) {
  Cloud cloud;
  for (int i = 0; i < 5; ++i) cloud.add(i, 0, 0);
  EXPECT_THROW(dimensionality(cloud.view(), cloud.view(), {}), InvalidArgument);
  EXPECT_THROW(dimensionality(cloud.view(), cloud.view(), {1.0, 1.0}), InvalidArgument);
  EXPECT_THROW(dimensionality(cloud.view(), cloud.view(), {-1.0}), InvalidArgument);
  EXPECT_THROW(dimensionality(cloud.view(), cloud.view(), {1.0}, 2), InvalidArgument);
  EXPECT_THROW(dimensionality(Cloud().view(), cloud.view(), {1.0}), InvalidArgument);
}

}  // namespace
}  // namespace m3c2::test

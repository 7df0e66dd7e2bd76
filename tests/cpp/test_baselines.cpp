// C2C and C2C_HF baselines (section 3.4): exact nearest neighbour against brute force, the
// least-squares plane model against a direct PCA, determinism across thread counts.

#include "test_support.hpp"

#include <m3c2/baselines.hpp>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <numeric>

namespace m3c2::test {
namespace {

std::pair<std::uint64_t, double> brute_nearest(const Cloud& ref, const Vec3& q) {
  std::pair<double, std::uint64_t> best{std::numeric_limits<double>::infinity(), 0};
  for (std::size_t j = 0; j < ref.size(); ++j) {
    const Vec3 p = ref[j];
    const double dx = p.x() - q.x(), dy = p.y() - q.y(), dz = p.z() - q.z();
    best = std::min(best, {dx * dx + dy * dy + dz * dz, j});
  }
  return {best.second, std::sqrt(best.first)};
}

double brute_plane_distance(const Cloud& ref, std::uint64_t p, const Vec3& q, std::size_t k) {
  std::vector<std::pair<double, std::uint64_t>> ranked;
  for (std::size_t j = 0; j < ref.size(); ++j) ranked.emplace_back((ref[j] - ref[p]).squaredNorm(), j);
  std::sort(ranked.begin(), ranked.end());
  Vec3 mean = Vec3::Zero();
  for (std::size_t j = 0; j < k; ++j) mean += ref[ranked[j].second];
  mean /= double(k);
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (std::size_t j = 0; j < k; ++j) {
    const Vec3 v = ref[ranked[j].second] - mean;
    cov += v * v.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> s(cov);
  return std::abs((q - mean).dot(s.eigenvectors().col(0)));
}

TEST(Baselines, NearestMatchesBruteForceOnRandomClouds) {
  const Cloud ref = random_box(11, 3000, {0, 0, 0}, {10, 10, 1});
  Cloud cmp = random_box(12, 800, {-2, -2, -1}, {12, 12, 3});
  cmp.add(50, 50, 50);  // far outside: the ball must grow a long way
  cmp.add(ref[17]);     // exactly on a reference point: distance 0
  std::vector<std::uint64_t> idx;
  std::vector<double> dist;
  nearest_neighbours(ref.view(), cmp.view(), idx, dist, with_threads(3));
  for (std::size_t i = 0; i < cmp.size(); ++i) {
    const auto [j, d] = brute_nearest(ref, cmp[i]);
    ASSERT_EQ(idx[i], j) << "query " << i;
    ASSERT_EQ(dist[i], d) << "query " << i;
  }
  EXPECT_EQ(dist[cmp.size() - 1], 0.0);
}

TEST(Baselines, TiesGoToTheLowestIndex) {
  // A binary grid: a query at the centre of a cell is equidistant from 4 points.
  const Cloud ref = plane_grid({0, 0, 0}, {0, 0, 1}, 10, 0.5);
  Cloud cmp;
  for (int i = -8; i < 8; ++i) cmp.add(0.25 + 0.5 * i, 0.25 - 0.5 * i, 0.0);
  const C2CResult r = c2c(ref.view(), cmp.view());
  for (std::size_t i = 0; i < cmp.size(); ++i) {
    const auto [j, d] = brute_nearest(ref, cmp[i]);
    EXPECT_EQ(r.nearest[i], j);
    EXPECT_EQ(r.distance[i], d);
    EXPECT_EQ(r.hf_distance[i], d);  // no model: C2C_HF is C2C
    EXPECT_TRUE(std::isnan(r.model_distance[i]));
  }
}

TEST(Baselines, UtmCoordinatesLoseNothing) {
  const Cloud local = random_box(5, 2000, {0, 0, 0}, {20, 20, 2});
  const Cloud query = random_box(6, 300, {0, 0, -1}, {20, 20, 3});
  const Vec3 shift{512345.0, 5123456.0, 0.0};
  const C2CResult a = c2c(local.view(), query.view());
  const Cloud ref_utm = local.translated(shift), query_utm = query.translated(shift);
  const C2CResult b = c2c(ref_utm.view(), query_utm.view());
  for (std::size_t i = 0; i < query.size(); ++i) {
    EXPECT_EQ(a.nearest[i], b.nearest[i]);
    EXPECT_NEAR(a.distance[i], b.distance[i], 1e-9);
  }
}

TEST(Baselines, PlaneModelMatchesDirectPca) {
  std::mt19937_64 rng(7);
  std::normal_distribution<double> noise(0.0, 0.01);
  Cloud ref = height_grid(0, 0, 40, 40, 0.1, [&](double x, double y) { return 0.2 * x - 0.1 * y + noise(rng); });
  const Cloud cmp = random_box(8, 200, {0.5, 0.5, -0.5}, {3.4, 3.4, 1.0});
  C2CParams p;
  p.model = LocalModel::kPlane;
  p.model_neighbours = 12;
  p.rule = ModelRule::kModelOnly;
  const C2CResult r = c2c(ref.view(), cmp.view(), p, with_threads(2));
  for (std::size_t i = 0; i < cmp.size(); ++i) {
    const auto [j, d] = brute_nearest(ref, cmp[i]);
    ASSERT_EQ(r.nearest[i], j);
    EXPECT_EQ(r.model_count[i], 12u);
    EXPECT_NEAR(r.model_distance[i], brute_plane_distance(ref, j, cmp[i], 12), 1e-10);
    EXPECT_EQ(r.hf_distance[i], r.model_distance[i]);
  }
  p.rule = ModelRule::kCloser;
  const C2CResult closer = c2c(ref.view(), cmp.view(), p);
  for (std::size_t i = 0; i < cmp.size(); ++i)
    EXPECT_EQ(closer.hf_distance[i], std::min(closer.distance[i], closer.model_distance[i]));
}

TEST(Baselines, PlaneModelRecoversAShiftBetweenGrids) {
  // Two offset grids of the same plane z = 0, the compared one raised by 0.3: the closest point is
  // sqrt(0.3^2 + offset^2) away, the plane model gives 0.3 exactly.
  const Cloud ref = plane_grid({0, 0, 0}, {0, 0, 1}, 15, 1.0);
  const Cloud cmp = plane_grid({0.5, 0.5, 0.3}, {0, 0, 1}, 10, 1.0);
  C2CParams p;
  p.model = LocalModel::kPlane;
  p.model_radius = 1.5;
  const C2CResult r = c2c(ref.view(), cmp.view(), p);
  for (std::size_t i = 0; i < cmp.size(); ++i) {
    EXPECT_NEAR(r.distance[i], std::sqrt(0.09 + 0.5), 1e-12);
    EXPECT_NEAR(r.model_distance[i], 0.3, 1e-12);
    EXPECT_NEAR(r.hf_distance[i], 0.3, 1e-12);
    EXPECT_EQ(r.model_count[i], 9u);  // 3 x 3 within 1.5 (the corners at sqrt(2) < 1.5)
  }
}

TEST(Baselines, NoModelFromCollinearNeighbours) {
  Cloud ref;
  for (int i = 0; i < 50; ++i) ref.add(0.1 * i, 0, 0);
  Cloud cmp;
  cmp.add(1.0, 1.0, 0.0);
  C2CParams p;
  p.model = LocalModel::kPlane;
  const C2CResult r = c2c(ref.view(), cmp.view(), p);
  EXPECT_TRUE(std::isnan(r.model_distance[0]));
  EXPECT_EQ(r.hf_distance[0], r.distance[0]);
  EXPECT_DOUBLE_EQ(r.distance[0], 1.0);
}

TEST(Baselines, SameBitsForAnyThreadCount) {
  const Pair pair = rough_pair(21, 5000);
  C2CParams p;
  p.model = LocalModel::kPlane;
  p.model_radius = 0.6;
  const C2CResult a = c2c(pair.reference.view(), pair.compared.view(), p, with_threads(1));
  const C2CResult b = c2c(pair.reference.view(), pair.compared.view(), p, with_threads(4));
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a.nearest[i], b.nearest[i]);
    EXPECT_EQ(std::memcmp(&a.distance[i], &b.distance[i], sizeof(double)), 0);
    EXPECT_EQ(std::memcmp(&a.hf_distance[i], &b.hf_distance[i], sizeof(double)), 0);
  }
}

TEST(Baselines, RejectsBadInputs) {
  const Cloud ref = random_box(1, 10, {0, 0, 0}, {1, 1, 1});
  Cloud empty;
  EXPECT_THROW(c2c(empty.view(), ref.view()), InvalidArgument);
  Cloud bad = ref;
  bad.xyz[4] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(c2c(ref.view(), bad.view()), InvalidArgument);
  C2CParams p;
  p.model = LocalModel::kPlane;
  p.model_radius = -1;
  EXPECT_THROW(c2c(ref.view(), ref.view(), p), InvalidArgument);
  p.model_radius = 0;
  p.model_neighbours = 2;
  EXPECT_THROW(c2c(ref.view(), ref.view(), p), InvalidArgument);
  EXPECT_TRUE(c2c(ref.view(), empty.view()).distance.empty());
}

}  // namespace
}  // namespace m3c2::test

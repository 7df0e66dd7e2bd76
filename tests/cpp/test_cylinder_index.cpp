// m3c2::CylinderIndex: counts against a brute-force cylinder, the mean and spread of the offsets
// against a direct two-pass sum, compute()'s own cylinder bits at the index's smallest diameter,
// and the same results for any thread count.

#include "test_support.hpp"

#include <m3c2/cylinder_index.hpp>

namespace m3c2::test {
namespace {

struct Axes {
  Cloud cores;
  std::vector<double> normals;
};

/// Core points over the pair's surface with tilted axes (not the grid's), some of them lifted
/// 3 m above it, so that short cylinders miss the cloud there and long ones reach it.
Axes tilted_axes(const Pair& pair) {
  Axes a;
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> tilt(-0.4, 0.4);
  for (std::size_t i = 0; i < pair.cores.size(); i += 3) {
    a.cores.add(pair.cores[i] + Vec3(0.0, 0.0, i % 2 ? 3.0 : 0.0));
    const Vec3 n = Vec3(tilt(rng), tilt(rng), 1.0).normalized();
    a.normals.insert(a.normals.end(), {n.x(), n.y(), n.z()});
  }
  a.normals[0] = a.normals[1] = a.normals[2] = 0.0;  // no axis: count 0
  return a;
}

TEST(CylinderIndex, CountsAndOffsetsAgainstBruteForce) {
  const Pair pair = rough_pair(11, 4000);
  const Axes axes = tilted_axes(pair);
  const CylinderIndex index(pair.reference.view(), 0.5);
  for (const auto& [diameter, half_length] :
       std::vector<std::pair<double, double>>{{0.5, 1.0}, {2.0, 1.0}, {0.5, 20.0}}) {
    const CylinderStatistics s = index.statistics(axes.cores.view(), axes.normals, diameter, half_length);
    std::size_t found = 0;
    for (std::size_t i = 0; i < axes.cores.size(); ++i) {
      const Vec3 n = normal_at(axes.normals, i), c = axes.cores[i];
      if (i == 0) {
        EXPECT_EQ(s.count[i], 0u);
        continue;
      }
      ASSERT_EQ(s.count[i], brute_cylinder_count(pair.reference, c, n, diameter / 2, -half_length, half_length)) << i;
      std::vector<double> t;
      for (std::size_t j = 0; j < pair.reference.size(); ++j) {
        const Vec3 d = pair.reference[j] - c;
        const double along = d.dot(n);
        if ((d - along * n).squaredNorm() <= diameter * diameter / 4 && std::abs(along) <= half_length)
          t.push_back(along);
      }
      if (t.empty()) {
        EXPECT_TRUE(std::isnan(s.mean[i]) && std::isnan(s.sigma[i])) << i;
        continue;
      }
      ++found;
      double mean = 0.0, ss = 0.0;
      for (const double v : t) mean += v;
      mean /= double(t.size());
      for (const double v : t) ss += (v - mean) * (v - mean);
      EXPECT_NEAR(s.mean[i], mean, 1e-12) << i;
      if (t.size() < 2)
        EXPECT_TRUE(std::isnan(s.sigma[i])) << i;
      else
        EXPECT_NEAR(s.sigma[i], std::sqrt(ss / double(t.size() - 1)), 1e-12) << i;
    }
    EXPECT_GT(found, axes.cores.size() / 4);
  }
}

TEST(CylinderIndex, SmallestDiameterGivesComputesBits) {
  // compute() with the axes imposed (kCorePoints) and no normal scales runs on the same grid.
  const Pair pair = rough_pair(12, 4000);
  const Axes axes = tilted_axes(pair);
  Params p;
  p.normal_source = NormalSource::kCorePoints;
  p.projection_diameter = 0.5;
  p.max_depth = 1.0;
  p.min_points = 1;
  const Result r = compute(pair.reference.view(), pair.compared.view(), axes.cores.view(), p, {}, axes.normals);
  const CylinderStatistics s =
      CylinderIndex(pair.reference.view(), 0.5).statistics(axes.cores.view(), axes.normals, 0.5, 1.0);
  std::size_t compared = 0;
  for (std::size_t i = 0; i < axes.cores.size(); ++i) {
    if (r.status[i] == PointStatus::kDegenerateNormal) continue;
    EXPECT_EQ(s.count[i], r.n1[i]) << i;
    if (r.n1[i] == 0 || r.n2[i] == 0) continue;  // compute() gives no offsets without both clouds
    ++compared;
    EXPECT_TRUE(BitIdentical(std::vector{s.mean[i], s.sigma[i]}, std::vector{r.i1[i], r.sigma1[i]})) << i;
  }
  EXPECT_GT(compared, axes.cores.size() / 4);
}

TEST(CylinderIndex, SameBitsForAnyThreadCount) {
  const Pair pair = rough_pair(13, 4000);
  const Axes axes = tilted_axes(pair);
  const CylinderStatistics one = CylinderIndex(pair.reference.view(), 0.5, with_threads(1))
                                     .statistics(axes.cores.view(), axes.normals, 2.0, 5.0, with_threads(1));
  const CylinderStatistics four = CylinderIndex(pair.reference.view(), 0.5, with_threads(4))
                                      .statistics(axes.cores.view(), axes.normals, 2.0, 5.0, with_threads(4));
  EXPECT_TRUE(BitIdentical(one.count, four.count));
  EXPECT_TRUE(BitIdentical(one.mean, four.mean));
  EXPECT_TRUE(BitIdentical(one.sigma, four.sigma));
}

TEST(CylinderIndex, RefusesBadArguments) {
  const Pair pair = rough_pair(14, 500);
  EXPECT_THROW(CylinderIndex(pair.reference.view(), 0.0), InvalidArgument);
  const CylinderIndex index(pair.reference.view(), 0.5);
  const std::vector<double> up = {0.0, 0.0, 1.0};
  Cloud one;
  one.add(1.0, 1.0, 0.0);
  EXPECT_THROW(index.statistics(one.view(), up, 0.25, 1.0), InvalidArgument);  // below the smallest
  EXPECT_THROW(index.statistics(one.view(), up, 0.5, 0.0), InvalidArgument);
  EXPECT_THROW(index.statistics(one.view(), {0.0, 1.0}, 0.5, 1.0), InvalidArgument);
  Cloud nan;
  nan.add(kNaN, 0.0, 0.0);
  EXPECT_THROW(index.statistics(nan.view(), up, 0.5, 1.0), InvalidArgument);
  EXPECT_THROW(CylinderIndex(nan.view(), 0.5), InvalidArgument);
}

}  // namespace
}  // namespace m3c2::test

// Rounding at the edges of the engine's geometric tests: each case here once went wrong by an
// ulp (found by review, reproduced, then fixed) and must stay right.

#include "test_support.hpp"

namespace m3c2::test {
namespace {

TEST(GridCorePoints, OriginNeverRoundsAboveTheLeftmostPoint) {
  // floor(1.7 / 0.1) * 0.1 == 1.7000000000000002 > 1.7: the leftmost point once got column -1,
  // which wrapped into the last column and spoiled both cells' medians.
  Cloud c;
  c.add(1.7, 0.0, 1.0);
  c.add(1.75, 0.0, 5.0);
  c.add(2.0, 0.0, 9.0);
  const Grid g = grid_core_points(c.view(), 0.1);
  ASSERT_LE(g.x0, 1.7);
  // Each point alone in its cell (z = its own median), and each cell centre within half a cell
  // of its point: the wrapped index had put x = 1.7 with x = 2.0 at the far right.
  ASSERT_EQ(g.core_points.size(), 9u);
  const double xs[] = {1.7, 1.75, 2.0}, zs[] = {1.0, 5.0, 9.0};
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(g.core_points[3 * k + 2], zs[k]);
    EXPECT_LE(std::abs(g.core_points[3 * k] - xs[k]), 0.05 + 1e-12);
  }
}

TEST(Subsample, PairsAFewUlpsCloserThanTheSpacingAreNeverBothKept) {
  // -1.2 - (-0.9) == -0.29999999999999993: closer than 0.3, yet rounding once put the two
  // points two cells apart and both were kept.
  Cloud c;
  for (const double x : {-3.3, -1.2, -0.9}) c.add(x, 0.0, 0.0);
  const auto kept = subsample_min_spacing(c.view(), 0.3);
  EXPECT_EQ(kept, (std::vector<std::uint64_t>{0, 1}));
}

TEST(CylinderQuery, RimCornersAtUtmCoordinatesAreCounted) {
  // Points on the rim of every segment boundary of a long, thin, tilted cylinder at a UTM
  // position: the segment centres are absolute coordinates whose rounding (about 1e-9 here)
  // once exceeded the search margin, and such points passed the cylinder test but were missed.
  const Vec3 core(500000.123, 5000000.456, 100.0);
  const Vec3 n = Vec3(0.3, 0.4, 0.8).normalized();
  const double d = 0.1, depth = 1.0, r = 0.5 * d;
  const auto [u, v] = orthonormal_basis(n);
  Cloud cloud;
  const int segments = 20;  // ceil(2 depth / d)
  for (int s = 0; s <= segments; ++s) {
    const double t = -depth + s * (2.0 * depth / segments);
    for (int a = 0; a < 24; ++a) {
      const double angle = a * (2.0 * M_PI / 24);
      cloud.add(core + t * n + r * (std::cos(angle) * u + std::sin(angle) * v));
    }
  }
  Params p = basic_params(1.0, d, depth);
  p.normal_source = NormalSource::kCorePoints;
  Cloud cores;
  cores.add(core);
  const std::vector<double> normals{n.x(), n.y(), n.z()};
  const Result res = compute(cloud.view(), cloud.view(), cores.view(), p, {}, normals);
  const std::uint32_t expected = brute_cylinder_count(cloud, core, n, r, -depth, depth);
  EXPECT_GT(expected, 200u);  // most rim points are inside by the exact predicate
  EXPECT_EQ(res.n1[0], expected);
  EXPECT_EQ(res.n2[0], expected);
}

TEST(Lod, NeedsTwoPointsPerCloudEvenWithPopulationVarianceAndMinPointsOne) {
  // With the population variance one point has sigma 0: an LOD from it would be z * reg and
  // the change "significant" on a single point; with the t statistic the DF would be 0.
  Cloud ref, cmp, cores;
  for (int k = 0; k < 5; ++k) ref.add(0.01 * k, 0.0, 0.001 * k);
  cmp.add(0.0, 0.0, 0.5);
  cores.add(0.0, 0.0, 0.0);
  Params p = basic_params(1.0, 0.2, 1.0);
  p.normal_source = NormalSource::kVertical;
  p.variance = Variance::kPopulation;
  p.min_points = 1;
  for (const bool t : {false, true}) {
    p.lod = t ? Lod::kAuto : Lod::kZ;
    const Result res = compute(ref.view(), cmp.view(), cores.view(), p);
    EXPECT_EQ(res.status[0], PointStatus::kTooFewPointsForLod);
    EXPECT_TRUE(std::isnan(res.lod[0]));
    EXPECT_EQ(res.significant[0], 0);
    EXPECT_DOUBLE_EQ(res.distance[0], 0.5 - 0.002);
  }
}

TEST(ImposedNormals, OrientationIsStillValidated) {
  Cloud c;
  c.add(0.0, 0.0, 0.0);
  Params p;
  p.normal_source = NormalSource::kVertical;
  p.projection_diameter = 1.0;
  p.max_depth = 1.0;
  p.orientation.direction[2] = 0.0;
  EXPECT_THROW(compute(c.view(), c.view(), c.view(), p), InvalidArgument);
}

TEST(CellIndices, AbsurdExtentForTheSpacingIsRefusedNotOverflowed) {
  // A stray point at 1e300 once overflowed the int64 cell index (undefined behaviour).
  Cloud c;
  c.add(0.0, 0.0, 0.0);
  c.add(1e300, 0.0, 0.0);
  EXPECT_THROW(subsample_min_spacing(c.view(), 0.1), InvalidArgument);
  EXPECT_THROW(grid_core_points(c.view(), 0.1), InvalidArgument);
}

}  // namespace
}  // namespace m3c2::test

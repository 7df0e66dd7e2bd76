// Where the normal comes from (section 3.1.2, NormalSource) and the two-pass depth search
// (section 5.3, DepthSearch::kTwoPass).
//
// Scene: the core point is the origin; the reference is the plane z = 0, the compared cloud a
// plane through (0, 0, 1) tilted to normal m. Both are grids symmetric under a half turn about
// their centre, so cylinders through those centres have exactly known mean positions.

#include "test_support.hpp"

namespace m3c2::test {
namespace {

const Vec3 kM = Vec3(0.3, 0.0, 1.0).normalized();

struct Scene {
  Cloud ref = plane_grid(Vec3::Zero(), Vec3::UnitZ(), 50, 0.04);  // +-2
  Cloud cmp = plane_grid(Vec3(0, 0, 1), kM, 50, 0.04);
  Cloud core = [] {
    Cloud c;
    c.add(0, 0, 0);
    return c;
  }();
};

Params source_params(NormalSource s) {
  Params p = basic_params(/*D=*/4.0, /*d=*/0.5, /*max_depth=*/3.0);
  p.normal_source = s;
  return p;
}

TEST(NormalSource, ReferenceUsesReferencePlaneNormal) {
  const Scene s;
  const Result r = compute(s.ref.view(), s.cmp.view(), s.core.view(), source_params(NormalSource::kReference));
  ASSERT_EQ(r.status[0], PointStatus::kOk);
  EXPECT_LT((normal_at(r.normal, 0) - Vec3::UnitZ()).norm(), 1e-10);
  // The z axis meets the compared grid at its centre (0, 0, 1): i2 = 1 by symmetry.
  EXPECT_NEAR(r.distance[0], 1.0, 1e-9);
}

TEST(NormalSource, ComparedUsesComparedPlaneNormal) {
  const Scene s;
  const Result r = compute(s.ref.view(), s.cmp.view(), s.core.view(), source_params(NormalSource::kCompared));
  ASSERT_EQ(r.status[0], PointStatus::kOk);
  EXPECT_LT((normal_at(r.normal, 0) - kM).norm(), 1e-10);
  // Every compared point has t = m . (0, 0, 1) = m_z; the reference cylinder is symmetric: i1 = 0.
  EXPECT_NEAR(r.i1[0], 0.0, 1e-9);
  EXPECT_NEAR(r.distance[0], kM.z(), 1e-9);
}

TEST(NormalSource, MeanIsNormalisedSumOfBothOrientedNormals) {
  const Scene s;
  const Result r = compute(s.ref.view(), s.cmp.view(), s.core.view(), source_params(NormalSource::kMean));
  ASSERT_EQ(r.status[0], PointStatus::kOk);
  const Vec3 n = (Vec3::UnitZ() + kM).normalized();
  EXPECT_LT((normal_at(r.normal, 0) - n).norm(), 1e-10);
  // The axis meets the compared plane at t = m_z / (m . n). The grid is not symmetric about that
  // point; with spacing 0.04 and ~120 points in the cylinder, the mean is off by < 1e-3 in-plane,
  // which moves t by < 1e-3 * sin(angle(n, m)) < 2e-4.
  EXPECT_NEAR(r.distance[0], kM.z() / kM.dot(n), 1e-3);
}

TEST(NormalSource, HorizontalDropsZFromReferenceNormal) {
  // A wall leaning back: normal (1, 0, 0.2); horizontal mode gives (1, 0, 0).
  const Vec3 wall_n = Vec3(1.0, 0.0, 0.2).normalized();
  const Cloud ref = plane_grid(Vec3::Zero(), wall_n, 30, 0.05);
  const Cloud cmp = plane_grid(Vec3(0.5, 0, 0), wall_n, 30, 0.05);
  Cloud core;
  core.add(0, 0, 0);
  Params p = source_params(NormalSource::kHorizontal);
  p.orientation.direction[0] = 1.0;
  p.orientation.direction[2] = 0.5;
  const Result r = compute(ref.view(), cmp.view(), core.view(), p);
  ASSERT_EQ(r.status[0], PointStatus::kOk);
  EXPECT_LT((normal_at(r.normal, 0) - Vec3::UnitX()).norm(), 1e-10);
  // Along +x the compared wall is 0.5 away in x (the axis meets it at its grid centre).
  EXPECT_NEAR(r.distance[0], 0.5, 1e-9);
}

TEST(NormalSource, CorePointsNormalIsUsedAndNormalised) {
  const Scene s;
  Params p = source_params(NormalSource::kCorePoints);
  const std::vector<double> given = {0.0, 0.0, 5.0};  // not unit: the unit vector is +Z
  const Result r = compute(s.ref.view(), s.cmp.view(), s.core.view(), p, {}, given);
  ASSERT_EQ(r.status[0], PointStatus::kOk);
  EXPECT_LT((normal_at(r.normal, 0) - Vec3::UnitZ()).norm(), 1e-12);
  EXPECT_NEAR(r.distance[0], 1.0, 1e-9);
}

// --- Two-pass depth search ------------------------------------------------------------------

Cloud flat(double z, int half = 20, double h = 0.1) { return plane_grid(Vec3(0, 0, z), Vec3::UnitZ(), half, h); }

TEST(DepthSearch, TwoPassFallsBackToMaxDepthWhenFirstPassFindsNothing) {
  const Cloud ref = flat(0.0), cmp = flat(3.0);
  Cloud core;
  core.add(0, 0, 0);
  Params p = basic_params(1.0, 0.35, 1.0);
  const Result single = compute(ref.view(), cmp.view(), core.view(), p);
  EXPECT_EQ(single.status[0], PointStatus::kEmptyCylinder2);
  p.depth_search = DepthSearch::kTwoPass;
  p.first_pass_depth = 1.0;
  p.max_depth = 5.0;
  const Result two = compute(ref.view(), cmp.view(), core.view(), p);
  ASSERT_EQ(two.status[0], PointStatus::kOk);
  EXPECT_NEAR(two.distance[0], 3.0, 1e-12);
  EXPECT_EQ(two.n2[0], brute_cylinder_count(cmp, Vec3::Zero(), Vec3::UnitZ(), 0.175, -5, 5));
}

TEST(DepthSearch, TwoPassKeepsFirstPassWhenItFindsPoints) {
  // Compared: a layer at z = 0.5 and another at z = 3. The first pass (half-length 1) sees only
  // the near layer; a single pass of half-length 5 averages both.
  const Cloud ref = flat(0.0);
  Cloud cmp = flat(0.5);
  cmp.append(flat(3.0));
  Cloud core;
  core.add(0, 0, 0);
  Params p = basic_params(1.0, 0.35, 5.0);
  const Result single = compute(ref.view(), cmp.view(), core.view(), p);
  EXPECT_NEAR(single.distance[0], 1.75, 1e-12);
  p.depth_search = DepthSearch::kTwoPass;
  p.first_pass_depth = 1.0;
  const Result two = compute(ref.view(), cmp.view(), core.view(), p);
  ASSERT_EQ(two.status[0], PointStatus::kOk);
  EXPECT_NEAR(two.distance[0], 0.5, 1e-12);
  EXPECT_EQ(two.n2[0], single.n2[0] / 2);
}

}  // namespace
}  // namespace m3c2::test
